"""``crowdweave capture``: generate procedural motion-capture takes (BVH + label sidecars).

Writes ``OUT/take_000.bvh``, ``take_000.labels.json``, ... and ``OUT/session.json`` (see
:mod:`authoring.procedural.session`), then prints a short summary and the quality figures
of :func:`authoring.capture_quality.take_quality`.

With ``--takes``: two- and three-person takes on a shared clock (:mod:`authoring.takes`,
:mod:`authoring.procedural.interactions`), one directory per take; ``--duet A.bvh B.bvh``
imports a recorded two-person take (the CMU salsa duet).
"""
from __future__ import annotations

import sys
import time

from authoring.commands.args import check_output_dir, integer, limits, number
from runtime.limits import MAX_CAPTURE_MINUTES, MAX_REPEAT, MAX_SEED, MAX_TAKE_MINUTES


def configure(parser):
    parser.add_argument("--minutes", type=number(0, MAX_CAPTURE_MINUTES, lo_open=True), default=3.0,
                        help=f"total minutes of motion (default 3; {limits(0, MAX_CAPTURE_MINUTES, lo_open=True)})")
    parser.add_argument("--seed", type=integer(0, MAX_SEED), default=0,
                        help=f"random seed (default 0; {limits(0, MAX_SEED)})")
    parser.add_argument("--out", required=True,
                        help="output directory (an earlier capture there is replaced: its takes are removed)")
    parser.add_argument("--fps", type=number(0, 1000, lo_open=True), default=30.0,
                        help=f"frame rate (default 30; {limits(0, 1000, lo_open=True)})")
    parser.add_argument("--take-minutes", type=number(0, MAX_TAKE_MINUTES, lo_open=True), default=2.0,
                        help=f"length of one take in minutes (default 2; {limits(0, MAX_TAKE_MINUTES, lo_open=True)})")
    parser.add_argument("--no-check", action="store_true", help="skip the quality check at the end")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    g = parser.add_argument_group("multi-character takes (Kim, Hwang, Hyun and Lee 2012)")
    g.add_argument("--takes", action="store_true",
                   help="write two- and three-person takes on a shared clock (OUT/<kind>_NNN/ with one BVH "
                        "per performer + take.json) instead of single-performer takes")
    g.add_argument("--kinds", default=None,
                   help="comma-separated scene kinds for --takes (default: all; see authoring.procedural.interactions)")
    g.add_argument("--repeat", type=integer(1, MAX_REPEAT), default=1,
                   help=f"takes per kind for --takes (default 1; {limits(1, MAX_REPEAT)})")
    g.add_argument("--duet", nargs=2, metavar=("A.bvh", "B.bvh"), default=None,
                   help="also import two BVH files recorded on one clock (e.g. the CMU salsa duet "
                        "60_10 + 61_10) as the two-person take OUT/duet/")


def run(args) -> int:
    from authoring.commands import CLIError

    if getattr(args, "takes", False) or getattr(args, "duet", None):
        return _run_takes(args)

    from tqdm import tqdm

    from authoring.procedural import write_session

    out = check_output_dir(args.out)
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


def _earlier_take_dirs(out) -> set:
    """Take directories an earlier ``--takes`` capture wrote into ``out`` (its takes.json lists
    them); the new capture removes those it does not write again."""
    import json
    try:
        m = json.loads((out / "takes.json").read_text(encoding="utf-8"))
        names = {r["name"] for r in m.get("takes", []) if isinstance(r, dict) and isinstance(r.get("name"), str)}
    except (OSError, ValueError, AttributeError, KeyError):
        return set()
    return {n for n in names if "/" not in n and n not in (".", "..") and (out / n / "take.json").is_file()}


def _run_takes(args) -> int:
    """``--takes`` / ``--duet``: multi-character takes (authoring.takes)."""
    from tqdm import tqdm

    from authoring.bvh import BVHError
    from authoring.commands import CLIError
    from authoring.procedural.interactions import SCENES
    from authoring.takes import DEFAULT_KINDS, TakeError, import_cmu_duet, write_takes

    kinds = DEFAULT_KINDS if args.kinds is None else tuple(k.strip() for k in args.kinds.split(",") if k.strip())
    bad = [k for k in kinds if k not in SCENES]
    if bad:
        raise CLIError(f"unknown take kind(s) {', '.join(bad)}; known: {', '.join(SCENES)}")
    out = check_output_dir(args.out)
    t0 = time.perf_counter()
    rows = []
    if args.takes:
        n = len(kinds) * args.repeat
        earlier = _earlier_take_dirs(out)
        with tqdm(total=n, unit="take", desc="takes", disable=args.quiet or not sys.stderr.isatty()) as bar:
            try:
                manifest = write_takes(out, args.seed, kinds, args.repeat, args.fps, progress=bar.update)
            except OSError as e:
                raise CLIError(f"{out}: cannot write ({e.strerror or e})") from None
        rows = manifest["takes"]
        import shutil
        for name in sorted(earlier - {r["name"] for r in rows}):     # takes of an earlier capture here
            shutil.rmtree(out / name, ignore_errors=True)
    if args.duet:
        try:
            tk = import_cmu_duet(args.duet[0], args.duet[1], fps=args.fps, name="duet")
        except (BVHError, TakeError) as e:
            raise CLIError(str(e)) from None
        except OSError as e:
            raise CLIError(f"{e.filename}: cannot read ({e.strerror})") from None
        tk.save(out / "duet")
        rows.append({"name": "duet", "kind": "duet", "people": tk.people, "frames": tk.num_frames,
                     "seconds": round(tk.num_frames / args.fps, 4), "events": []})
    elapsed = time.perf_counter() - t0
    frames = sum(r["frames"] for r in rows)
    print(f"wrote {len(rows)} takes to {out}: {frames} frames ({frames / args.fps:.1f} s per performer) at "
          f"{args.fps:g} fps, seed {args.seed}, in {elapsed:.1f} s")
    if not args.no_check:
        from authoring.capture_quality import take_quality

        print("  take                       people  seconds  foot sliding in contact mean / p95 (cm/s)  events")
    for r in rows:
        ev = ", ".join(f"{e['label']}{tuple(e['people'])}@{e['start']}-{e['end']}" for e in r["events"]) or "-"
        q = ""
        if not args.no_check:
            s = take_quality(out / r["name"])["summary"]
            q = f"{100 * s['foot_contact_mean_speed_m_s']:6.2f} / {100 * s['foot_contact_p95_speed_m_s']:6.2f}"
            if s["hyperextended_frames"]:
                q += f" ({s['hyperextended_frames']} hyperextended knee frames)"
        print(f"  {r['name']:26s} {len(r['people']):6d}  {r['seconds']:7.1f}  {q:42s}  {ev}")
    return 0
