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
