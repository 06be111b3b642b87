"""The rules every generated scenario obeys, checked on the parsed scenario and the world as
the runtime reads them (:class:`~.params.GenParams` lists the rules). The generator runs this
check on everything it writes; it also serves users who write their own scenarios."""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from .timing import arrival_bounds, legs

__all__ = ["scenario_problems", "endpoints"]

TOL = 1e-6


def endpoints(sc) -> list:
    """(name, what, (x, z)) of every start (not on a seat) and every goal position (a seat's
    own position, a box's stand point)."""
    out = []
    for c in sc.characters:
        if c.start_marker is None:
            out.append((c.name, "start", np.asarray(c.position, float)))
        for gi, g in enumerate(c.goals):
            out.append((c.name, f"goal {gi}", np.asarray(g.position, float)))
    return out


def _clearance_problems(sc, env, p) -> list:
    out = []
    if not env.num_obstacles:
        return out
    for c in sc.characters:
        if c.start_marker is None and env.distance(np.asarray(c.position, float)[None])[0] < p.clearance - TOL:
            out.append(f"{c.name} start: closer than {p.clearance} m to an obstacle")
        for gi, g in enumerate(c.goals):
            pos = np.asarray(g.position, float)
            d = float(env.distance(pos[None])[0])
            if g.kind == "seat":
                front = pos + p.approach * np.array([math.sin(g.heading), math.cos(g.heading)])
                if d < p.seat_clearance - TOL or env.distance(front[None])[0] < p.clearance - TOL:
                    out.append(f"{c.name} goal {gi}: seat {g.marker} or the point in front of it is too close to an obstacle")
            elif d < p.clearance - TOL:
                out.append(f"{c.name} goal {gi}: closer than {p.clearance} m to an obstacle ({d:.3f} m)")
            if g.kind == "box":
                crate = env.markers[g.marker].position
                if env.distance(crate[None])[0] < p.crate_clearance - TOL:
                    out.append(f"{c.name} goal {gi}: box {g.marker} is closer than {p.crate_clearance} m to an obstacle")
    return out


def scenario_problems(sc, env, fs, p) -> list:
    """Every broken rule of the parsed scenario ``sc`` in world ``env`` (``fs``: its
    :class:`~.freespace.FreeSpace`), one sentence each; empty when the scenario is valid."""
    out = _clearance_problems(sc, env, p)
    pts = endpoints(sc)
    if len(pts) > 1:
        xz = np.array([q for _, _, q in pts])
        for i, j in sorted(cKDTree(xz).query_pairs(p.spacing - TOL)):
            out.append(f"{pts[i][0]} {pts[i][1]} and {pts[j][0]} {pts[j][1]} are "
                       f"{float(np.hypot(*(xz[i] - xz[j]))):.3f} m apart (< {p.spacing} m)")
    rows = legs(sc, fs, p)
    for c, row in zip(sc.characters, rows):
        for gi, leg in enumerate(row):
            if not math.isfinite(leg.distance):
                out.append(f"{c.name} goal {gi}: not reachable from the previous point with clearance {fs.radius} m")
    if out:
        return out
    latest = 0.0
    lo, hi = p.window_width
    try:
        bounds_all = arrival_bounds(sc, rows, p)
    except ValueError as e:
        return [f"timing: {e}"]
    for c, bounds in zip(sc.characters, bounds_all):
        for gi, (g, (E, w, late)) in enumerate(zip(c.goals, bounds)):
            latest = max(latest, late)
            if g.time is not None and not (lo - TOL <= g.time[1] - g.time[0] <= hi + TOL):
                out.append(f"{c.name} goal {gi}: window {list(g.time)} is not {lo}-{hi} s wide")
            if g.after is not None:
                a, b = g.after["within"]
                if not (lo - TOL <= b - a <= hi + TOL):
                    out.append(f"{c.name} goal {gi}: after.within {[a, b]} is not {lo}-{hi} s wide")
            if w is not None and w[0] < E - TOL:
                out.append(f"{c.name} goal {gi}: window opens at {w[0]:.2f} s, before the earliest arrival {E:.2f} s")
    if sc.duration < latest + p.margin - TOL:
        out.append(f"duration {sc.duration} s is shorter than the latest arrival {latest:.1f} s plus {p.margin} s")
    return out
