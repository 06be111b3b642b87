"""Viewer + runtime World: a real window under Xvfb (the test starts and stops its
own server) and headless EGL.

Each case runs the viewer on a :class:`runtime.World` in a subprocess (pyglet chooses its
display backend once per process) and checks

* the screenshot: at the projected root of every character the World places on screen, and
  at the middle of every obstacle, the pixels differ from a bare frame (same camera, no
  characters, no obstacles); on empty ground they do not;
* a left click at a character's projected position selects it, and a right click on the
  ground sends it there. Under Xvfb both clicks are real X input events synthesized with the
  XTest extension (they go through the X server and pyglet's event loop); headless, they are
  the pyglet handlers called directly;
* the character arrives: its played motion, recorded tick by tick, is checked by the
  independent checker (``runtime.crowd.checker.check_crowd``): position error <= 1 mm at the
  clicked ground point, motion within eps, no obstacle overlap.
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from screenshots import Screenshot, xvfb_display

ROOT = Path(__file__).resolve().parents[1]
WORLD = ROOT / "samples" / "example_world" / "world.usda"

SCRIPT = r"""
import ctypes, json, sys
from pathlib import Path
import numpy as np
mode, lib, world, out = sys.argv[1:5]
out = Path(out)
from runtime.viewer import headless, make_viewer
headless.configure(mode == "headless")
import pyglet
from pyglet.window import mouse
from runtime.crowd.checker import check_crowd
from runtime.crowd.environment import Environment
from runtime.crowd.scenario import CharacterSpec, GoalSpec, Scenario
from runtime.crowd.tracks import Track
from runtime.motion.graph import MotionGraph
from runtime.world import MAX_BUFFER, World
from usd_io.world import read_world

env = read_world(world)
w = World(MotionGraph.load(lib), world=env, budget_ms=1e6, seed=2)
starts = [(-6.0, -6.0), (6.0, -6.0), (-6.0, 6.0), (6.0, 6.0), (0.0, -8.0), (-8.0, 0.0), (8.0, 1.0)]
for i, p in enumerate(starts):
    if env.distance(np.array([p]))[0] > 0.8:
        w.spawn(f"c{i}", p, heading=0.5 * i)
n = len(w.names)
v = make_viewer(w, headless=(mode == "headless"), width=1280, height=720)
v.paused = True                       # the World stands still while the screen is examined
v.hud.visible = False
v.run(max_frames=3)
W, H = v.framebuffer_size()

# -- screenshot: characters where the World says they are, obstacles, ground ------------------
v.run(max_frames=1, screenshot=out / "shot.png")
joints = w.joint_positions()          # the World's poses at the render time drawn
vp = v.view_projection()
view, proj = v.camera.view(), v.camera.projection(W, H)
v.renderer.set_environment(Environment.open_ground())
v.renderer.draw(view, proj, v.camera.eye, W, H, None, None)
v.save_screenshot(out / "bare.png")
v.renderer.set_environment(env, None, draw_boxes=False)
np.savez(out / "frame.npz", vp=vp, size=np.array([W, H]), joints=joints)

# -- select by a click at the character's projected position --------------------------------
roots = joints[:, 0].astype(float)
px, front = v.project(roots)
inside = front & (px[:, 0] > 40) & (px[:, 0] < W - 40) & (px[:, 1] > 60) & (px[:, 1] < H - 60)
d = np.hypot(*(px[:, None, :] - px[None, :, :]).transpose(2, 0, 1))
d[np.arange(n), np.arange(n)] = np.inf


def free_target(k):
    # a ground point 3-5 m from character k, on screen, reachable in a straight line, clear of
    # obstacles and of the other characters
    r = roots[k][[0, 2]]
    others = np.delete(roots[:, [0, 2]], k, axis=0)
    for dist in (4.0, 3.5, 3.0, 5.0):
        for ang in np.linspace(0, 2 * np.pi, 24, endpoint=False):
            g = r + dist * np.array([np.sin(ang), np.cos(ang)])
            gp, gf = v.project(np.array([g[0], 0.0, g[1]]))
            if (gf and 40 < gp[0] < W - 40 and 60 < gp[1] < H - 60 and env.distance(g[None])[0] > 0.8
                    and env.segment_clear(r, g, 0.5) and np.hypot(*(others - g).T).min() > 1.5):
                return gp
    return None


order = np.argsort(-np.where(inside, d.min(axis=1), -1.0), kind="stable")
k, target = next(((int(i), t) for i in order if inside[i] for t in [free_target(int(i))] if t is not None),
                 (None, None))
assert k is not None, "no character on screen with free ground near it"
name = w.names[k]

if mode == "window":
    x11 = ctypes.cdll.LoadLibrary("libX11.so.6")
    xtst = ctypes.cdll.LoadLibrary("libXtst.so.6")
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XWarpPointer.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_int, ctypes.c_int,
                                 ctypes.c_uint, ctypes.c_uint, ctypes.c_int, ctypes.c_int]
    x11.XSync.argtypes = [ctypes.c_void_p, ctypes.c_int]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    xtst.XTestFakeButtonEvent.argtypes = [ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_ulong]
    xtst.XTestQueryExtension.argtypes = [ctypes.c_void_p] + [ctypes.POINTER(ctypes.c_int)] * 4
    dpy = x11.XOpenDisplay(None)
    a, b, c, e = (ctypes.c_int() for _ in range(4))
    assert xtst.XTestQueryExtension(dpy, a, b, c, e), "the X server has no XTest extension"
    xwin = v.window._window

    def click(x, y, button):
        # window pixel (x, y), origin bottom-left (pyglet) -> X11 origin top-left
        x11.XWarpPointer(dpy, 0, xwin, 0, 0, 0, 0, int(x), int(H - 1 - y))
        xtst.XTestFakeButtonEvent(dpy, button, 1, 0)
        xtst.XTestFakeButtonEvent(dpy, button, 0, 0)
        x11.XSync(dpy, 0)
        for _ in range(20):                # let pyglet's event loop deliver it
            v.run(max_frames=1)
            if (button == 1 and v.selected is not None) or (button == 3 and v.commands_sent):
                break
