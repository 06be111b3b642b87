"""Seeded random scenarios for goal-directed crowds: a world stage (``world.usda``) and a
crowd (``scenario.toml``, the schema of :mod:`runtime.crowd.scenario`) that are valid by
construction, for tests and benchmarks of the planner (Sung, Kovar and Gleicher 2005).

    from authoring.scenario_gen import generate_scenario
    gen = generate_scenario(seed=3, characters=60)           # kind="mixed"
    gen.write("out/random60")                                 # out/random60/world.usda + scenario.toml
    sc, env = gen.scenario(), gen.env                         # in memory: parsed Scenario, Environment

The world is a walled plaza cut into districts of about ``group_size`` characters, one crowd
kind each (:mod:`.layout`): crossing flows among rotated, scaled and nested obstacles, room
swaps through doors, meetings at points, sitting down on seats, carrying boxes. Starts and
goals are drawn per district (:mod:`.tasks`), then arrival windows and ``after`` constraints
(:mod:`.timing`). What breaks a rule is drawn again; a layout that cannot hold its characters
is drawn again as a whole, up to ``attempts`` times, then :class:`ScenarioGenError` says why.
Every scenario is checked against the rules before it is returned (:mod:`.validity`). The
same seed and parameters give byte-identical files.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from runtime.assets import atomic_write_bytes
from runtime.crowd.scenario import parse_scenario
from runtime.limits import MAX_CHARACTER_SECONDS, MAX_DURATION

from ..scenario_file import scenario_toml
from .freespace import FreeSpace
from .layout import build_world, plan_districts
from .params import KINDS, GenParams, ScenarioGenError
from .tasks import Crowded, draw_tasks
from .timing import assign_timing, legs
from .validity import scenario_problems

__all__ = ["generate_scenario", "GeneratedScenario", "GenParams", "ScenarioGenError", "KINDS", "scenario_problems",
           "FreeSpace"]

WORLD_FILE = "world.usda"
SCENARIO_FILE = "scenario.toml"


@dataclass
class GeneratedScenario:
    """A generated scenario: ``data`` (the scenario dict, ``scenario.toml``'s keys), ``world``
    (the :class:`usd_io.world_writer.WorldBuilder` of ``world.usda``), ``env`` (its
    :class:`~runtime.crowd.environment.Environment`), ``kinds`` (character name -> kind),
    ``free`` (the :class:`FreeSpace` the rules were checked in) and the parameters."""
    data: dict
    world: object
    env: object
    kinds: dict
    free: FreeSpace
    params: GenParams
    seed: int

    def scenario(self, path: str = "<generated scenario>", node_labels=None):
        """The parsed :class:`runtime.crowd.scenario.Scenario` (validated against ``env``)."""
        return parse_scenario(self.data, path, env=self.env, node_labels=node_labels)

    def toml(self) -> str:
        return scenario_toml(self.data)

    def write(self, out_dir) -> Path:
        """Write ``out_dir/world.usda`` and ``out_dir/scenario.toml`` (each atomically)."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        self.world.save(out / WORLD_FILE)
        atomic_write_bytes(out / SCENARIO_FILE, self.toml().encode())
        return out


def _doc(p: GenParams, seed: int) -> str:
    return (f"crowdweave generated world: seed {seed}, {p.characters} characters, kind {p.kind}, "
            f"{p.area_per_character:g} m^2 per character (metres, Y up). Written by authoring.scenario_gen.")


def _attempt(p: GenParams, seed: int, attempt: int):
    rng = np.random.default_rng([int(seed), int(attempt)])
    W, D, districts = plan_districts(p, rng)
    world = build_world(rng, (W, D), districts, _doc(p, seed))
    env = world.environment()
    fs = FreeSpace(env, (0.0, 0.0, W, D), p.walk_radius, p.grid)
    tasks = draw_tasks(p, env, fs, rng, districts, world)
    env = world.environment()              # now with the box markers
    chars = [{"name": t.name,
              "start": {"position": [round(float(t.start[0]), 3), round(float(t.start[1]), 3)],
                        "heading": t.heading, "pose": "stand"},
              "goal": [dict(g) for g in t.goals]} for t in tasks]
    data = {"name": f"random-{p.kind}-{p.characters}-s{seed}",
            "description": f"generated: seed {seed}, {p.characters} characters, kind {p.kind}, "
                           f"{len(districts)} districts ({', '.join(d.kind for d in districts)})",
            "world": WORLD_FILE, "library": p.library, "duration": 1.0, "seed": int(seed), "character": chars}
    # positions as the runtime reads them (box stand points from the markers), then timing
    # (goals are untimed here: any duration within the limits reads the same positions)
    horizon = min(MAX_DURATION, MAX_CHARACTER_SECONDS / max(1, len(chars)))
    untimed = parse_scenario({**data, "duration": horizon}, "<generated scenario>", env=env)
    data["duration"] = assign_timing(tasks, [c["goal"] for c in chars], legs(untimed, fs, p), rng, p)
    return data, world, env, fs, {t.name: t.kind for t in tasks}


def generate_scenario(seed: int = 0, characters: int = 60, kind: str = "mixed", params: GenParams | None = None,
                      **overrides) -> GeneratedScenario:
    """A random valid scenario (see the module docstring). ``params`` (or keyword overrides of
    :class:`GenParams` fields) set sizes, rules and timing; ``characters`` and ``kind`` win
    over ``params``."""
    p = replace(params or GenParams(), characters=int(characters), kind=str(kind), **overrides)
    p.validate()
    why = None
    for attempt in range(p.attempts):
        try:
            data, world, env, fs, kinds = _attempt(p, seed, attempt)
        except Crowded as e:
            why = str(e)
            continue
        sc = parse_scenario(data, "<generated scenario>", env=env)
        problems = scenario_problems(sc, env, fs, p)
        if problems:        # the construction keeps every rule: this is a bug, not bad luck
            raise AssertionError(f"generated scenario (seed {seed}) breaks its rules: " + "; ".join(problems[:5]))
        return GeneratedScenario(data, world, env, kinds, fs, p, int(seed))
    raise ScenarioGenError(
        f"cannot place {p.characters} characters of kind {p.kind!r} at {p.area_per_character:g} m^2 each (more for "
        f"seats and boxes) keeping {p.clearance} m from obstacles and {p.spacing} m between endpoints, in "
        f"{p.attempts} layouts (last: {why}); give more area per character or fewer characters")
