"""Scaling out on Dask: the same work on a LocalCluster of 1 and of 2 worker processes.

Tables, figures only (no asserts), all from one run; ``load`` is the 1-minute load average when a
row finished (on a machine shared with other jobs, a high one means the workers did not have the
cores to themselves):

1. **Sweep** (``crowdweave batch``'s ``run_batch``): ``--variants`` variants of the ``grid``
   generator (``--characters`` characters walking 6 m, 12 s baked, seeds 0..n-1) on 1 and on 2
   workers: seconds to start the cluster, seconds for the sweep, the total, and the ratio 1 / 2
   workers; whether the two runs wrote the same stage bytes.
2. **Motion-graph build** of ``--minutes`` of generated capture (``build_graph``): in this process,
   and with the frame-distance blocks on 1 and on 2 workers (cluster start apart); whether the
   packs are byte-identical.
3. **Value-clip layers** (``--clip-characters`` x 300 frames, 100 per layer): the local process
   pool (2 processes), and 2 Dask workers returning each layer to this process (what
   ``crowdweave bake --scheduler`` does) against 2 Dask workers writing each layer into a
   directory they share with this process.
4. **Flock graph (DDG) build** of a 150 s 2D recording with the exact metric in 1 and 2 processes
   of its own pool (``DDGBuildParams.workers``): how much a second process gains there.
5. **Planning regions** (the figures of ``docs/scale_out.md``): planning seconds of one region
   (a ``crossing``: two columns 2 m apart swapping sides 10 m away) against its number of
   characters (mean, min and max over seeds); then two regions
   planned independently side by side with a fence gap between them, and the checker's count of
   overlapping pairs across the fence (what border repair must fix).

    .venv/bin/python bench/scale_out.py [--quick] [--variants 8] [--characters 6] [--minutes 20]

``--quick``: 4 variants of 3 characters, 3 minutes of capture, 200 clip characters, no DDG row,
regions of up to 16 characters.
"""
from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from authoring.batch import local_cluster, run_batch  # noqa: E402
from authoring.batch.cluster import block_mapper  # noqa: E402
from authoring.batch.sweep import parse_sweep  # noqa: E402


def _quiet(*_a, **_k):
    pass


def _client(n):
    from distributed import Client
    t0 = time.perf_counter()
    cluster = local_cluster(n)
    client = Client(cluster, set_as_default=False)
    client.wait_for_workers(n)
    return cluster, client, time.perf_counter() - t0


def _close(cluster, client):
    client.close()
    cluster.close()


def _header(title: str, hdr: str) -> None:
    print(title)
    print(hdr)
    print("-" * len(hdr))


def _digest(paths) -> str:
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    return h.hexdigest()[:12]


def sweep_rows(tmp: Path, variants: int, characters: int):
    data = {"sweep": {"name": "bench", "generator": "grid"},
            "generator": {"characters": characters, "distance": 6.0, "duration": 12.0},
            "axes": {"seed": list(range(variants))}}
    sweep = parse_sweep(data, tmp / "sweep.toml")
    rows = []
    for n in (1, 2):
        cluster, client, t_start = _client(n)
        out = tmp / f"sweep{n}"
        try:
            t0 = time.perf_counter()
            res = run_batch(sweep, out, client=client)
            t_sweep = time.perf_counter() - t0
        finally:
            _close(cluster, client)
        stages = sorted(out.glob("*/stage.usdc"))
        rows.append({"workers": n, "start": t_start, "sweep": t_sweep, "total": t_start + t_sweep,
                     "load": os.getloadavg()[0],
                     "passed": res.counts["passed"], "variants": len(res.variants), "digest": _digest(stages),
                     "plan": sum(r.get("plan_seconds") or 0 for r in res.records.values())})
    return rows


