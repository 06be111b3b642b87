"""The viewer: a real window under Xvfb (the test starts and stops its own server), headless EGL,
picking and right-click commands, camera maths, and that importing the runtime loads no GL.

pyglet chooses its display backend once per process, so every rendering case runs in a
subprocess; both modes are exercised in one pytest run. A screenshot is checked against a second
frame rendered by the same viewer with the same camera but no characters and no obstacles: at
the projected position of every visible character root and every obstacle the pixels must
differ from that bare ground/sky frame, and at empty ground away from everything they must not.
"""
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from screenshots import Screenshot, xvfb_display

ROOT = Path(__file__).resolve().parents[1]
WORLD = ROOT / "samples" / "example_world" / "world.usda"

SHOT_SCRIPT = r"""
import json, sys
from pathlib import Path
import numpy as np
mode, lib, world, out, n = sys.argv[1:6]
out = Path(out)
from runtime.viewer import headless, make_viewer, TrackScene
headless.configure(mode == "headless")
from runtime.crowd.environment import Environment
from runtime.motion.graph import MotionGraph
from usd_io.world import read_world
scene = TrackScene(MotionGraph.load(lib), int(n), read_world(world), seed=3, flock=8)
v = make_viewer(scene, headless=(mode == "headless"), width=1280, height=720)
info = v.run(seconds=1.0, min_frames=3, screenshot=out / "shot.png")
w, h = info.width, info.height
view, proj = v.camera.view(), v.camera.projection(w, h)
assert np.allclose(proj @ view, info.view_projection)
# the same camera, no characters, no obstacles, no HUD: the ground/background reference
v.renderer.set_environment(Environment.open_ground())
v.renderer.draw(view, proj, v.camera.eye, w, h, None, None)
v.save_screenshot(out / "bare.png")
np.savez(out / "frame.npz", vp=info.view_projection, size=np.array([w, h]), joints=info.joint_positions,
         flock=info.flock_positions, hud=np.array(v.hud.rects(), dtype=float).reshape(-1, 4))
import pyglet
print(json.dumps({"frames": info.frames, "fps": info.fps, "renderer": pyglet.gl.gl_info.get_renderer(),
                  "mode": headless.current_mode(), "lod": v.renderer.lod_counts}))
v.close()
"""

CLICK_SCRIPT = r"""
import json, sys
import numpy as np
lib, world = sys.argv[1:3]
from runtime.viewer import headless, make_viewer, TrackScene
headless.configure(True)
from pyglet.window import mouse
from runtime.motion.graph import MotionGraph
from usd_io.world import read_world
env = read_world(world)
scene = TrackScene(MotionGraph.load(lib), 30, env, seed=5)
v = make_viewer(scene, headless=True, width=1280, height=720)
v.run(max_frames=2)
w, h = v.framebuffer_size()
roots = v.info.joint_positions[:, 0].astype(float)
px, front = v.project(roots)
inside = front & (px[:, 0] > 40) & (px[:, 0] < w - 40) & (px[:, 1] > 60) & (px[:, 1] < h - 120)
d = np.hypot(*(px[:, None, :] - px[None, :, :]).transpose(2, 0, 1))
d[np.arange(len(d)), np.arange(len(d))] = np.inf
sep = np.where(inside, d.min(axis=1), -1.0)
k = int(np.argmax(sep))
x, y = (int(c) for c in px[k])
v.on_mouse_press(x, y, mouse.LEFT, 0)
v.on_mouse_release(x, y, mouse.LEFT, 0)
selected = [v.selected, scene.selected]
# a ground point 4 m from the character, reachable in a straight line, on screen
r = roots[k][[0, 2]]
goal = None
for a in np.linspace(0, 2 * np.pi, 16, endpoint=False):
    g = r + 4.0 * np.array([np.sin(a), np.cos(a)])
    gp, gf = v.project(np.array([g[0], 0.0, g[1]]))
    if gf and 40 < gp[0] < w - 40 and 60 < gp[1] < h - 120 and env.segment_clear(r, g, 0.5) and env.distance(g) > 0.8:
        goal = g
        break
assert goal is not None
gx, gy = (int(c) for c in gp)
v.on_mouse_press(gx, gy, mouse.RIGHT, 0)
cmd = scene.commands[-1]
# the character walks there (greedy wander towards its way point)
best = np.inf
for _ in range(25 * 30):
    scene.step(1 / 30)
    best = min(best, float(np.hypot(*(scene.roots()[k, :2] - goal))))
    if best < 1.0:
        break
# keys: space pauses, '.' steps one tick, +/- scale time
from pyglet.window import key
v.on_key_press(key.SPACE, 0)
paused = v.paused
t0 = scene.ticks
v.run(max_frames=3)
frozen = scene.ticks == t0
v.on_key_press(key.PERIOD, 0)
stepped = scene.ticks - t0
v.on_key_press(key.PLUS, 0)
v.on_key_press(key.PLUS, 0)
v.on_key_press(key.MINUS, 0)
keys = {"paused": paused, "frozen": frozen, "stepped": stepped, "scale": v.time_scale}
# movable boxes from scene.box_positions() are drawn (and replace the static box markers)
import pyglet
def frame_rgb():
    v.draw()
    img = pyglet.image.get_buffer_manager().get_color_buffer().get_image_data()
    return np.frombuffer(img.get_data("RGB", w * 3), np.uint8).reshape(h, w, 3).astype(int)
box = np.array([goal[0], 0.0, goal[1], 0.4])
before = frame_rgb()
scene.box_positions = lambda: box[None]
after = frame_rgb()
bp, _ = v.project(box[:3] + [0.0, 0.2, 0.0])
bx, by = (int(c) for c in bp)
box_diff = int(np.abs(after[by, bx] - before[by, bx]).sum())
markers = [m.position for m in env.markers_with_role("box")]
mp, _ = v.project(np.array([[m[0], 0.2, m[1]] for m in markers]))
static_gone = [int(np.abs(after[int(y), int(x)] - before[int(y), int(x)]).sum()) for x, y in mp
               if 0 <= x < w and 0 <= y < h]
print(json.dumps({"k": k, "selected": selected, "cmd_index": cmd[0], "cmd_xz": cmd[1].tolist(),
                  "goal": goal.tolist(), "closest": best, "pixel": [gx, gy], "keys": keys,
                  "box_diff": box_diff, "static_box_diffs": static_gone}))
v.close()
"""


