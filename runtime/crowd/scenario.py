"""Scenarios: ``samples/<name>/scenario.toml`` .

```toml
name = "meet20"
world = "world.usda"        # optional: open ground
library = "default"         # or a path to a motion-graph pack
duration = 20.0             # seconds to bake
seed = 0
[synthesis]                 # optional, paper defaults
epsilon = [0.02, 2.0, 0.0667]
passes = 3                  # planning passes: characters left without a clean plan go first next time
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
```

Validation happens before any planning and raises :class:`ScenarioError` naming the
character and the goal: unknown keys, a dependency cycle, a goal inside an obstacle, a pose
the library lacks, a window too short for any motion, unknown markers.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["ScenarioError", "Scenario", "CharacterSpec", "GoalSpec", "FlockSpec", "load_scenario", "parse_scenario",
           "planning_order", "BOX_REACH"]

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

    def character(self, name: str) -> CharacterSpec:
        for c in self.characters:
            if c.name == name:
                return c
        raise KeyError(name)


_TOP = {"name", "world", "library", "duration", "seed", "synthesis", "character", "description", "flock", "tiling"}
_TILING = {"name", "zone", "patches", "period", "horizon", "seed", "team"}
_TEAM = {"count", "start", "heading", "targets"}
_FLOCK = {"name", "ddg", "count", "region", "altitude", "positions", "seed"}
_CHAR = {"name", "start", "goal"}
_START = {"position", "heading", "pose", "seat"}
_GOAL = {"position", "heading", "pose", "time", "seat", "box", "after"}




def _tiling_spec(path, ti: int, rt: dict, markers: dict) -> TilingSpec:
    name = str(rt.get("name", f"zone{ti}"))
    where = f"{path}: tiling {name!r}"
    bad = set(rt) - _TILING
    if bad:
        raise ScenarioError(f"{where}: unknown keys {sorted(bad)}")
    zone = rt.get("zone")
    m = markers.get(zone) if zone is not None else None
    if m is None or m.role != "region" or m.polygon is None:
        raise ScenarioError(f"{where}: needs zone = a region marker with an outline in the world (got {zone!r})")
    lo, hi = np.min(m.polygon, axis=0), np.max(m.polygon, axis=0)
    bounds = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
    patches = str(rt.get("patches", "synthetic"))
    if patches != "synthetic":
        pp = Path(path).parent / patches
        if not pp.is_file():
            raise ScenarioError(f"{where}: patches {patches!r}: no such file ({pp})")
        patches = str(pp)
    teams = []
    raw = rt.get("team", [])
    if not isinstance(raw, list) or not raw:
        raise ScenarioError(f"{where}: needs at least one [[tiling.team]]")
    for k, tm in enumerate(raw):
        tw = f"{where} team {k}"
        bad = set(tm) - _TEAM
        if bad:
            raise ScenarioError(f"{tw}: unknown keys {sorted(bad)}")
        try:
            count = int(tm.get("count", 1))
            start = tuple(float(v) for v in tm["start"])
            heading = math.radians(float(tm.get("heading", 0.0)))
            targets = [tuple(float(v) for v in t) for t in tm.get("targets", [])]
        except (KeyError, TypeError, ValueError) as e:
            raise ScenarioError(f"{tw}: needs count, start = [x, z], heading, targets = [[x, z], ...] ({e})") from None
        if count < 1 or len(start) != 2 or any(len(t) != 2 for t in targets):
            raise ScenarioError(f"{tw}: count must be >= 1, start and every target [x, z]")
        for p in [start] + targets:
            if not (bounds[0] < p[0] < bounds[2] and bounds[1] < p[1] < bounds[3]):
                raise ScenarioError(f"{tw}: point {list(p)} is outside the zone {zone} {bounds}")
        teams.append({"count": count, "start": start, "heading": heading, "targets": targets})
    period = float(rt.get("period", 8.0))
    horizon = float(rt.get("horizon", 1.5))
    if period <= 0 or horizon <= 0:
        raise ScenarioError(f"{where}: period and horizon must be positive")
    return TilingSpec(name, bounds, teams, patches, period, horizon, int(rt.get("seed", ti)), zone)

def _vec2(v, where):
    try:
        a = np.asarray(v, dtype=np.float64).reshape(2)
    except (ValueError, TypeError):
        raise ScenarioError(f"{where}: expected [x, z], got {v!r}") from None
    if not np.all(np.isfinite(a)):
        raise ScenarioError(f"{where}: position is not finite")
    return a


def load_scenario(path, env=None, node_labels=None) -> Scenario:
    """Read and validate ``scenario.toml`` (a file or a sample directory)."""
    p = Path(path)
    if p.is_dir():
        p = p / "scenario.toml"
    try:
        data = tomllib.loads(p.read_text())
    except FileNotFoundError:
        raise ScenarioError(f"{p}: scenario file not found") from None
    except tomllib.TOMLDecodeError as e:
        raise ScenarioError(f"{p}: not valid TOML: {e}") from None
    return parse_scenario(data, str(p), env=env, node_labels=node_labels)


def parse_scenario(data: dict, path: str = "<scenario>", env=None, node_labels=None) -> Scenario:
    unknown = set(data) - _TOP
    if unknown:
        raise ScenarioError(f"{path}: unknown top-level keys {sorted(unknown)}")
    duration = float(data.get("duration", 20.0))
    if not duration > 0:
        raise ScenarioError(f"{path}: duration must be positive")
    syn = dict(data.get("synthesis", {}))
    eps = tuple(float(x) for x in syn.get("epsilon", (0.02, 2.0, 1.0 / 15.0)))
    if len(eps) != 3 or min(eps) <= 0:
        raise ScenarioError(f"{path}: synthesis.epsilon must be three positive numbers")
    if not isinstance(syn.get("start_still", False), bool):
        raise ScenarioError(f"{path}: synthesis.start_still must be true or false")
    ap = syn.get("approach_point", 0.0)
    if isinstance(ap, bool) or not isinstance(ap, (int, float)) or not 0.0 <= float(ap) <= 5.0:
        raise ScenarioError(f"{path}: synthesis.approach_point must be a distance in metres from 0 to 5")
    markers = env.markers if env is not None else {}
    chars = []
    names = set()
    raw_chars = data.get("character", [])
    raw_flocks = data.get("flock", [])
    raw_tilings = data.get("tiling", [])
    if not isinstance(raw_chars, list) or not isinstance(raw_flocks, list) or not isinstance(raw_tilings, list) \
            or not (raw_chars or raw_flocks or raw_tilings):
        raise ScenarioError(f"{path}: no [[character]], [[flock]] or [[tiling]] entries")
    tilings = [_tiling_spec(path, ti, rt, markers) for ti, rt in enumerate(raw_tilings)]
    flocks = []
    for fi, rf in enumerate(raw_flocks):
        fname = str(rf.get("name", f"flock{fi}"))
        bad = set(rf) - _FLOCK
        if bad:
            raise ScenarioError(f"{path}: flock {fname!r}: unknown keys {sorted(bad)}")
        if "ddg" not in rf:
            raise ScenarioError(f"{path}: flock {fname!r}: needs ddg (a pack path or {{dim, agents, seconds, seed}})")
        region = rf.get("region")
        if region is not None:
            m = markers.get(region)
            if m is None or m.role != "region" or m.polygon is None:
                raise ScenarioError(f"{path}: flock {fname!r}: no region marker {region!r} with an outline in the world")
        alt = tuple(float(a) for a in rf["altitude"]) if "altitude" in rf else None
        flocks.append(FlockSpec(fname, rf["ddg"], int(rf.get("count", 1)), region, alt, rf.get("positions"),
                                int(rf.get("seed", fi))))
    for ci, rc in enumerate(raw_chars):
        name = str(rc.get("name", f"c{ci:02d}"))
        where = f"{path}: character {name!r}"
        bad = set(rc) - _CHAR
        if bad:
            raise ScenarioError(f"{where}: unknown keys {sorted(bad)}")
        if name in names:
            raise ScenarioError(f"{where}: duplicate character name")
        names.add(name)
        st = dict(rc.get("start", {}))
        bad = set(st) - _START
        if bad:
            raise ScenarioError(f"{where} start: unknown keys {sorted(bad)}")
        start_marker = None
        if "seat" in st:
            m = markers.get(st["seat"])
            if m is None or m.role != "seat":
                raise ScenarioError(f"{where} start: no seat marker {st['seat']!r} in the world")
            pos, heading, pose, start_marker = m.position.copy(), m.heading, "sit", st["seat"]
        else:
            if "position" not in st:
                raise ScenarioError(f"{where} start: needs a position or a seat")
            pos = _vec2(st["position"], f"{where} start")
            heading = math.radians(float(st.get("heading", 0.0)))
            pose = str(st.get("pose", "stand"))
        spec = CharacterSpec(name, pos, heading, pose, start_marker=start_marker)
        goals = rc.get("goal", [])
        for gi, rg in enumerate(goals):
            gw = f"{where} goal {gi}"
            bad = set(rg) - _GOAL
            if bad:
                raise ScenarioError(f"{gw}: unknown keys {sorted(bad)}")
            kind, marker = "position", None
            if "seat" in rg:
                m = markers.get(rg["seat"])
                if m is None or m.role != "seat":
                    raise ScenarioError(f"{gw}: no seat marker {rg['seat']!r} in the world")
                gpos, gh, gpose, kind, marker = m.position.copy(), m.heading, "sit", "seat", rg["seat"]
            elif "box" in rg:
                m = markers.get(rg["box"])
                if m is None or m.role != "box":
                    raise ScenarioError(f"{gw}: no box marker {rg['box']!r} in the world")
                # stand in front of the box, facing it: the box's +Z points at the character
                fwd = np.array([math.sin(m.heading), math.cos(m.heading)])
                gpos = m.position + BOX_REACH * fwd
                gh = m.heading + math.pi
                gpose, kind, marker = "carry", "box", rg["box"]
            else:
                if "position" not in rg:
                    raise ScenarioError(f"{gw}: needs a position, a seat or a box")
                gpos = _vec2(rg["position"], gw)
                gh = math.radians(float(rg["heading"])) if "heading" in rg else None
                gpose = None
            if "pose" in rg:
                gpose = str(rg["pose"])
            if "heading" in rg and kind != "position":
                gh = math.radians(float(rg["heading"]))
            tw = None
            if "time" in rg:
                t = rg["time"]
                try:
                    tw = (float(t[0]), float(t[1])) if isinstance(t, (list, tuple)) else (float(t), float(t))
                except (TypeError, ValueError, IndexError):
                    raise ScenarioError(f"{gw}: time must be [t_a, t_b] seconds") from None
                if tw[1] < tw[0]:
                    raise ScenarioError(f"{gw}: time window [{tw[0]}, {tw[1]}] is empty")
                if tw[0] < 0 or tw[1] > duration:
                    raise ScenarioError(f"{gw}: time window [{tw[0]}, {tw[1]}] outside the scenario's 0..{duration} s")
                if math.floor(tw[1] * 30 + 1e-6) < math.ceil(tw[0] * 30 - 1e-6):
                    raise ScenarioError(f"{gw}: time window [{tw[0]}, {tw[1]}] is too short: it holds no 1/30 s frame")
            after = None
            if "after" in rg:
                a = dict(rg["after"])
                if "character" not in a:
                    raise ScenarioError(f"{gw}: after needs a character")
                w = a.get("within", (0.0, 1.0))
                after = {"character": str(a["character"]), "goal": int(a.get("goal", 0)),
                         "within": (float(w[0]), float(w[1]))}
                if after["within"][1] < after["within"][0]:
                    raise ScenarioError(f"{gw}: after.within is an empty interval")
            spec.goals.append(GoalSpec(gpos, gh, gpose, tw, after, marker, kind))
        chars.append(spec)
    sc = Scenario(str(data.get("name", Path(path).parent.name)), path, data.get("world"),
                  str(data.get("library", "default")), duration, int(data.get("seed", 0)), eps, chars, syn, flocks,
                  tilings)
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
