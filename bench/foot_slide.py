"""Benchmark: planted-foot slide of baked stages, with and without the foot lock, and of the raw capture.

For each crowd sample (planned once) and each tiling sample, the characters are written to USD
twice in the same run -- the library's poses as they are, and with planted feet locked
(runtime/motion/footlock.py, what ``crowdweave bake`` writes) -- and both stages are measured
from the file through UsdSkel by runtime/footslide.py (a foot is planted when its toe joint is
within 5 cm of that foot's lowest point and its vertical speed is under 15 cm/s; figures are the
horizontal speeds of planted feet). The raw procedural capture (a take converted from its BVH, as
``crowdweave convert`` does) is measured the same way for comparison. Crowd characters and tiled
characters of a sample are reported apart and together; the table also gives the lowest foot
point and the signed knee flexion range; "within" holds them to runtime.footslide's limits (and
the capture's knee range, kept in the library, when it has one). No asserts.

    CROWDWEAVE_CACHE=... python bench/foot_slide.py [--samples meet20 plaza tiling_static_30] [--take 0]
        [--keep DIR]   (keep the stages written)
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
DEFAULT = ("meet20", "fetch_boxes20", "rooms_box", "theater40", "spell70", "grid300", "grid500", "plaza",
           "tiling_static_30")


def _bake(groups, fps, num_frames, path, lock):
    """Write ``groups`` [(label, tracks, library)] into one stage; returns {label: SkelRoot paths}."""
    from usd_io.crowd import build_crowd_stage, character_path
    from usd_io.stage import export_layer
    stage = None
    roots = {}
    for label, tracks, lib in groups:
        if not tracks:
            continue
        stage = build_crowd_stage(tracks, lib, fps, stage=stage, num_frames=num_frames, foot_lock=lock)
        roots[label] = [character_path(n) for n in tracks]
    export_layer(stage.GetRootLayer(), str(path))
    return roots


def sample_groups(name):
    """(groups, fps, frames) of a sample: crowd characters planned by the scheduler and the
    tiled characters of its zones, or the characters of a tiling sample."""
    from authoring.commands.bake import bake_tilings, load_sample
    from authoring.commands.bake_tiling import load_tiling, tiling_config_path
    toml = tiling_config_path(SAMPLES / name)
    if toml is not None:
        cfg, res, lib = load_tiling(toml)
        tracks = {f"{name}_{k:03d}": tr.to_track() for k, tr in enumerate(res.tracks())}
        return [("tiled", tracks, lib)], res.fps, max(t.start_frame + len(t) for t in tracks.values())
    from runtime.crowd.scheduler import plan_scenario
    sc, graph, env, roadmap = load_sample(SAMPLES / name, log=lambda *a: None, progress=False)
    result = plan_scenario(sc, graph, env, roadmap, log=lambda *a: None)
    groups = [("crowd", {c.name: c.track for c in result.characters}, graph)]
    if sc.tilings:
        zones, _ = bake_tilings(sc, graph, env, result.fps, result.num_frames)
        tiled = {}
        for z in zones:
            tiled.update(z.tracks())
        groups.append(("tiled", tiled, zones[0].library if zones else graph))
    return groups, result.fps, result.num_frames


def raw_capture(take: int, out: Path):
    from authoring.bvh import read_bvh
    from authoring.default_library import default_capture_dir
    from usd_io.skel import write_clip_stage
    bvh = default_capture_dir() / f"take_{take:03d}.bvh"      # built with the default library
    write_clip_stage(out, read_bvh(bvh).clip, name=bvh.stem)
    return bvh


def row(label, f):
    return (f"{label:<34} {f['characters']:>5} {f['planted_frames']:>8} {f['mean_cm_s']:>7.1f} {f['p95_cm_s']:>7.1f} "
            f"{f['sliding_share'] * 100:>8.1f}% {f['lowest_foot_m'] * 100:>8.1f} "
            f"{f['knee_flexion_deg'][0]:>6.1f}-{f['knee_flexion_deg'][1]:<6.1f} {'yes' if f['within'] else 'no':>6}")


def main(argv=None):
    from runtime.footslide import LIMITS, knee_range_of, measure_stage, slide_passed
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", nargs="*", default=list(DEFAULT))
    ap.add_argument("--take", type=int, default=0, help="the capture take measured for comparison")
    ap.add_argument("--keep", default=None, help="a directory to keep the stages in")
    args = ap.parse_args(argv)
    out = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="foot-slide-"))
    out.mkdir(parents=True, exist_ok=True)
    print(f"planted-foot slide (limits: mean <= {LIMITS['mean_cm_s']} cm/s, p95 <= {LIMITS['p95_cm_s']} cm/s, "
          f"sliding share <= {LIMITS['sliding_share'] * 100:.0f}%); stages in {out}")
    head = (f"{'stage':<34} {'chars':>5} {'planted':>8} {'mean':>7} {'p95':>7} {'sliding':>9} {'lowest':>8} "
            f"{'knee deg':>13} {'within':>6}")
    print(head)
    print("-" * len(head))
    try:
        bvh = raw_capture(args.take, out / "capture.usdc")
        f = measure_stage(out / "capture.usdc")
        f["within"] = slide_passed(f)
        print(row(f"raw capture ({bvh.name})", f), flush=True)
    except Exception as e:      # the capture is optional for the table
        print(f"raw capture: not measured ({type(e).__name__}: {e})")
    for name in args.samples:
        t0 = time.perf_counter()
        try:
            groups, fps, frames = sample_groups(name)
        except Exception as e:
            print(f"{name}: not measured ({type(e).__name__}: {e})", flush=True)
            continue
        if not any(tracks for _, tracks, _ in groups):
            print(f"{name}: no characters to measure", flush=True)
            continue
        for lock in (False, True):
            path = out / f"{name}{'_locked' if lock else '_raw'}.usdc"
            roots = _bake(groups, fps, frames, path, lock)
            parts = list(roots.items()) + ([("all", sum(roots.values(), []))] if len(roots) > 1 else [])
            knees = {label: knee_range_of(lib) for label, _, lib in groups}
            for label, r in parts:
                f = measure_stage(path, r)
                kr = [k for k in (knees.get(label) if label != "all" else None, *knees.values()) if k is not None]
                f["within"] = slide_passed(f, kr[0] if kr else None)
                print(row(f"{name} {label} {'locked' if lock else 'unlocked'}", f), flush=True)
        print(f"  ({name}: {time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