def print_sweep(rows, characters):
    _header(f"\n1. Sweep: {rows[0]['variants']} variants of {characters} characters (grid, 6 m, 12 s), LocalCluster",
            f"{'workers':>7} {'start s':>8} {'sweep s':>8} {'total s':>8} {'plan s (sum)':>12} {'passed':>7} {'stages':>13}"
            f" {'load':>5}")
    for r in rows:
        print(f"{r['workers']:>7} {r['start']:>8.1f} {r['sweep']:>8.1f} {r['total']:>8.1f} {r['plan']:>12.1f} "
              f"{r['passed']:>3}/{r['variants']:<3} {r['digest']:>13} {r['load']:>5.1f}")
    a, b = rows
    print(f"ratio 1 / 2 workers: sweep {a['sweep'] / b['sweep']:.2f}x, total {a['total'] / b['total']:.2f}x; "
          f"stages identical: {'yes' if a['digest'] == b['digest'] else 'NO'}")


def graph_rows(tmp: Path, minutes: float):
    from authoring.motion_graph.build import GraphBuildParams, build_graph
    from authoring.motion_graph.sources import load_takes
    from authoring.procedural import write_session
    t0 = time.perf_counter()
    write_session(tmp / "capture", minutes, 0)
    t_gen = time.perf_counter() - t0
    takes = load_takes([str(tmp / "capture")], fps=30.0)
    frames = sum(t.clip.num_frames for t in takes)
    rows = []
    for n in (0, 1, 2):
        cluster = client = None
        t_start = 0.0
        if n:
            cluster, client, t_start = _client(n)
        try:
            t0 = time.perf_counter()
            g = build_graph(takes, GraphBuildParams(), log=_quiet, map_blocks=block_mapper(client) if client else None)
            t_build = time.perf_counter() - t0
        finally:
            if client:
                _close(cluster, client)
        pack = tmp / f"graph{n}.cwpack"
        g.save(pack)
        rows.append({"workers": n, "start": t_start, "build": t_build, "digest": _digest([pack]),
                     "load": os.getloadavg()[0],
                     "nodes": g.num_nodes, "edges": g.num_edges})
    return rows, frames, t_gen


def print_graph(rows, frames, minutes, t_gen):
    _header(f"\n2. Motion-graph build: {minutes:g} min of generated capture ({frames} frames, generated in "
            f"{t_gen:.1f} s), frame-distance blocks",
            f"{'where':<18} {'start s':>8} {'build s':>8} {'nodes':>6} {'edges':>6} {'pack':>13} {'load':>5}")
    for r in rows:
        where = "this process" if r["workers"] == 0 else f"{r['workers']} worker" + ("s" if r["workers"] > 1 else "")
        print(f"{where:<18} {r['start']:>8.1f} {r['build']:>8.1f} {r['nodes']:>6} {r['edges']:>6} {r['digest']:>13} "
              f"{r['load']:>5.1f}")
    p, a, b = rows
    same = p["digest"] == a["digest"] == b["digest"]
    print(f"ratio 1 / 2 workers: {a['build'] / b['build']:.2f}x (with cluster start {(a['build'] + a['start']) / (b['build'] + b['start']):.2f}x); "
          f"this process / 2 workers: {p['build'] / b['build']:.2f}x; packs identical: {'yes' if same else 'NO'}")