def _run(script, args, env_extra=None, drop_display=False, timeout=240):
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT))
    if drop_display:
        env.pop("DISPLAY", None)
    env.update(env_extra or {})
    proc = subprocess.run([sys.executable, "-c", script, *map(str, args)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, f"viewer subprocess failed:\n{proc.stdout}\n{proc.stderr[-4000:]}"
    return json.loads(proc.stdout.strip().splitlines()[-1])


FLOOR_SCRIPT = r"""
import json
import numpy as np
from runtime.viewer import headless
headless.configure(True)
import pyglet
from pyglet import gl
from runtime.crowd.environment import Environment, Marker
from runtime.motion.skeleton import Skeleton
from runtime.viewer.camera import OrbitCamera
from runtime.viewer.gl import Mesh
from runtime.viewer.lighting import SKY_HORIZON, fog_range, shade_uniforms
from runtime.viewer.meshes import environment_mesh
from runtime.viewer.render import Renderer
W, H = 960, 540
config = gl.Config(double_buffer=True, depth_size=24, stencil_size=8, major_version=3, minor_version=3,
                   forward_compatible=True, red_size=8, green_size=8, blue_size=8, alpha_size=8)
win = pyglet.window.Window(W, H, config=config, visible=False)
turned = np.array([[0.0, -3.0], [3.0, 0.0], [0.0, 3.0], [-3.0, 0.0]]) + [0.0, -12.0]
env = Environment([[[8, 8], [10, 8], [10, 10], [8, 10.0]]], None, [
    Marker("/a", "region", (0, 0), 0.0, [[-6, -4], [6, -4], [6, 4], [-6, 4]]),
    Marker("/b", "region", (1, 1), 0.0, [[-5, -3], [7, -3], [7, 5], [-5, 5]]),     # coplanar, overlapping /a
    Marker("/c", "region", (0, -12), 0.0, turned),                                  # not axis-aligned
    Marker("/s", "spawn", (2, 1), 0.3), Marker("/t", "seat", (-2, 2), 1.0)])
r = Renderer(Skeleton(["r", "a"], np.array([-1, 0]), [[0, 0, 0], [0, 0.5, 0]]))
r.set_environment(env)
cam = OrbitCamera(target=np.array([1.0, 0.0, -2.0]), distance=26.0, yaw=0.6, pitch=0.55)
view, proj, eye = cam.view(), cam.projection(W, H), cam.eye

def grab():
    buf = (gl.GLubyte * (W * H * 3))()
    gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 1)
    gl.glReadPixels(0, 0, W, H, gl.GL_RGB, gl.GL_UNSIGNED_BYTE, buf)
    return np.frombuffer(buf, np.uint8).reshape(H, W, 3).astype(int)

r.draw(view, proj, eye, W, H)
shot = grab()
# the painter's order: the whole backdrop, then everything in the environment's mesh order
r.backdrop.set_area(r.area)
gl.glViewport(0, 0, W, H)
gl.glClearColor(*SKY_HORIZON, 1.0)
gl.glClear(gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT | gl.GL_STENCIL_BUFFER_BIT)
centre = np.array([0.5 * (r.area[0] + r.area[2]), 0.0, 0.5 * (r.area[1] + r.area[3])])
dist = float(np.linalg.norm(eye - centre))
shade = shade_uniforms(fog_range(dist))
r.backdrop.draw(view, proj @ view, eye, dist, shade)
gl.glEnable(gl.GL_DEPTH_TEST)
gl.glDepthFunc(gl.GL_LEQUAL)
m = Mesh([(0, 3), (1, 3), (2, 3)])
m.upload(environment_mesh(env))
r._draw_lit(m, proj @ view, eye, shade)
ref = grab()
d = np.abs(shot - ref).sum(axis=2)
fill = np.array([0.76, 0.72, 0.60]) * 255
print(json.dumps({"over2": float((d > 2).mean()), "over12": int((d > 12).sum()), "max": int(d.max()),
                  "floor_in_view": float((np.abs(ref - fill).sum(axis=2) < 150).mean())}))
"""


@pytest.fixture(scope="module")
def xvfb():
    """A private Xvfb server (1280x720x24) for this module; yields its DISPLAY string."""
    yield from xvfb_display()


def _check_screenshot(out: Path, n: int):
    """Pixels at characters, flock agents and obstacles differ from the bare frame; empty
    ground does not."""
    from usd_io.world import read_world
    shot = Screenshot(out)
    assert shot.joints.shape[0] == n
    # characters: their roots (hips), where the world says they are
    shown = shot.drawn_at(shot.joints[:, 0], "characters", int(0.75 * n))
    # flock agents: arrowheads on the ground
    fl = shot.frame["flock"]
    assert len(fl) == 8
    shot.drawn_at(fl + [0.0, 0.1, 0.0], "flock agents", 4)
    env = read_world(WORLD)
    shot.obstacles_drawn(env)
    shot.empty_ground_is_bare(env)
    return shown


@pytest.fixture(scope="module")
def library(default_graph):
    if not default_graph.path:
        pytest.skip("default library has no pack path")
    return default_graph.path


@pytest.mark.display
@pytest.mark.slow
def test_window_under_xvfb_shows_ground_obstacles_and_characters(xvfb, library, tmp_path):
    n = 40
    res = _run(SHOT_SCRIPT, ["window", library, WORLD, tmp_path, n], env_extra={"DISPLAY": xvfb})
    assert res["mode"] == "window" and res["frames"] >= 2
    shown = _check_screenshot(tmp_path, n)
    assert shown >= 30


@pytest.mark.display
@pytest.mark.slow
def test_headless_egl_shows_ground_obstacles_and_characters(library, tmp_path):
    n = 40
    res = _run(SHOT_SCRIPT, ["headless", library, WORLD, tmp_path, n], drop_display=True)
    assert res["mode"] == "headless" and res["frames"] >= 2
    shown = _check_screenshot(tmp_path, n)
    assert shown >= 30


@pytest.mark.display
@pytest.mark.slow
def test_click_selects_right_click_sends_the_character_there_and_keys_work(library):
    res = _run(CLICK_SCRIPT, [library, WORLD], drop_display=True)
    k = res["k"]
    assert res["selected"] == [k, k]
    assert res["cmd_index"] == k
    err = math.hypot(res["cmd_xz"][0] - res["goal"][0], res["cmd_xz"][1] - res["goal"][1])
    assert err < 0.05, f"go-to target {res['cmd_xz']} is {err * 100:.1f} cm from the clicked ground point {res['goal']}"
    assert res["closest"] < 1.0, f"character {k} got no closer than {res['closest']:.2f} m to its target"
    assert res["keys"] == {"paused": True, "frozen": True, "stepped": 1, "scale": 2.0}
    assert res["box_diff"] > 40, "a box from scene.box_positions() was not drawn"
    assert res["static_box_diffs"] and min(res["static_box_diffs"]) > 40, "static box markers still drawn"


@pytest.mark.display
def test_floor_markings_first_and_backdrop_last_paint_the_painters_picture():
    """Overlapping coplanar region fills, a turned one, a spawn disc, a seat and an obstacle:
    drawn front to back (floor markings topmost first under a stencil, the backdrop at the far
    plane, less what rectangular fills hide), the frame is the one the painter's order gives
    (the whole backdrop first, then the environment in its mesh order)."""
    res = _run(FLOOR_SCRIPT, [], drop_display=True)
    assert res["floor_in_view"] > 0.1, res
    assert res["over2"] < 0.002 and res["over12"] <= 40, res


# -- no display needed ------------------------------------------------------------------------------

def test_camera_projection_and_ground_picking_round_trip():
    from runtime.viewer.camera import OrbitCamera
    cam = OrbitCamera(target=np.array([2.0, 0.0, -1.0]), distance=18.0, yaw=0.7, pitch=0.6)
    w, h = 1280, 720
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-8, 8, 50), np.zeros(50), rng.uniform(-8, 8, 50)])
    px, front = cam.project(pts, w, h)
    assert front.all()
    for p, q in zip(pts, px):
        hit = cam.ground_hit(q[0] - 0.5, q[1] - 0.5, w, h)   # a pixel is taken at its centre
        assert np.abs(hit - p[[0, 2]]).max() < 1e-6
    # the target projects to the middle of the window; a point behind the eye is flagged
    c, f = cam.project(cam.target, w, h)
    assert f and np.allclose(c, [w / 2, h / 2])
    behind = cam.eye + (cam.eye - cam.target)
    assert not cam.project(behind, w, h)[1]
    # a ray above the horizon meets no ground
    up = OrbitCamera(distance=10.0, pitch=0.05)
    assert up.ground_hit(640, 719, w, h) is None


