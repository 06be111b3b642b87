"""``crowdweave bake samples/tiling_NAME --out out.usdc``: a tiling sample (``tiling.toml``) written
to USD like a crowd, so tiled motion opens in a DCC tool and is checked the same way.

The tiling is the sample's own (``tiling.cwpack`` beside ``tiling.toml``, as
``samples/make_tiling_samples.py`` wrote it) or, without one, computed from the config (static:
Algorithms 1 and 2; interactive: the teams stepped on the clock). Every character (its identity
continuous across stitched patches) becomes a SkelRoot posed from the patch library, planted feet
locked as in a crowd bake. The tiling checker (:func:`runtime.tiling.check.check_tiling`) checks
the tiling independently and measures planted-foot slide on the written stage; as in a crowd
bake only a stage that passes replaces ``--out``.
"""
from __future__ import annotations

import time
from pathlib import Path

__all__ = ["tiling_config_path", "run_tiling"]


def tiling_config_path(sample) -> Path | None:
    """The ``tiling.toml`` of a sample directory without a ``scenario.toml`` (or a path to one)."""
    p = Path(sample)
    if p.is_dir() and not (p / "scenario.toml").exists() and (p / "tiling.toml").exists():
        return p / "tiling.toml"
    if p.is_file() and p.name == "tiling.toml":
        return p
    return None


def load_tiling(toml: Path, quiet: bool = True):
    """(config, TilingResult, patch library) of a tiling sample."""
    from authoring.default_library import ensure_library
    from runtime.library import load_library
    from runtime.tiling.result import TilingResult
    from runtime.tiling.scenario import build_library, load_config, run_config
    cfg = load_config(toml)
    name = cfg.get("library", {}).get("graph", "default")
    ensure_library(name, toml.parent, log=(lambda *a: None) if quiet else print, progress=not quiet)
    graph = load_library(name, toml.parent)
    lib = build_library(cfg, graph)
    pack = toml.parent / "tiling.cwpack"
    res = TilingResult.load(pack, lib) if pack.exists() else run_config(cfg, graph, lib)
    return cfg, res, lib


def run_tiling(args, toml: Path, out: Path, report_path: Path | None) -> int:
    """The bake of a tiling sample; ``out`` and ``report_path`` already checked by the command."""
    from authoring.commands import CLIError
    from authoring.commands.bake_output import keep_result, print_feet
    from runtime.assets import AssetError, pause_point, temp_path
    from runtime.footslide import knee_range_of
    from runtime.tiling.check import check_tiling, check_tiling_feet
    from runtime.tiling.scenario import TilingConfigError
    from usd_io.clips import remove_unused_clip_dirs
    from usd_io.crowd import build_crowd_stage, character_path
    from usd_io.stage import export_layer

    if args.seed is not None:
        raise CLIError(f"--seed: {toml} is a tiling; its seed is the config's (change `seed` there)")
    t0 = time.perf_counter()
    try:
        cfg, res, lib = load_tiling(toml, quiet=args.quiet)
    except (TilingConfigError, AssetError, ValueError, FileNotFoundError) as e:
        raise CLIError(str(e)) from None
    t_tile = time.perf_counter() - t0
    name = cfg.get("name") or toml.parent.name
    tracks = {f"{name}_{k:03d}": tr.to_track() for k, tr in enumerate(res.tracks())}
    num_frames = max([tr.start_frame + len(tr) for tr in tracks.values()] + [1])
    tmp = None
    try:
        stage = build_crowd_stage(tracks, lib, res.fps, num_frames=num_frames, out_path=out, clips_per=args.clips_per,
                                  workers=args.workers, scheduler=args.scheduler, instancing=args.instancing,
                                  look_seed=args.look_seed, metadata={"tiling": name, "config": str(toml)})
        pause_point("writing")
        tmp = temp_path(out, suffix=".tmp" + out.suffix)
        export_layer(stage.GetRootLayer(), str(tmp))
        t_write = time.perf_counter() - t0 - t_tile
        pause_point("checking")
        rep = check_tiling(res)
        feet = check_tiling_feet(tmp, [character_path(n) for n in tracks], knee_range_of(lib)) if tracks else None
        passed = rep.passed and (feet is None or not feet["enforced"] or feet["within_limits"])
        report = {"kind": "tiling", "name": name, "summary": {**rep.summary(), "passed": bool(passed)},
                  "feet": {"tiled": feet} if feet else {}, "timing": {"tiling_seconds": t_tile, "write_seconds": t_write}}
        note = keep_result(tmp, out, report_path, report, passed, args.keep_failed)
    finally:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        remove_unused_clip_dirs(out)
    print(f"{name}: {len(tracks)} tiled characters, {num_frames} frames ({'loaded' if (toml.parent / 'tiling.cwpack').exists() else 'tiled'} "
          f"in {t_tile:.1f} s), {note} in {t_write:.1f} s")
    print(rep)
    print_feet(report["feet"])
    print(f"checker: {'PASSED' if passed else 'FAILED'}")
    return 0 if passed else 1
