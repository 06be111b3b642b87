"""``crowdweave author graph INPUTS... --out lib.cwpack``: build a snap-together motion graph."""
from __future__ import annotations

import sys
import time
from contextlib import contextmanager

from authoring.commands.args import check_output, integer, number


def configure(p):
    p.add_argument("inputs", nargs="+", help="take directories (procedural capture) and/or BVH files")
    p.add_argument("--out", required=True, help="output pack (.cwpack); a USD preview is written beside it")
    p.add_argument("--scale", type=number(0, 1000, lo_open=True), default=None,
                   help="metres per BVH unit (default: by skeleton family; > 0, at most 1000)")
    p.add_argument("--labels", default=None,
                   help="label sidecar JSON, one label for all BVH frames, or 'derive' (default: sidecars, "
                        "else derived from the motion: stand, turn on the spot, walk; hops, backward or "
                        "sideways travel and uneven ground left out)")
    p.add_argument("--mirror", action="store_true",
                   help="add every take mirrored left to right (a left turn becomes a right turn)")
    p.add_argument("--fps", type=number(0, 1000, lo_open=True), default=30.0,
                   help="graph frame rate (default 30; > 0, at most 1000)")
    p.add_argument("--threshold", type=number(0, 1000, lo_open=True), default=None,
                   help="hub match threshold, RMS cm (default 6; 14 for capture with derived labels; > 0, at most 1000)")
    p.add_argument("--no-usd", action="store_true", help="skip the USD preview")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="compute the frame-distance blocks on the Dask cluster at ADDRESS (e.g. tcp://host:8786); "
                        "the pack is the same")
    p.add_argument("--workers", type=integer(1, 256), default=1, metavar="N",
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
    from authoring.motion_graph.library import build_library
    from authoring.motion_graph.sources import LabelError
    from runtime.motion import SkeletonMismatchError

    out = check_output(args.out)
    if not args.no_usd:
        check_output(out.with_suffix(".usda"), None, "--out (its USD preview)")
    t0 = time.perf_counter()
    quiet = args.quiet or not sys.stderr.isatty()
    try:
        with _distance_blocks(args.scheduler, args.workers) as map_blocks, \
                tqdm(desc="reading takes", unit="file", disable=quiet) as rbar, \
                tqdm(desc="frame distances", unit="frame", disable=quiet) as bar:
            g, report = build_library(args.inputs, mirror=args.mirror, labels=args.labels,
                                      threshold_cm=args.threshold, fps=args.fps, scale=args.scale,
                                      log=print, progress=bar.update, read_progress=rbar.update,
                                      map_blocks=map_blocks)
    except (FileNotFoundError, BVHError, LabelError, SkeletonMismatchError, ValueError) as e:
        raise CLIError(str(e)) from None
    for line in report:
        print(line)
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
