"""Space-time routes: where and when a character can walk among those planned before it.

The greedy seeds (section 3.2 of Sung, Kovar and Gleicher 2005) follow the static roadmap and
only react to planned characters edge by edge, so in a dense cross-flow or at a door they walk
into the others and the randomized search cannot repair it. This module searches a route in
space and time first, against the occupancy of the characters planned before -- the
reservation table of cooperative pathfinding (Silver 2005) and prioritized planning (van den
Berg and Overmars 2005). A disc of the walking radius moves on a lattice of cells around the
static route, one cell per time step (to any of the eight neighbours) or stays where it is; a
cell is blocked in a step when a planned character's cylinder, grown by the walker's, covers it
at the step's middle or end. The search is a wavefront over time (breadth first, all cells of a
step at once, vectorized), so the route found arrives as early as the lattice allows; two
wavefronts run side by side, one through every free cell and one through the cells with room to
spare from the walls, and the roomy route is taken unless it arrives much later (way points
beside a door post or a corner make seeds whose spliced motions cut into it). The planner uses
the route's turns as the seeds' way points and its first wait as a departure delay, and the
forward seed keeps to the whole route's timing (:class:`~.seeds.GreedySeed`'s ``schedule``).

Limits (beside the code): ``CELL`` = 0.45 m lattice and ``STEP`` = 12 frames (0.4 s at 30 Hz:
1.1 m/s straight, 1.6 m/s diagonal); the lattice covers ``CORRIDOR`` = 4 m around the static
route; planned characters are seen at two instants per step with ``SLACK`` = 0.3 m of extra
radius for their motion in between; the route keeps ``ROOMY`` = 0.3 m more from static
obstacles where that costs at most ``ROOMY_WAIT`` = 3 time steps (1.2 s); the search yields
every ``SLICE`` time steps, so a long one is spread over ticks.
"""
from __future__ import annotations

import numpy as np

from .types import Step

__all__ = ["timed_route", "timed_route_steps", "CELL", "STEP", "CORRIDOR", "SLACK", "SLICE", "ROOMY", "ROOMY_WAIT"]

CELL = 0.45         # m between lattice points
STEP = 12           # frames per time step
CORRIDOR = 4.0      # m of lattice around the static route
SLACK = 0.3         # m added to the planned characters' radii for their motion within a step
SLICE = 8           # time steps of the wavefront per yield of timed_route_steps (a few ms each)
ROOMY = 0.3         # m more clearance from static obstacles the route keeps where it can ...
ROOMY_WAIT = 3      # ... arriving up to this many time steps later than through tighter cells


def _corridor(route_xz: np.ndarray, static, radius: float):
    """Lattice points within ``CORRIDOR`` of the polyline ``route_xz`` and clear of static
    obstacles by ``radius``: (origin (2,), free (nx, nz) bool, clearance (nx, nz) in m: inf
    without obstacles)."""
    lo = route_xz.min(axis=0) - CORRIDOR
    hi = route_xz.max(axis=0) + CORRIDOR
    nx, nz = (np.ceil((hi - lo) / CELL).astype(int) + 1)
    gx, gz = np.meshgrid(lo[0] + CELL * np.arange(nx), lo[1] + CELL * np.arange(nz), indexing="ij")
    pts = np.stack([gx.ravel(), gz.ravel()], axis=1)
    a, b = route_xz[:-1], route_xz[1:]
    ab = b - a
    den = np.maximum((ab * ab).sum(1), 1e-12)
    t = np.clip(((pts[:, None, :] - a[None]) * ab[None]).sum(-1) / den[None], 0.0, 1.0)
    foot = a[None] + t[..., None] * ab[None]
    d = np.hypot(pts[:, None, 0] - foot[..., 0], pts[:, None, 1] - foot[..., 1]).min(axis=1)
    free = d <= CORRIDOR
    clear = np.asarray(static(pts), dtype=np.float64) if static is not None else np.full(len(pts), np.inf)
    free &= clear >= radius
    return lo, free.reshape(nx, nz), clear.reshape(nx, nz)


def _dilate(m: np.ndarray) -> np.ndarray:
    """Cells of ``m`` and their eight neighbours."""
    out = m.copy()
    out[1:] |= m[:-1]
    out[:-1] |= m[1:]
    row = out.copy()
    out[:, 1:] |= row[:, :-1]
    out[:, :-1] |= row[:, 1:]
    return out


