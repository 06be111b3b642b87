"""Benchmark: the splice cost of Sung, Kovar and Gleicher 2005 (Eq. 1-2) over one search iteration's motion pairs.

``runtime.crowd.planner.costs.pair_costs`` costs n_m perturbed (M_f, M_b) pairs every iteration of the
randomized search: every prefix/suffix split meeting at a node, the per-pair minimum. Compared
in the same run: the numpy passes (``compiled = False``) and the numba kernel of
``runtime/crowd/planner/kernels.py`` (the default when numba is installed), on random walks of
the default library of 8-40 clips per motion. Prints the median milliseconds per call and the
ratio, and checks both give the same (i, j) for every pair.

    CROWDWEAVE_CACHE=/tmp/cwcache .venv/bin/python bench/splice_costs.py [--pairs 200] [--repeat 50]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def random_pairs(g, P, L, rng):
    F = -np.ones((P, L), np.int64)
    B = -np.ones((P, L), np.int64)
    nf, nb = rng.integers(8, L, P), rng.integers(8, L, P)
    start = int(g.edge_src[0])
    for p in range(P):
        F[p, :nf[p]] = g.random_walk(start, nf[p], rng)
        B[p, L - nb[p]:] = g.random_walk(int(rng.integers(g.num_nodes)), nb[p], rng)
    return F, nf, B, nb, start


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=200, help="pairs per call (the paper's n_m)")
    ap.add_argument("--repeat", type=int, default=50)
    args = ap.parse_args(argv)
    from authoring.default_library import ensure_library
    from runtime.crowd.planner import MotionLibrary
    from runtime.crowd.planner import kernels as search_kernels
    from runtime.crowd.planner.costs import pair_costs
    from runtime.motion.graph import MotionGraph
    g = MotionGraph.load(ensure_library("default", log=lambda *a: None, progress=False))
    lib = MotionLibrary(g)
    rng = np.random.default_rng(0)
    print(f"{'motion length':>14}{'pairs':>7}{'numpy ms':>10}{'kernel ms':>11}{'ratio':>8}  same (i, j)")
    for L in (16, 28, 40):
        F, nf, B, nb, start = random_pairs(g, args.pairs, L, rng)
        goal_node = int(g.edge_dst[B[0, -1]])
        s, goal = np.array([0.0, 0.0, 0.0]), np.array([6.0, 4.0, 1.0])
        times, outs = {}, {}
        for compiled in ((False, True) if search_kernels.AVAILABLE else (False,)):
            def cost():
                return pair_costs(lib, lib.params, F, nf, B, nb, s, goal, start, goal_node, (8.0, 10.0),
                                  compiled=compiled)
            outs[compiled] = cost()   # (also compiles)
            t = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                cost()
                t.append(time.perf_counter() - t0)
            times[compiled] = 1000 * float(np.median(t))
        if True in times:
            same = all(np.array_equal(outs[False][k], outs[True][k]) for k in (1, 2))
            print(f"{L:>14}{args.pairs:>7}{times[False]:>10.3f}{times[True]:>11.3f}{times[False] / times[True]:>7.1f}x  {same}")
        else:
            print(f"{L:>14}{args.pairs:>7}{times[False]:>10.3f}{'-':>11}{'-':>8}  (numba not installed)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
