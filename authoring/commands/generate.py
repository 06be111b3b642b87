"""``crowdweave generate scenario --seed S --characters N [--kind K] --out DIR``: a random but
valid world stage and crowd scenario (``DIR/world.usda`` + ``DIR/scenario.toml``) for testing
and benchmarking the planner (see :mod:`authoring.scenario_gen`). Same seed and options, same
bytes."""
from __future__ import annotations

from authoring.scenario_gen.params import KINDS, GenParams

_DEFAULTS = GenParams()


def configure_scenario(p):
    """The options of ``generate scenario`` (also used by ``samples/make_random_scenario.py``)."""
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--characters", type=int, default=_DEFAULTS.characters,
                   help=f"number of characters (default {_DEFAULTS.characters})")
    p.add_argument("--kind", default="mixed", choices=("mixed",) + KINDS,
                   help="crowd task: crossing flows, room swaps through doors, meetings at points, sitting down, "
                        "carrying boxes; mixed (default) draws one per district of characters")
    p.add_argument("--area-per-character", type=float, default=_DEFAULTS.area_per_character, metavar="M2",
                   help=f"ground per character, m^2, obstacles included (default {_DEFAULTS.area_per_character:g}; "
                        "seats and boxes districts get 1.25x and 1.6x)")
    p.add_argument("--group-size", type=int, default=_DEFAULTS.group_size, metavar="N",
                   help=f"characters per district (default {_DEFAULTS.group_size})")
    p.add_argument("--out", required=True, help="output directory (world.usda and scenario.toml are written there)")


def configure(p):
    sub = p.add_subparsers(dest="what", metavar="WHAT", required=True)
    s = sub.add_parser("scenario", help="a random valid world and crowd scenario",
                       description="a random valid world (world.usda) and crowd scenario (scenario.toml)")
    configure_scenario(s)


def run_scenario(args) -> int:
    from authoring.commands import CLIError
    from authoring.scenario_gen import ScenarioGenError, generate_scenario
    try:
        gen = generate_scenario(seed=args.seed, characters=args.characters, kind=args.kind,
                                area_per_character=args.area_per_character, group_size=args.group_size)
    except ScenarioGenError as e:
        raise CLIError(str(e)) from None
    out = gen.write(args.out)
    kinds = {}
    for k in gen.kinds.values():
        kinds[k] = kinds.get(k, 0) + 1
    x0, z0, x1, z1 = gen.env.bounds()
    sc = gen.scenario()
    timed = sum(1 for c in sc.characters for g in c.goals if g.time is not None)
    after = sum(1 for c in sc.characters for g in c.goals if g.after is not None)
    goals = sum(len(c.goals) for c in sc.characters)
    print(f"wrote {out / 'world.usda'} and {out / 'scenario.toml'}")
    print(f"{sc.name}: {len(sc.characters)} characters (" + ", ".join(f"{n} {k}" for k, n in kinds.items()) +
          f"), {goals} goals ({timed} with a window, {after} after another character), {sc.duration:g} s")
    print(f"world: {x1 - x0:.1f} x {z1 - z0:.1f} m, {gen.env.num_obstacles} obstacle footprints, "
          f"{len(gen.env.markers_with_role('seat'))} seats, {len(gen.env.markers_with_role('box'))} boxes")
    return 0


def run(args) -> int:
    return run_scenario(args)
