"""``crowdweave run SAMPLE``: a sample world in the viewer, its scenario driven online.

The runtime World plans every goal of the sample's scenario while the characters move
(staged synthesis); click a character to select it, right-click the ground to send it there.
``--headless --seconds N --screenshot out.png`` renders without a display (EGL)."""
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
    p.add_argument("--budget-ms", type=number(0, 1000, lo_open=True), default=4.0,
                   help="planning time per tick, ms (default 4; > 0, at most 1000)")


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
    if args.screenshot:
        from authoring.commands.args import check_output
        check_output(args.screenshot, (".png",), "--screenshot")
    sample = args.sample or default_sample()
    try:
        sc, graph, env, roadmap = load_sample(sample, progress=sys.stderr.isatty())
    except (ScenarioError, AssetError, ValueError, FileNotFoundError) as e:
        raise CLIError(str(e)) from None
    world = World(graph, world=env, roadmap=roadmap, seed=sc.seed, budget_ms=args.budget_ms)
    world.apply_scenario(sc)
    if sc.flocks:
        world.add_scenario_flocks(sc)
    if sc.tilings:
        world.add_scenario_tiling(sc)
    world.on("warning", lambda e: print(f"[{e.time:6.1f}s] warning {e.character}: {e.data.get('message', '')}",
                                         file=sys.stderr))
    info = run_viewer(world, headless=args.headless, seconds=args.seconds, screenshot=args.screenshot,
                      width=args.width, height=args.height)
    if args.screenshot:
        print(f"wrote {args.screenshot}")
    extra = ""
    if world.tilings:
        extra += f", {sum(len(z) for z in world.tilings)} tiled"
    if world.flocks:
        extra += f", {len(world.flock_positions()[0])} flock agents"
    print(f"{sc.name}: {len(world.names)} characters{extra}, {world.time:.1f} s simulated, "
          f"{getattr(info, 'fps', 0):.1f} fps")
    return 0
