"""Benchmark: pose evaluation for a whole crowd, vectorized vs per character.

N characters (default 10,000) on the default motion library, each with two consecutive ticks'
states (library frames a, b = a + 1, blend t, planar root) and a render ``alpha`` between the
ticks. Every method produces the joint world positions (N, J, 3) of all characters at ``alpha``:

* ``PoseBatch fused tick``: what a world does once per tick when numba is importable -- ``push``
  and one ``positions(alpha)`` in the fused parallel kernels (runtime/pose_kernels.py);
* ``... walking, foot lock`` / ``no lock``: the same over a sequence of ticks in which every
  character walks on through its clip (so planted feet are pinned, released and pinned again
  as in a world), with the foot lock (runtime/motion/footlock.py, the default) and without;
* ``PoseBatch tick``: the numpy path -- ``push`` (one gather of the precomputed
  per-frame root-local positions and a blend) plus one ``positions(alpha)``;
* ``PoseBatch push only``: the per-tick half alone;
* ``PoseBatch frame``: a rendered frame between ticks -- ``positions(alpha)`` only;
* ``evaluate_world``: the stateless call (both ticks gathered every call);
* ``exact vectorized``: ``evaluate_poses`` (slerp) for both ticks, slerp between them, FK, float64;
* baselines, run in the same process: a Python loop over characters, each evaluated with the
  same exact math (``evaluate_poses`` + slerp + ``forward_kinematics`` on one character), and a
  loop calling ``evaluate_world`` on one character at a time.

Ratios are against the per-character exact loop (the straightforward way). The table also
prints the largest position difference of each method from that loop. Timings are the minimum
and median over repeats (the machine may be shared: the load average is printed). No asserts.

    CROWDWEAVE_CACHE=/tmp/cwcache .venv/bin/python bench/pose_eval.py [--n 10000] [--repeat 30]
        [--loop-characters 2000]   (the loops run on this many characters, scaled to N; 0 = all)
"""
from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

from runtime.crowd.tracks import evaluate_poses
from runtime import pose_kernels
from runtime.library import load_library
from runtime.motion import quat
from runtime.motion.fk import forward_kinematics
from runtime.pose import PoseBatch, PoseState, PoseTable, evaluate_world


def make_states(graph, n, seed=0):
    rng = np.random.default_rng(seed)
    g = graph
    e = rng.integers(0, g.num_edges, n)
    k = rng.integers(1, np.maximum(g.edge_frames[e] - 2, 2))
    fa = g.edge_start[e] + np.minimum(k, g.edge_frames[e] - 2)
    t = rng.random(n).astype(np.float32)
    root = np.column_stack([rng.uniform(-50, 50, (n, 2)), rng.uniform(-math.pi, math.pi, n)])
    step = np.column_stack([rng.normal(0, 0.045, (n, 2)), rng.normal(0, 0.02, n)])
    prev = PoseState(fa - 1, fa, t, root - step)
    cur = PoseState(fa, fa + 1, t, root)
    return prev, cur


def walking_ticks(graph, cur, ticks):
    """``ticks`` consecutive states of every character walking on through the library from ``cur``."""
    T = len(graph.frame_height)
    out = []
    for k in range(ticks):
        fa = np.minimum(cur.frames_a + k, T - 2)
        step = np.column_stack([np.sin(cur.root[:, 2]), np.cos(cur.root[:, 2])]) * 0.045 * k
        out.append(PoseState(fa, fa + 1, cur.frames_t, cur.root + np.column_stack([step, np.zeros(len(fa))])))
    return out


def timed_sequence(batch, states, alpha):
    """Per-tick milliseconds of push + positions over ``states`` (the first two only warm up)."""
    ts = []
    for k, st in enumerate(states):
        t0 = time.perf_counter()
        batch.push(st)
        batch.positions(alpha)
        if k >= 2:
            ts.append(time.perf_counter() - t0)
    return np.array(ts) * 1e3


def loop_exact(graph, prev, cur, alpha, count):
    """Reference: one character at a time, the same math as the exact vectorized path."""
    out = np.empty((count, graph.skeleton.num_joints, 3))
    for i in range(count):
        d = cur.root[i] - prev.root[i]
        d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
        r = prev.root[i] + alpha * d
        p0, q0 = evaluate_poses(graph, prev.frames_a[i], prev.frames_b[i], prev.frames_t[i], r)
        p1, q1 = evaluate_poses(graph, cur.frames_a[i], cur.frames_b[i], cur.frames_t[i], r)
        q = quat.slerp(q0, q1, np.full(q0.shape[:-1], alpha))
        out[i] = forward_kinematics(graph.skeleton, p0 + alpha * (p1 - p0), q)[1]
    return out


def loop_table(graph, prev, cur, alpha, count):
    out = np.empty((count, graph.skeleton.num_joints, 3), dtype=np.float32)
    for i in range(count):
        out[i] = evaluate_world(graph, cur.frames_a[i:i + 1], cur.frames_b[i:i + 1], cur.frames_t[i:i + 1],
                                cur.root[i:i + 1], prev=prev.take(slice(i, i + 1)), alpha=alpha)[0]
    return out


