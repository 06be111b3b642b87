"""Choosing pyglet's display backend: a real window (X11, e.g. under Xvfb) or headless EGL.

pyglet picks its display backend once per process, when ``pyglet.window`` is first imported:
``pyglet.options["headless"] = True`` before that import renders through EGL into an offscreen
surface (llvmpipe on machines without a GPU); otherwise pyglet needs an X display. The choice
cannot be changed afterwards, so :func:`configure` must run before anything imports
``pyglet.window`` or ``pyglet.gl`` (the viewer's GL modules import them lazily for this reason),
and a process that needs both modes (the tests) runs one of them in a subprocess.
"""
from __future__ import annotations

import os
import sys

__all__ = ["configure", "ensure", "display_available", "current_mode", "ModeError"]


class ModeError(RuntimeError):
    """pyglet's backend was already chosen differently in this process."""


def display_available() -> bool:
    """Whether an X display is configured (``DISPLAY`` set)."""
    return bool(os.environ.get("DISPLAY"))


_chosen: str | None = None


def current_mode() -> str | None:
    """"headless" or "window" once chosen (by :func:`configure`, or by pyglet's window/GL
    modules having been imported), else None."""
    if _chosen is not None:
        return _chosen
    if "pyglet.window" not in sys.modules and "pyglet.gl" not in sys.modules:
        return None
    import pyglet
    return "headless" if pyglet.options["headless"] else "window"


def configure(headless: bool | None = None) -> str:
    """Select the backend before pyglet's window/GL modules load; returns the mode chosen.

    ``headless=None`` keeps the mode already chosen, else picks headless when no ``DISPLAY`` is
    set. Raises :class:`ModeError` when the other mode was already chosen in this process, and a
    RuntimeError naming the fix when a window is asked for without a display."""
    have = current_mode()
    if headless is None:
        if have is not None:
            return have
        headless = not display_available()
    want = "headless" if headless else "window"
    if have is not None:
        if have != want:
            raise ModeError(f"pyglet's backend is already {have} in this process (chosen once per process); "
                            f"{want} rendering needs a separate process")
        return have
    if not headless and not display_available():
        raise RuntimeError("no X display (DISPLAY is not set): run with --headless, or start Xvfb "
                           "(apt-get install -y xvfb; Xvfb :99 & export DISPLAY=:99)")
    import pyglet
    global _chosen
    pyglet.options["headless"] = bool(headless)
    pyglet.options["shadow_window"] = False
    if headless:
        pyglet.options["headless_device"] = int(os.environ.get("CROWDWEAVE_EGL_DEVICE", "0"))
    _chosen = want
    return want


def ensure() -> str:
    """The mode already chosen, or choose one now (headless when there is no ``DISPLAY``).
    The viewer's GL modules call this before importing ``pyglet.gl``."""
    return current_mode() or configure(None)
