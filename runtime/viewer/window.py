"""The viewer window: a pyglet window (X11 or headless EGL), the orbit camera, the renderer,
the HUD, input handling and the frame loop. The scene is read only through
:class:`runtime.view.SceneView`; the optional members of
:class:`runtime.view.InteractiveSceneView` are looked up with ``getattr``.

Import this module only after :func:`runtime.viewer.headless.configure` (``run_viewer`` does it).
"""
from __future__ import annotations

import io
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import headless

headless.ensure()                       # pyglet's backend must be chosen before pyglet.window loads
import pyglet  # noqa: E402
from pyglet import gl  # noqa: E402
from pyglet.window import key, mouse  # noqa: E402

from ..assets import atomic_write_bytes  # noqa: E402
from ..view import SceneView  # noqa: E402
from .camera import OrbitCamera, look_at_landmark  # noqa: E402
from .hud import Hud, format_stats  # noqa: E402
from .render import Renderer  # noqa: E402

__all__ = ["Viewer", "FrameInfo"]

PICK_RADIUS_PX = 40.0
DRAG_THRESHOLD_PX = 4
HUD_REFRESH_S = 0.25       # the HUD's figures are refreshed this often (laying text out is not free)


@dataclass
class FrameInfo:
    """What the last frame showed: enough to locate things in a screenshot."""
    frames: int = 0
    seconds: float = 0.0
    fps: float = 0.0
    width: int = 0
    height: int = 0
    view_projection: np.ndarray = field(default_factory=lambda: np.eye(4))
    joint_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3)))
    flock_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    selected: int | None = None
    screenshot: str | None = None
    timings_ms: dict = field(default_factory=dict)