def test_runtime_imports_no_gl_and_mode_conflicts_are_reported():
    code = r"""
import sys, runtime, runtime.pose, runtime.viewer, runtime.viewer.camera, runtime.viewer.scene, runtime.viewer.meshes
import runtime.viewer.figures, runtime.viewer.lighting
assert not any(m.startswith("pyglet") for m in sys.modules), sorted(m for m in sys.modules if m.startswith("pyglet"))
from runtime.viewer import headless
assert headless.current_mode() is None
assert headless.configure(True) == "headless"
import pyglet.window
assert headless.current_mode() == "headless"
try:
    headless.configure(False)
except headless.ModeError as e:
    print("ok", e)
"""
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.startswith("ok") and "separate process" in proc.stdout


def test_figure_style_meshes_and_polygon_triangulation(default_graph):
    from runtime.motion.skeleton import Skeleton
    from runtime.viewer.figures import FigureStyle
    from runtime.viewer.meshes import capsule_mesh, environment_mesh, triangulate
    from runtime.crowd.environment import Environment, Marker
    sk = default_graph.skeleton
    st = FigureStyle.for_skeleton(sk)
    assert len(st.near) == 14 and len(st.far) == 6
    J = sk.num_joints + len(st.virtual)
    for bs in (st.near, st.far):
        assert bs.a.max() < J and bs.b.max() < J and (bs.a != bs.b).all() and (bs.radius > 0).all()
    pts = st.points(np.zeros((2, sk.num_joints, 3)) + np.arange(sk.num_joints)[None, :, None] * [0, 0.1, 0])
    assert pts.shape == (2, J, 3)
    head, neck, length = st.virtual[0]
    assert np.allclose(pts[0, -1], pts[0, head] + length * np.array([0, 1, 0]) * np.sign(head - neck))
    # any other skeleton: one capsule per bone longer than 3 cm
    other = Skeleton(["r", "a", "b", "c"], np.array([-1, 0, 1, 1]), [[0, 0, 0], [0, 0.5, 0], [0, 0.01, 0], [0.2, 0, 0]])
    g = FigureStyle.for_skeleton(other)
    assert sorted(zip(g.near.a.tolist(), g.near.b.tolist())) == [(0, 1), (1, 3)]
    # capsule mesh: closed, outward winding
    v, idx = capsule_mesh(8, 1)
    tri = idx.reshape(-1, 3)
    p = v[:, :3] * 0.3 + np.c_[np.zeros((len(v), 2)), v[:, 3]]
    n = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    assert (np.sum(n * v[tri].mean(axis=1)[:, :3], axis=1) > 0).all()
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert (counts == 2).all()
    # ear clipping of a concave polygon covers exactly its area
    poly = np.array([[0, 0], [4, 0], [4, 3], [2, 1], [0, 3.0]])
    t = triangulate(poly)
    a = poly[t]
    u, w = a[:, 1] - a[:, 0], a[:, 2] - a[:, 0]
    area = 0.5 * np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]).sum()
    assert len(t) == 3 and abs(area - 8.0) < 1e-9
    # environment mesh: unit normals, prisms up to their height, markers drawn
    env = Environment([poly], [[6, 0, 0.5]], [Marker("/seat", "seat", (0, -3), 0.0)])
    m = environment_mesh(env, heights=[2.0, 0.5])
    assert np.allclose(np.linalg.norm(m[:, 3:6], axis=1), 1.0, atol=1e-5)
    assert abs(m[:, 1].max() - 2.0) < 1e-6
    near_seat = np.hypot(m[:, 0] - 0, m[:, 2] + 3) < 0.5
    assert near_seat.any() and m[near_seat, 1].max() > 0.8


