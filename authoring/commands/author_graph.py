"""``crowdweave author graph INPUTS... --out lib.cwpack``: build a snap-together motion graph."""
from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from pathlib import Path


def configure(p):
    p.add_argument("inputs", nargs="+", help="take directories (procedural capture) and/or BVH files")
    p.add_argument("--out", required=True, help="output pack (.cwpack); a USD preview is written beside it")
    p.add_argument("--scale", type=float, default=None, help="metres per BVH unit (default: by skeleton family)")
    p.add_argument("--labels", default=None, help="label sidecar JSON, or one label for all BVH frames (default: sidecars, else 'walk')")
    p.add_argument("--fps", type=float, default=30.0, help="graph frame rate (default 30)")
    p.add_argument("--threshold", type=float, default=None, help="hub match threshold, RMS cm (default 6)")
    p.add_argument("--no-usd", action="store_true", help="skip the USD preview")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="compute the frame-distance blocks on the Dask cluster at ADDRESS (e.g. tcp://host:8786); "
                        "the pack is the same")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="without --scheduler: compute the frame-distance blocks on a local cluster of N worker "
                        "processes (default 1: in this process; see docs/scale_out.md for when more pays)")


@contextmanager
def _distance_blocks(scheduler, workers):
    """``map_blocks`` for the build: on the cluster at ``scheduler``, on a local cluster of
    ``workers`` processes, or None (this process)."""
    if not scheduler and workers <= 1:
        yield None
        return
    from authoring.batch.cluster import ClusterError, block_mapper, dask_client
    from authoring.commands import CLIError
    try:
        with dask_client(scheduler, None if scheduler else workers) as client:
            print(f"frame distances on {scheduler or 'a local cluster'} "
                  f"({len(client.scheduler_info(n_workers=-1).get('workers', {}))} workers)")
            yield block_mapper(client)
    except ClusterError as e:
        raise CLIError(str(e)) from None


def run(args) -> int:
    from tqdm import tqdm

    from authoring.bvh import BVHError
    from authoring.commands import CLIError
    from authoring.motion_graph.build import GraphBuildParams, build_graph
    from authoring.motion_graph.sources import LabelError, load_takes
    from runtime.motion import SkeletonMismatchError

    t0 = time.perf_counter()
    quiet = args.quiet or not sys.stderr.isatty()
    try:
        with tqdm(desc="reading takes", unit="file", disable=quiet) as bar:
            takes = load_takes(args.inputs, fps=args.fps, scale=args.scale, labels=args.labels, progress=bar.update)
    except (FileNotFoundError, BVHError, LabelError, SkeletonMismatchError) as e:
        raise CLIError(str(e)) from None
    frames = sum(t.clip.num_frames for t in takes)
    print(f"{len(takes)} takes, {frames} frames ({frames / args.fps:.1f} s) at {args.fps:g} fps")
    params = GraphBuildParams(fps=args.fps)
    if args.threshold is not None:
        params.threshold_cm = args.threshold
    if args.workers < 1:
        raise CLIError(f"--workers must be at least 1, got {args.workers}")
    try:
        with _distance_blocks(args.scheduler, args.workers) as map_blocks, \
                tqdm(total=frames, desc="frame distances", unit="frame", disable=quiet) as bar:
            g = build_graph(takes, params, progress=bar.update, log=print, map_blocks=map_blocks)
    except (ValueError, SkeletonMismatchError) as e:
        raise CLIError(str(e)) from None
    out = Path(args.out)
    g.save(out)
    s = g.summary()
    print(f"wrote {out}: {s['nodes']} nodes, {s['edges']} edges, {s['seconds']} s of motion, "
          f"median parallel {s['parallel']['median_parallel']:g} ({time.perf_counter() - t0:.1f} s)")
    if not args.no_usd:
        try:
            from usd_io.library import write_library_preview
        except ImportError:
            print("(USD preview not available in this build)")
        else:
            usd = out.with_suffix(".usda")
            write_library_preview(usd, g)
            print(f"wrote {usd}")
    return 0
