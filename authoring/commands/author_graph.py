"""``crowdweave author graph INPUTS... --out lib.cwpack``: build a snap-together motion graph."""
from __future__ import annotations

import sys
import time

from authoring.commands.args import check_output, number


def configure(p):
    p.add_argument("inputs", nargs="+", help="take directories (procedural capture) and/or BVH files")
    p.add_argument("--out", required=True, help="output pack (.cwpack); a USD preview is written beside it")
    p.add_argument("--scale", type=number(0, 1000, lo_open=True), default=None,
                   help="metres per BVH unit (default: by skeleton family; > 0, at most 1000)")
    p.add_argument("--labels", default=None, help="label sidecar JSON, or one label for all BVH frames (default: sidecars, else 'walk')")
    p.add_argument("--fps", type=number(0, 1000, lo_open=True), default=30.0,
                   help="graph frame rate (default 30; > 0, at most 1000)")
    p.add_argument("--threshold", type=number(0, 1000, lo_open=True), default=None,
                   help="hub match threshold, RMS cm (default 6; > 0, at most 1000)")
    p.add_argument("--no-usd", action="store_true", help="skip the USD preview")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args) -> int:
    from tqdm import tqdm

    from authoring.bvh import BVHError
    from authoring.commands import CLIError
    from authoring.motion_graph.build import GraphBuildParams, build_graph
    from authoring.motion_graph.sources import LabelError, load_takes
    from runtime.motion import SkeletonMismatchError

    out = check_output(args.out)
    if not args.no_usd:
        check_output(out.with_suffix(".usda"), None, "--out (its USD preview)")
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
    try:
        with tqdm(total=frames, desc="frame distances", unit="frame", disable=quiet) as bar:
            g = build_graph(takes, params, progress=bar.update, log=print)
    except (ValueError, SkeletonMismatchError) as e:
        raise CLIError(str(e)) from None
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
