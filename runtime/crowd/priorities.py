"""The planning order, chosen with a stand-in plan: discs on a space-time lattice.

Characters are planned one after another (Sung, Kovar and Gleicher 2005, section 3.1), each
avoiding the ones before it: prioritized planning, whose success depends on the order (van den
Berg and Overmars 2005). Bennewitz, Burgard and Thrun (2002) search the orders themselves,
judging each by planning the whole team with it. Planning a character's motion costs seconds
here; the stand-in costs milliseconds: every character is a disc that walks the space-time
lattice of :func:`~runtime.crowd.planner.route.timed_route` (the rerouted rung's search) from
goal to goal, against the discs planned before it and the starts of those not planned yet
(held, as in :func:`~runtime.crowd.scheduler.hold_starts`), and must arrive inside each
window. The order is chosen per interaction group (characters whose routes come within
``GROUP_REACH`` of each other with nothing between: a walled district, a cross-flow): of the
candidate orders of :data:`CANDIDATES`, the one whose stand-in leaves the fewest characters
without a route, then a few steps of hill climbing that move a character left without one to
the front of its group. Groups are planned one after another; across groups the order does
not matter (their routes never come near each other).

Limits (beside the code): the character being planned is a disc of ``WALK_RADIUS``, everyone
else (walking or standing) one of ``STAND_RADIUS`` (the lattice adds ``route.SLACK``); a state change (sitting down, picking a box up) takes
``CHANGE_S``; at most ``CLIMB_STEPS`` stand-in plans of a group per hill climb; a group of
more than ``MAX_GROUP`` characters keeps the file order.
"""
from __future__ import annotations

import numpy as np

from .planner.route import STEP, timed_route

__all__ = ["character_legs", "route_legs", "lattice_failures", "interaction_groups", "coarse_groups", "route_points",
           "lattice_order", "CANDIDATES", "WALK_RADIUS", "STAND_RADIUS", "GROUP_REACH", "CLIMB_STEPS", "CHANGE_S",
           "MAX_GROUP"]

CANDIDATES = ("file", "endpoints", "earliest", "longest")   # orders tried first, per group
WALK_RADIUS = 0.45      # m: the disc of the character the stand-in is planning
STAND_RADIUS = 0.35     # m: ... and of everyone else (held starts, planned discs walking or standing)
GOAL_RELEASE = 1.2      # m: a held start this close to a character's goal gives way to it (a swap)
GROUP_REACH = 2.0       # m between two routes, in sight of each other, that joins their groups
GROUP_SAMPLE = 0.5      # m between the route points the groups are found from
CLIMB_STEPS = 6         # stand-in plans per group spent on hill climbing
MAX_GROUP = 40          # characters: a larger group keeps the file order (a stand-in plan costs about
#                         the square of the group's size; a grid of hundreds is one group)
CHANGE_S = {"seat": 3.0, "box": 3.0}   # s of state change after arriving at such a goal


def character_legs(c, env, roadmap) -> list:
    """Character ``c``'s legs: per goal with a position, (goal index, way points (n, 2) from the
    previous goal, or the start, to it): the roadmap's (straight lines without a roadmap)."""
    prev = np.asarray(c.position, float)
    row = []
    for gi, g in enumerate(c.goals):
        if g.position is None:
            continue
        b = np.asarray(g.position, float)
        way = roadmap.waypoints(env, prev, b) if roadmap is not None and env is not None else np.array([prev, b])
        row.append((gi, np.asarray(way, float)))
        prev = b
    return row


def route_legs(sc, env, roadmap) -> list:
    """Per character of ``sc``, its legs (:func:`character_legs`)."""
    return [character_legs(c, env, roadmap) for c in sc.characters]


