"""``crowdweave demo``: the main job.

Generates the default procedural capture (seed 0) if it is not cached yet, builds the
default motion library from it, prints both summaries, and then opens the plaza sample in the
viewer (``crowdweave run``): characters walking to seats, meeting and fetching boxes, planned
live by the runtime. When no display can be opened it says so and renders the plaza headless
instead (EGL, no X server), saving the last frame as a PNG in the cache directory.
``--no-window`` stops after the summaries.
"""
from __future__ import annotations

import argparse
import os
import sys

from authoring.commands.args import number


def configure(p):
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--no-window", action="store_true", help="only build and summarise, do not open the viewer")
    p.add_argument("--seconds", type=number(0, 1e6, lo_open=True), default=None,
                   help="close the viewer after this many seconds (default: when the window is closed; "
                        "20 s when rendering headless; > 0, at most 1e6)")


def display_available() -> tuple[bool, str]:
    """Can an X display be opened? (pyglet draws windows through X11; on Wayland desktops
    through XWayland.) Probed with Xlib itself, so pyglet's backend is not chosen yet."""
    name = os.environ.get("DISPLAY")
    if not name:
        return False, "DISPLAY is not set"
    try:
        import ctypes
        import ctypes.util
        lib = ctypes.util.find_library("X11")
        if lib is None:
            return False, "libX11 is not installed"
        x11 = ctypes.cdll.LoadLibrary(lib)
        x11.XOpenDisplay.restype = ctypes.c_void_p
        x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
        x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
        d = x11.XOpenDisplay(name.encode())
        if not d:
            return False, f"cannot open display {name!r}"
        x11.XCloseDisplay(d)
        return True, name
    except OSError as e:
        return False, f"cannot load libX11 ({e})"


def run(args) -> int:
    from authoring.capture_quality import format_quality, take_quality
    from authoring.default_library import default_capture_dir, ensure_library
    from runtime.library import cache_dir
    from runtime.motion.graph import MotionGraph
    path = ensure_library("default", progress=not args.quiet)
    cap = default_capture_dir()
    print(f"\ndefault capture: {cap}")
    print(format_quality(take_quality(cap)))
    s = MotionGraph.load(path).summary()
    print(f"\ndefault library: {path}")
    print(f"  {s['nodes']} hub nodes, {s['edges']} edges, {s['seconds']} s of motion, "
          f"median parallel edges {s['parallel']['median_parallel']:g}")
    print(f"  node labels: {s['node_labels']}")
    print("  states: " + ", ".join(f"{k} {v.get('edges', 0)} edges" for k, v in s["states"].items()))
    sys.stdout.flush()
    if args.no_window:
        return 0
    from authoring.commands import run as run_cmd
    ok, why = display_available()
    ns = argparse.Namespace(sample=None, headless=False, seconds=args.seconds, screenshot=None, width=1280,
                            height=720, budget_ms=None, record=None)
    if ok:
        print(f"\nopening the plaza sample on display {why} (close the window to quit; click a character, "
              "right-click the ground to send it there)")
    else:
        shot = cache_dir() / "plaza.png"
        ns.headless, ns.screenshot = True, str(shot)
        ns.seconds = 20.0 if args.seconds is None else args.seconds
        print(f"\nno display ({why}): rendering the plaza sample headless for {ns.seconds:g} s instead; "
              f"its last frame goes to {shot}.\nOn a desktop this command opens the viewer window "
              "(`crowdweave run` opens it too).")
    sys.stdout.flush()
    return run_cmd.run(ns)