class Viewer:
    """Renders a scene (see :mod:`runtime.view`) in a window and handles input.

    ``window`` may be given (an existing pyglet window, e.g. owned by a game); otherwise one of
    ``width`` x ``height`` is created. ``frame_ms`` holds the last frame's timings (ms) of
    "step", "poses", "render" and "gl wait"."""

    def __init__(self, scene: SceneView, width: int = 1280, height: int = 720, window=None, caption="crowdweave",
                 vsync: bool = False, visible: bool = True):
        self.scene = scene
        if window is None:
            # 8 bits per channel: without asking, headless EGL picks RGB565, which llvmpipe fills
            # far more slowly than its native BGRA8 (and which bands the colours)
            # a stencil buffer lets overlapping floor markings shade each pixel once (render.py)
            config = gl.Config(double_buffer=True, depth_size=24, stencil_size=8, major_version=3, minor_version=3,
                               forward_compatible=True, red_size=8, green_size=8, blue_size=8, alpha_size=8)
            try:
                window = pyglet.window.Window(width, height, caption=caption, resizable=True, config=config,
                                              vsync=vsync, visible=visible)
            except pyglet.window.NoSuchConfigException:
                window = pyglet.window.Window(width, height, caption=caption, resizable=True, vsync=vsync,
                                              visible=visible)
        self.window = window
        self.camera = OrbitCamera()
        self.renderer = Renderer(scene.skeleton)
        self.renderer.characters.names_source = lambda: getattr(scene, "names", None)   # looks by name
        self.view_name = "overview"        # the last view a key (or the opening) chose
        self._rng = np.random.default_rng(0)   # "follow a random character" (R)
        self._last_positions = None
        self.selected: int | None = None
        self.follow = False
        self._env = None
        self._dynamic_boxes = False
        self._sync_environment()
        self.hud = Hud(window)
        self.paused = False
        self.time_scale = 1.0
        self.target_marker = None          # (x, z, until) of the last go-to command
        self.info = FrameInfo()
        self._press = None                 # (x, y, button, modifiers) of a pending left click
        self._dragged = False
        self._fps_frames = 0
        self._fps_t0 = time.perf_counter()
        self._fps = 0.0
        self._hud_due = 0.0                # when the HUD's text is next refreshed
        self._hud_key = None               # what refreshes it at once when it changes
        self.frame_ms: dict[str, float] = {}
        self.commands_sent: list[tuple[int, np.ndarray]] = []
        self._clock = None                 # time of the last update (kept across run() calls)
        window.push_handlers(self)

    # -- scene access -------------------------------------------------------------------------------
    def _optional(self, name: str):
        """The scene's optional member ``name`` (:class:`runtime.view.InteractiveSceneView`),
        or None when it has none."""
        return getattr(self.scene, name, None)

    def _sync_environment(self):
        """(Re)build the static environment mesh when the scene's environment object changes
        or the scene starts or stops providing ``box_positions``."""
        env = getattr(self.scene, "environment", None)
        dynamic_boxes = self._optional("box_positions") is not None
        if env is None or (env is self._env and dynamic_boxes == self._dynamic_boxes):
            return
        heights = self._optional("obstacle_heights")
        self.renderer.set_environment(env, heights, draw_boxes=not dynamic_boxes)
        if self._env is None:
            self.camera.frame(self.renderer.area, margin=0.85)
            self.jump("plaza")           # the busy part at a person's scale, when the scene says where
        self._env = env
        self._dynamic_boxes = dynamic_boxes

    def framebuffer_size(self):
        return self.window.get_framebuffer_size()

    def view_projection(self) -> np.ndarray:
        """The camera's 4x4 world -> clip matrix for the current framebuffer size."""
        w, h = self.framebuffer_size()
        return self.camera.view_projection(w, h)

    def project(self, points):
        """Framebuffer pixels (..., 2), origin bottom-left (the same as window/mouse coordinates
        except on HiDPI screens), and an in-front mask, for world points (..., 3)."""
        w, h = self.framebuffer_size()
        return self.camera.project(points, w, h)

    def _scale(self):
        """Framebuffer pixels per window (mouse) unit (1 except on HiDPI screens)."""
        w, _ = self.window.get_size()
        fw, _ = self.framebuffer_size()
        return fw / max(w, 1)

    # -- picking and commands ------------------------------------------------------------------------
    def pick(self, x: float, y: float):
        """Index of the character whose projected root is nearest window point (x, y) (within
        ``PICK_RADIUS_PX``), or None."""
        P = self._last_positions
        if P is None or len(P) == 0:
            P = np.asarray(self.scene.joint_positions())
        if len(P) == 0:
            return None
        s = self._scale()
        px, front = self.project(P[:, 0])
        d = np.hypot(px[:, 0] - (x + 0.5) * s, px[:, 1] - (y + 0.5) * s)
        d[~front] = np.inf
        i = int(np.argmin(d))
        return i if d[i] <= PICK_RADIUS_PX * s else None

    def select(self, i) -> None:
        self.selected = i
        select = self._optional("select")
        if select is not None:
            select(i)

    def ground_point(self, x: float, y: float):
        """(x, z) of the ground under the centre of window pixel (x, y), or None."""
        s = self._scale()
        w, h = self.framebuffer_size()
        return self.camera.ground_hit((x + 0.5) * s - 0.5, (y + 0.5) * s - 0.5, w, h)

    def go_to(self, x: float, y: float):
        """Send the selected character to the ground point under window pixel (x, y)."""
        if self.selected is None:
            return None
        hit = self.ground_point(x, y)
        if hit is None:
            return None
        command_go_to = self._optional("command_go_to")
        if command_go_to is not None:
            command_go_to(self.selected, hit)
        self.commands_sent.append((self.selected, hit))
        self.target_marker = (float(hit[0]), float(hit[1]), time.perf_counter() + 3.0)
        return hit

    # -- views ---------------------------------------------------------------------------------------
    def landmarks(self) -> dict:
        """The scene's named places (``landmarks()``: name -> (x, y, z, radius)), or {}."""
        f = self._optional("landmarks")
        return dict(f()) if f is not None else {}

    def jump(self, name: str) -> bool:
        """Point the camera at a view: "plaza" (the scene's busiest stretch, at a person's scale),
        "tiled" (the tiling zone), "flocks" (the birds, where they are now), "follow" (follow a
        random character). Returns False (camera unchanged) when the scene has no such place."""
        cam = self.camera
        if name == "follow":
            P = self._last_positions if self._last_positions is not None else np.asarray(self.scene.joint_positions())
            if P is None or len(P) == 0:
                return False
            self.select(int(self._rng.integers(len(P))))
            root = P[self.selected, 0]
            look_at_landmark(cam, name, (root[0], 0.0, root[2], 1.0))
            self.follow = True
            self.view_name = name
            return True
        spot = self.landmarks().get(name)
        if spot is None:
            return False
        look_at_landmark(cam, name, spot)
        self.follow = False
        self.view_name = name
        return True

    # -- pyglet events -------------------------------------------------------------------------------
    def on_mouse_press(self, x, y, button, modifiers):
        if button == mouse.RIGHT:
            self.go_to(x, y)
        elif button == mouse.LEFT:
            self._press = (x, y, button, modifiers)
            self._dragged = False

    def on_mouse_release(self, x, y, button, modifiers):
        if button == mouse.LEFT and self._press is not None:
            if not self._dragged:
                self.select(self.pick(x, y))
            self._press = None

    def on_mouse_drag(self, x, y, dx, dy, buttons, modifiers):
        if self._press is not None:
            px, py = self._press[:2]
            if abs(x - px) + abs(y - py) > DRAG_THRESHOLD_PX:
                self._dragged = True
        if buttons & mouse.MIDDLE or (buttons & mouse.LEFT and modifiers & key.MOD_SHIFT):
            self.camera.pan(dx, dy, self.window.get_size()[1])
            self.follow = False
        elif buttons & mouse.LEFT and self._dragged:
            self.camera.orbit(dx, dy)

    def on_mouse_scroll(self, x, y, scroll_x, scroll_y):
        self.camera.zoom(scroll_y)

    def on_key_press(self, symbol, modifiers):
        if symbol == key.SPACE:
            self.paused = not self.paused
        elif symbol in (key.PERIOD, key.NUM_DECIMAL):
            self.paused = True
            dt = self._optional("dt")
            self.scene.step(float(1.0 / 30.0 if dt is None else dt))
        elif symbol in (key.PLUS, key.EQUAL, key.NUM_ADD):
            self.time_scale = min(self.time_scale * 2.0, 16.0)
        elif symbol in (key.MINUS, key.NUM_SUBTRACT):
            self.time_scale = max(self.time_scale / 2.0, 1.0 / 16.0)
        elif symbol == key.F:
            self.follow = not self.follow
        elif symbol == key.H:
            self.hud.visible = not self.hud.visible
        elif symbol in (key.P, key.T, key.B, key.R):
            self.jump({key.P: "plaza", key.T: "tiled", key.B: "flocks", key.R: "follow"}[symbol])
        elif symbol == key.ESCAPE:
            self.window.has_exit = True
            return pyglet.event.EVENT_HANDLED

    def on_close(self):
        self.window.has_exit = True

    # -- frame ----------------------------------------------------------------------------------------
    def update(self, dt: float) -> None:
        t0 = time.perf_counter()
        if not self.paused:
            self.scene.step(dt * self.time_scale)
        self.frame_ms["step"] = (time.perf_counter() - t0) * 1e3

    def draw(self) -> None:
        self._sync_environment()
        t0 = time.perf_counter()
        P = np.asarray(self.scene.joint_positions())
        flock_positions, box_positions = self._optional("flock_positions"), self._optional("box_positions")
        flock = flock_positions() if flock_positions is not None else None
        boxes = box_positions() if box_positions is not None else None
        t1 = time.perf_counter()
        self._last_positions = P
        if self.follow and self.selected is not None and self.selected < len(P):
            root = P[self.selected, 0]
            self.camera.target += 0.15 * (np.array([root[0], self.camera.target[1], root[2]]) - self.camera.target)
        w, h = self.framebuffer_size()
        view, proj = self.camera.view(), self.camera.projection(w, h)
        vp = proj @ view
        rings = []
        if self.selected is not None and self.selected < len(P):
            r = P[self.selected, 0]
            rings.append((float(r[0]), float(r[2]), 0.55, (1.0, 0.85, 0.15, 0.95)))
        if self.target_marker is not None:
            x, z, until = self.target_marker
            if time.perf_counter() < until:
                rings.append((x, z, 0.45, (0.15, 0.85, 1.0, 0.95)))
            else:
                self.target_marker = None
        self.renderer.draw(view, proj, self.camera.eye, w, h, P, flock, self.selected, rings, boxes)
        t2 = time.perf_counter()
        self.frame_ms["poses"] = (t1 - t0) * 1e3
        self.frame_ms["render"] = (t2 - t1) * 1e3
        gl.glViewport(0, 0, w, h)
        self._draw_hud()
        self.info.width, self.info.height = w, h
        self.info.view_projection = vp
        self.info.joint_positions = P
        self.info.flock_positions = np.zeros((0, 3)) if flock is None else np.asarray(flock[0])
        self.info.selected = self.selected

    def _draw_hud(self):
        n = len(self._last_positions) if self._last_positions is not None else 0
        now = time.perf_counter()
        key = (self.selected, self.time_scale, self.paused, n, self.window.get_size())
        if now >= self._hud_due or key != self._hud_key:
            self._hud_due, self._hud_key = now + HUD_REFRESH_S, key
            hud_stats = self._optional("hud_stats")
            stats = dict(hud_stats()) if hud_stats is not None else {}
            vstats = {"fps": round(self._fps, 1), "render ms": round(self.frame_ms.get("render", 0.0), 2),
                      "speed": f"x{self.time_scale:g}" + (" PAUSED" if self.paused else "")}
            if "characters" not in stats:
                vstats["characters"] = n
            if self.selected is not None:
                vstats["selected"] = self.selected
            self.hud.update(format_stats(vstats, stats))
        gl.glDisable(gl.GL_DEPTH_TEST)
        gl.glEnable(gl.GL_BLEND)
        gl.glBlendFunc(gl.GL_SRC_ALPHA, gl.GL_ONE_MINUS_SRC_ALPHA)
        self.hud.draw()

    def grab_rgb(self) -> np.ndarray:
        """The frame just drawn (the back buffer) as (height, width, 3) uint8, top row first."""
        w, h = self.framebuffer_size()
        buf = (gl.GLubyte * (w * h * 3))()
        gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 1)
        gl.glReadPixels(0, 0, w, h, gl.GL_RGB, gl.GL_UNSIGNED_BYTE, buf)
        return np.frombuffer(buf, dtype=np.uint8).reshape(h, w, 3)[::-1]

    def save_screenshot(self, path) -> str:
        """Save the frame just drawn (the back buffer) as a PNG, atomically."""
        path = Path(path)
        img = pyglet.image.get_buffer_manager().get_color_buffer()
        buf = io.BytesIO()
        img.save("screenshot.png", file=buf, encoder=_png_encoder())
        atomic_write_bytes(path, buf.getvalue())
        return str(path)

    def _tick_fps(self):
        self._fps_frames += 1
        now = time.perf_counter()
        if now - self._fps_t0 >= 0.5:
            self._fps = self._fps_frames / (now - self._fps_t0)
            self._fps_frames = 0
            self._fps_t0 = now

    def run(self, seconds: float | None = None, screenshot=None, max_frames: int | None = None,
            min_frames: int = 1, finish: bool = True, record=None) -> FrameInfo:
        """The frame loop: events, ``scene.step`` by the elapsed real time (times the time
        scale, unless paused), draw, flip. Stops when the window closes, after ``seconds`` (and
        at least ``min_frames``) or ``max_frames``; then saves ``screenshot`` (the last frame)
        if given. ``finish`` waits for GL to complete each frame (honest frame times with
        software rendering). ``record`` (a :class:`~runtime.viewer.record.GifRecorder`) is
        handed the frames it asks for; the caller saves it."""
        win = self.window
        start = time.perf_counter()
        last = self._clock if self._clock is not None else start
        frames = 0
        while not win.has_exit:
            win.switch_to()
            win.dispatch_events()
            pyglet.clock.tick()
            now = time.perf_counter()
            self.update(min(now - last, 0.25))     # a stalled frame does not fast-forward the scene
            last = self._clock = now
            self.draw()
            if finish:
                t0 = time.perf_counter()
                gl.glFinish()
                self.frame_ms["gl wait"] = (time.perf_counter() - t0) * 1e3
            frames += 1
            self._tick_fps()
            elapsed = time.perf_counter() - start
            if record is not None and record.due(elapsed):
                record.add(self.grab_rgb(), elapsed)
            done = ((seconds is not None and elapsed >= seconds and frames >= min_frames)
                    or (max_frames is not None and frames >= max_frames))
            if done and screenshot is not None:
                self.info.screenshot = self.save_screenshot(screenshot)
            win.flip()
            if done:
                break
        elapsed = time.perf_counter() - start
        self.info.frames = frames
        self.info.seconds = elapsed
        self.info.fps = frames / elapsed if elapsed > 0 else 0.0
        self.info.timings_ms = dict(self.frame_ms)
        return self.info

    def close(self):
        try:
            self.window.remove_handlers(self)
        finally:
            self.window.close()


def _png_encoder():
    from pyglet.image.codecs.png import PNGImageEncoder
    return PNGImageEncoder()
