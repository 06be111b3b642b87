"""``crowdweave convert IN.bvh OUT.usda|.usdc``: a BVH file as a UsdSkel stage.

Reads the BVH with :func:`authoring.bvh.read_bvh` (scale by skeleton family unless
``--scale``; synthetic first frame dropped when detected unless ``--drop-first-frame``
says otherwise; the file's own frame rate unless ``--fps``), writes one SkelRoot with a
Skeleton and a bound SkelAnimation through :func:`usd_io.skel.write_clip_stage` (atomic:
temporary file, then rename), validates the written file with
:func:`usd_io.validate.validate_stage` and prints a one-line summary. Exit code 1 when the
written stage has validation errors (they are listed on stderr).
"""
from __future__ import annotations

import sys
from pathlib import Path

from authoring.commands import CLIError
from authoring.commands.args import check_output, number

_DROP = {"auto": "auto", "yes": True, "no": False}


def configure(parser):
    parser.add_argument("input", help="BVH file to read")
    parser.add_argument("output", help="USD file to write (.usda text, .usdc or .usd binary)")
    parser.add_argument("--scale", type=number(0, 1000, lo_open=True), default=None,
                        help="metres per BVH file unit (default: by skeleton family; 1 for unknown skeletons; "
                             "> 0, at most 1000)")
    parser.add_argument("--fps", type=number(0, 1000, lo_open=True), default=None,
                        help="resample to this frame rate (default: keep the file's rate; > 0, at most 1000)")
    parser.add_argument("--drop-first-frame", choices=tuple(_DROP), default="auto",
                        help="drop a synthetic T-pose/rest first frame (default: auto-detect)")
    parser.add_argument("--name", default=None,
                        help="name of the SkelRoot prim, the stage's defaultPrim (default: the input file name)")


def run(args) -> int:
    from authoring.bvh import BVHError, read_bvh
    from usd_io.stage import USD_EXTENSIONS, StageError, valid_prim_name
    from usd_io.skel import write_clip_stage
    from usd_io.validate import errors, validate_stage

    src = Path(args.input)
    out = Path(args.output)
    if out.suffix.lower() not in USD_EXTENSIONS:
        raise CLIError(f"{out}: output must end in {', '.join(USD_EXTENSIONS)} (got {out.suffix or 'no extension'!r})")
    check_output(out, USD_EXTENSIONS, "output")
    if not src.is_file():
        raise CLIError(f"{src}: file not found" if not src.exists() else f"{src}: not a file")
    try:
        motion = read_bvh(src, scale=args.scale, drop_first_frame=_DROP[args.drop_first_frame], fps=args.fps)
    except BVHError as e:
        raise CLIError(str(e)) from None
    except OSError as e:
        raise CLIError(f"{src}: cannot read: {e.strerror or e}") from None

    clip = motion.clip
    name = valid_prim_name(args.name or src.stem, "Character")
    meta = {
        "source": src.name,
        "family": motion.family,
        "sourceFps": float(motion.source_fps),
        "scale": float(motion.scale),
        "droppedFirstFrame": bool(motion.dropped_first_frame),
    }
    try:
        info = write_clip_stage(out, clip, name, metadata=meta)
    except StageError as e:
        raise CLIError(str(e)) from None
    except OSError as e:
        raise CLIError(f"{out}: cannot write: {e.strerror or e}") from None

    issues = validate_stage(out)
    errs = errors(issues)
    warns = [i for i in issues if i.severity == "warning"]
    fps = f"{clip.fps:g} fps" + ("" if args.fps is None else f" (resampled from {motion.source_fps:g} fps)")
    dropped = ", synthetic first frame dropped" if motion.dropped_first_frame else ""
    print(f"wrote {out}: SkelRoot {info.root}, {info.joints} joints, {info.frames} frames at {fps} "
          f"({clip.duration:.2f} s), family {motion.family}, scale {motion.scale:g} m/unit{dropped}; "
          f"validation: {len(errs)} errors, {len(warns)} warnings")
    for i in errs + warns:
        print(f"  {i}", file=sys.stderr)
    return 1 if errs else 0
