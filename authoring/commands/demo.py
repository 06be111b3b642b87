"""``crowdweave demo``: the main job.

Generates the default procedural capture (seed 0) if it is not cached yet, builds the
default motion library from it, and prints both summaries.
"""
from __future__ import annotations

import sys


def configure(p):
    p.add_argument("--quiet", action="store_true", help="no progress bars")


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
    return 0
