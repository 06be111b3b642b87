"""Scenarios: ``samples/<name>/scenario.toml`` .

```toml
name = "meet20"
world = "world.usda"        # optional: open ground
library = "default"         # or a path to a motion-graph pack
duration = 20.0             # seconds to bake
seed = 0
[synthesis]                 # optional, paper defaults
epsilon = [0.02, 2.0, 0.0667]
passes = 4                  # planning passes: later ones repair the characters left without a clean plan
start_still = false         # true: "stand" starts on a still node first, false: on a walking hub first;
                            # unset: still first for characters whose first window leaves time to wait
approach_point = 0.0        # m: way points to a seat pass this far in front of it first (0: off)
[[character]]
name = "c01"
start = { position = [0.0, 0.0], heading = 0.0, pose = "stand" }   # or seat = "/World/Seats/s01"
  [[character.goal]]        # in order; every key optional except a position, a seat or a box
  position = [4.0, 2.0]
  heading = 90.0            # degrees about +Y, 0 = facing +Z
  pose = "sit"              # a node label of the library
  time = [8.0, 9.0]         # absolute arrival window, seconds (equal ends allowed)
  seat = "/World/Seats/s01" # sets position, heading and pose "sit" from the marker
  box = "/World/Boxes/b01"  # stands in front of the box facing it, pose "carry" (picks it up)
  after = { character = "c02", goal = 0, within = [0.0, 1.0] }  # relative timing
[ambient]                   # optional: people going about their day (runtime.world.ambient)
count = 300
seed = 0
region = "/World/Regions/ambient"   # a region marker: where they walk (default: the world's bounds)
linger = [10.0, 40.0]       # seconds at a spot, on a bench, in a conversation
```

Validation happens before any planning and raises :class:`ScenarioError` with one line naming
the file, the table (the character and goal, the flock, the tiling zone and team) and the key:
unknown keys in any table (``[synthesis]`` too), values of the wrong type, numbers that are not
finite or out of range (degrees, seconds, seeds 0 .. 2^63-1), inputs over the limits of
:mod:`runtime.limits` (duration, characters x duration, flock recordings), two names that
become the same USD prim name (:func:`prim_name`), a dependency cycle, a goal inside an
obstacle, a pose the library lacks, a window too short for any motion, unknown markers.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..limits import (MAX_CHARACTER_SECONDS, MAX_CHARACTERS, MAX_DURATION, MAX_FLOCK_AGENT_SECONDS, MAX_FLOCK_AGENTS,
                      MAX_FLOCK_SECONDS, MAX_FLOCKS, MAX_GOALS, MAX_SEED, MAX_TEAM, MAX_TOML_BYTES)
from .schema import Table, read_toml, show

__all__ = ["ScenarioError", "Scenario", "CharacterSpec", "GoalSpec", "FlockSpec", "AmbientSpec", "load_scenario", "parse_scenario",
           "read_scenario_toml", "scenario_sources", "planning_order", "prim_name", "BOX_REACH"]

# Distance from a box marker to the root of a character standing at it, facing it (m).
START_CLEARANCE = 0.3    # m from obstacles a start position needs (the default library's standing
                         # idle cylinder is 0.27 m; seat starts, being markers, are exempt)
BOX_REACH = 0.45
# Fastest the default library moves (m/s); used to reject windows too short for any motion.
MAX_SPEED = 2.0


class ScenarioError(ValueError):
    """A scenario that cannot be planned; names the file, character and goal."""


@dataclass
class GoalSpec:
    position: np.ndarray
    heading: float | None = None        # radians
    pose: str | None = None
    time: tuple | None = None           # absolute (t_a, t_b)
    after: dict | None = None           # {"character": str, "goal": int, "within": (a, b)}
    marker: str | None = None           # seat/box prim path, if the goal came from one
    kind: str = "position"              # "position" | "seat" | "box"


@dataclass
class CharacterSpec:
    name: str
    position: np.ndarray
    heading: float
    pose: str
    goals: list[GoalSpec] = field(default_factory=list)
    start_marker: str | None = None


@dataclass
class FlockSpec:
    """``[[flock]]``: ``count`` flocks walking one flock motion graph (Lai, Chenney and Fan 2005).

    ``ddg`` is a pack path (relative to the scenario) or a recording recipe
    ``{dim, agents, seconds, seed}`` that the authoring tools record and build once (cached);
    ``region`` a ``crowdweave:role = "region"`` prim whose outline the flocks' centroids never
    leave (with ``altitude = [y0, y1]`` for 3D flocks: a box); ``positions`` optional centroid
    starts (default: spread over the region)."""
    name: str
    ddg: object
    count: int = 1
    region: str | None = None
    altitude: tuple | None = None
    positions: list | None = None
    seed: int = 0


@dataclass
class TilingSpec:
    """``[[tiling]]``: a tiled interaction zone (Kim, Hwang, Hyun and Lee 2012, interactive tiling; see
    :mod:`runtime.tiling.zone`). ``zone`` is a ``crowdweave:role = "region"`` prim whose
    outline's bounding rectangle is the zone (``bounds`` = x0, z0, x1, z1); ``patches`` a
    motion-patch pack (path relative to the scenario) or ``"synthetic"`` (built from the motion
    library); each ``[[tiling.team]]`` has ``count``, ``start`` = [x, z], ``heading`` (degrees,
    0 = +Z) and ``targets`` = [[x, z], ...] visited in turn, ``period`` seconds each."""
    name: str
    bounds: tuple
    teams: list
    patches: str = "synthetic"
    period: float = 8.0
    horizon: float = 1.5
    seed: int = 0
    zone: str | None = None


@dataclass
class AmbientSpec:
    """``[ambient]``: ``count`` people kept busy by :class:`runtime.world.ambient.AmbientLife`
    (run time only: the offline bake plans the ``[[character]]`` entries). ``region`` a region
    marker whose outline's bounding rectangle is where they walk (``bounds``; None: the world's
    bounds); ``linger`` (min, max) seconds spent at a spot, on a bench, in a conversation."""
    count: int
    seed: int = 0
    region: str | None = None
    bounds: tuple | None = None
    linger: tuple = (10.0, 40.0)


@dataclass
class Scenario:
    name: str
    path: str
    world: str | None
    library: str
    duration: float
    seed: int
    epsilon: tuple
    characters: list[CharacterSpec]
    synthesis: dict = field(default_factory=dict)
    flocks: list = field(default_factory=list)
    tilings: list = field(default_factory=list)
    ambient: AmbientSpec | None = None

    def character(self, name: str) -> CharacterSpec:
        for c in self.characters:
            if c.name == name:
                return c
        raise KeyError(name)


_TOP = {"name", "world", "library", "duration", "seed", "synthesis", "character", "description", "flock", "tiling",
        "ambient"}
_AMBIENT = {"count", "seed", "region", "linger"}
_SYNTHESIS = {"epsilon", "passes", "start_still", "approach_point", "n_m", "k_m", "n_max"}
_TILING = {"name", "zone", "patches", "period", "horizon", "seed", "team"}
_TEAM = {"count", "start", "heading", "targets"}
_FLOCK = {"name", "ddg", "count", "region", "altitude", "positions", "seed"}
_DDG = {"dim", "agents", "seconds", "seed"}
_CHAR = {"name", "start", "goal"}
_START = {"position", "heading", "pose", "seat"}
_GOAL = {"position", "heading", "pose", "time", "seat", "box", "after"}
_AFTER = {"character", "goal", "within"}
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def prim_name(name: str) -> str:
    """The USD prim name a baked character (or flock) called ``name`` gets: ``name`` itself when
    it is a valid identifier (ASCII letters, digits and '_', not starting with a digit), else
    every other character replaced by '_' and a leading digit kept behind a '_' ("bob smith" ->
    "bob_smith", "1st" -> "_1st", "Zoë" -> "Zo_"). The bake keeps the original name on the prim
    (``crowdweave:name``); :func:`parse_scenario` rejects two names that become the same."""
    name = str(name)
    if _IDENTIFIER.match(name):
        return name
    s = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return "_" + s if not s or s[0].isdigit() else s


def _ambient_spec(top: Table, markers: dict) -> AmbientSpec | None:
    if "ambient" not in top:
        return None
    t = top.table("ambient", "[ambient]", _AMBIENT)
    count = t.integer("count", 0, 0, MAX_CHARACTERS)
    bounds = region = None
    if "region" in t:
        region = t.string("region", nonempty=True)
        m = markers.get(region)
        if m is None or m.role != "region" or m.polygon is None:
            t.fail("region", f"no region marker {region!r} with an outline in the world")
        lo, hi = np.min(m.polygon, axis=0), np.max(m.polygon, axis=0)
        bounds = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
    linger = t.interval("linger", (10.0, 40.0), lo=0.0, hi=MAX_DURATION) if "linger" in t else (10.0, 40.0)
    return AmbientSpec(count, t.integer("seed", 0, 0, MAX_SEED), region, bounds, tuple(float(v) for v in linger))


def _tiling_spec(path, ti: int, rt: dict, markers: dict) -> TilingSpec:
    t = Table(path, f"tiling {ti}", rt, _TILING, ScenarioError)
    name = t.string("name", f"zone{ti}", nonempty=True)
    t.where = f"tiling {name!r}"
    where = f"{path}: {t.where}"
    zone = t.string("zone") if "zone" in t else None
    m = markers.get(zone) if zone is not None else None
    if m is None or m.role != "region" or m.polygon is None:
        raise ScenarioError(f"{where}: needs zone = a region marker with an outline in the world (got {zone!r})")
    lo, hi = np.min(m.polygon, axis=0), np.max(m.polygon, axis=0)
    bounds = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
    patches = t.string("patches", "synthetic", nonempty=True)
    if patches != "synthetic":
        pp = Path(path).parent / patches
        if not pp.is_file():
            t.fail("patches", f"{patches!r}: no such file ({pp})")
        patches = str(pp)
    raw = t.tables("team", 64)
    if not raw:
        raise ScenarioError(f"{where}: needs at least one [[tiling.team]]")
    teams = []
    for k, tm in enumerate(raw):
        tt = Table(path, f"{t.where} team {k}", tm, _TEAM, ScenarioError)
        count = tt.integer("count", 1, 1, MAX_TEAM)
        start = tuple(float(v) for v in tt.vector("start", 2))
        heading = math.radians(tt.number("heading", 0.0, unit="degrees"))
        targets = tt.data.get("targets", [])
        if not isinstance(targets, list) or len(targets) > 1000:
            tt.fail("targets", f"must be a list of [x, z] points, got {show(targets)}")
        targets = [tuple(float(v) for v in tt.check_vector(f"targets[{i}]", p, 2)) for i, p in enumerate(targets)]
        for key, p in [("start", start)] + [(f"targets[{i}]", p) for i, p in enumerate(targets)]:
            if not (bounds[0] < p[0] < bounds[2] and bounds[1] < p[1] < bounds[3]):
                raise ScenarioError(f"{where} team {k}: point {list(p)} is outside the zone {zone} {bounds} ({key})")
        teams.append({"count": count, "start": start, "heading": heading, "targets": targets})
    period = t.number("period", 8.0, lo=0.0, hi=MAX_DURATION, lo_open=True, unit="s")
    horizon = t.number("horizon", 1.5, lo=0.0, hi=60.0, lo_open=True, unit="s")
    return TilingSpec(name, bounds, teams, patches, period, horizon, t.integer("seed", ti, 0, MAX_SEED), zone)


def load_scenario(path, env=None, node_labels=None) -> Scenario:
    """Read and validate ``scenario.toml`` (a file or a sample directory); the file is read with
    a hard size limit (:data:`runtime.limits.MAX_TOML_BYTES`)."""
    p = Path(path)
    if p.is_dir():
        p = p / "scenario.toml"
    return parse_scenario(read_scenario_toml(p), str(p), env=env, node_labels=node_labels)


def scenario_sources(data: dict, path: str = "<scenario>") -> tuple:
    """(world, library) a parsed scenario names, checked (strings; world None for open ground),
    for loading them before the whole scenario is validated against them."""
    top = Table(path, "top level", data, _TOP, ScenarioError)
    world = top.string("world", nonempty=True) if "world" in top else None
    return world, top.string("library", "default", nonempty=True)


def read_scenario_toml(path) -> dict:
    """The parsed TOML of a scenario file (ScenarioError naming the file if it cannot be read,
    is too large or is not valid TOML)."""
    return read_toml(path, MAX_TOML_BYTES, ScenarioError)


def _synthesis(top: Table) -> tuple[dict, tuple]:
    eps = (0.02, 2.0, 1.0 / 15.0)
    if "synthesis" not in top:
        return {}, eps
    t = top.table("synthesis", "[synthesis]", _SYNTHESIS)
    if "epsilon" in t:
        v = t.data["epsilon"]
        if not (isinstance(v, list) and len(v) == 3 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                             and math.isfinite(x) and x > 0 for x in v)):
            t.fail("epsilon", f"must be [m/s, deg/s, s/s]: three positive finite numbers, got {show(v)}")
        eps = tuple(float(x) for x in v)
    if "start_still" in t:
        t.boolean("start_still")
    if "approach_point" in t:
        t.number("approach_point", lo=0.0, hi=5.0, unit="m")
    if "passes" in t:
        t.integer("passes", lo=1, hi=20)
    for k, hi in (("n_m", 100_000), ("k_m", 100_000), ("n_max", 1_000_000)):
        if k in t:
            t.integer(k, lo=1, hi=hi)
    return dict(t.data), eps


def _flock_spec(path, fi: int, rf, markers: dict) -> FlockSpec:
    t = Table(path, f"flock {fi}", rf, _FLOCK, ScenarioError)
    fname = t.string("name", f"flock{fi}", nonempty=True)
    t.where = f"flock {fname!r}"
    if "ddg" not in t:
        t.fail("ddg", "missing: a pack path or {dim, agents, seconds, seed}")
    ddg = t.data["ddg"]
    if isinstance(ddg, dict):
        d = t.table("ddg", f"flock {fname!r} ddg", _DDG)
        d.integer("dim", 2, 2, 3)
        agents = d.integer("agents", 20, 2, MAX_FLOCK_AGENTS)
        seconds = d.number("seconds", 120.0, lo=0.0, hi=MAX_FLOCK_SECONDS, lo_open=True, unit="s")
        d.integer("seed", 0, 0, MAX_SEED)
        if agents * seconds > MAX_FLOCK_AGENT_SECONDS:
            d.fail("seconds", f"{agents} agents x {seconds:g} s is more than the limit of "
                              f"{MAX_FLOCK_AGENT_SECONDS:g} agent-seconds of recording")
    else:
        t.string("ddg", nonempty=True)
    count = t.integer("count", 1, 1, MAX_FLOCKS)
    region = t.string("region") if "region" in t else None
    if region is not None:
        m = markers.get(region)
        if m is None or m.role != "region" or m.polygon is None:
            t.fail("region", f"no region marker {region!r} with an outline in the world")
    alt = t.interval("altitude", unit="m") if "altitude" in t else None
    positions = None
    if "positions" in t:
        v = t.data["positions"]
        if not isinstance(v, list) or not 1 <= len(v) <= MAX_FLOCKS:
            t.fail("positions", f"must be a list of 1 to {MAX_FLOCKS} [x, y, z] centroids, got {show(v)}")
        positions = [t.check_vector(f"positions[{i}]", p, 3).tolist() for i, p in enumerate(v)]
    return FlockSpec(fname, ddg, count, region, alt, positions, t.integer("seed", fi, 0, MAX_SEED))


def _marker(t: Table, key: str, role: str, markers: dict):
    path = t.string(key, nonempty=True)
    m = markers.get(path)
    if m is None or m.role != role:
        t.fail(key, f"no {role} marker {path!r} in the world")
    return path, m


def _start(t: Table, name: str, markers: dict):
    st = t.table("start", f"character {name!r} start", _START)
    if "seat" in st:
        if "position" in st:
            st.fail("seat", "give a position or a seat, not both")
        path, m = _marker(st, "seat", "seat", markers)
        return m.position.copy(), m.heading, "sit", path
    if "position" not in st:
        st.fail("position", "missing: a start needs a position or a seat")
    pos = st.vector("position", 2)
    heading = math.radians(st.number("heading", 0.0, unit="degrees"))
    return pos, heading, st.string("pose", "stand", nonempty=True), None


def _goal(path, where: str, rg, markers: dict, duration: float) -> GoalSpec:
    g = Table(path, where, rg, _GOAL, ScenarioError)
    given = [k for k in ("position", "seat", "box") if k in g]
    if len(given) > 1:
        g.fail(given[1], f"give one of position, seat or box, not {' and '.join(given)}")
    kind, marker = "position", None
    if "seat" in g:
        marker, m = _marker(g, "seat", "seat", markers)
        gpos, gh, gpose, kind = m.position.copy(), m.heading, "sit", "seat"
    elif "box" in g:
        marker, m = _marker(g, "box", "box", markers)
        # stand in front of the box, facing it: the box's +Z points at the character
        fwd = np.array([math.sin(m.heading), math.cos(m.heading)])
        gpos, gh, gpose, kind = m.position + BOX_REACH * fwd, m.heading + math.pi, "carry", "box"
    else:
        if "position" not in g:
            g.fail("position", "missing: a goal needs a position, a seat or a box")
        gpos, gh, gpose = g.vector("position", 2), None, None
    if "pose" in g:
        gpose = g.string("pose", nonempty=True)
    if "heading" in g:
        gh = math.radians(g.number("heading", unit="degrees"))
    tw = None
    if "time" in g:
        tw = g.interval("time", scalar=True)
        if tw[0] < 0 or tw[1] > duration:
            g.fail("time", f"window [{tw[0]}, {tw[1]}] outside the scenario's 0..{duration} s")
        if math.floor(tw[1] * 30 + 1e-6) < math.ceil(tw[0] * 30 - 1e-6):
            g.fail("time", f"window [{tw[0]}, {tw[1]}] is too short: it holds no 1/30 s frame")
    after = None
    if "after" in g:
        a = g.table("after", f"{where} after", _AFTER)
        after = {"character": a.string("character", nonempty=True), "goal": a.integer("goal", 0, 0, MAX_GOALS - 1),
                 "within": a.interval("within", (0.0, 1.0), lo=-MAX_DURATION, hi=MAX_DURATION)}
    return GoalSpec(gpos, gh, gpose, tw, after, marker, kind)


def _check_names(path, chars, tilings, flocks) -> None:
    """Two characters (or two flocks) whose USD prim names would be the same: an error now,
    before planning, rather than a bake that cannot write them."""
    for what, names in (("character", [(f"character {c.name!r}", c.name) for c in chars]
                         + [(f"tiling {t.name!r} character {t.name}_{ti}_{k}", f"{t.name}_{ti}_{k}")
                            for t in tilings for ti, team in enumerate(t.teams) for k in range(team["count"])]),
                        ("flock", [(f"flock {f.name!r} (flock {f.name}_{k:02d})", f"{f.name}_{k:02d}")
                                   for f in flocks for k in range(len(f.positions or [0] * f.count))])):
        seen = {}
        for label, name in names:
            pn = prim_name(name)
            if pn in seen:
                raise ScenarioError(f"{path}: {seen[pn]} and {label} both become the USD {what} prim {pn!r}; "
                                    "rename one")
            seen[pn] = label


def parse_scenario(data: dict, path: str = "<scenario>", env=None, node_labels=None) -> Scenario:
    """Validate a parsed scenario (see the module docstring) and build the :class:`Scenario`.

    Every key is checked against the schema before anything else: unknown keys (in any table),
    wrong types, numbers that are not finite or out of range, and inputs over the limits of
    :mod:`runtime.limits` raise :class:`ScenarioError` naming the file, the table and the key."""
    top = Table(path, "top level", data, _TOP, ScenarioError)
    name = top.string("name", Path(path).parent.name)
    world = top.string("world", nonempty=True) if "world" in top else None
    library = top.string("library", "default", nonempty=True)
    duration = top.number("duration", 20.0, lo=0.0, hi=MAX_DURATION, lo_open=True, unit="s")
    seed = top.integer("seed", 0, 0, MAX_SEED)
    top.string("description", "")
    syn, eps = _synthesis(top)
    markers = env.markers if env is not None else {}
    raw_chars = top.tables("character", MAX_CHARACTERS)
    raw_flocks = top.tables("flock", 100)
    raw_tilings = top.tables("tiling", 100)
    ambient = _ambient_spec(top, markers)
    if not (raw_chars or raw_flocks or raw_tilings or (ambient and ambient.count)):
        raise ScenarioError(f"{path}: no [[character]], [[flock]], [[tiling]] or [ambient] entries")
    tilings = [_tiling_spec(path, ti, rt, markers) for ti, rt in enumerate(raw_tilings)]
    flocks = [_flock_spec(path, fi, rf, markers) for fi, rf in enumerate(raw_flocks)]
    chars = []
    names = set()
    for ci, rc in enumerate(raw_chars):
        t = Table(path, f"character {ci}", rc, _CHAR, ScenarioError)
        cname = t.string("name", f"c{ci:02d}", nonempty=True)
        t.where = f"character {cname!r}"
        if cname in names:
            t.fail("name", "duplicate character name")
        names.add(cname)
        pos, heading, pose, start_marker = _start(t, cname, markers)
        spec = CharacterSpec(cname, pos, heading, pose, start_marker=start_marker)
        for gi, rg in enumerate(t.tables("goal", MAX_GOALS)):
            spec.goals.append(_goal(path, f"character {cname!r} goal {gi}", rg, markers, duration))
        chars.append(spec)
    n = len(chars) + sum(team["count"] for tl in tilings for team in tl.teams)
    if n + (ambient.count if ambient else 0) > MAX_CHARACTERS:
        raise ScenarioError(f"{path}: {n + (ambient.count if ambient else 0)} characters (crowd, tiled and "
                            f"ambient): more than the limit of {MAX_CHARACTERS}")
    if n * duration > MAX_CHARACTER_SECONDS:
        raise ScenarioError(f"{path}: duration: {n} characters x {duration:g} s is more than the limit of "
                            f"{MAX_CHARACTER_SECONDS:g} character-seconds (a bake holds about 4.5 KB per "
                            "character and frame); shorten the scenario or split the crowd")
    _check_names(path, chars, tilings, flocks)
    sc = Scenario(name, path, world, library, duration, seed, eps, chars, syn, flocks, tilings, ambient)
    validate(sc, env, node_labels)
    return sc


def planning_order(sc: Scenario) -> list[int]:
    """Characters in an order that respects ``after`` (topological; ties keep file order).
    A cycle is a ScenarioError naming the characters in it."""
    idx = {c.name: i for i, c in enumerate(sc.characters)}
    deps = [set() for _ in sc.characters]
    why = {}    # (i, d) -> "goal gi after <d> goal gd"
    for i, c in enumerate(sc.characters):
        for gi, g in enumerate(c.goals):
            if g.after:
                other = g.after["character"]
                if other not in idx:
                    raise ScenarioError(f"{sc.path}: character {c.name!r} goal {gi}: after names unknown character {other!r}")
                oc = sc.characters[idx[other]]
                if not (0 <= g.after["goal"] < len(oc.goals)):
                    raise ScenarioError(f"{sc.path}: character {c.name!r} goal {gi}: {other!r} has no goal {g.after['goal']}")
                if idx[other] == i:
                    if g.after["goal"] >= gi:
                        raise ScenarioError(f"{sc.path}: character {c.name!r} goal {gi}: after refers to its own later goal")
                    continue
                deps[i].add(idx[other])
                why.setdefault((i, idx[other]), f"goal {gi} after {other!r} goal {g.after['goal']}")
    order, state = [], [0] * len(deps)   # 0 new, 1 on stack, 2 done

    def visit(i, stack):
        if state[i] == 2:
            return
        if state[i] == 1:
            cyc = stack[stack.index(i):] + [i]
            steps = [f"{sc.characters[a].name!r} {why.get((a, b), '')}" for a, b in zip(cyc[:-1], cyc[1:])]
            raise ScenarioError(f"{sc.path}: timing dependency cycle: " +
                                " -> ".join(sc.characters[k].name for k in cyc) + " (" + "; ".join(steps) + ")")
        state[i] = 1
        for d in sorted(deps[i]):
            visit(d, stack + [i])
        state[i] = 2
        order.append(i)

    for i in range(len(deps)):
        visit(i, [])
    return order


def validate(sc: Scenario, env=None, node_labels=None) -> None:
    planning_order(sc)
    for c in sc.characters:
        if node_labels is not None and c.pose not in node_labels:
            raise ScenarioError(f"{sc.path}: character {c.name!r} start: pose {c.pose!r} is not in the library "
                                f"{sc.library!r} (it has {sorted(node_labels)})")
        if env is not None and c.start_marker is None:
            d0 = float(env.distance(c.position[None])[0])
            if d0 < 0:
                raise ScenarioError(f"{sc.path}: character {c.name!r} start position {c.position.tolist()} is inside an obstacle")
            if d0 < START_CLEARANCE:
                raise ScenarioError(f"{sc.path}: character {c.name!r} start position {c.position.tolist()} is "
                                    f"{d0:.2f} m from an obstacle: a standing character needs {START_CLEARANCE} m "
                                    f"(it would overlap the obstacle from the first frame)")
        prev_pos, prev_t = c.position, 0.0
        for gi, g in enumerate(c.goals):
            gw = f"{sc.path}: character {c.name!r} goal {gi}"
            if node_labels is not None and g.pose is not None and g.pose not in node_labels:
                raise ScenarioError(f"{gw}: pose {g.pose!r} is not in the library {sc.library!r} "
                                    f"(it has {sorted(node_labels)})")
            if env is not None and g.kind == "position" and env.distance(g.position[None])[0] < 0:
                raise ScenarioError(f"{gw}: position {g.position.tolist()} is inside an obstacle")
            if g.time is not None:
                need = float(np.hypot(*(g.position - prev_pos))) / MAX_SPEED
                if g.time[1] - prev_t < need:
                    raise ScenarioError(f"{gw}: window ends at {g.time[1]} s but the goal is "
                                        f"{need * MAX_SPEED:.1f} m away: too short for any motion "
                                        f"(needs at least {need:.1f} s after {prev_t:.1f} s)")
                prev_t = g.time[0]
            prev_pos = g.position