def _blocked(lo, shape, xz: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Cells within ``reach`` of any of the points ``xz`` (vectorized over points and the
    cells of each one's bounding square)."""
    nx, nz = shape
    out = np.zeros(shape, dtype=bool)
    near = np.all((xz + reach[:, None] > lo - CELL) & (xz - reach[:, None] < lo + CELL * np.array(shape)), axis=1)
    xz, reach = xz[near], reach[near]
    if len(xz) == 0:
        return out
    k = int(np.ceil(reach.max() / CELL))
    off = np.arange(-k, k + 1)
    ci = np.rint((xz - lo) / CELL).astype(np.int64)
    ii = np.broadcast_to(ci[:, 0, None, None] + off[None, :, None], (len(xz), len(off), len(off)))
    jj = np.broadcast_to(ci[:, 1, None, None] + off[None, None, :], (len(xz), len(off), len(off)))
    cx = lo[0] + CELL * ii
    cz = lo[1] + CELL * jj
    hit = np.hypot(cx - xz[:, 0, None, None], cz - xz[:, 1, None, None]) < reach[:, None, None]
    hit &= (ii >= 0) & (ii < nx) & (jj >= 0) & (jj < nz)
    out[ii[hit], jj[hit]] = True
    return out


def timed_route(route_xz, start_frame: int, occupied_at, static, radius: float, last_frame: int, hold=None):
    """A route in space and time from ``route_xz[0]`` to ``route_xz[-1]`` that keeps clear of
    the characters planned before: :func:`timed_route_steps` run to its end (same arguments
    and result)."""
    steps = timed_route_steps(route_xz, start_frame, occupied_at, static, radius, last_frame, hold)
    while True:
        try:
            next(steps)
        except StopIteration as stop:
            return stop.value


def timed_route_steps(route_xz, start_frame: int, occupied_at, static, radius: float, last_frame: int, hold=None):
    """Generator: the route search time-sliced -- it yields :attr:`Step.WAYPOINTS` after every
    :data:`SLICE` time steps of the wavefront (a planner step of the World's per-tick budget)
    and returns the route.

    Args:
        route_xz: (n, 2) the static route (the roadmap's way points), start first.
        start_frame: the clock frame the character may leave at.
        occupied_at: ``occupied_at(frame) -> (xz (M, 2), radius (M,))``: where the characters
            planned before are at a frame, and their cylinders.
        static: signed distance to the obstacles, or None.
        radius: the walking disc (m, margin included).
        last_frame: the route must arrive by this frame.
        hold: ``hold(frame) -> bool``: whether standing at the goal from ``frame`` on is clear
            (a last goal), or None.

    Returns:
        (way points (m, 2) of the route's turns, the frames it is at each, the departure delay
        in frames, the whole route: ((k, 2) where it is at each time step, waits included, and
        (k,) the frames)), or None when the goal cannot be reached by ``last_frame``.
    """
    route_xz = np.asarray(route_xz, dtype=np.float64)
    lo, free, clear = _corridor(route_xz, static, radius)
    shape = free.shape

    def cell(p):
        ij = np.clip(np.rint((np.asarray(p) - lo) / CELL).astype(int), 0, np.array(shape) - 1)
        return int(ij[0]), int(ij[1])

    s_ij, g_ij = cell(route_xz[0]), cell(route_xz[-1])
    free[s_ij] = free[g_ij] = True
    roomy = free & (clear >= radius + ROOMY)
    roomy[s_ij] = roomy[g_ij] = True
    reach_now = np.zeros(shape, dtype=bool)
    reach_now[s_ij] = True
    # two wavefronts side by side: through any free cell, and through roomy cells only (way
    # points there keep the seeds off door posts and corners); the roomy route is taken
    # unless it arrives more than ROOMY_WAIT steps after the other
    layers, layers_r = [reach_now], [reach_now]
    k_max = (last_frame - start_frame) // STEP
    found = found_any = None
    for k in range(1, k_max + 1):
        if k % SLICE == 0:
            yield Step.WAYPOINTS
        f0 = start_frame + (k - 1) * STEP
        busy = np.zeros(shape, dtype=bool)
        for f in (f0 + STEP // 2, f0 + STEP):
            xz, r = occupied_at(f)
            if len(xz):
                busy |= _blocked(lo, shape, np.asarray(xz, dtype=np.float64),
                                 np.asarray(r, dtype=np.float64) + radius + SLACK)
        cand = _dilate(layers[-1]) & free & ~busy
        if not cand.any():
            break
        layers.append(cand)
        layers_r.append(_dilate(layers_r[-1]) & roomy & ~busy)
        roomy_there = layers_r[-1][g_ij]
        if cand[g_ij] and (found_any is None or roomy_there) and (hold is None or hold(f0 + STEP)):
            if roomy_there:
                found, layers = k, layers_r
                break
            found_any = k
        if found_any is not None and k - found_any >= ROOMY_WAIT:
            found = found_any
            break
    if found is None:
        found = found_any
    if found is None:
        return None
    # back from the goal: each step to a cell reachable one step earlier, nearest the start
    cells = [g_ij]
    for k in range(found, 0, -1):
        i, j = cells[-1]
        best, best_d = None, np.inf
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                p = (i + di, j + dj)
                if 0 <= p[0] < shape[0] and 0 <= p[1] < shape[1] and layers[k - 1][p]:
                    d = np.hypot(p[0] - s_ij[0], p[1] - s_ij[1]) + (0.0 if (di, dj) == (0, 0) else 1e-3)
                    if d < best_d:
                        best, best_d = p, d
        cells.append(best)
    cells = cells[::-1]
    pts = lo + CELL * np.asarray(cells, dtype=np.float64)
    pts[0], pts[-1] = route_xz[0], route_xz[-1]
    frames = start_frame + STEP * np.arange(len(cells))
    moving = np.flatnonzero(np.any(np.diff(np.asarray(cells), axis=0) != 0, axis=1))
    delay = int(frames[moving[0]] - start_frame) if len(moving) else 0
    # the turns of the route: drop waits and cells straight on
    keep = [0]
    for i in range(1, len(cells) - 1):
        d0 = np.subtract(cells[i], cells[keep[-1]])
        d1 = np.subtract(cells[i + 1], cells[i])
        if not d1.any() or (d0[0] * d1[1] - d0[1] * d1[0] == 0 and d0 @ d1 >= 0):
            continue
        keep.append(i)
    keep.append(len(cells) - 1)
    return pts[keep], frames[keep], delay, (pts, frames)