def lattice_failures(sc, static, legs, order, fps: float, n_total: int) -> list:
    """The characters of ``order`` (indices into ``sc.characters``) that the stand-in plan
    leaves without a route to one of their goals in time, in order.

    Args:
        sc: the scenario. static: signed distance to the obstacles (callable on (n, 2)), or None.
        legs: per character, [(goal index, way points)] (:func:`route_legs`).
        order: the characters to plan, in turn; the others are not there at all.
        fps, n_total: the clock (frames per second, frames in the scenario).
    """
    order = list(order)
    T = n_total // STEP + 2
    starts = np.array([np.asarray(sc.characters[ci].position, float) for ci in order]).reshape(-1, 2)
    pos = np.repeat(starts[:, None], T, axis=1)     # (characters, time steps, 2): held starts at first
    rad = np.full(len(order), STAND_RADIUS)
    arrive = {}
    failed = []
    names = {c.name: i for i, c in enumerate(sc.characters)}
    planned = np.zeros(len(order), dtype=bool)
    for k, ci in enumerate(order):
        c = sc.characters[ci]
        mask = np.ones(len(order), dtype=bool)
        mask[k] = False
        # held starts at this character's goals give way (a swap of places)
        for _, way in legs[ci]:
            near = ~planned & (np.hypot(*(starts - way[-1]).T) < GOAL_RELEASE)
            mask &= ~near
        f = 0
        ok = True
        row = legs[ci]
        for j, (gi, way) in enumerate(row):
            g = c.goals[gi]
            w = g.time
            if g.after is not None:
                a = arrive.get((names[g.after["character"]], g.after["goal"]))
                if a is not None:
                    lo, hi = a / fps + g.after["within"][0], a / fps + g.after["within"][1]
                    w = (lo, hi) if w is None else (max(w[0], lo), min(w[1], hi))
            last = min(int(w[1] * fps), n_total - 1) if w is not None else n_total - 1
            b = way[-1]
            sel = pos[mask]
            sel_r = rad[mask]

            def occupied_at(frame, sel=sel, sel_r=sel_r):
                t = min(T - 1, int(round(frame / STEP)))
                return sel[:, t], sel_r

            def hold(frame, b=b, sel=sel, sel_r=sel_r):
                t = min(T - 1, int(round(frame / STEP)))
                d = np.hypot(sel[:, t:, 0] - b[0], sel[:, t:, 1] - b[1])
                return not (d < sel_r[:, None] + STAND_RADIUS).any()

            route = timed_route(way, f, occupied_at, static, WALK_RADIUS, last,
                                hold if j == len(row) - 1 else None)
            if route is None:
                ok = False
                break
            pts, frames = route[3]
            ts = np.clip(frames // STEP, 0, T - 1)
            pos[k, ts] = pts
            pos[k, ts[-1]:] = b
            arr = int(frames[-1])
            if w is not None:
                arr = max(arr, int(w[0] * fps))
            arrive[(ci, gi)] = arr
            f = arr + int(CHANGE_S.get(g.kind, 0.0) * fps)
        planned[k] = True
        if not ok:
            failed.append(ci)
    return failed


def route_points(sc, legs, members=None) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``GROUP_SAMPLE`` along the routes (start, way points, goals) of ``members``
    (default: everyone), and the character of each: ((n, 2), (n,))."""
    pts, owner = [], []
    for i in (range(len(sc.characters)) if members is None else members):
        c = sc.characters[i]
        line = np.concatenate([np.asarray(c.position, float)[None]] + [way for _, way in legs[i]])
        seg = np.diff(line, axis=0)
        for a, d, L in zip(line[:-1], seg, np.hypot(*seg.T)):
            m = max(1, int(np.ceil(L / GROUP_SAMPLE)))
            pts.append(a + (np.arange(m) / m)[:, None] * d)
            owner.append(np.full(m, i))
        pts.append(line[-1:])
        owner.append(np.array([i]))
    return np.concatenate(pts), np.concatenate(owner)


def _components(n: int, edges: np.ndarray) -> list:
    """Connected components of characters 0..n-1 joined by ``edges`` (k, 2), each in index
    order, ordered by their first member."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    _, label = connected_components(coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n)),
                                    directed=False)
    groups: dict = {}
    for i in range(n):
        groups.setdefault(int(label[i]), []).append(i)
    return sorted(groups.values(), key=lambda g: g[0])


def _ties(sc) -> np.ndarray:
    names = {c.name: i for i, c in enumerate(sc.characters)}
    return np.asarray([(i, names[g.after["character"]]) for i, c in enumerate(sc.characters) for g in c.goals
                       if g.after is not None], dtype=np.int64).reshape(-1, 2)


