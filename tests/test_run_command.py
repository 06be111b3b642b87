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
    kinds = {k for k, *_ in w.crowd.commands}
    assert {"sit", "pick_up", "put_down", "go_to"} <= kinds
    boxes = w.box_positions()
    assert boxes.shape == (len(env.markers_with_role("box")), 4)


@pytest.mark.slow
def test_plaza_runs_crowd_tiling_and_flocks_in_one_tick(default_graph):
    """The main sample shows all three systems: goal-directed crowd characters, a tiled
    interaction zone and a flock, each advanced by the same World tick."""
    from authoring.commands.bake import load_sample
    from runtime.world import World
    sc, graph, env, roadmap = load_sample(ROOT / "samples" / "plaza", log=lambda *a: None, progress=False)
    assert sc.characters and sc.tilings and sc.flocks
    w = World(graph, world=env, roadmap=roadmap, seed=sc.seed, budget_ms=50)
    w.apply_scenario(sc)
    w.add_scenario_flocks(sc)
    w.add_scenario_tiling(sc)
    zone = w.tilings[0]
    fpos0 = w.flock_positions()[0].copy()
    tiled0 = zone.roots()[:, :2].copy()
    crowd0 = w.joint_positions()[:len(w.names), 0].copy()
    for _ in range(300):
        w.tick()
    pos = w.joint_positions()
    assert pos.shape[0] == len(w.names) + len(zone) == len(sc.characters) + 8
    assert np.linalg.norm(pos[:len(w.names), 0] - crowd0, axis=-1).max() > 1.0      # the crowd walks
    assert np.linalg.norm(zone.roots()[:, :2] - tiled0, axis=-1).mean() > 1.0       # the teams walk
    assert np.linalg.norm(w.flock_positions()[0] - fpos0, axis=-1).mean() > 1.0    # the birds fly
    assert w.stats["plans_done"] > 0
    rep = zone.check().summary()
    assert rep["interpenetrations"] == 0 and rep["danglings"] == 0 and rep["obstacle_hits"] == 0, rep
    # tiled characters stay inside the fenced zone (the crowd's roadmap keeps out of it)
    x0, z0, x1, z1 = zone.bounds
    r = zone.roots()
    assert ((r[:, 0] > x0) & (r[:, 0] < x1) & (r[:, 1] > z0) & (r[:, 1] < z1)).all()
    # and the birds keep inside their sky box (the flocks' independent walk checker)
    from authoring.commands.bake import bake_flocks
    rep = bake_flocks(sc, env, 30.0, 900)
    assert rep["passed"] and rep["frames_outside"] == 0, {k: v for k, v in rep.items() if k != "_arrays"}


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
    assert "313 characters (300 ambient)" in r.stdout and "8 tiled" in r.stdout and "p99" in r.stdout


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
    assert "no display (DISPLAY is not set)" in r.stdout and "313 characters" in r.stdout
    assert shot.exists() and shot.stat().st_size > 10_000
