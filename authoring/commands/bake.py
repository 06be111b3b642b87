"""``crowdweave bake SAMPLE --out out.usdc [--report report.json] [--clips-per N]``: plan a
scenario, write the baked crowd to USD (optionally as value clips, one layer per N characters),
read it back and print the independent checker's summary.

Nothing is replaced unless the run succeeds. Every input is checked before work starts (the
scenario against its schema and limits, the numbers on the command line, that ``--out`` and
``--report`` can be written). The stage is written to a temporary file beside ``--out`` and the
checker reads that file; only a stage that passes is renamed onto ``--out`` (and only then is
the report written). A stage that fails is removed, or with ``--keep-failed`` kept as
``OUT.failed.usdc`` (report ``REPORT.failed.json``) beside the good one. Temporary files and
directories are removed on every exit path (errors, Ctrl-C, SIGTERM); those of a bake killed
with ``kill -9`` carry its pid and are removed by the next bake to the same path; value-clip
workers die with the bake (:mod:`usd_io.clips`).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

from authoring.commands.args import integer, limits
from authoring.commands.bake_output import bake_feet, keep_result, print_feet
from runtime.crowd.goals import LADDER_KINDS, ladder_summary
from runtime.limits import MAX_CHARACTERS, MAX_SEED

MAX_WORKERS = 64


def configure(p):
    p.add_argument("sample", help="a sample directory (with scenario.toml, or tiling.toml for a tiling sample) or a "
                                  "scenario .toml file")
    p.add_argument("--out", required=True, help="output stage (.usdc default, .usda for text)")
    p.add_argument("--report", default=None, help="write the checker's full report as JSON")
    p.add_argument("--seed", type=integer(0, MAX_SEED), default=None,
                   help=f"override the scenario's seed ({limits(0, MAX_SEED)})")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--clips-per", type=integer(1, MAX_CHARACTERS), default=None, metavar="N",
                   help="write the animation as USD value clips, one layer per N characters, in a directory "
                        f"beside --out (for very large crowds; {limits(1, MAX_CHARACTERS)})")
    p.add_argument("--workers", type=integer(1, MAX_WORKERS), default=None, metavar="W",
                   help=f"processes writing value-clip layers (default 2; {limits(1, MAX_WORKERS)})")
    p.add_argument("--keep-failed", action="store_true",
                   help="when the checker fails, keep the new stage as OUT.failed.usdc (and the report as "
                        "REPORT.failed.json) beside the previous ones; by default a failed bake writes nothing")
    p.add_argument("--instancing", action="store_true",
                   help="share one Skeleton and body between the characters as instanceable prototypes (UsdSkel "
                        "bind-state instancing; not with --clips-per; Blender 4.2 does not skin instanced bodies)")
    p.add_argument("--look-seed", type=integer(0, MAX_SEED), default=0, metavar="S",
                   help=f"seed of the characters' looks (colours, width, props; {limits(0, MAX_SEED)}; the "
                        "viewer uses 0 too)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="write the value-clip layers on the workers of the Dask cluster at ADDRESS "
                        "(e.g. tcp://host:8786; needs --clips-per; the layers come back to this process)")


def bake_sample(sample, out, *, quiet: bool = True, **options) -> int:
    """``crowdweave bake SAMPLE --out OUT`` as a function: the same code path as the command
    (:func:`run`), so the files are the same bytes. ``options`` are the command's other options
    by their argument names (``report``, ``seed``, ``clips_per``, ``workers``, ...; the rest keep
    their defaults). Prints what the command prints; returns its exit code (0: the checker
    passed, 1: it failed); bad input raises :class:`authoring.commands.CLIError`."""
    import argparse
    parser = argparse.ArgumentParser(prog="crowdweave bake")
    configure(parser)
    args = parser.parse_args([str(sample), "--out", str(out)])
    for key, value in options.items():
        if not hasattr(args, key):
            raise TypeError(f"bake_sample: unknown option {key!r}")
        setattr(args, key, value)
    args.quiet = quiet
    return run(args)


def load_sample(sample, log=print, progress=True):
    """Scenario, library, environment and roadmap of a sample (building what is missing). The
    scenario is validated against its world before the library is built or the roadmap made."""
    from authoring.default_library import ensure_library
    from runtime.crowd.scenario import parse_scenario, read_scenario_toml, scenario_sources
    from runtime.library import load_library
    sp = Path(sample)
    toml = sp / "scenario.toml" if sp.is_dir() else sp
    base = toml.parent
    data = read_scenario_toml(toml)
    world_name, lib_name = scenario_sources(data, str(toml))
    env = world = None
    if world_name:
        from usd_io.world import read_world
        world = base / world_name
        env = read_world(world)
    parse_scenario(data, str(toml), env=env)          # everything but the library's poses, before building it
    ensure_library(lib_name, base, log=log, progress=progress)
    graph = load_library(lib_name, base)
    sc = parse_scenario(data, str(toml), env=env, node_labels=set(graph.node_labels_all()))
    roadmap = None
    if env is not None and (len(env.polygons) or len(env.circles)):
        from authoring.roadmap import load_or_build_roadmap
        from runtime.library import cache_dir
        roadmap = load_or_build_roadmap(world, cache_dir() / "roadmaps", seed=0, env=env)
    if sc.flocks:
        from authoring.flock_cache import resolve_scenario_flocks
        resolve_scenario_flocks(sc, base, log=log, progress=progress)
    return sc, graph, env, roadmap


def bake_flocks(sc, env, fps, num_frames):
    """Walk the scenario's flocks for the whole duration and check them independently
    (positions only: centroids inside the region, no step above the recording's + 10%).
    Flocks of one DDG share one FlockSystem, as in a World."""
    import numpy as np

    from runtime.flock import FlockSystem, WalkChecker
    from runtime.world.scenario import scenario_flock_starts
    dt = 1.0 / fps
    systems, regions, rows = {}, {}, []
    for spec, ddg, pos, headings, regs in scenario_flock_starts(sc, env):
        fs = systems.get(id(ddg))
        if fs is None:
            fs = systems[id(ddg)] = FlockSystem(ddg, seed=spec.seed)
            regions[id(ddg)] = []
        rows.append((spec, fs, fs.add_flocks(pos, headings, regs)))
        regions[id(ddg)] += regs
    walks = [(fs, WalkChecker(fs.ddg.max_step, fs.ddg.fps, regions[k], tolerance=0.1),
              [fs.positions().copy()], [fs.orientations().copy()]) for k, fs in systems.items()]
    for fs, chk, _, _ in walks:
        chk.update(fs.positions(), dt)
    for _ in range(num_frames - 1):
        for fs, chk, pos, ori in walks:
            fs.step(dt)
            pos.append(fs.positions().copy())
            ori.append(fs.orientations().copy())
            chk.update(fs.positions(), dt)
    recorded = {id(fs): (np.stack(pos), np.stack(ori)) for fs, _, pos, ori in walks}
    arrays = {}
    for spec, fs, r in rows:
        pos, ori = recorded[id(fs)]
        for k, f in enumerate(r):
            arrays[f"{spec.name}_{k:02d}"] = (pos[:, f], ori[:, f])
    sums = [chk.summary() for _, chk, _, _ in walks]
    outside = sum(x["frames_outside"] for x in sums)
    worst = max((x["worst_step_ratio"] for x in sums), default=0.0)
    return {"flocks": sum(fs.n_flocks for fs, _, _, _ in walks), "agents": walks[-1][0].n_agents if walks else 0,
            "frames_outside": int(outside), "worst_step_ratio": float(worst),
            "passed": bool(outside == 0 and worst <= 1.1), "_arrays": arrays}


def bake_tilings(sc, graph, env, fps, num_frames):
    """Run the scenario's tiled interaction zones for the whole bake (the same zones a World
    steps per tick) and check each independently (runtime.tiling.check). Returns
    (zones, report): each zone's ``tracks()`` index its own patch library's pose tables."""
    from runtime.world.scenario import scenario_tiling_zones
    zones = scenario_tiling_zones(sc, graph, env, 0.0)
    for f in range(1, num_frames):
        for z in zones:
            z.step(f / fps)
    report = {"zones": [], "passed": True}
    for z in zones:
        s = z.check().summary()
        ok = s["danglings"] == 0 and s["interpenetrations"] == 0 and s["frames_over_limits"] == 0 \
            and s["obstacle_hits"] == 0
        report["zones"].append({"name": z.name, "characters": len(z), "passed": ok, **s})
        report["passed"] = report["passed"] and ok
    return zones, report


def _print_summary(sc, report, tiling_report, flock_report, n, t_plan, t_write, out_note, warnings):
    if tiling_report:
        for zr in tiling_report["zones"]:
            print(f"tiling {zr['name']}: {zr['characters']} characters, {zr['patches']} patches, danglings "
                  f"{zr['danglings']}, interpenetrations {zr['interpenetrations']}, frames over deformation limits "
                  f"{zr['frames_over_limits']}, obstacle hits {zr['obstacle_hits']}")
    if flock_report:
        print(f"flocks: {flock_report['flocks']} flocks of {flock_report['agents']}, frames outside their region "
              f"{flock_report['frames_outside']}, worst step / recorded max {flock_report['worst_step_ratio']:.3f}")
    s = report["summary"]
    print(f"{sc.name}: {n} characters planned in {t_plan:.2f} s"
          + (f" ({t_plan / n * 1000:.0f} ms each)" if n else "") + f", {out_note} in {t_write:.1f} s")
    print(f"checker: position error <= {s['max_position_error_mm']:.3g} mm, heading error <= "
          f"{s['max_heading_error_deg']:.3g} deg, {s['goals_in_window']}/{s['goals']} arrivals in window, "
          f"{s['poses_ok']}/{s['goals']} poses right")
    print(f"checker: adjustment within eps for {s['characters_within_eps']}/{n} characters "
          f"(max {s['max_adjust_m_s'] * 100:.2f} cm/s, {s['max_adjust_deg_s']:.2f} deg/s, {s['max_adjust_s_s']:.4f} s/s); "
          f"{s['character_overlap_pairs']} overlapping pairs, {s['obstacle_overlap_characters']} characters in obstacles")
    print_feet(report.get("feet", {}))
    lad = report.get("ladder", {}).get("summary")
    if lad and n:
        parts = [f"{lad[k]} {k}" for k in LADDER_KINDS if lad[k]]
        if parts:
            print(f"planner: {lad['clean']}/{n} characters meet every constraint; " + ", ".join(parts)
                  + (f" (latest {lad['max_late_s']:.2f} s)" if lad["late"] else "")
                  + (f" (eps x {lad['max_eps_factor']:.2f})" if lad["relaxed"] else ""))
    print(f"checker: {'PASSED' if s['passed'] else 'FAILED'}" + (f"  ({len(warnings)} planner warnings)" if warnings else ""))


def run(args) -> int:
    from tqdm import tqdm

    from authoring.commands import CLIError
    from authoring.commands.args import check_output
    from runtime.assets import AssetError, pause_point, sweep_stale_temps, temp_path
    from runtime.crowd.checker import check_crowd
    from runtime.crowd.scenario import ScenarioError
    from runtime.crowd.scheduler import plan_scenario
    from usd_io.clips import remove_unused_clip_dirs
    from usd_io.crowd import read_tracks
    from usd_io.stage import USD_EXTENSIONS, export_layer

    quiet = args.quiet or not sys.stderr.isatty()
    out = check_output(args.out, USD_EXTENSIONS, "--out")
    report_path = check_output(args.report, None, "--report") if args.report else None
    if report_path is not None and report_path.resolve() == out.resolve():
        raise CLIError(f"--report {report_path}: the same file as --out")
    for p in (out, report_path):
        if p is not None:
            sweep_stale_temps(p)            # left by bakes that were killed
    if args.instancing and args.clips_per is not None:
        raise CLIError("--instancing and --clips-per: value clips are written without instancing")
    if args.scheduler and args.clips_per is None:
        raise CLIError("--scheduler writes value-clip layers on a Dask cluster: give --clips-per N too")
    from authoring.commands.bake_tiling import run_tiling, tiling_config_path
    tiling = tiling_config_path(args.sample)
    if tiling is not None:              # a tiling sample (tiling.toml): its characters, like a crowd
        return run_tiling(args, tiling, out, report_path)
    if args.scheduler:                  # before planning, which can take long
        from authoring.batch.cluster import ClusterError, check_scheduler
        try:
            check_scheduler(args.scheduler)
        except ClusterError as e:
            raise CLIError(str(e)) from None
    try:
        sc, graph, env, roadmap = load_sample(args.sample, progress=not quiet)
    except (ScenarioError, AssetError, ValueError, FileNotFoundError) as e:
        raise CLIError(str(e)) from None
    if args.seed is not None:
        sc.seed = args.seed
    pause_point("planning")
    t0 = time.perf_counter()
    with tqdm(total=len(sc.characters), desc="planning", unit="char", disable=quiet) as bar:
        try:
            result = plan_scenario(sc, graph, env, roadmap, progress=bar.update,
                                   log=lambda m: tqdm.write(m, file=sys.stderr))
        except ScenarioError as e:
            raise CLIError(str(e)) from None
    t_plan = time.perf_counter() - t0
    tracks = {c.name: c.track for c in result.characters}
    flock_report = bake_flocks(sc, env, result.fps, result.num_frames) if sc.flocks else None
    zones, tiling_report = bake_tilings(sc, graph, env, result.fps, result.num_frames) if sc.tilings else ([], None)
    from runtime.crowd.tracks import box_trajectories
    from usd_io.crowd import build_crowd_stage, write_props
    world_path = Path(sc.path).parent / sc.world if sc.world else None
    tmp = None
    try:
        stage = build_crowd_stage(tracks, graph, result.fps, num_frames=result.num_frames, world_path=world_path,
                                  out_path=out, clips_per=args.clips_per, workers=args.workers,
                                  scheduler=args.scheduler, instancing=args.instancing, look_seed=args.look_seed,
                                  metadata={"scenario": sc.name, "library": str(graph.path), "seed": sc.seed})
        for z in zones:   # tiled characters: SkelRoots like the crowd's, posed from the zone's patches
            build_crowd_stage(z.tracks(), z.library, result.fps, stage=stage, num_frames=result.num_frames,
                              instancing=args.instancing and args.clips_per is None, look_seed=args.look_seed)
        write_props(stage, box_trajectories(sc, result.characters, graph, env, result.num_frames))
        if flock_report:
            from usd_io.flock import write_flock_instancer
            for name, (pos, ori) in flock_report.pop("_arrays").items():
                write_flock_instancer(stage, name, pos, ori)
        pause_point("writing")
        tmp = temp_path(out, suffix=".tmp" + out.suffix)
        export_layer(stage.GetRootLayer(), str(tmp))
        t_write = time.perf_counter() - t0 - t_plan
        pause_point("checking")
        # the checker reads the baked stage back (the temporary file), not the planner's objects
        report = check_crowd(sc, read_tracks(tmp) if sc.characters else {}, graph, env, result.fps).to_dict()
        from runtime.footslide import knee_range_of
        feet = bake_feet(tmp, tracks, zones, knee_range_of(graph))
        report["feet"] = feet
        if tiling_report:
            report["tiling"] = tiling_report
            report["summary"]["passed"] = report["summary"]["passed"] and tiling_report["passed"]
        for f in feet.values():
            if f["enforced"]:
                report["summary"]["passed"] = report["summary"]["passed"] and f["within_limits"]
        if flock_report:
            report["flocks"] = flock_report
            report["summary"]["passed"] = report["summary"]["passed"] and flock_report["passed"]
        passed = report["summary"]["passed"]
        warnings = [w for c in result.characters for w in c.warnings]
        report["timing"] = {"plan_seconds": t_plan, "write_seconds": t_write,
                            "per_character": {c.name: c.seconds for c in result.characters}}
        report["warnings"] = warnings
        report["ladder"] = {"summary": ladder_summary(result.characters),
                            "characters": {c.name: [st.to_dict() for st in c.ladder]
                                           for c in result.characters if c.ladder}}
        note = keep_result(tmp, out, report_path, report, passed, args.keep_failed)
    finally:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        # a clip directory written for this bake that no kept stage refers to goes too
        remove_unused_clip_dirs(out)
    _print_summary(sc, report, tiling_report, flock_report, len(sc.characters), t_plan, t_write, note, warnings)
    return 0 if passed else 1
