"""Benchmark: the goal-directed crowd planner (Sung, Kovar and Gleicher 2005) with and without its compiled kernels.

Three per-step paths of ``runtime.crowd`` are compiled with numba when it is installed:

* the splice cost of the randomized search (Eq. 1-2, ``planner.kernels.pair_costs``);
* the greedy seed planner's two-edge lookahead (section 3.2, ``planner.kernels.lookahead_errors``);
* the space-time index query (the compiled query of ``spacetime``), which also stops at the first
  collision in the final tests (``SpaceTimeIndex.first_overlap``).

This plans the same scenarios twice in one run -- numpy paths only (the kernels switched off)
and compiled -- and prints the planning seconds of each, their ratio, and whether the two
plans are the same to the bit (they must be: the kernels do the numpy paths' arithmetic).
Figures only, no asserts; planning is single-threaded.

    CROWDWEAVE_CACHE=/tmp/cwcache .venv/bin/python bench/crowd_kernels.py [--samples grid300,meet20] [--grid 10x6]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for p in (ROOT, ROOT / "samples"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))


def plan(sc, graph, env, roadmap, compiled: bool):
    """(seconds, tracks) of one planning run with the kernels on or off."""
    from runtime.crowd import spacetime
    from runtime.crowd.planner import kernels
    from runtime.crowd.scheduler import plan_scenario
    saved = kernels.ENABLED, spacetime.ENABLED
    try:
        if not compiled:
            kernels.ENABLED, spacetime.ENABLED = False, False
        t0 = time.perf_counter()
        res = plan_scenario(sc, graph, env=env, roadmap=roadmap)
        return time.perf_counter() - t0, res
    finally:
        kernels.ENABLED, spacetime.ENABLED = saved


def same_plans(a, b) -> bool:
    for ca, cb in zip(a.characters, b.characters):
        ta, tb = ca.track, cb.track
        if not (np.array_equal(ta.root, tb.root) and np.array_equal(ta.frames_a, tb.frames_a)
                and np.array_equal(ta.frames_b, tb.frames_b) and np.array_equal(ta.frames_t, tb.frames_t)):
            return False
    return len(a.characters) == len(b.characters)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", default="grid300,meet20",
                    help="comma-separated sample names (samples/<name>); '' for none")
    ap.add_argument("--grid", default="10x6",
                    help="also a COLSxROWS grid_scenario at 2.2 m spacing (dense: failures and repairs); '' for none")
    args = ap.parse_args(argv)
    from authoring.commands.bake import load_sample
    from runtime.crowd.planner import kernels as search_kernels
    from runtime.crowd.scenario import parse_scenario
    from runtime.library import load_library

    graph = load_library("default", None)
    cases = []
    for name in filter(None, args.samples.split(",")):
        sc, g, env, roadmap = load_sample(ROOT / "samples" / name, log=lambda m: None, progress=False)
        cases.append((name, sc, g, env, roadmap))      # the sample's own library
    if args.grid:
        import make_samples
        cols, rows = (int(v) for v in args.grid.lower().split("x"))
        data = make_samples.grid_scenario(cols, rows, spacing=2.2, seed=0, name=f"grid{cols}x{rows}@2.2")
        cases.append((f"grid {cols}x{rows} at 2.2 m",
                      parse_scenario(data, "<grid>", node_labels=set(graph.node_labels_all())), graph, None, None))
    if not search_kernels.AVAILABLE:
        print("numba is not installed: only the numpy paths exist, nothing to compare")
        return 0
    print(f"{'scenario':<24}{'characters':>11}{'numpy s':>10}{'compiled s':>12}{'ratio':>8}  same plans")
    for name, sc, g, env, roadmap in cases:
        t_np, r_np = plan(sc, g, env, roadmap, False)
        t_c, r_c = plan(sc, g, env, roadmap, True)
        print(f"{name:<24}{len(sc.characters):>11}{t_np:>10.2f}{t_c:>12.2f}{t_np / t_c:>7.2f}x  {same_plans(r_np, r_c)}",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
