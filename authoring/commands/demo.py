"""``crowdweave demo``: the main job.

Generates the default procedural capture (seed 0) if it is not cached yet, builds the
default motion library from it, and prints both summaries.
"""
from __future__ import annotations

import sys


def configure(p):
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args) -> int:
    from authoring.capture_quality import take_quality
    from authoring.default_library import default_capture_dir, ensure_library
    from runtime.motion.graph import MotionGraph
    path = ensure_library("default", progress=not args.quiet)
    cap = default_capture_dir()
    q = take_quality(cap)
    print(f"\ndefault capture: {cap}")
    for k in ("takes", "duration_s", "foot_contact_speed_cm_s", "max_knee_flexion_deg", "knee_hyperextension",
              "label_counts"):
        if k in q:
            print(f"  {k}: {q[k]}")
    s = MotionGraph.load(path).summary()
    print(f"\ndefault library: {path}")
    print(f"  {s['nodes']} hub nodes, {s['edges']} edges, {s['seconds']} s of motion, "
          f"median parallel edges {s['parallel']['median_parallel']:g}")
    print(f"  node labels: {s['node_labels']}")
    print(f"  states: " + ", ".join(f"{k} {v.get('edges', 0)} edges" for k, v in s["states"].items()))
    sys.stdout.flush()
    return 0