def _chunk_to_shared_dir(graph, fps, name, items, directory):
    """The shared-filesystem alternative: the worker writes the layer where the stage's
    process will find it and returns only its digest."""
    from usd_io.clips import chunk_layer_bytes
    _, data = chunk_layer_bytes(graph, fps, name, items)
    path = Path(directory) / name
    with open(path, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    return name, hashlib.sha256(data).hexdigest()


def clip_rows(tmp: Path, characters: int, frames: int = 300, per: int = 100):
    from distributed import as_completed

    from runtime.library import load_library
    from usd_io.clips import write_clip_layers
    from usd_io.crowd import character_path
    sys.path.insert(0, str(ROOT / "bench"))
    from usd_bake import make_tracks
    graph = load_library("default")
    tracks = make_tracks(graph, characters, frames)
    items = [(character_path(k), t) for k, t in tracks.items()]
    rows = []
    t0 = time.perf_counter()
    with write_clip_layers(tmp / "pool" / "crowd.usdc", items, graph, 30.0, per, workers=2) as cl:
        cl.wait()
    rows.append(("process pool, 2 processes", 0.0, time.perf_counter() - t0))
    cluster, client, t_start = _client(2)
    best = {"Dask, layers returned": [], "Dask, shared directory": []}
    try:
        g = client.scatter(graph, broadcast=True, hash=False)
        chunks = [(f"chunk_{k:04d}.usdc", [(str(p), t) for p, t in items[i:i + per]])
                  for k, i in enumerate(range(0, len(items), per))]
        for rep in range(3):           # the first round warms the workers (imports, USD); best of the others
            t0 = time.perf_counter()
            with write_clip_layers(tmp / f"dask{rep}" / "crowd.usdc", items, graph, 30.0, per,
                                   scheduler=client.scheduler.address) as cl:
                cl.wait()
            best["Dask, layers returned"].append(time.perf_counter() - t0)
            shared = tmp / f"shared{rep}"
            shared.mkdir()
            t0 = time.perf_counter()
            futs = [client.submit(_chunk_to_shared_dir, g, 30.0, n, c, str(shared), pure=False) for n, c in chunks]
            for f in as_completed(futs, loop=client.loop):
                f.result()
            best["Dask, shared directory"].append(time.perf_counter() - t0)
    finally:
        _close(cluster, client)
    rows += [(k, t_start, min(v[1:])) for k, v in best.items()]
    size = sum(p.stat().st_size for p in (tmp / "shared0").iterdir())
    return rows, size


def print_clips(rows, characters, size):
    _header(f"\n3. Value-clip layers: {characters} characters x 300 frames, 100 per layer ({size / 1e6:.0f} MB; "
            "the pool's row includes starting its processes, as in a bake; Dask rows: best of 2 after a "
            "warm-up round)", f"{'writer':<28} {'write s':>8}")
    for name, _, t in rows:
        print(f"{name:<28} {t:>8.2f}")


def ddg_rows():
    from authoring.boids import BoidsParams, record_flock
    from authoring.ddg import DDGBuildParams, build_ddg
    rec = record_flock(BoidsParams(dim=2, n_agents=20), 150.0, seed=1)
    rows = []
    for w in (1, 2):
        t0 = time.perf_counter()
        _, st = build_ddg(rec, DDGBuildParams(workers=w))
        rows.append((w, time.perf_counter() - t0, st.seconds_exact, st.exact_evaluations))
    return rows


def print_ddg(rows):
    _header("\n4. Flock graph (DDG) build, 150 s 2D recording of 20 agents",
            f"{'processes':>9} {'build s':>8} {'exact metric s':>15} {'evaluations':>12}")
    for w, t, te, n in rows:
        print(f"{w:>9} {t:>8.1f} {te:>15.1f} {n:>12}")
    print(f"ratio 1 / 2 processes: {rows[0][1] / rows[1][1]:.2f}x")


def _plan_region(graph, n, seed, z_offset=0.0, prefix=""):
    from authoring.batch.generators import crossing
    from runtime.crowd.scenario import parse_scenario
    from runtime.crowd.scheduler import plan_scenario
    data = crossing(characters=n, spacing=2.0, distance=10.0, duration=20.0, seed=seed)
    for c in data["character"]:
        c["name"] = prefix + c["name"]
        c["start"]["position"][1] += z_offset
        c["goal"][0]["position"][1] += z_offset
    sc = parse_scenario(data)
    t0 = time.perf_counter()
    res = plan_scenario(sc, graph)
    return data, res, time.perf_counter() - t0


def region_rows(sizes, seeds=(0, 1)):
    from runtime.library import load_library
    graph = load_library("default")
    _plan_region(graph, 2, 99)                    # compile / load the kernels first
    rows = []
    for n in sizes:
        ts = [_plan_region(graph, n, s)[2] for s in seeds]
        rows.append((n, float(np.mean(ts)), float(np.min(ts)), float(np.max(ts))))
    return rows


def border_rows(n, gaps, seed=0):
    """Two regions of ``n`` characters planned apart, ``gap`` m between their facing rows."""
    from runtime.crowd.checker import check_crowd
    from runtime.crowd.scenario import parse_scenario
    from runtime.library import load_library
    graph = load_library("default")
    width = ((n + 1) // 2 - 0.5) * 2.0         # a crossing's extent across the walk (spacing 2 m)
    out = []
    for gap in gaps:
        da, ra, ta = _plan_region(graph, n, seed, 0.0, "a_")
        db, rb, tb = _plan_region(graph, n, seed + 1, width + gap, "b_")
        merged = parse_scenario({**da, "character": da["character"] + db["character"]})
        tracks = {c.name: c.track for c in ra.characters + rb.characters}
        pairs = check_crowd(merged, tracks, graph, None, ra.fps).character_overlaps
        cross = [p for p in pairs if p["a"][:2] != p["b"][:2]]          # a_... against b_...
        names = {x for p in cross for x in (p["a"], p["b"])}
        out.append((gap, ta + tb, len(pairs), len(cross), len(names)))
    return out


def print_regions(rows, borders, n_border):
    _header("\n5. Planning regions: two columns 2 m apart swapping sides 10 m away (20 s), planned in this process",
            f"{'characters':>10} {'plan s':>8} {'min':>6} {'max':>6} {'s / character':>13}")
    for n, m, lo, hi in rows:
        print(f"{n:>10} {m:>8.2f} {lo:>6.2f} {hi:>6.2f} {m / n:>13.3f}")
    _header(f"\n   two regions of {n_border} characters planned independently, side by side",
            f"{'fence gap m':>11} {'plan s':>7} {'overlapping pairs':>17} {'across the fence':>16} "
            f"{'characters to repair':>20}")
    for gap, t, pairs, cross, names in borders:
        print(f"{gap:>11.1f} {t:>7.1f} {pairs:>17} {cross:>16} {names:>20}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--variants", type=int, default=8)
    ap.add_argument("--characters", type=int, default=6)
    ap.add_argument("--minutes", type=float, default=20.0)
    ap.add_argument("--clip-characters", type=int, default=1000)
    ap.add_argument("--regions", type=int, nargs="*", default=[8, 16, 32, 64], metavar="N",
                    help="region sizes (characters) of table 5")
    ap.add_argument("--skip", nargs="*", default=[], choices=["sweep", "graph", "clips", "ddg", "regions"])
    args = ap.parse_args(argv)
    if args.quick:
        args.variants, args.characters, args.minutes, args.clip_characters = 4, 3, 3.0, 200
        args.regions = [4, 8, 16]
        args.skip = sorted(set(args.skip) | {"ddg"})
    from authoring.default_library import ensure_library
    ensure_library("default", log=_quiet, progress=False)
    print(f"{os.cpu_count()} cores; load average before: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    tmp = Path(tempfile.mkdtemp(prefix="crowdweave-scale-out-"))
    try:
        if "sweep" not in args.skip:
            print_sweep(sweep_rows(tmp, args.variants, args.characters), args.characters)
        if "graph" not in args.skip:
            rows, frames, t_gen = graph_rows(tmp, args.minutes)
            print_graph(rows, frames, args.minutes, t_gen)
        if "clips" not in args.skip:
            rows, size = clip_rows(tmp, args.clip_characters)
            print_clips(rows, args.clip_characters, size)
        if "ddg" not in args.skip:
            print_ddg(ddg_rows())
        if "regions" not in args.skip:
            n_border = args.regions[min(1, len(args.regions) - 1)]
            print_regions(region_rows(args.regions), border_rows(n_border, (0.5, 1.5, 2.5)), n_border)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"\nload average after: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