def timed(fn, repeat):
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return np.array(ts) * 1e3, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=10000, help="characters")
    ap.add_argument("--repeat", type=int, default=30)
    ap.add_argument("--alpha", type=float, default=0.37, help="render time between the two ticks")
    ap.add_argument("--loop-characters", type=int, default=2000,
                    help="characters the per-character loops run on (timed, then scaled to N); 0 = all N")
    ap.add_argument("--library", default="default")
    args = ap.parse_args(argv)
    g = load_library(args.library)
    n, a = args.n, args.alpha
    J = g.skeleton.num_joints
    prev, cur = make_states(g, n)
    t0 = time.perf_counter()
    PoseTable.for_graph(g)
    build_ms = (time.perf_counter() - t0) * 1e3
    rows = []
    batches = [("", PoseBatch(g, fused=False, foot_lock=False))]
    if pose_kernels.AVAILABLE:
        t0 = time.perf_counter()
        PoseBatch(g, fused=True).push(cur)       # compile (or load the cached kernels)
        compile_ms = (time.perf_counter() - t0) * 1e3
        batches.insert(0, (" fused", PoseBatch(g, fused=True, foot_lock=False)))
    for tag, batch in batches:
        batch.push(prev)

        def tick():
            batch.push(cur)
            return batch.positions(a)

        ms, _ = timed(tick, args.repeat)          # (re-pushing cur: same work as a real tick)
        batch.push(prev)
        batch.push(cur)
        rows.append((f"PoseBatch{tag} tick (push + positions)", ms, batch.positions(a).copy()))
        ms, _ = timed(lambda: batch.push(cur), args.repeat)
        batch.push(prev)
        batch.push(cur)
        rows.append((f"PoseBatch{tag} push only (per tick)", ms, batch.positions(a).copy()))
        ms, _ = timed(lambda: batch.positions(a), args.repeat)
        rows.append((f"PoseBatch{tag} frame (positions)", ms, batch.positions(a).copy()))
    walk = walking_ticks(g, cur, args.repeat + 2)
    lock_rows = []
    for tag, fused in ([(" fused", True)] if pose_kernels.AVAILABLE else []) + [("", False)]:
        for lock in (False, True):
            b = PoseBatch(g, fused=fused, foot_lock=lock)
            ms = timed_sequence(b, walk, a)
            lock_rows.append((f"PoseBatch{tag} walking, {'foot lock' if lock else 'no lock'}", ms,
                              None if not lock else int(b._lock.locked.sum())))
    ms, out_ew = timed(lambda: evaluate_world(g, cur.frames_a, cur.frames_b, cur.frames_t, cur.root, prev=prev,
                                              alpha=a), max(5, args.repeat // 3))
    rows.append(("evaluate_world (stateless)", ms, out_ew))
    ms, out_ex = timed(lambda: evaluate_world(g, cur.frames_a, cur.frames_b, cur.frames_t, cur.root, prev=prev,
                                              alpha=a, exact=True), 3)
    rows.append(("exact vectorized (slerp + FK, f64)", ms, out_ex))

    m = args.loop_characters or n
    t0 = time.perf_counter()
    ref = loop_exact(g, prev, cur, a, m)
    loop_ms = (time.perf_counter() - t0) * 1e3 * n / m
    t0 = time.perf_counter()
    ref_t = loop_table(g, prev, cur, a, m)
    loop_t_ms = (time.perf_counter() - t0) * 1e3 * n / m

    load = os.getloadavg()
    print(f"pose evaluation: {n} characters x {J} joints, default library {len(g.frame_height)} frames, "
          f"alpha {a}; table build {build_ms:.0f} ms (once per library)")
    if pose_kernels.AVAILABLE:
        import numba
        print(f"fused kernels: numba {numba.__version__}, {numba.get_num_threads()} threads; first call "
              f"{compile_ms:.0f} ms (compile or load from cache)")
    else:
        print("fused kernels: numba not importable; numpy path only")
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} CPUs"
          + (f"; loops timed on {m} characters and scaled to {n}" if m != n else ""))
    print()
    head = f"{'method':<40} {'ms/eval min':>11} {'median':>8} {'evals/s':>9} {'vs loop':>9} {'max |dp| to loop':>17}"
    print(head)
    print("-" * len(head))
    print(f"{'per-character loop (exact, reference)':<40} {loop_ms:>11.1f} {loop_ms:>8.1f} {1e3 / loop_ms:>9.2f} "
          f"{1.0:>8.1f}x {0.0:>15.4f} m")
    dt = np.abs(ref_t - ref).max()
    print(f"{'per-character loop (evaluate_world)':<40} {loop_t_ms:>11.1f} {loop_t_ms:>8.1f} {1e3 / loop_t_ms:>9.2f} "
          f"{loop_ms / loop_t_ms:>8.1f}x {dt:>15.4f} m")
    for name, ms, out in rows:
        d = float(np.abs(np.asarray(out)[:m] - ref).max())
        best, med = ms.min(), float(np.median(ms))
        print(f"{name:<40} {best:>11.2f} {med:>8.2f} {1e3 / med:>9.1f} {loop_ms / med:>8.0f}x {d:>15.4f} m")
    print()
    print(f"{'walking ticks (push + positions)':<40} {'ms/tick min':>11} {'median':>8} {'feet pinned':>12}")
    for name, ms, pinned in lock_rows:
        print(f"{name:<40} {ms.min():>11.2f} {float(np.median(ms)):>8.2f} "
              f"{'' if pinned is None else f'{pinned}/{2 * n}':>12}")
    print()
    tick_med = float(np.median(rows[0][1]))
    print(f"{rows[0][0]}:")
    print(f"per tick (push + one frame): median {tick_med:.2f} ms = {1e3 / tick_med:.0f} ticks/s "
          f"(target <= 3 ms); {loop_ms / tick_med:.0f}x the per-character loop (target >= 30x)")
    if lock_rows:
        off, on = float(np.median(lock_rows[0][1])), float(np.median(lock_rows[1][1]))
        print(f"{lock_rows[1][0]}: median {on:.2f} ms per tick against {off:.2f} ms without the lock "
              f"(+{on - off:.2f} ms; target <= 3 ms)")


if __name__ == "__main__":
    main()