def test_floor_split_and_what_the_backdrop_leaves_out():
    from runtime.crowd.environment import Environment, Marker
    from runtime.viewer.meshes import FLOOR_MAX_Y, environment_mesh, floor_rects, line_pieces, rect_minus, split_floor
    turned = np.array([[0.0, -3.0], [3.0, 0.0], [0.0, 3.0], [-3.0, 0.0]])
    env = Environment([[[8, 8], [10, 8], [10, 10], [8, 10.0]]], None, [
        Marker("/a", "region", (0, 0), 0.0, [[-6, -4], [6, -4], [6, 4], [-6, 4]]),
        Marker("/c", "region", (0, -12), 0.0, turned), Marker("/s", "spawn", (2, 1), 0.3),
        Marker("/t", "seat", (-2, 2), 1.0)])
    mesh = environment_mesh(env)
    floor, rest = split_floor(mesh)
    assert len(floor) + len(rest) == len(mesh) and len(floor) % 3 == 0 and len(rest) % 3 == 0
    assert (floor[:, 1] <= FLOOR_MAX_Y).all() and np.allclose(floor[:, 3:6], [0, 1, 0])
    ty = floor[::3, 1]
    assert (np.diff(ty) <= 0).all() and ty[0] > ty[-1]              # topmost first
    assert rest[:, 1].max() > 0.9 and rest[:, 1].max() == mesh[:, 1].max()   # the obstacle and the seat
    assert sorted(map(tuple, np.unique(np.round(floor[:, 6:9], 4), axis=0))) == sorted(
        map(tuple, np.unique(np.round(mesh[(mesh[:, 1] <= FLOOR_MAX_Y) & (mesh[:, 4] > 0.999), 6:9], 4), axis=0)))
    assert floor_rects(env) == [(-6.0, -4.0, 6.0, 4.0)]               # the turned square is not one
    # a rectangle less holes: the uncovered area, in cells that do not overlap the holes
    rect, holes = (0.0, 0.0, 10.0, 6.0), [(2.0, 1.0, 4.0, 3.0), (3.0, 2.0, 12.0, 4.0)]
    cells = rect_minus(rect, holes)
    area = sum((c[2] - c[0]) * (c[3] - c[1]) for c in cells)
    assert abs(area - (60.0 - 4.0 - 14.0 + 1.0)) < 1e-9
    for c in cells:
        for h in holes:
            assert min(c[2], h[2]) <= max(c[0], h[0]) or min(c[3], h[3]) <= max(c[1], h[1])
    assert rect_minus(rect, [(-1, -1, 11, 7)]) == [] and rect_minus(rect, []) == [rect]
    # a line less what lies under a hole (but for the overlap), through the uncut line's points
    whole = line_pieces(-150.0, 150.0, 25.0, [])
    assert len(whole) == 1 and np.allclose(whole[0], np.linspace(-150, 150, 13))
    runs = line_pieces(-150.0, 150.0, 25.0, [(-36.5, 36.5)], overlap=0.5)
    assert [r[-1] for r in runs][:1] == [-36.0] and runs[1][0] == 36.0
    kept = np.concatenate(runs)
    assert set(np.linspace(-150, 150, 13)) - set(kept) == {-25.0, 0.0, 25.0}
    assert line_pieces(0.0, 10.0, 25.0, [(-1.0, 11.0)]) == []
