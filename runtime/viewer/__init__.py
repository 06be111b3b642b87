"""The crowdweave viewer: a pyglet window or headless EGL renderer for any scene.

pyglet's GL modules are imported only inside this package, and lazily: importing
``runtime.viewer`` loads no GL (pyglet's window backend is chosen once per process, see
:mod:`runtime.viewer.headless`). :func:`run_viewer` selects the backend, then imports the
window and renderer.

Scene protocol
--------------
The viewer reads a scene only through :class:`runtime.view.SceneView` (``environment``,
``skeleton``, ``joint_positions()``, ``step(dt)``) and the optional members of
:class:`runtime.view.InteractiveSceneView` (``dt``, ``obstacle_heights``,
``flock_positions()``, ``box_positions()``, ``hud_stats()``, ``select(i)``,
``command_go_to(i, xz)``, ``landmarks()``), each used when the scene has it. A :class:`runtime.World`
provides them all; :class:`TrackScene` is a stand-in. The skeleton's joint names choose the
figure style (CMU names give shaded capsule-limbed people); joint 0 of each character is its
root (picking, shadows, selection ring); movable boxes from ``box_positions()`` (0.4 m crates)
are drawn instead of the environment's static box markers. The viewer passes ``step`` the real
frame time times the time scale, and ``dt`` for a single step.

Modules
-------
``window`` (the frame loop and input), ``camera`` (numpy; the views), ``record`` (an animated
GIF of the frames), ``render`` (one frame) with its
passes ``backdrop`` and ``characters``, ``figures`` and ``meshes`` (geometry, numpy),
``lighting`` (colours), ``gl`` (GL wrappers; GLSL in ``shaders/``), ``hud``, ``headless``
(backend choice), ``scene`` (:class:`TrackScene`), ``baseline`` (the benchmark's references).

Entry points
------------
* :func:`run_viewer` ``(scene, headless=False, seconds=None, screenshot=None, width=1280,
  height=720)`` -- choose the backend, open the viewer, run the frame loop (until the window
  closes, or for ``seconds``), save the last frame as a PNG; returns a
  :class:`~runtime.viewer.window.FrameInfo` with the frame count and fps, the framebuffer size,
  the camera's ``view_projection`` (4x4, column vectors) and the joint positions drawn in the
  last frame. :func:`project` ``(view_projection, points, width, height)`` maps world points to
  pixels (origin bottom-left; PNG row = height - 1 - y).
* :func:`make_viewer` -- the same without running: a :class:`~runtime.viewer.window.Viewer`
  with ``camera`` (:class:`OrbitCamera`), ``view_projection()``, ``project(points)``,
  ``pick(x, y)``, ``go_to(x, y)``, ``run(...)``, ``draw()``, ``save_screenshot(path)``, and the
  pyglet event handlers (``on_mouse_press`` etc.) that input goes through.

Input: left click selects the character whose projected root is nearest the pointer (within
40 px); left drag orbits, middle or Shift+left drag pans, the wheel zooms; right click on the
ground calls ``scene.command_go_to(selected, xz)`` (ray-plane intersection with y = 0); Space
pauses, '.' steps one tick, +/- double/halve the time scale, F follows the selection, H hides the
HUD, Esc quits.

Views (:func:`~runtime.viewer.camera.look_at_landmark`, from the scene's ``landmarks()``): the
opening view is the scene's "plaza" landmark (a World with ambient people: their busiest
stretch) seen from 18 m at 24 degrees, where a person in the middle of a 1280 x 720 view is
at least 30 px tall; without one, the whole environment. Keys: P back to that view, T the tiling
zone ("tiled"), B the flocks where they are now ("flocks"), R follow a random character (F
stops following); a key whose place the scene lacks does nothing.
"""
from __future__ import annotations

from ..view import SceneView
from .camera import OrbitCamera, project
from .scene import TrackScene

__all__ = ["run_viewer", "make_viewer", "TrackScene", "OrbitCamera", "project"]


def make_viewer(scene: SceneView, headless: bool | None = False, width: int = 1280, height: int = 720, **kwargs):
    """Select pyglet's backend (headless EGL, or a window on ``$DISPLAY``; ``None`` = headless
    when there is no display) and create a :class:`~runtime.viewer.window.Viewer` for ``scene``."""
    from . import headless as backend
    backend.configure(headless)
    from .window import Viewer
    return Viewer(scene, width=width, height=height, **kwargs)


def run_viewer(scene: SceneView, headless: bool | None = False, seconds: float | None = None, screenshot=None,
               width: int = 1280, height: int = 720, max_frames: int | None = None, min_frames: int = 1,
               camera=None, record=None, **kwargs):
    """Open the viewer on ``scene`` and run until the window closes, or for ``seconds`` /
    ``max_frames``; save the last frame to ``screenshot`` (PNG) if given.

    ``camera`` (optional) is a callable ``f(viewer.camera)`` to position the camera before the
    first frame. ``record`` (a :class:`~runtime.viewer.record.GifRecorder`) collects frames
    for an animated GIF, saved when the loop ends. Returns a
    :class:`~runtime.viewer.window.FrameInfo`: frame count, fps, the framebuffer size, the
    view-projection matrix and the joint positions of the last frame (so a caller can project
    world points into the screenshot with :func:`project`)."""
    viewer = make_viewer(scene, headless=headless, width=width, height=height, **kwargs)
    try:
        if camera is not None:
            camera(viewer.camera)
        info = viewer.run(seconds=seconds, screenshot=screenshot, max_frames=max_frames, min_frames=min_frames,
                          record=record)
        if record is not None:
            record.save()
        return info
    finally:
        viewer.close()
