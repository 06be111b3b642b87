"""Data-driven groups benchmark (Lai, Chenney and Fan 2005, Table 1 and section 6), all figures
from one run.

    .venv/bin/python bench/ddg.py [--seconds 600] [--flocks 1000] [--ticks 300] [--workers 1]

1. Table 1: for 20-agent 2D and 3D flocks, record ``--seconds`` of boids, build the DDG with the
   lower-bound pruning and print label, transitions, memory (MB), build seconds, plus the size of
   the difference matrix and the fraction of exact metric evaluations the bound skipped.
2. Cost per virtual second of walking the DDG against simulating the same boids, measured here:
   the recorder's simulation of one flock, the same simulation batched over ``--flocks`` flocks,
   a FlockSystem walking one flock, and one walking ``--flocks`` flocks (per flock).
3. Tick time (step + positions + velocities) for ``--flocks`` concurrent 20-agent flocks, each
   constrained to its own region (80 m L-shaped polygon in 2D, 80 x 40 x 80 m box in 3D).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from authoring.boids import BoidsParams, BoidsSim, record_flock  # noqa: E402
from authoring.ddg import DDGBuildParams, build_ddg  # noqa: E402
from runtime.flock.region import Box, Polygon  # noqa: E402
from runtime.flock.walk import FlockSystem  # noqa: E402

FPS = 30.0


def regions_for(dim, n, spacing=100.0, half=40.0):
    """One region per flock on a grid (an 80 m L-shaped polygon in 2D, as in the tests; an
    80 x 40 x 80 m box in 3D), and a start point inside each."""
    side = int(np.ceil(np.sqrt(n)))
    regs, starts = [], []
    for k in range(n):
        ox, oz = (k % side) * spacing, (k // side) * spacing
        if dim == 2:
            regs.append(Polygon([[ox - half, oz - half], [ox + half, oz - half], [ox + half, oz], [ox, oz],
                                 [ox, oz + half], [ox - half, oz + half]]))
            starts.append([ox - half / 2, 0.0, oz - half / 2])
        else:
            regs.append(Box([ox - half, 0, oz - half], [ox + half, 40, oz + half]))
            starts.append([ox, 20.0, oz])
    return regs, np.array(starts)


def time_sim(params, n_flocks, seconds):
    sim = BoidsSim(params, n_flocks, seed=1)
    for _ in range(10):
        sim.step()
    steps = int(seconds * params.fps)
    t0 = time.perf_counter()
    for _ in range(steps):
        sim.step()
    return (time.perf_counter() - t0) / (steps / params.fps) / n_flocks


def time_walk(ddg, n, seconds, regions=None, starts=None, warm=60):
    """Ticks of a FlockSystem with ``n`` flocks, after ``warm`` untimed ticks."""
    fs = FlockSystem(ddg, seed=1)
    if starts is None:
        starts = np.zeros((n, 3))
        starts[:, 0] = np.arange(n) * 100.0
        if ddg.dim == 3:
            starts[:, 1] = 20.0
    fs.add_flocks(starts, np.linspace(0, 2 * np.pi, n, endpoint=False), regions)
    dt = 1.0 / FPS
    for _ in range(warm):
        fs.step(dt)
        fs.positions()
    ticks = []
    for _ in range(int(seconds * FPS)):
        t0 = time.perf_counter()
        fs.step(dt)
        fs.positions()
        fs.velocities()
        ticks.append(time.perf_counter() - t0)
    ticks = np.array(ticks)
    outside = 0
    if regions is not None:
        c = fs.centroids()
        outside = sum(not r.contains(c[i][None])[0] for i, r in enumerate(regions))
    return ticks, fs.stats, outside


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=600.0, help="seconds of flock recorded per DDG")
    ap.add_argument("--flocks", type=int, default=1000)
    ap.add_argument("--ticks", type=int, default=900, help="ticks timed for the concurrent-flock test")
    ap.add_argument("--warm", type=int, default=300, help="untimed ticks first (initial look-ahead plans run out)")
    ap.add_argument("--workers", type=int, default=1, help="processes for the exact metric")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)

    import os
    print(f"load average at start: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    rows, ddgs, recs = [], {}, {}
    for dim in (2, 3):
        p = BoidsParams(n_agents=20, dim=dim)
        t0 = time.perf_counter()
        rec = record_flock(p, args.seconds, seed=args.seed)
        t_rec = time.perf_counter() - t0
        g, st = build_ddg(rec, DDGBuildParams(workers=args.workers))
        ddgs[dim], recs[dim] = g, rec
        rows.append((f"20-{dim}D", g.n_transitions, g.nbytes / 1e6, st.seconds_total, t_rec, st, g))

    print(f"\nTable 1 (Lai, Chenney and Fan 2005): DDGs built from {args.seconds:g} s of 20-agent boids "
          f"(candidates every {DDGBuildParams().candidate_stride} frames, workers={args.workers})")
    print(f"{'Descr.':<7} {'Trans.':>6} {'Mem.MB':>7} {'Time s':>7} | {'nodes':>5} {'edges':>5} "
          f"{'cand.':>5} {'pairs':>8} {'exact':>8} {'skipped':>7} {'minima':>6} {'rec. s':>6}")
    for label, trans, mb, secs, t_rec, st, g in rows:
        print(f"{label:<7} {trans:>6d} {mb:>7.2f} {secs:>7.1f} | {g.n_nodes:>5d} {g.n_edges:>5d} "
              f"{st.candidates:>5d} {st.pairs:>8d} {st.exact_evaluations:>8d} "
              f"{100 * st.skipped_fraction:>6.1f}% {st.local_minima:>6d} {t_rec:>6.1f}")
    print("paper:  20-2D 7200 50 2200 | 20-3D 7200 50 2400 (2.4 GHz P4)")
    for label, *_rest in rows:
        st = _rest[4]
        print(f"  {label}: exact metric {st.seconds_exact:.1f} s for {st.exact_evaluations} pairs "
              f"({1e6 * st.seconds_exact / max(st.exact_evaluations, 1):.0f} us/pair), bound {st.seconds_bound:.2f} s, "
              f"{st.rounds} rounds, tau {st.tau:.3f} m^2; {st.accepted_pairs} minima taken, "
              f"{st.rejected_spacing} too close to a cut, {st.rejected_blend} without a smooth blend")

    print("\nCost per virtual second, per flock (same run, best of 3; 20 agents; 'batch' = "
          f"{args.flocks} flocks advanced together, cost divided by {args.flocks})")
    print(f"{'':<7} {'sim 1':>9} {'sim batch':>10} {'walk 1':>9} {'walk batch':>11} | "
          f"{'sim1/walkN':>10} {'simN/walkN':>10} {'sim1/walk1':>10}")
    for dim in (2, 3):
        p = BoidsParams(n_agents=20, dim=dim)
        # best of three runs each: the minimum is the code's cost with the least interference
        sim1 = min(time_sim(p, 1, 10.0) for _ in range(3))
        simn = min(time_sim(p, args.flocks, 1.0) for _ in range(3))
        walk1 = min(time_walk(ddgs[dim], 1, 10.0)[0].sum() / 10.0 for _ in range(3))
        walkn = min(time_walk(ddgs[dim], args.flocks, 2.0)[0].sum() / 2.0 / args.flocks for _ in range(3))
        print(f"{dim}D      {1e3 * sim1:>7.3f}ms {1e3 * simn:>8.3f}ms {1e3 * walk1:>7.3f}ms {1e3 * walkn:>9.4f}ms | "
              f"{sim1 / walkn:>9.0f}x {simn / walkn:>9.0f}x {sim1 / walk1:>9.1f}x")
    print("paper: walk 7.5 ms vs simulation 100 ms per virtual second (13x); target here >= 200x")

    print(f"\nTick time, {args.flocks} concurrent 20-agent flocks, each in its own region "
          f"(step + positions + velocities, {args.ticks} ticks after {args.warm} untimed ticks)")
    print(f"{'':<4} {'median':>8} {'mean':>8} {'p95':>8} {'max':>8} | {'searches':>8} {'expans.':>8} "
          f"{'fallbacks':>9} {'outside':>7}")
    for dim in (2, 3):
        regs, starts = regions_for(dim, args.flocks)
        ticks, stats, outside = time_walk(ddgs[dim], args.flocks, args.ticks / FPS, regs, starts, args.warm)
        ms = 1e3 * ticks
        print(f"{dim}D   {np.median(ms):>6.2f}ms {ms.mean():>6.2f}ms {np.percentile(ms, 95):>6.2f}ms "
              f"{ms.max():>6.2f}ms | {stats['searches']:>8d} {stats['expansions']:>8d} "
              f"{stats['fallbacks']:>9d} {outside:>7d}")
    print("target: <= 3 ms per tick")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