def interaction_groups(sc, env, legs, members=None) -> list:
    """Characters whose routes (start, way points, goals) come within ``GROUP_REACH`` of each
    other with a clear line between (not through a wall), or who are tied by ``after``, as
    groups (lists of indices, each in file order; groups ordered by their first member).
    ``members``: only among these (a union of whole groups, as :func:`coarse_groups` gives)."""
    from scipy.spatial import cKDTree
    n = len(sc.characters)
    P, O = route_points(sc, legs, members)
    pairs = cKDTree(P).query_pairs(GROUP_REACH, output_type="ndarray").reshape(-1, 2)
    owners = O[pairs]
    other = owners[:, 0] != owners[:, 1]
    if env is not None and (len(env.polygons) or len(env.circles)):
        other[other] = env.segment_clear(P[pairs[other, 0]], P[pairs[other, 1]], 0.0)
    groups = _components(n, np.concatenate([owners[other], _ties(sc)]))
    if members is None:
        return groups
    inside = set(int(i) for i in members)
    return [g for g in groups if g[0] in inside]


def coarse_groups(sc, legs) -> list:
    """Unions of :func:`interaction_groups`, found without pairing points: characters with
    route points in the same or neighbouring squares of side ``GROUP_REACH`` (two points that
    close always are), or tied by ``after``. Same form as :func:`interaction_groups`."""
    P, O = route_points(sc, legs)
    cells = np.floor(P / GROUP_REACH).astype(np.int64)
    cells -= cells.min(axis=0)
    width = int(cells[:, 1].max()) + 3
    key = (cells[:, 0] + 1) * width + cells[:, 1] + 1
    rows = np.unique(np.stack([key, O], axis=1), axis=0)          # (cell, character), by cell
    key_u, first = np.unique(rows[:, 0], return_index=True)
    same = rows[1:, 0] == rows[:-1, 0]
    edges = [np.stack([rows[1:, 1][same], rows[:-1, 1][same]], axis=1)]
    for dx, dz in ((1, -1), (1, 0), (1, 1), (0, 1)):
        k2 = rows[:, 0] + dx * width + dz
        at = np.minimum(np.searchsorted(key_u, k2), len(key_u) - 1)
        hit = key_u[at] == k2
        edges.append(np.stack([rows[hit, 1], rows[first[at[hit]], 1]], axis=1))
    return _components(len(sc.characters), np.concatenate(edges + [_ties(sc)]))


def _to_front(order: list, ci: int, deps: list) -> list:
    """``order`` with ``ci`` moved as early as its ``after`` dependencies allow."""
    rest = [o for o in order if o != ci]
    k = max([rest.index(d) + 1 for d in deps[ci] if d in rest], default=0)
    return rest[:k] + [ci] + rest[k:]


def lattice_order(sc, env, roadmap, static, fps: float, n_total: int, candidates: dict, deps: list,
                  climb: int = CLIMB_STEPS, log=None) -> list:
    """The planning order chosen per interaction group by the stand-in plan (see the module
    docstring): the candidate with the fewest characters left without a route (ties: the
    earlier candidate), then up to ``climb`` hill-climbing steps, each moving the first such
    character to the front of the group, kept when fewer are left without one.

    Args:
        candidates: {name: order of all characters}, in the order they are preferred; the
            first is kept by groups over ``MAX_GROUP``.
        deps: per character, the characters whose arrivals time its goals (``after``): a
            character is never moved before them.
    """
    legs = route_legs(sc, env, roadmap)
    full = candidates
    first = next(iter(full))
    out = []
    for group in interaction_groups(sc, env, legs):
        members = set(group)
        if len(group) > MAX_GROUP:
            out += [ci for ci in full[first] if ci in members]
            if log:
                log(f"order of {len(group)} characters from {sc.characters[group[0]].name}: {first} "
                    f"(more than {MAX_GROUP} in one group)")
            continue
        best, best_f, best_how = None, None, None
        for how, whole in full.items():
            order = [ci for ci in whole if ci in members]
            if best is not None and order == best:
                continue
            f = lattice_failures(sc, static, legs, order, fps, n_total)
            if best_f is None or len(f) < len(best_f):
                best, best_f, best_how = order, f, how
            if not f:
                break
        steps = 0
        tried = set()
        while best_f and steps < climb:
            ci = next((c for c in best_f if c not in tried), None)
            if ci is None:
                break
            tried.add(ci)
            order = _to_front(best, ci, deps)
            if order == best:
                continue
            steps += 1
            f = lattice_failures(sc, static, legs, order, fps, n_total)
            if len(f) < len(best_f):
                best, best_f, best_how, tried = order, f, best_how + "+climb", set()
        if log and len(group) > 1:
            log(f"order of {len(group)} characters from {sc.characters[group[0]].name}: {best_how}, "
                f"{len(best_f)} without a stand-in route")
        out += best
    return out
