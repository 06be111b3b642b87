"""``crowdweave author patches TAKES... --out patches.cwpack``: a motion-patch library (Kim, Hwang,
Hyun and Lee 2012, section 4) from multi-character takes.

Detects episodes (contact, proximity with reaction, synchronicity), chooses the patch
boundaries over the largest pose groups, cuts one patch per episode and mixes in
single-character walking / turning / idle patches: from a motion graph (``--singles library``,
default library ``default``) or cut from the takes themselves (``--singles takes``).
"""
from __future__ import annotations

import sys
import time

from authoring.commands.args import check_output, integer, limits, number
from runtime.limits import MAX_SEED


def configure(p):
    p.add_argument("takes", nargs="+", metavar="TAKES",
                   help="take directories (with take.json) or directories of takes (crowdweave capture --takes)")
    p.add_argument("--out", required=True, help="output pack (.cwpack, kind motion_patches)")
    p.add_argument("--singles", choices=("auto", "library", "takes", "none"), default="auto",
                   help="where single-character patches come from: the motion library (--library), the "
                        "takes' eventless stretches, or none (default auto: library if it is built, else takes)")
    p.add_argument("--library", default="default",
                   help="motion-graph library for single-character patches and pose-class names (default: default)")
    p.add_argument("--seed", type=integer(0, MAX_SEED), default=0,
                   help=f"seed for choosing among parallel library edges (default 0; {limits(0, MAX_SEED)})")
    p.add_argument("--threshold", type=number(0, 10, lo_open=True), default=None,
                   help="pose-group threshold, RMS metres (default 0.06; > 0, at most 10)")
    p.add_argument("--k", type=integer(1, 16), default=None, help="largest pose groups considered (default 10; 1-16)")
    p.add_argument("--weight", type=number(0, 1e6), default=None,
                   help="frames per extra pose class in the boundary cost (default 60; 0-1e6)")
    p.add_argument("--max-pad", type=number(0, 600, lo_open=True), default=None,
                   help="seconds a boundary may lie from its episode (default 5; > 0, at most 600)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    from tqdm import tqdm

    from authoring.bvh import BVHError
    from authoring.commands import CLIError
    from authoring.patches.build import PatchBuildError, PatchBuildParams, build_patch_library
    from authoring.takes import TakeError, find_take_dirs, load_take
    from runtime.assets import AssetError

    out = check_output(args.out)
    t0 = time.perf_counter()
    quiet = args.quiet or not sys.stderr.isatty()
    params = PatchBuildParams()
    b = params.boundaries
    for name, attr, ok in (("threshold", "threshold", lambda v: v > 0), ("k", "k", lambda v: 1 <= v <= 16),
                           ("weight", "weight", lambda v: v >= 0), ("max_pad", "max_pad_s", lambda v: v > 0)):
        v = getattr(args, name)
        if v is not None:
            if not ok(v):
                raise CLIError(f"--{name.replace('_', '-')} {v} is out of range")
            setattr(b, attr, v)
    try:
        dirs = [d for t in args.takes for d in find_take_dirs(t)]
    except TakeError as e:
        raise CLIError(str(e)) from None
    takes = []
    try:
        with tqdm(total=len(dirs), desc="reading takes", unit="take", disable=quiet) as bar:
            for d in dirs:
                takes.append(load_take(d))
                bar.update(1)
    except (TakeError, BVHError) as e:
        raise CLIError(str(e)) from None
    people = sum(t.num_people for t in takes)
    print(f"{len(takes)} takes, {people} performers, {sum(t.num_frames for t in takes)} frames at {takes[0].fps:g} fps")

    graph = None
    singles = args.singles
    if singles in ("auto", "library"):
        from runtime.library import load_library, resolve_library
        path = resolve_library(args.library)
        if singles == "auto" and not path.exists():
            singles = "takes"
            print(f"(library {args.library!r} not built at {path}: single-character patches come from the takes)")
        else:
            try:
                graph = load_library(args.library)
            except AssetError as e:
                raise CLIError(str(e)) from None
            singles = "graph"
    try:
        with tqdm(total=len(takes), desc="episodes", unit="take", disable=quiet) as bar:
            res = build_patch_library(takes, params, graph=graph, singles=singles, progress=bar.update,
                                      log=print, seed=args.seed)
    except PatchBuildError as e:
        raise CLIError(str(e)) from None
    lib = res.library
    if not lib.patches:
        raise CLIError("no patches could be built from these takes (no episodes and no single-character material)")
    try:
        lib.save(out)
    except OSError as e:
        raise CLIError(f"{out}: cannot write ({e.strerror or e})") from None
    s = lib.summary()
    multi = [p for p in lib.patches if p.num_characters > 1]
    print(f"episodes: {s_eps(res)}; dropped {len(res.dropped)}")
    for t, i, why in res.dropped:
        print(f"  dropped {t} episode {i}: {why}")
    print(f"pose classes: {', '.join(res.classes[:12])}{' ...' if len(res.classes) > 12 else ''} "
          f"(chosen pose groups {len(res.chosen)} of the {len(res.groups)} largest)")
    print(f"wrote {out}: {s['patches']} patches ({len(multi)} multi-character, "
          f"{s['patches'] - len(multi)} single), characters per patch {s['characters_per_patch']}, "
          f"{s['constraints']} constraints, {s['seconds']} s of motion ({time.perf_counter() - t0:.1f} s)")
    print("labels: " + ", ".join(f"{k} {v}" for k, v in s["labels"].items()))
    return 0


def s_eps(res) -> str:
    from collections import Counter
    c = Counter(len(e.people) for v in res.episodes.values() for e in v)
    return f"{sum(c.values())} (" + ", ".join(f"{k} people: {n}" for k, n in sorted(c.items())) + ")"
