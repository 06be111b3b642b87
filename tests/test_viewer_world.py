"""Viewer + runtime World (issue 5): a real window under Xvfb (the test starts and stops its
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
import select
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

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
s = w._chars[name].slot
rec = []
extra = 0
for _ in range(30 * 20):
    w.step(w.dt)
    f = w.head[s] % MAX_BUFFER
    rec.append((int(w.buf_a[s, f]), int(w.buf_b[s, f]), float(w.buf_t[s, f]), w.buf_root[s, f].copy()))
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
    result["check"] = {"position_error_m": rep["goals"][0]["position_error_m"],
                       "within_eps": rep["characters"][name]["within_eps"],
                       "obstacle_overlaps": len(rep["obstacle_overlaps"])}
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
    exe = shutil.which("Xvfb")
    if exe is None:
        pytest.skip("Xvfb is not installed (apt-get install -y xvfb)")
    r, wfd = os.pipe()
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen([exe, "-displayfd", str(wfd), "-screen", "0", "1280x720x24", "-nolisten", "tcp"],
                            pass_fds=(wfd,), stdout=subprocess.DEVNULL, stderr=log)
    os.close(wfd)
    try:
        buf, end = b"", time.monotonic() + 20.0
        while not buf.endswith(b"\n"):
            ready, _, _ = select.select([r], [], [], max(0.0, end - time.monotonic()))
            chunk = os.read(r, 64) if ready else b""
            if not chunk:
                break
            buf += chunk
        line = buf.decode().strip()
        if not line:
            log.seek(0)
            pytest.fail(f"Xvfb did not report a display: {log.read().decode(errors='replace')[-2000:]}")
        yield f":{line}"
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
        os.close(r)
        log.close()


def _png(path):
    from pyglet.extlibs import png   # pure Python decoder: no GL, no display
    w, h, rows, _ = png.Reader(filename=str(path)).asRGBA8()
    return np.array([np.frombuffer(bytes(row), np.uint8) for row in rows]).reshape(h, w, 4)[..., :3].astype(int)


def _check_screenshot(out: Path, n: int) -> int:
    """Pixels at the World's characters and at obstacles differ from the bare frame; empty
    ground far from everything does not. Returns the number of characters seen."""
    from runtime.viewer.camera import project
    from usd_io.world import read_world
    shot, bare = _png(out / "shot.png"), _png(out / "bare.png")
    f = np.load(out / "frame.npz")
    w, h = (int(v) for v in f["size"])
    assert shot.shape == bare.shape == (h, w, 3)
    vp, joints = f["vp"], f["joints"]
    assert joints.shape[0] == n

    def on_screen(px, front, m=3):
        return front & (px[:, 0] >= m) & (px[:, 0] < w - m) & (px[:, 1] >= m) & (px[:, 1] < h - m)

    def diff(px):
        """Largest colour difference (sum over RGB) in the 3x3 block around each pixel."""
        out_ = []
        for x, y in px:
            c, r = int(x), h - 1 - int(y)            # PNG rows run top to bottom
            out_.append(int(np.abs(shot[r - 1:r + 2, c - 1:c + 2] - bare[r - 1:r + 2, c - 1:c + 2]).sum(-1).max()))
        return np.array(out_)

    px, front = project(vp, joints[:, 0].astype(float), w, h)
    vis = on_screen(px, front)
    d = diff(px[vis])
    assert (d > 40).all(), f"characters not drawn at {px[vis][d <= 40].round(1).tolist()} (diffs {d[d <= 40]})"
    env = read_world(WORLD)
    centres = [p.mean(axis=0) for p in env.polygons] + [c[:2] for c in env.circles]
    px, front = project(vp, np.array([[c[0], 0.5, c[1]] for c in centres]), w, h)
    vis_o = on_screen(px, front)
    assert vis_o.sum() >= len(centres) - 1
    d = diff(px[vis_o])
    assert (d > 40).all(), f"obstacles not drawn at {px[vis_o][d <= 40].round(1).tolist()}"
    rng = np.random.default_rng(0)
    x0, z0, x1, z1 = env.bounds(1.0)
    g = np.column_stack([rng.uniform(x0, x1, 600), rng.uniform(z0, z1, 600)])
    far = env.distance(g) > 1.0
    far &= np.min(np.hypot(*(g[:, None, :] - joints[None, :, 0, [0, 2]]).transpose(2, 0, 1)), axis=1) > 2.5
    mk = np.array([m.position for m in env.markers.values()])
    far &= np.min(np.hypot(*(g[:, None, :] - mk[None]).transpose(2, 0, 1)), axis=1) > 2.0
    for m in env.markers.values():
        if m.polygon is not None:
            lo, hi = m.polygon.min(axis=0) - 0.5, m.polygon.max(axis=0) + 0.5
            far &= ~np.all((g >= lo) & (g <= hi), axis=1)
    gp, gf = project(vp, np.column_stack([g[:, 0], np.zeros(len(g)), g[:, 1]]), w, h)
    ok = far & on_screen(gp, gf)
    assert ok.sum() >= 20
    assert (diff(gp[ok]) <= 24).mean() >= 0.8, "empty ground differs from the bare frame"
    return int(vis.sum())


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
