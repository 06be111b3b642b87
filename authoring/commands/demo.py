"""``crowdweave demo``: the main job.

Generates the default procedural capture (seed 0) if it is not cached yet, builds the
default motion library from it, prints both summaries, and then, when a display is available,
opens the plaza sample in the viewer (``crowdweave run``); ``--no-window`` stops after the
summaries.
"""
from __future__ import annotations

import sys


def configure(p):
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--no-window", action="store_true", help="only build and summarise, do not open the viewer")


def run(args) -> int:
    from authoring.capture_quality import format_quality, take_quality
    from authoring.default_library import default_capture_dir, ensure_library
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
    print(f"  states: " + ", ".join(f"{k} {v.get('edges', 0)} edges" for k, v in s["states"].items()))
    sys.stdout.flush()
    import os
    if args.no_window:
        return 0
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        print("\nno display: to see the crowd, run `crowdweave run` on a desktop, or "
              "`crowdweave run --headless --seconds 20 --screenshot plaza.png`")
        return 0
    from authoring.commands import run as run_cmd
    import argparse
    ns = argparse.Namespace(sample=None, headless=False, seconds=None, screenshot=None, width=1280, height=720,
                            budget_ms=4.0)
    print("\nopening the plaza sample (close the window to quit)")
    return run_cmd.run(ns)
