"""``crowdweave bake SAMPLE --out out.usdc [--report report.json]``: plan a scenario, write
the baked crowd to USD, read it back and print the independent checker's summary."""
from __future__ import annotations

import json
import sys
import time
from pathlib import Path


def configure(p):
    p.add_argument("sample", help="a sample directory (with scenario.toml) or a scenario .toml file")
    p.add_argument("--out", required=True, help="output stage (.usdc default, .usda for text)")
    p.add_argument("--report", default=None, help="write the checker's full report as JSON")
    p.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def load_sample(sample, log=print, progress=True):
    """Scenario, library, environment and roadmap of a sample (building what is missing)."""
    from authoring.default_library import ensure_library
    from runtime.crowd.scenario import load_scenario
    from runtime.library import load_library
    sp = Path(sample)
    toml = sp / "scenario.toml" if sp.is_dir() else sp
    base = toml.parent
    import tomllib
    try:
        head = tomllib.loads(toml.read_text())
    except FileNotFoundError:
        from runtime.crowd.scenario import ScenarioError
        raise ScenarioError(f"{toml}: scenario file not found") from None
    env = roadmap = None
    if head.get("world"):
        from authoring.roadmap import load_or_build_roadmap
        from runtime.library import cache_dir
        from usd_io.world import read_world
        world = base / head["world"]
        env = read_world(world)
        if len(env.polygons) or len(env.circles):
            roadmap = load_or_build_roadmap(world, cache_dir() / "roadmaps", radius=0.35, seed=0, env=env)
    lib_name = head.get("library", "default")
    ensure_library(lib_name, base, log=log, progress=progress)
    graph = load_library(lib_name, base)
    sc = load_scenario(toml, env=env, node_labels=set(graph.node_labels_all()))
    return sc, graph, env, roadmap


def run(args) -> int:
    from tqdm import tqdm

    from authoring.cli import CLIError
    from runtime.assets import AssetError
    from runtime.crowd.checker import check_crowd
    from runtime.crowd.scenario import ScenarioError
    from runtime.crowd.scheduler import plan_scenario
    from usd_io.crowd import read_tracks, write_crowd_stage

    quiet = args.quiet or not sys.stderr.isatty()
    out = Path(args.out)
    if out.suffix not in (".usda", ".usdc", ".usd"):
        raise CLIError(f"{out}: output must end in .usdc, .usda or .usd")
    try:
        sc, graph, env, roadmap = load_sample(args.sample, progress=not quiet)
    except (ScenarioError, AssetError, ValueError, FileNotFoundError) as e:
        raise CLIError(str(e)) from None
    if args.seed is not None:
        sc.seed = args.seed
    t0 = time.perf_counter()
    with tqdm(total=len(sc.characters), desc="planning", unit="char", disable=quiet) as bar:
        try:
            result = plan_scenario(sc, graph, env, roadmap, progress=bar.update,
                                   log=lambda m: tqdm.write(m, file=sys.stderr))
        except ScenarioError as e:
            raise CLIError(str(e)) from None
    t_plan = time.perf_counter() - t0
    tracks = {c.name: c.track for c in result.characters}
    write_crowd_stage(out, tracks, graph, result.fps,
                      metadata={"scenario": sc.name, "library": str(graph.path), "seed": sc.seed})
    t_write = time.perf_counter() - t0 - t_plan
    # the checker reads the baked stage back, not the planner's objects
    report = check_crowd(sc, read_tracks(out), graph, env, result.fps)
    s = report["summary"]
    n = len(sc.characters)
    print(f"{sc.name}: {n} characters planned in {t_plan:.2f} s ({t_plan / max(n, 1) * 1000:.0f} ms each), "
          f"wrote {out} in {t_write:.1f} s")
    print(f"checker: position error <= {s['max_position_error_mm']:.3g} mm, heading error <= "
          f"{s['max_heading_error_deg']:.3g} deg, {s['goals_in_window']}/{s['goals']} arrivals in window, "
          f"{s['poses_ok']}/{s['goals']} poses right")
    print(f"checker: adjustment within eps for {s['characters_within_eps']}/{n} characters "
          f"(max {s['max_adjust_m_s'] * 100:.2f} cm/s, {s['max_adjust_deg_s']:.2f} deg/s, {s['max_adjust_s_s']:.4f} s/s); "
          f"{s['character_overlap_pairs']} overlapping pairs, {s['obstacle_overlap_characters']} characters in obstacles")
    warnings = [w for c in result.characters for w in c.warnings]
    print(f"checker: {'PASSED' if s['passed'] else 'FAILED'}" + (f"  ({len(warnings)} planner warnings)" if warnings else ""))
    if args.report:
        report["timing"] = {"plan_seconds": t_plan, "write_seconds": t_write,
                            "per_character": {c.name: c.seconds for c in result.characters}}
        report["warnings"] = warnings
        from runtime.assets import atomic_write_bytes
        atomic_write_bytes(args.report, json.dumps(report, indent=1, default=float).encode())
    return 0 if s["passed"] else 1
