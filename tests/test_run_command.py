"""`crowdweave run` drives a sample's scenario through the runtime World and renders it."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_world_applies_a_scenario(default_graph):
    from authoring.commands.bake import load_sample
    from runtime.world import World
    sc, graph, env, roadmap = load_sample(ROOT / "samples" / "plaza", log=lambda *a: None, progress=False)
    w = World(graph, world=env, roadmap=roadmap, seed=sc.seed, budget_ms=1e6)
    w.apply_scenario(sc)
    assert sorted(w.names) == sorted(c.name for c in sc.characters)
    kinds = {k for k, *_ in w._commands}
    assert {"sit", "pick_up", "put_down", "go_to"} <= kinds
    boxes = w.box_positions()
    assert boxes.shape == (len(env.markers_with_role("box")), 4)


@pytest.mark.slow
@pytest.mark.display
def test_run_headless_screenshot(tmp_path, default_graph):
    out = tmp_path / "plaza.png"
    env = dict(os.environ)
    r = subprocess.run([sys.executable, "-m", "authoring.cli", "run", str(ROOT / "samples" / "plaza"), "--headless",
                        "--seconds", "2", "--screenshot", str(out), "--width", "640", "--height", "360"],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert out.exists() and out.stat().st_size > 10_000
    assert "13 characters" in r.stdout


def test_display_probe_reports_why_there_is_none(monkeypatch):
    from authoring.commands.demo import display_available
    monkeypatch.delenv("DISPLAY", raising=False)
    assert display_available() == (False, "DISPLAY is not set")
    monkeypatch.setenv("DISPLAY", ":987")          # no server there
    ok, why = display_available()
    assert not ok and ("cannot open display ':987'" in why or "libX11" in why)


@pytest.mark.slow
@pytest.mark.display
def test_demo_without_a_display_renders_the_plaza_headless(tmp_path, default_graph):
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    env["CROWDWEAVE_CACHE"] = str(Path(default_graph.path).parent)     # the library is built already
    shot = Path(env["CROWDWEAVE_CACHE"]) / "plaza.png"
    if shot.exists():
        shot.unlink()
    r = subprocess.run([sys.executable, "-m", "authoring.cli", "demo", "--quiet", "--seconds", "1"],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "no display (DISPLAY is not set)" in r.stdout and "13 characters" in r.stdout
    assert shot.exists() and shot.stat().st_size > 10_000
