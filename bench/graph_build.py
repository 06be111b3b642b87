"""Benchmark: motion-graph build times, and the chunked frame distance against a per-pair loop.

Two tables, figures only (no asserts):

1. **Graph builds** (``authoring.motion_graph.build.build_graph``, default ``GraphBuildParams``
   unless ``--threshold``): seconds to read the takes and to build the graph, with the graph's
   size, from

   * the CMU MotionBuilder-family files in ``../shared/mocap/cmu`` (02_01, 07_05, 05_01,
     16_11 (A', same family), 09_06, 01_01);
   * the same plus the two salsa files (60_10, 61_10), when they load in the same family;
   * 5 minutes of generated takes (``authoring.procedural.write_session(tmp, 5.0, 0)``,
     generated into a temporary directory first; generation time is printed apart).

2. **Frame distance** (Kovar et al. 2002, closed form; :mod:`authoring.motion_graph.distance`)
   over all frame pairs of the generated takes: ``distance_rows`` in row chunks (float64
   features, and float32 features) against a plain per-pair Python loop calling
   ``aligned_distance_reference`` on the two window point clouds, in the same run. The loop
   runs on random pairs until ``--baseline-seconds`` have passed; both are reported as pairs
   per second and the ratio is rate against rate. The largest difference between the loop's
   and the chunked distances on the loop's pairs is printed as a sanity check.

    .venv/bin/python bench/graph_build.py [--quick] [--minutes 5] [--chunk 512] [--baseline-seconds 3]

``--quick``: 1 minute of generated takes, no salsa row, 1 s of baseline loop.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT.parent / "shared" / "mocap" / "cmu"
MB_FILES = ["cmu_02_01_walk.bvh", "cmu_07_05_slow_walk.bvh", "cmu_05_01_walk.bvh",
            "cmu_16_11_walk_veer_left_retargeted.bvh", "cmu_09_06_run.bvh", "cmu_01_01_jumps_turn_around.bvh"]
SALSA_FILES = ["cmu_60_10_salsa_duet_A_male.bvh", "cmu_61_10_salsa_duet_B_female.bvh"]


def _quiet(*_a, **_k):
    pass


def build_row(name, inputs, params):
    """Load + build one graph; returns a dict for the table (error text on failure)."""
    from authoring.motion_graph.build import build_graph
    from authoring.motion_graph.sources import load_takes
    t0 = time.perf_counter()
    takes = load_takes(inputs, fps=params.fps)
    t1 = time.perf_counter()
    frames = sum(t.clip.num_frames for t in takes)
    row = {"source": name, "takes": len(takes), "frames": frames, "input_s": frames / params.fps,
           "load": t1 - t0}
    try:
        g = build_graph(takes, params, log=_quiet)
    except ValueError as e:
        row.update(build=time.perf_counter() - t1, error=str(e))
        return row, takes
    row.update(build=time.perf_counter() - t1, nodes=g.num_nodes, edges=g.num_edges, edge_s=g.total_seconds,
               pairs=g.meta.get("pairs_evaluated", frames * frames))
    return row, takes


def print_build_table(rows):
    print("\nGraph builds (build_graph, default GraphBuildParams)")
    hdr = f"{'source':<38} {'takes':>5} {'frames':>7} {'input s':>8} {'load s':>7} {'build s':>8} " \
          f"{'frames/s':>9} {'nodes':>5} {'edges':>5} {'edge s':>7}"
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        base = (f"{r['source']:<38} {r['takes']:>5} {r['frames']:>7} {r['input_s']:>8.1f} {r['load']:>7.2f} "
                f"{r['build']:>8.2f} {r['frames'] / r['build']:>9.0f}")
        if "error" in r:
            print(base + f"  failed: {r['error']}")
        else:
            print(base + f" {r['nodes']:>5} {r['edges']:>5} {r['edge_s']:>7.1f}")


def window_clouds(positions, joint_weights, half_window):
    """Per-frame window point clouds (N, K, 3) and point weights (K,), laid out as
    ``frame_features`` builds them (clamped windows, tent weight x joint weight)."""
    offs = np.arange(-half_window, half_window + 1)
    tw = (half_window + 1 - np.abs(offs)).astype(np.float64)
    w = (tw[:, None] * np.asarray(joint_weights, dtype=np.float64)[None, :]).reshape(-1)
    clouds = []
    for P in positions:
        F = len(P)
        idx = np.clip(np.arange(F)[:, None] + offs[None, :], 0, F - 1)
        clouds.append(P[idx].reshape(F, -1, 3))
    return np.concatenate(clouds), w


def chunked_all_pairs(feats, chunk):
    """All N x N distances, row chunk by row chunk (the result is reduced to a checksum so
    only one chunk is alive at a time, as in the builder)."""
    from authoring.motion_graph.distance import distance_rows
    N = len(feats.sq)
    total = 0.0
    t0 = time.perf_counter()
    for s in range(0, N, chunk):
        D, _ = distance_rows(feats, slice(s, min(N, s + chunk)))
        total += float(D.sum())
    return time.perf_counter() - t0, total


def loop_pairs(clouds, w, pairs, budget_s):
    """Per-pair Python loop over ``pairs`` (M, 2) until ``budget_s`` passes."""
    from authoring.motion_graph.distance import aligned_distance_reference
    out = []
    t0 = time.perf_counter()
    for i, j in pairs:
        out.append(aligned_distance_reference(clouds[i], clouds[j], w)[0])
        if len(out) % 64 == 0 and time.perf_counter() - t0 > budget_s:
            break
    return time.perf_counter() - t0, np.array(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="1 minute of generated takes, no salsa, short baseline")
    ap.add_argument("--minutes", type=float, default=None, help="minutes of generated takes (default 5, quick 1)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--chunk", type=int, default=512, help="rows per distance chunk")
    ap.add_argument("--baseline-seconds", type=float, default=None, help="time budget of the per-pair loop")
    ap.add_argument("--threshold", type=float, default=None, help="hub threshold, RMS cm (default GraphBuildParams)")
    args = ap.parse_args(argv)
    minutes = args.minutes if args.minutes is not None else (1.0 if args.quick else 5.0)
    budget = args.baseline_seconds if args.baseline_seconds is not None else (1.0 if args.quick else 3.0)

    from authoring.motion_graph.build import GraphBuildParams
    from authoring.motion_graph.distance import frame_features
    from authoring.procedural import write_session

    params = GraphBuildParams()
    if args.threshold is not None:
        params.threshold_cm = args.threshold
    print(f"crowdweave bench/graph_build.py  (numpy {np.__version__}, python {sys.version.split()[0]})")
    rows = []

    # -- CMU MotionBuilder family ----------------------------------------------------------------
    if CMU.is_dir():
        from authoring.motion_graph.sources import load_takes
        mb = [CMU / f for f in MB_FILES if (CMU / f).exists()]
        row, mb_takes = build_row(f"CMU MotionBuilder ({len(mb)} files)", mb, params)
        rows.append(row)
        if not args.quick:
            salsa = [CMU / f for f in SALSA_FILES if (CMU / f).exists()]
            ref = mb_takes[0].clip.skeleton
            same = [f for f in salsa if load_takes([f], fps=params.fps)[0].clip.skeleton.same_family(ref)]
            if same:
                row, _ = build_row(f"CMU MotionBuilder + salsa ({len(mb) + len(same)} files)", mb + same, params)
                rows.append(row)
            if len(same) < len(salsa):
                print(f"(salsa files not in the MotionBuilder family, left out: "
                      f"{', '.join(f.name for f in salsa if f not in same)})")
    else:
        print(f"(CMU files not found at {CMU}: CMU rows skipped)")

    # -- generated takes ------------------------------------------------------------------------
    with tempfile.TemporaryDirectory(prefix="cw-bench-") as tmp:
        t0 = time.perf_counter()
        write_session(tmp, minutes, args.seed)
        gen_s = time.perf_counter() - t0
        row, gen_takes = build_row(f"generated {minutes:g} min (seed {args.seed})", [tmp], params)
        rows.append(row)
    print(f"(generating {minutes:g} min of takes took {gen_s:.1f} s; not part of the build time)")
    print_build_table(rows)

    # -- distance: chunked vs per-pair loop ----------------------------------------------------
    sk = gen_takes[0].clip.skeleton
    jw = np.array([float(params.joint_weights.get(n, 1.0)) for n in sk.names])   # as build_graph weighs joints
    positions = [t.clip.positions(origin=np.zeros(3)) for t in gen_takes]
    t0 = time.perf_counter()
    f64 = frame_features(positions, jw, params.half_window)
    feat_s = time.perf_counter() - t0
    f32 = frame_features(positions, jw, params.half_window, dtype=np.float32)
    N = len(f64.sq)
    n_pairs = N * N
    chunk_s, _ = chunked_all_pairs(f64, args.chunk)
    chunk32_s, _ = chunked_all_pairs(f32, args.chunk)

    clouds, w = window_clouds(positions, jw, params.half_window)
    rng = np.random.default_rng(args.seed)
    pairs = rng.integers(0, N, size=(200_000, 2))
    loop_s, loop_d = loop_pairs(clouds, w, pairs, budget)
    done = pairs[:len(loop_d)]
    from authoring.motion_graph.distance import distance_rows
    ref = np.array([distance_rows(f64, slice(i, i + 1), slice(j, j + 1))[0][0, 0] for i, j in done[:2000]])
    diff = float(np.abs(ref - loop_d[:len(ref)]).max())

    rate_loop = len(loop_d) / loop_s
    print(f"\nFrame distance over all pairs of the generated takes: {N} frames, {n_pairs:,} pairs, "
          f"window {2 * params.half_window + 1} frames x {int((jw > 0).sum())} weighted joints")
    hdr = f"{'method':<44} {'pairs':>14} {'seconds':>9} {'pairs/s':>12} {'vs loop':>9}"
    print(hdr)
    print("-" * len(hdr))
    print(f"{'per-pair loop (aligned_distance_reference)':<44} {len(loop_d):>14,} {loop_s:>9.2f} "
          f"{rate_loop:>12,.0f} {1.0:>8.0f}x")
    for name, secs in ((f"chunked distance_rows float64 ({args.chunk} rows)", chunk_s),
                       (f"chunked distance_rows float32 ({args.chunk} rows)", chunk32_s)):
        rate = n_pairs / secs
        print(f"{name:<44} {n_pairs:>14,} {secs:>9.2f} {rate:>12,.0f} {rate / rate_loop:>8.0f}x")
    print(f"(features: {feat_s:.2f} s; loop estimate for all pairs: {n_pairs / rate_loop / 3600:.1f} h; "
          f"largest |loop - chunked| on {len(ref)} pairs: {diff:.1e} m^2)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
