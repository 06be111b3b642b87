"""Online load test of the runtime (issue 5): N characters, each given a new random reachable
goal every 3-8 s, for T simulated seconds.

Prints p50/p99/max of the tick time split into planning and the rest, how far planning went
over its budget, planning throughput (goals planned per second of simulation), and the
independent check of every completed goal: the root where the ``arrived`` event says it
arrived must be the commanded position and heading, and no two characters' bounding
cylinders may overlap on any recorded frame.

    .venv/bin/python bench/runtime_load.py                 # 500 characters, 120 s
    .venv/bin/python bench/runtime_load.py --characters 100 --seconds 30
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from runtime.crowd.checker import overlapping_pairs  # noqa: E402
from runtime.world import MAX_BUFFER, World  # noqa: E402


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--characters", type=int, default=500)
    p.add_argument("--seconds", type=float, default=120.0)
    p.add_argument("--budget-ms", type=float, default=4.0)
    p.add_argument("--spacing", type=float, default=2.5, help="metres between characters on the start grid")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)

    w = World("default", seed=a.seed, budget_ms=a.budget_ms)
    n = a.characters
    side = int(math.ceil(math.sqrt(n)))
    half = side * a.spacing / 2
    rng = np.random.default_rng(a.seed)
    for i in range(n):
        w.spawn(f"c{i:04d}", ((i % side) * a.spacing - half, (i // side) * a.spacing - half), rng.uniform(-math.pi, math.pi))
    goals = {}
    arrivals = []
    w.on("arrived", lambda e: arrivals.append(e))
    next_goal = rng.uniform(0.0, 3.0, n)           # first goals staggered over 3 s
    ticks = int(a.seconds * w.fps)
    plan_ms = np.zeros(ticks)
    tick_ms = np.zeros(ticks)
    rec_xz = np.zeros((ticks, n, 2), dtype=np.float32)
    rec_r = np.zeros((ticks, n), dtype=np.float32)
    given = 0
    t_wall = time.perf_counter()
    names = [f"c{i:04d}" for i in range(n)]
    for k in range(ticks):
        now = w.time
        due = np.flatnonzero(next_goal <= now)
        for i in due:
            # a random reachable point a few metres away, inside the crowd's area
            r = w.root_states()[i]
            for _ in range(20):
                d, ang = rng.uniform(3.0, 8.0), rng.uniform(-math.pi, math.pi)
                gx, gz = r[0] + d * math.sin(ang), r[1] + d * math.cos(ang)
                if abs(gx) < half + 2 and abs(gz) < half + 2:
                    break
            h = rng.uniform(-math.pi, math.pi)
            w.go_to(names[i], (gx, gz), heading=h)
            goals.setdefault(names[i], []).append((now, gx, gz, h))
            given += 1
            next_goal[i] = now + rng.uniform(3.0, 8.0)
        t0 = time.perf_counter()
        w.tick()
        tick_ms[k] = (time.perf_counter() - t0) * 1000
        plan_ms[k] = w.stats["plan_ms"]
        s = np.flatnonzero(w.active)
        fk = w.head[s] % MAX_BUFFER
        rec_xz[k] = w.buf_root[s, fk, :2]
        rec_r[k] = np.maximum(w.graph.frame_radius[w.buf_a[s, fk]], w.graph.frame_radius[w.buf_b[s, fk]])
    wall = time.perf_counter() - t_wall

    # independent check of completed goals
    errs_p, errs_h = [], []
    for e in arrivals:
        gl = goals[e.character]
        # the goal this arrival answers: the last one given before it whose position matches best
        cand = [g for g in gl if g[0] <= e.time]
        f = e.data["frame"]
        kf = f - 1                                 # recorded after tick f-1 -> frame f
        if not (0 <= kf < ticks):
            continue
        i = names.index(e.character)
        pos = rec_xz[kf, i].astype(np.float64)
        g = min(cand, key=lambda g: np.hypot(g[1] - pos[0], g[2] - pos[1]))
        errs_p.append(float(np.hypot(g[1] - pos[0], g[2] - pos[1])))
        errs_h.append(float(np.degrees(abs((e.data["heading"] - g[3] + math.pi) % (2 * math.pi) - math.pi))))
    pairs = overlapping_pairs(rec_xz.astype(np.float64), rec_r.astype(np.float64))
    rest = tick_ms - plan_ms
    over = plan_ms - a.budget_ms
    print(f"runtime load: {n} characters, {a.seconds:g} simulated s, budget {a.budget_ms:g} ms/tick, "
          f"wall {wall:.1f} s")
    print(f"{'':14s}{'p50':>9s}{'p99':>9s}{'max':>9s}  (ms per tick)")
    for label, arr in (("planning", plan_ms), ("rest", rest), ("tick", tick_ms)):
        print(f"{label:14s}{np.percentile(arr, 50):9.2f}{np.percentile(arr, 99):9.2f}{arr.max():9.2f}")
    print(f"planning over budget: p99 {np.percentile(over, 99):.2f} ms, max {over.max():.2f} ms")
    print(f"goals given {given}, completed {len(arrivals)} ({len(arrivals) / a.seconds:.1f}/s), "
          f"queue at the end {w.stats['queue']}")
    if errs_p:
        print(f"completed goals: max position error {1000 * max(errs_p):.3g} mm, max heading error {max(errs_h):.3g} deg")
    print(f"overlapping character pairs over all frames: {len(pairs)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
