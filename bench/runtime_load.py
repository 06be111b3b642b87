"""Online load test of the runtime: N characters, each given a new random reachable
goal every 3-8 s, for T simulated seconds.

Prints p50/p99/max of the tick time split into planning and the rest, how far planning went
over its budget, planning throughput (plans finished per second of simulation) and the
independent check of every completed goal (``runtime.crowd.checker``): the root where the
``arrived`` event says it arrived must be the commanded position and heading (<= 1 mm,
<= 0.1 deg), the per-frame adjustment of the goal's segment (from its hand-off to the
arrival, as played) must be within eps (``checker.adjustment_rates``), and no two
characters' bounding cylinders may overlap on any recorded frame
(``checker.overlapping_pairs``; a goal passes only if its character overlaps nobody during
its segment).

Planning time is measured twice: wall-clock (what a frame sees; on a shared machine it
includes time the process was preempted) and the planning thread's CPU time. The "preempted"
line counts ticks whose wall planning time exceeds its CPU time by more than 0.5 ms.

A goal is *reachable* when it lies inside the crowd's area and at least ``--clearance``
metres from every other character's current position and from where its buffered motion
ends (a spot another character stands on cannot be reached).

    .venv/bin/python bench/runtime_load.py                 # 500 characters, 120 s
    .venv/bin/python bench/runtime_load.py --characters 100 --seconds 30
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from runtime.crowd.checker import adjustment_rates, overlapping_pairs  # noqa: E402
from runtime.crowd.tracks import Track  # noqa: E402
from runtime.motion.cylinders import blend_cylinders  # noqa: E402
from runtime.world import MAX_BUFFER, World  # noqa: E402


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--characters", type=int, default=500)
    p.add_argument("--seconds", type=float, default=120.0)
    p.add_argument("--budget-ms", type=float, default=4.0)
    p.add_argument("--spacing", type=float, default=2.5, help="metres between characters on the start grid")
    p.add_argument("--clearance", type=float, default=1.2, help="metres a goal keeps from other characters")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)

    w = World("default", seed=a.seed, budget_ms=a.budget_ms)
    n = a.characters
    side = int(math.ceil(math.sqrt(n)))
    half = side * a.spacing / 2
    rng = np.random.default_rng(a.seed)
    names = [f"c{i:04d}" for i in range(n)]
    for i in range(n):
        w.spawn(names[i], ((i % side) * a.spacing - half, (i // side) * a.spacing - half), rng.uniform(-math.pi, math.pi))
    slot = np.array([w.slot(m) for m in names])
    pb = w.playback
    goals = {}
    arrivals = []
    warnings = []
    w.on("arrived", arrivals.append)
    w.on("warning", warnings.append)
    next_goal = rng.uniform(0.0, 3.0, n)           # first goals staggered over 3 s
    ticks = int(a.seconds * w.fps)
    plan_ms = np.zeros(ticks)
    plan_cpu = np.zeros(ticks)
    tick_ms = np.zeros(ticks)
    steps = np.zeros(ticks, dtype=np.int64)
    rec_a = np.zeros((ticks, n), dtype=np.int64)
    rec_b = np.zeros((ticks, n), dtype=np.int64)
    rec_t = np.zeros((ticks, n), dtype=np.float32)
    rec_root = np.zeros((ticks, n, 3))
    given = unreachable = 0
    t_wall = time.perf_counter()
    for k in range(ticks):
        now = w.time
        due = np.flatnonzero(next_goal <= now)
        if len(due):
            cur = pb.buf_root[slot, pb.head[slot] % MAX_BUFFER, :2]
            end = pb.buf_root[slot, pb.tail[slot] % MAX_BUFFER, :2]
        for i in due:
            # a random reachable point a few metres away, inside the crowd's area
            r = cur[i]
            ok = False
            for _ in range(30):
                d, ang = rng.uniform(3.0, 8.0), rng.uniform(-math.pi, math.pi)
                gx, gz = r[0] + d * math.sin(ang), r[1] + d * math.cos(ang)
                if abs(gx) < half + 2 and abs(gz) < half + 2:
                    dc = np.hypot(cur[:, 0] - gx, cur[:, 1] - gz)
                    de = np.hypot(end[:, 0] - gx, end[:, 1] - gz)
                    dc[i] = de[i] = np.inf
                    if min(dc.min(), de.min()) >= a.clearance:
                        ok = True
                        break
            next_goal[i] = now + rng.uniform(3.0, 8.0)
            if not ok:
                unreachable += 1
                continue
            h = rng.uniform(-math.pi, math.pi)
            w.go_to(names[i], (gx, gz), heading=h)
            goals.setdefault(names[i], []).append((now, gx, gz, h))
            given += 1
        t0 = time.perf_counter()
        w.tick()
        tick_ms[k] = (time.perf_counter() - t0) * 1000
        plan_ms[k] = w.stats["plan_ms"]
        plan_cpu[k] = w.stats["plan_cpu_ms"]
        steps[k] = w.stats["plan_steps"]
        fk = pb.head[slot] % MAX_BUFFER
        rec_a[k] = pb.buf_a[slot, fk]
        rec_b[k] = pb.buf_b[slot, fk]
        rec_t[k] = pb.buf_t[slot, fk]
        rec_root[k] = pb.buf_root[slot, fk]
    wall = time.perf_counter() - t_wall
    load = os.getloadavg()

    # independent check of completed goals
    g = w.graph
    cxz, rad = blend_cylinders(g, rec_a, rec_b, rec_root)
    pairs = overlapping_pairs(cxz, rad)
    in_pair = {}
    # frames of overlap per character (which goals' motions are involved)
    over_frames = {}
    if pairs:
        for f in range(ticks):
            xz = cxz[f]
            for (i, j) in pairs:
                if np.hypot(*(xz[i] - xz[j])) < rad[f, i] + rad[f, j]:
                    over_frames.setdefault(i, []).append(f)
                    over_frames.setdefault(j, []).append(f)
                    in_pair[i] = in_pair[j] = True
    eps = w.params.eps
    rows = []
    for e in sorted(arrivals, key=lambda e: e.data["frame"]):
        f = e.data["frame"]
        kf = f - 1                                 # recorded after tick f-1 -> frame f
        if not (0 <= kf < ticks):
            continue
        i = names.index(e.character)
        pos = rec_root[kf, i, :2]
        cand = [q for q in goals[e.character] if q[0] <= e.time]
        q = min(cand, key=lambda q: np.hypot(q[1] - pos[0], q[2] - pos[1]))
        pe = float(np.hypot(q[1] - pos[0], q[2] - pos[1]))
        he = float(np.degrees(abs((rec_root[kf, i, 2] - q[3] + math.pi) % (2 * math.pi) - math.pi)))
        k0 = max(e.data["start_frame"] - 1, 0)     # the goal's planned segment
        tr = Track(rec_a[:, i], rec_b[:, i], rec_t[:, i], rec_root[:, i], 1)
        rates = adjustment_rates(g, tr, k0, kf, w.fps)
        hits = [x for x in over_frames.get(i, []) if k0 <= x <= kf]
        ok = (pe <= 1e-3 and he <= 0.1 and rates[0] <= eps[0] * 1.001 and rates[1] <= eps[1] * 1.001
              and rates[2] <= eps[2] * 1.001 and not hits)
        rows.append((pe, he, rates, bool(hits), ok))

    rest = tick_ms - plan_ms
    print(f"runtime load: {n} characters, {a.seconds:g} simulated s, budget {a.budget_ms:g} ms/tick, "
          f"wall {wall:.1f} s, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} CPUs")
    print(f"{'':22s}{'p50':>9s}{'p99':>9s}{'max':>9s}  (ms per tick)")
    for label, arr in (("planning (wall)", plan_ms), ("planning (thread CPU)", plan_cpu), ("rest", rest),
                       ("tick", tick_ms)):
        print(f"{label:22s}{np.percentile(arr, 50):9.2f}{np.percentile(arr, 99):9.2f}{arr.max():9.2f}")
    over, over_cpu = plan_ms - a.budget_ms, plan_cpu - a.budget_ms
    pre = plan_ms - plan_cpu > 0.5
    print(f"planning over budget (wall): p99 {np.percentile(over, 99):.2f} ms, max {over.max():.2f} ms, "
          f"ticks > budget + 1 ms: {int(np.sum(over > 1))} of {ticks}")
    print(f"planning over budget (CPU):  p99 {np.percentile(over_cpu, 99):.2f} ms, max {over_cpu.max():.2f} ms, "
          f"ticks > budget + 1 ms: {int(np.sum(over_cpu > 1))} of {ticks}")
    print(f"preempted while planning (wall - CPU > 0.5 ms): {int(pre.sum())} ticks; "
          f"of the ticks > budget + 1 ms (wall), {int(np.sum(pre & (over > 1)))} were preempted")
    print(f"planner steps per tick: p50 {np.percentile(steps, 50):.0f}, max {steps.max()}")
    done, failed = w.stats["plans_done"], w.stats["plans_failed"]
    print(f"goals given {given} (+{unreachable} draws with no reachable spot), plans used {done} "
          f"({done / a.seconds:.2f}/s), plans failed {failed} ({failed / a.seconds:.2f}/s), "
          f"moved later {w.stats['plans_shifted']}, planned again {w.stats['plans_redone']}, "
          f"retried {w.stats['plans_retried']}, "
          f"queue at the end {w.stats['queue']}, warnings {len(warnings)}")
    fin = done + failed + w.stats["plans_redone"] + w.stats["plans_retried"]
    print(f"planning CPU {plan_cpu.sum() / 1000:.2f} s in all, {plan_cpu.sum() / max(fin, 1):.0f} ms per finished "
          f"plan, {plan_cpu.sum() / max(done, 1):.0f} ms per used plan")
    print(f"completed goals (arrived events) {len(arrivals)} ({len(arrivals) / a.seconds:.2f}/s); "
          f"checked {len(rows)}, pass {sum(r[4] for r in rows)}")
    if rows:
        print(f"  max position error {1000 * max(r[0] for r in rows):.3g} mm, max heading error "
              f"{max(r[1] for r in rows):.3g} deg, max adjustment {max(r[2][0] for r in rows):.4f} m/s "
              f"{max(r[2][1] for r in rows):.3f} deg/s {max(r[2][2] for r in rows):.4f} s/s "
              f"(eps {eps[0]} m/s {eps[1]} deg/s {eps[2]:.4f} s/s), in an overlap {sum(r[3] for r in rows)}")
    print(f"overlapping character pairs over all frames: {len(pairs)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
