"""Viewer + runtime World (issue 5): clicking selects a character, a right-click on the ground
sends it there through World.go_to, and it arrives exactly there (headless EGL, subprocess)."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
WORLD = ROOT / "samples" / "example_world" / "world.usda"

SCRIPT = r"""
import json, sys
import numpy as np
lib, world = sys.argv[1:3]
from runtime.viewer import headless, make_viewer
headless.configure(True)
from pyglet.window import mouse
from runtime.motion.graph import MotionGraph
from runtime.world import World
from usd_io.world import read_world
env = read_world(world)
w = World(MotionGraph.load(lib), world=env, budget_ms=1e6, seed=2)
starts = [(-6.0, -6.0), (6.0, -6.0), (-6.0, 6.0), (6.0, 6.0), (0.0, -8.0)]
for i, p in enumerate(starts):
    if env.distance(np.array([p]))[0] > 0.8:
        w.spawn(f"c{i}", p)
v = make_viewer(w, headless=True, width=1280, height=720)
v.run(max_frames=2)
wd, ht = v.framebuffer_size()
roots = v.info.joint_positions[:, 0].astype(float)
px, front = v.project(roots)
inside = front & (px[:, 0] > 40) & (px[:, 0] < wd - 40) & (px[:, 1] > 60) & (px[:, 1] < ht - 120)
k = int(np.flatnonzero(inside)[0])
x, y = (int(c) for c in px[k])
v.on_mouse_press(x, y, mouse.LEFT, 0)
v.on_mouse_release(x, y, mouse.LEFT, 0)
r = roots[k][[0, 2]]
goal = None
for a in np.linspace(0, 2 * np.pi, 24, endpoint=False):
    g = r + 4.0 * np.array([np.sin(a), np.cos(a)])
    gp, gf = v.project(np.array([g[0], 0.0, g[1]]))
    if gf and 40 < gp[0] < wd - 40 and 60 < gp[1] < ht - 120 and env.distance(g[None])[0] > 0.8:
        goal = g
        break
gx, gy = (int(c) for c in gp)
clicked = v.camera.ground_hit(gx, gy, wd, ht) if hasattr(v.camera, "ground_hit") else None
arrived = []
w.on("arrived", arrived.append)
v.on_mouse_press(gx, gy, mouse.RIGHT, 0)
for _ in range(30 * 25):
    w.step(w.dt)
    if arrived:
        break
e = arrived[0] if arrived else None
print(json.dumps({"selected": v.selected, "k": k, "name": w.names[k],
                  "arrived": None if e is None else [e.character, list(e.data["position"])],
                  "clicked": None if clicked is None else [float(c) for c in clicked]}))
"""


@pytest.mark.display
@pytest.mark.slow
def test_right_click_sends_the_selected_character_and_it_arrives_exactly(default_graph):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT)
    env.pop("DISPLAY", None)
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(default_graph.path), str(WORLD)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    r = json.loads(proc.stdout.strip().splitlines()[-1])
    assert r["selected"] == r["k"]
    assert r["arrived"] is not None, "the character never arrived"
    name, pos = r["arrived"]
    assert name == r["name"]
    cx, cz = r["clicked"]
    assert abs(pos[0] - cx) < 1e-3 and abs(pos[1] - cz) < 1e-3      # exactly where the click hit the ground