else:
    def click(x, y, button):
        b = mouse.LEFT if button == 1 else mouse.RIGHT
        v.on_mouse_press(int(x), int(y), b, 0)
        v.on_mouse_release(int(x), int(y), b, 0)

x, y = (int(c) for c in px[k])
click(x, y, 1)
selected = v.selected

# -- right click on free ground near it ----------------------------------------------------
arrived = []
w.on("arrived", arrived.append)
click(int(target[0]), int(target[1]), 3)
sent = [[int(i), [float(c) for c in xz]] for i, xz in v.commands_sent]
v.close()

# -- the character walks there: record what it plays, tick by tick -------------------------
s, pb = w.slot(name), w.playback
rec = []
extra = 0
for _ in range(30 * 20):
    w.step(w.dt)
    f = pb.head[s] % MAX_BUFFER
    rec.append((int(pb.buf_a[s, f]), int(pb.buf_b[s, f]), float(pb.buf_t[s, f]), pb.buf_root[s, f].copy()))
    if arrived:
        extra += 1
        if extra > 5:
            break
result = {"mode": headless.current_mode(), "n": n, "k": k, "selected": selected, "sent": sent,
          "arrived": None if not arrived else [arrived[0].character, list(arrived[0].data["position"])]}
if sent:
    goal = np.array(sent[-1][1])
    tr = Track(np.array([q[0] for q in rec]), np.array([q[1] for q in rec]),
               np.array([q[2] for q in rec], np.float32), np.array([q[3] for q in rec]), 0)
    root0 = rec[0][3]
    sc = Scenario(name="click", path="", world=str(world), library=str(lib), duration=len(rec) / w.fps, seed=0,
                  epsilon=tuple(w.params.eps),
                  characters=[CharacterSpec(name, root0[:2].copy(), float(root0[2]), "stand", [GoalSpec(goal)])])
    rep = check_crowd(sc, {name: tr}, w.graph, env, w.fps)
    result["check"] = {"position_error_m": rep.goals[0]["position_error_m"],
                       "within_eps": rep.characters[name]["within_eps"],
                       "obstacle_overlaps": len(rep.obstacle_overlaps)}
print(json.dumps(result))
"""


def _run(mode, out, display=None, timeout=180):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT)
    env.pop("DISPLAY", None)
    if display:
        env["DISPLAY"] = display
    lib = _library()
    proc = subprocess.run([sys.executable, "-c", SCRIPT, mode, str(lib), str(WORLD), str(out)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"viewer subprocess failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


_LIB = []


def _library():
    return _LIB[0]


@pytest.fixture(autouse=True)
def _lib(default_graph):
    if not default_graph.path:
        pytest.skip("default library has no pack path")
    _LIB[:] = [default_graph.path]


@pytest.fixture
def xvfb():
    """A private Xvfb server (1280x720x24) started for the test; yields its DISPLAY string and
    stops it afterwards. Skips when Xvfb is not installed."""
    yield from xvfb_display()


def _check_screenshot(out: Path, n: int) -> int:
    """Pixels at the World's characters and at obstacles differ from the bare frame; empty
    ground far from everything does not. Returns the number of characters seen."""
    from usd_io.world import read_world
    shot = Screenshot(out)
    assert shot.joints.shape[0] == n
    shown = shot.drawn_at(shot.joints[:, 0], "characters", 0)
    env = read_world(WORLD)
    shot.obstacles_drawn(env)
    shot.empty_ground_is_bare(env)
    return shown


def _check_click_and_arrival(res):
    k = res["k"]
    assert res["selected"] == k, f"the click at character {k} selected {res['selected']}"
    assert res["sent"] and res["sent"][-1][0] == k, f"no go-to for character {k}: {res['sent']}"
    assert res["arrived"] is not None, "the character never arrived"
    goal = res["sent"][-1][1]
    pos = res["arrived"][1]
    assert abs(pos[0] - goal[0]) < 1e-3 and abs(pos[1] - goal[1]) < 1e-3
    chk = res["check"]
    assert chk["position_error_m"] <= 1e-3, chk
    assert chk["within_eps"] and chk["obstacle_overlaps"] == 0, chk


@pytest.mark.display
@pytest.mark.slow
def test_world_in_a_window_under_xvfb_screenshot_and_synthesized_clicks(xvfb, tmp_path):
    res = _run("window", tmp_path, display=xvfb)
    assert res["mode"] == "window"
    assert _check_screenshot(tmp_path, res["n"]) >= res["n"] - 1
    _check_click_and_arrival(res)


@pytest.mark.display
@pytest.mark.slow
def test_world_headless_screenshot_click_select_and_right_click_go_to(tmp_path):
    res = _run("headless", tmp_path)
    assert res["mode"] == "headless"
    assert _check_screenshot(tmp_path, res["n"]) >= res["n"] - 1
    _check_click_and_arrival(res)
