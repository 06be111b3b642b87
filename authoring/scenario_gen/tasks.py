"""The characters of a generated scenario: starts and goals drawn per district, by kind.

Every endpoint is drawn uniformly in its region and kept only if it obeys the rules
(:class:`~.params.GenParams`): clearance from the obstacles, ``spacing`` from every endpoint
drawn before (starts, goals, seats in use, box stand points; crates keep 1 m), and a walk
from the character's previous point in the same free component. A character that finds no
such endpoint in ``tries`` draws makes the whole layout start again (:class:`Crowded`).
Timing is added afterwards (:mod:`.timing`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from runtime.crowd.scenario import BOX_REACH

from .layout import OPPOSITE, District
from .obstacles import turn
from .params import KIND_PREFIX

__all__ = ["Crowded", "Task", "Endpoints", "draw_tasks", "CRATE_SPACING"]

CRATE_SPACING = 1.0     # m from a crate to any endpoint but its own stand point
SEAT_START_GAP = 3.0    # m from a seats district's starts to every seat (out of the rows' lanes)
BATCH = 32


class Crowded(Exception):
    """No endpoint obeying the rules was found for a character (the layout is redrawn)."""


@dataclass
class Task:
    """One character before timing: ``start`` (x, z), ``heading`` degrees, ``goals`` as
    scenario goal dicts (without time or after), ``kind``, ``meeting`` (id of its meeting,
    if any), ``group`` (district index)."""
    name: str
    kind: str
    group: int
    start: np.ndarray
    heading: float
    goals: list = field(default_factory=list)
    meeting: int | None = None


class Endpoints:
    """Endpoints drawn so far (kept ``spacing`` apart) and crates (kept ``CRATE_SPACING`` away)."""

    def __init__(self, spacing: float):
        self.spacing = spacing
        self.points = np.zeros((0, 2))
        self.crates = np.zeros((0, 2))

    def clear(self, P, extra=()) -> np.ndarray:
        """Which of the points ``P`` (K, 2) keep their distances (also from ``extra`` points)."""
        P = np.asarray(P, float).reshape(-1, 2)
        pts = np.concatenate([self.points, np.asarray(extra, float).reshape(-1, 2)])
        ok = np.ones(len(P), bool)
        if len(pts):
            ok &= np.min(np.hypot(*(P[:, None] - pts[None]).transpose(2, 0, 1)), axis=1) >= self.spacing
        if len(self.crates):
            ok &= np.min(np.hypot(*(P[:, None] - self.crates[None]).transpose(2, 0, 1)), axis=1) >= CRATE_SPACING
        return ok

    def add(self, *ps):
        self.points = np.concatenate([self.points, np.asarray(ps, float).reshape(-1, 2)])

    def add_crate(self, c):
        self.crates = np.concatenate([self.crates, np.asarray(c, float).reshape(1, 2)])


def _heading_deg(v) -> float:
    return round(math.degrees(math.atan2(v[0], v[1])), 1)


def _pos(p) -> list:
    return [round(float(p[0]), 3), round(float(p[1]), 3)]


class _Drawer:
    def __init__(self, params, env, fs, rng, endpoints: Endpoints, world):
        self.p, self.env, self.fs, self.rng, self.ep, self.world = params, env, fs, rng, endpoints, world

    def clearance(self, P) -> np.ndarray:
        P = np.asarray(P, float).reshape(-1, 2)
        return self.env.distance(P) if self.env.num_obstacles else np.full(len(P), np.inf)

    def point(self, region, accept=None, clearance=None, extra=()):
        """A point of ``region`` (x0, z0, x1, z1) with the clearance, spacing and ``accept``
        (a test on the point), or None after ``tries`` candidates."""
        x0, z0, x1, z1 = region
        if x1 <= x0 or z1 <= z0:
            return None
        clearance = self.p.clearance if clearance is None else clearance
        for _ in range(max(1, self.p.tries // BATCH)):
            P = np.round(self.rng.uniform((x0, z0), (x1, z1), size=(BATCH, 2)), 2)
            P = P[self.clearance(P) >= clearance]
            P = P[self.ep.clear(P, extra)]
            for q in P:
                if accept is None or accept(q):
                    return q
        return None

    def in_free_space(self, q) -> bool:
        return self.fs.component(q) > 0

    def same_component(self, a):
        ca = self.fs.component(a)
        return lambda q: ca > 0 and self.fs.component(q) == ca

    def start_heading(self, start, towards) -> float:
        if self.rng.random() < 0.25:
            return round(float(self.rng.uniform(-180.0, 180.0)), 1)
        return round(_heading_deg(np.asarray(towards) - start) + float(self.rng.uniform(-20.0, 20.0)), 1)


def _walk(dr: _Drawer, d: District, name, src, dst, where):
    """A start in region ``src`` and a goal in ``dst`` reachable from it (``where``: the two
    regions' descriptions for the error)."""
    start = dr.point(src, dr.in_free_space)
    if start is None:
        raise Crowded(f"{name}: no start in {where[0]} of district {d.index}")
    goal = dr.point(dst, dr.same_component(start), extra=[start])
    if goal is None:
        raise Crowded(f"{name}: no goal in {where[1]} of district {d.index} reachable from its start")
    dr.ep.add(start, goal)
    return start, goal


def _crossing(dr: _Drawer, d: District, names):
    out = []
    for i, name in enumerate(names):
        src, dst = d.flows[i % len(d.flows)]
        start, goal = _walk(dr, d, name, d.bands[src], d.bands[dst], (f"the {src} band", f"the {dst} band"))
        g = {"position": _pos(goal)}
        if dr.rng.random() < 0.5:
            flow = {"-x": 90.0, "+x": -90.0, "-z": 0.0, "+z": 180.0}[OPPOSITE[dst]]
            g["heading"] = round(flow + float(dr.rng.uniform(-30.0, 30.0)), 1)
        out.append(Task(name, "crossing", d.index, start, dr.start_heading(start, goal), [g]))
    return out


def _rooms(dr: _Drawer, d: District, names):
    out = []
    n = len(d.rooms)
    for i, name in enumerate(names):
        a = i % n
        b = (a + 1 + int(dr.rng.integers(n - 1))) % n if n > 1 else a
        start, goal = _walk(dr, d, name, d.rooms[a], d.rooms[b], (f"room {a}", f"room {b}"))
        g = {"position": _pos(goal)}
        if dr.rng.random() < 0.5:
            g["heading"] = round(float(dr.rng.uniform(-180.0, 180.0)), 1)
        out.append(Task(name, "rooms", d.index, start, dr.start_heading(start, goal), [g]))
    return out


def _meeting_sizes(n, rng) -> list:
    sizes, rem = [], n
    while rem:
        choices = [k for k in (2, 3, 4) if k <= rem and rem - k != 1] or [rem]
        k = int(rng.choice(choices))
        sizes.append(k)
        rem -= k
    return sizes


def _meeting(dr: _Drawer, d: District, names, first_meeting: int):
    """Groups of 2-4 arrive together at points on a circle round a meeting point, facing it;
    each member starts at least 3 m beyond the circle."""
    out = []
    at = 0
    for m, k in enumerate(_meeting_sizes(len(names), dr.rng)):
        r = max(0.75, 0.75 / math.sin(math.pi / k)) + 0.05 if k > 1 else 0.0
        members = names[at:at + k]
        at += k
        placed = None
        for _ in range(60):
            centre = dr.point(d.inset(1.0), clearance=0.3)
            if centre is None:
                break
            phase = float(dr.rng.uniform(0.0, 360.0))
            spots = [np.round(centre + r * turn(np.array([0.0, 1.0]), phase + j * 360.0 / k), 3) for j in range(k)]
            if np.any(dr.clearance(spots) < dr.p.clearance) or not dr.ep.clear(spots).all():
                continue
            comp = dr.fs.component(spots[0])
            if comp == 0 or any(dr.fs.component(s) != comp for s in spots[1:]):
                continue
            starts = []
            for s in spots:
                q = dr.point(d.rect, lambda q: float(np.hypot(*(q - centre))) >= r + 3.0 and dr.fs.component(q) == comp,
                             extra=spots + starts)
                if q is None:
                    break
                starts.append(q)
            if len(starts) == k:
                placed = (centre, spots, starts)
                break
        if placed is None:
            raise Crowded(f"{members[0]}: no meeting place for {k} in district {d.index}")
        centre, spots, starts = placed
        dr.ep.add(*spots, *starts)
        for name, s, q in zip(members, spots, starts):
            g = {"position": _pos(s), "heading": _heading_deg(centre - s)}
            out.append(Task(name, "meeting", d.index, q, dr.start_heading(q, s), [g], first_meeting + m))
    return out


def _seats(dr: _Drawer, d: District, names):
    """Each character walks from outside the rows (``SEAT_START_GAP`` from every seat) to a
    seat and sits down."""
    p = dr.p
    usable = []
    for path, s, yaw in d.seats:
        front = s + p.approach * turn(np.array([0.0, 1.0]), yaw)
        if dr.clearance([s])[0] >= p.seat_clearance and dr.clearance([front])[0] >= p.clearance \
                and dr.fs.component(front) > 0:
            usable.append((path, s, front))
    if len(usable) < len(names):
        raise Crowded(f"{names[0]}: district {d.index} has {len(usable)} usable seats for {len(names)} characters")
    pick = dr.rng.choice(len(usable), size=len(names), replace=False)
    chosen = [usable[int(i)] for i in pick]
    dr.ep.add(*[s for _, s, _ in chosen])
    seats = np.array([s for _, s, _ in d.seats])
    out = []
    for name, (path, s, front) in zip(names, chosen):
        comp = dr.fs.component(front)

        def outside_rows(q):
            # starts stand outside the rows and their lanes, where the others walk to their seats
            return np.hypot(*(seats - q).T).min() >= SEAT_START_GAP and dr.fs.component(q) == comp
        start = dr.point(d.rect, outside_rows)
        if start is None:
            raise Crowded(f"{name}: no start in district {d.index} that reaches seat {path}")
        dr.ep.add(start)
        out.append(Task(name, "seats", d.index, start, dr.start_heading(start, s), [{"seat": path}]))
    return out


def _boxes(dr: _Drawer, d: District, names):
    """Each character walks to a box, picks it up facing it and carries it 3-7 m on, at most
    35 degrees off straight ahead (carrying clips turn only while walking on), along a straight
    path clear of the obstacles by ``box_clearance``, and puts it down there (pose "stand");
    the pick-up and put-down spots keep ``box_clearance`` too."""
    p = dr.p
    out = []
    for name in names:
        placed = None
        for _ in range(p.tries // 4):
            crate = dr.point(d.inset(1.0), clearance=p.crate_clearance)
            if crate is None:
                break
            heading = round(float(dr.rng.uniform(-180.0, 180.0)), 1)
            fwd = turn(np.array([0.0, 1.0]), heading)
            stand = crate + BOX_REACH * fwd
            put = np.round(stand + float(dr.rng.uniform(3.0, 7.0)) * turn(-fwd, float(dr.rng.uniform(-35.0, 35.0))), 2)
            if np.any(dr.clearance([stand, put]) < p.box_clearance) or not dr.ep.clear([stand, put]).all():
                continue
            if float(np.hypot(*(put - crate))) < CRATE_SPACING:
                continue
            if dr.env.num_obstacles and not dr.env.segment_clear(stand[None], put[None], p.box_clearance)[0]:
                continue
            comp = dr.fs.component(stand)
            if comp == 0:
                continue
            start = dr.point(d.rect, lambda q: float(np.hypot(*(q - stand))) >= 3.0 and dr.fs.component(q) == comp,
                             extra=[stand, put])
            if start is None or float(np.hypot(*(start - crate))) < CRATE_SPACING:
                continue
            placed = (crate, heading, stand, put, start)
            break
        if placed is None:
            raise Crowded(f"{name}: no box, put-down spot and start fit in district {d.index}")
        crate, heading, stand, put, start = placed
        dr.ep.add(stand, put, start)
        dr.ep.add_crate(crate)
        path = dr.world.box(f"{name}_box", crate[0], crate[1], heading)
        out.append(Task(name, "boxes", d.index, start, dr.start_heading(start, stand),
                        [{"box": path}, {"position": _pos(put), "pose": "stand"}]))
    return out


def draw_tasks(params, env, fs, rng, districts, world) -> list:
    """Tasks of every district (districts with the least freedom first: seats, boxes,
    meetings, rooms, crossings); returned in district order, names numbered in that order."""
    dr = _Drawer(params, env, fs, rng, Endpoints(params.spacing), world)
    names, at = {}, 0
    for d in districts:
        names[d.index] = [f"{KIND_PREFIX[d.kind]}{at + k:03d}" for k in range(d.n)]
        at += d.n
    order = sorted(districts, key=lambda d: ("seats", "boxes", "meeting", "rooms", "crossing").index(d.kind))
    out, meetings = {}, 0
    for d in order:
        if d.kind == "crossing":
            out[d.index] = _crossing(dr, d, names[d.index])
        elif d.kind == "rooms":
            out[d.index] = _rooms(dr, d, names[d.index])
        elif d.kind == "meeting":
            out[d.index] = _meeting(dr, d, names[d.index], meetings)
            meetings = 1 + max([t.meeting for t in out[d.index]], default=meetings - 1)
        elif d.kind == "seats":
            out[d.index] = _seats(dr, d, names[d.index])
        else:
            out[d.index] = _boxes(dr, d, names[d.index])
    return [t for d in districts for t in out[d.index]]
