"""``crowdweave run SAMPLE``: a sample world in the viewer, its scenario driven online.

The runtime World plans every goal of the sample's scenario while the characters move
(staged synthesis); a scenario's ``[ambient]`` people are kept busy by
:class:`runtime.world.ambient.AmbientLife`. Click a character to select it, right-click the
ground to send it there. ``--headless --seconds N --screenshot out.png`` renders without a
display (EGL); ``--record clip.gif`` keeps an animated GIF of the window. At the end it prints
what ran: characters (crowd, ambient, tiled, flock agents), the ambient goals met on time and
the tick times (p50 / p99)."""
from __future__ import annotations

import sys

from authoring.commands.args import integer, number


def configure(p):
    p.add_argument("sample", nargs="?", default=None,
                   help="a sample directory or scenario .toml (default: the plaza sample)")
    p.add_argument("--headless", action="store_true", help="render off-screen (no display needed)")
    p.add_argument("--seconds", type=number(0, 1e6, lo_open=True), default=None,
                   help="stop after this many seconds (> 0, at most 1e6)")
    p.add_argument("--screenshot", default=None, help="save the last frame as PNG")
    p.add_argument("--width", type=integer(16, 16384), default=1280, help="window width (default 1280; 16-16384)")
    p.add_argument("--height", type=integer(16, 16384), default=720, help="window height (default 720; 16-16384)")
    p.add_argument("--record", default=None, help="save an animated GIF of the window (10 frames a second of "
                                                  "the run, 640 px wide, the first 15 s)")
    p.add_argument("--budget-ms", type=number(0, 1000, lo_open=True), default=None,
                   help="planning time per tick, ms (default 4, or 12 for a scenario with [ambient] people; "
                        "> 0, at most 1000)")


def default_sample():
    from pathlib import Path
    return Path(__file__).resolve().parents[2] / "samples" / "plaza"


def run(args) -> int:
    from authoring.commands import CLIError
    from authoring.commands.bake import load_sample
    from runtime.assets import AssetError
    from runtime.crowd.scenario import ScenarioError
    from runtime.viewer import run_viewer
    from runtime.world import World
    from authoring.commands.args import check_output
    if args.screenshot:
        check_output(args.screenshot, (".png",), "--screenshot")
    record = None
    if getattr(args, "record", None):
        from runtime.viewer.record import GifRecorder
        record = GifRecorder(check_output(args.record, (".gif",), "--record"))
    sample = args.sample or default_sample()
    try:
        sc, graph, env, roadmap = load_sample(sample, progress=sys.stderr.isatty())
    except (ScenarioError, AssetError, ValueError, FileNotFoundError) as e:
        raise CLIError(str(e)) from None
    from runtime.world.ambient import AMBIENT_BUDGET_MS, AMBIENT_JOB_SLICE
    budget = args.budget_ms if args.budget_ms is not None else (AMBIENT_BUDGET_MS if sc.ambient else 4.0)
    world = World(graph, world=env, roadmap=roadmap, seed=sc.seed, budget_ms=budget,
                  job_slice=AMBIENT_JOB_SLICE if sc.ambient else None)
    world.apply_scenario(sc)
    if sc.flocks:
        world.add_scenario_flocks(sc)
    if sc.tilings:
        world.add_scenario_tiling(sc)
    life = world.add_scenario_ambient(sc)
    ambient = set(life.names) if life is not None else set()
    world.on("warning", lambda e: e.character in ambient or print(
        f"[{e.time:6.1f}s] warning {e.character}: {e.data.get('message', '')}", file=sys.stderr))
    info = run_viewer(world, headless=args.headless, seconds=args.seconds, screenshot=args.screenshot,
                      width=args.width, height=args.height, record=record)
    if args.screenshot:
        print(f"wrote {args.screenshot}")
    if record is not None:
        print(f"wrote {args.record} ({len(record.frames)} frames)")
    print(summary(sc, world, life, info))
    return 0


def summary(sc, world, life, info) -> str:
    """What ran: characters, goals met on time, tick times (the lines ``crowdweave run`` prints)."""
    extra = ""
    if life is not None:
        extra += f" ({len(life.names)} ambient)"
    if world.tilings:
        extra += f", {sum(len(z) for z in world.tilings)} tiled"
    if world.flocks:
        extra += f", {len(world.flock_positions()[0])} flock agents"
    lines = [f"{sc.name}: {len(world.names)} characters{extra}, {world.time:.1f} s simulated, "
             f"{getattr(info, 'fps', 0):.1f} fps"]
    if life is not None:
        s = life.stats
        done = s["met"] + s["late"] + s["failed"]
        moved = int((life.goals_had > 0).sum())
        lines.append(f"ambient: {moved}/{len(life.names)} people have had goals; {s['arrived']} arrivals "
                     f"({s['strolls']} strolls, {s['walks']} timed walks, {s['sits']} sits, {s['carries']} carries, "
                     f"{s['meetings']} meetings given)")
        if done:
            lines.append(f"goals met on time: {s['met']}/{done} ({100 * life.on_time:.0f}%) of the timed goals "
                         f"finished ({s['late']} late, {s['failed']} not planned; {s['goals']} given)")
        else:
            lines.append(f"goals met on time: none of the {s['goals']} timed goals given has finished yet")
    lines.append(f"tick: p50 {world.tick_percentile(50):.1f} ms, p99 {world.tick_percentile(99):.1f} ms, "
                 f"planning budget {world.budget * 1000:g} ms; plans used {world.stats['plans_done']}, "
                 f"not used {world.stats['plans_failed']}")
    return "\n".join(lines)
