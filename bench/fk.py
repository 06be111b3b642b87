"""Benchmark: forward kinematics throughput, vectorized vs per-joint per-frame Python loops.

Builds a seeded random clip on the 31-joint CMU MotionBuilder skeleton (default 10,000
frames) and times ``runtime.motion.fk.forward_kinematics`` (level by level, numpy over frames
and joints) against two baselines run in the same process:

* ``loop/quat``: a Python loop over frames and joints calling the same ``quat.mul`` /
  ``quat.rotate`` on one joint at a time (what a direct port of a textbook FK looks like);
* ``loop/float``: the same loop on plain Python floats (no numpy call overhead), the fastest
  per-joint loop one can write in pure Python.

The baselines run on a subset of frames (until ``--baseline-seconds`` have passed) and their
throughput is taken per joint-frame, so the comparison is rate against rate. The table also
prints the largest position difference between each baseline and the vectorized result on
the frames the baseline computed. Figures only, no asserts.

    .venv/bin/python bench/fk.py [--frames 10000] [--repeat 5] [--baseline-seconds 2]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from runtime.motion import quat
from runtime.motion.fk import forward_kinematics
from runtime.motion.skeleton import CMU_MB_NAMES, CMU_MB_PARENTS, Skeleton


def make_clip(frames: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    J = len(CMU_MB_NAMES)
    offsets = rng.normal(0.0, 0.15, size=(J, 3))
    offsets[0] = 0.0
    sk = Skeleton(CMU_MB_NAMES, np.array(CMU_MB_PARENTS), offsets)
    t = np.arange(frames)[:, None, None] / 30.0
    amp = rng.uniform(0.1, 1.0, size=(1, J, 3))
    freq = rng.uniform(0.2, 2.0, size=(1, J, 3))
    euler = np.degrees(amp * np.sin(2 * np.pi * freq * t))
    rot = quat.from_euler(euler, "ZYX")
    root = np.stack([np.linspace(0, 10, frames), np.full(frames, 0.95), np.zeros(frames)], axis=-1)
    return sk, root, rot


def fk_loop_quat(sk, root, rot, frames):
    J = sk.num_joints
    out = np.empty((frames, J, 3))
    par, off = sk.parents, sk.offsets
    for f in range(frames):
        gr = [None] * J
        gp = [None] * J
        gr[0] = rot[f, 0]
        gp[0] = root[f]
        for j in range(1, J):
            p = par[j]
            gr[j] = quat.mul(gr[p], rot[f, j])
            gp[j] = gp[p] + quat.rotate(gr[p], off[j])
        out[f] = gp
    return out


def _qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def _qrot(q, v):
    w, x, y, z = q
    vx, vy, vz = v
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))


def fk_loop_float(sk, root, rot, frames):
    J = sk.num_joints
    par = [int(p) for p in sk.parents]
    off = [tuple(map(float, o)) for o in sk.offsets]
    rot_l = rot[:frames].tolist()
    root_l = root[:frames].tolist()
    out = []
    for f in range(frames):
        r = rot_l[f]
        gr = [None] * J
        gp = [None] * J
        gr[0] = tuple(r[0])
        gp[0] = tuple(root_l[f])
        for j in range(1, J):
            p = par[j]
            gr[j] = _qmul(gr[p], r[j])
            d = _qrot(gr[p], off[j])
            pp = gp[p]
            gp[j] = (pp[0] + d[0], pp[1] + d[1], pp[2] + d[2])
        out.append(gp)
    return np.array(out)


def time_baseline(fn, sk, root, rot, budget: float, max_frames: int):
    """Run ``fn`` on growing frame counts until ``budget`` seconds are used; returns
    (frames, seconds, result) of the largest run."""
    n = 8
    best = None
    spent = 0.0
    while True:
        n = min(n, max_frames)
        t0 = time.perf_counter()
        res = fn(sk, root, rot, n)
        dt = time.perf_counter() - t0
        spent += dt
        best = (n, dt, res)
        if n >= max_frames or spent + 2.2 * dt > budget:
            return best
        n *= 2


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=10_000, help="clip length in frames (default 10000)")
    ap.add_argument("--repeat", type=int, default=5, help="vectorized runs; the best is reported")
    ap.add_argument("--baseline-seconds", type=float, default=2.0, help="time budget per baseline")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)

    sk, root, rot = make_clip(args.frames, args.seed)
    J = sk.num_joints
    forward_kinematics(sk, root[:10], rot[:10])           # warm-up
    times = []
    for _ in range(max(1, args.repeat)):
        t0 = time.perf_counter()
        _, vec_pos = forward_kinematics(sk, root, rot)
        times.append(time.perf_counter() - t0)
    t_vec = min(times)
    rows = [("vectorized forward_kinematics", args.frames, t_vec, args.frames * J / t_vec, 0.0)]
    for label, fn in (("loop/quat (quat.mul, quat.rotate)", fk_loop_quat),
                      ("loop/float (pure Python math)", fk_loop_float)):
        n, dt, res = time_baseline(fn, sk, root, rot, args.baseline_seconds, args.frames)
        rows.append((label, n, dt, n * J / dt, float(np.abs(res - vec_pos[:n]).max())))

    vec_rate = rows[0][3]
    print(f"FK throughput: {args.frames} frames x {J} joints = {args.frames * J:,} joint-frames "
          f"(numpy {np.__version__}; vectorized best of {args.repeat})")
    print(f"{'method':36s} {'frames':>8s} {'seconds':>9s} {'joint-frames/s':>15s} "
          f"{'vectorized / this':>18s} {'max |dp| m':>11s}")
    for label, n, dt, rate, err in rows:
        print(f"{label:36s} {n:8d} {dt:9.4f} {rate:15.3e} {vec_rate / rate:18.1f} {err:11.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
