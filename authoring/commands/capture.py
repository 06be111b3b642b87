"""``crowdweave capture``: generate procedural motion-capture takes (BVH + label sidecars).

Writes ``OUT/take_000.bvh``, ``take_000.labels.json``, ... and ``OUT/session.json`` (see
:mod:`authoring.procedural.session`), then prints a short summary and the quality figures
of :func:`authoring.capture_quality.take_quality`.
"""
from __future__ import annotations

import sys
import time


def configure(parser):
    parser.add_argument("--minutes", type=float, default=3.0, help="total minutes of motion (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--fps", type=float, default=30.0, help="frame rate (default 30)")
    parser.add_argument("--take-minutes", type=float, default=2.0,
                        help="length of one take in minutes (default 2)")
    parser.add_argument("--no-check", action="store_true", help="skip the quality check at the end")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    from authoring.cli import CLIError

    if not (args.minutes > 0):
        raise CLIError(f"--minutes must be positive, not {args.minutes}")
    if not (args.take_minutes > 0):
        raise CLIError(f"--take-minutes must be positive, not {args.take_minutes}")
    if not (0 < args.fps <= 1000):
        raise CLIError(f"--fps must be in (0, 1000], not {args.fps}")
    from pathlib import Path

    from tqdm import tqdm

    from authoring.procedural import write_session

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CLIError(f"{out}: exists and is not a directory")
    t0 = time.perf_counter()
    total = args.minutes * 60.0
    with tqdm(total=round(total, 1), unit="s", desc="capture", disable=args.quiet or not sys.stderr.isatty(),
              bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} s motion [{elapsed}<{remaining}]") as bar:
        def progress(sec):
            bar.update(min(sec, max(bar.total - bar.n, 0)))
        try:
            manifest = write_session(out, args.minutes, args.seed, args.fps, args.take_minutes, progress)
        except OSError as e:
            raise CLIError(f"{out}: cannot write ({e.strerror or e})") from None
    elapsed = time.perf_counter() - t0
    counts: dict[str, int] = {}
    frames = 0
    for t in manifest["takes"]:
        frames += t["frames"]
        for k, v in t["segments"].items():
            counts[k] = counts.get(k, 0) + v
    print(f"wrote {len(manifest['takes'])} takes to {out}: {frames} frames, {frames / args.fps:.1f} s at "
          f"{args.fps:g} fps, seed {args.seed}, in {elapsed:.1f} s")
    print("segments: " + ", ".join(f"{k} {counts[k]}" for k in sorted(counts)))
    if not args.no_check:
        from authoring.capture_quality import format_quality, take_quality

        print(format_quality(take_quality(out)))
    return 0
