"""Way points bent around people who stand still.

The roadmap knows the obstacles, not the characters. A character that is not planned yet stands
where it starts (its start is held, :meth:`runtime.crowd.reservations.Reservations.hold`), so for
the character planned now it is a disc that will not move. The greedy seeds (section 3.2 of
Sung, Kovar and Gleicher 2005) head straight along the way points, walk into such a disc, and
the randomized search, which optimises the end error only, cannot see the collision it has to
undo. Here the way points go round the discs first: where a segment passes closer than the
clearance to a disc, a way point beside the disc is inserted, on the side the segment already
passes (or the other one when that side is blocked by an obstacle).

Limits: at most ``MAX_BENDS`` inserted points; discs within the clearance of the start or the
goal are left alone (nothing routes round a neighbour one is standing next to: the search and
the ladder deal with those); the inserted point keeps ``radius`` from the obstacles, and both new
segments are tested with :meth:`~runtime.crowd.environment.Environment.segment_clear`.
"""
from __future__ import annotations

import numpy as np

__all__ = ["bend_around", "MAX_BENDS", "BEND_EXTRA"]

MAX_BENDS = 6        # way points inserted at most
BEND_EXTRA = 0.25    # m added to the clearance for the inserted point (a stride does not follow
#                      a way point exactly)


def _first_hit(a, b, xz, reach, skip):
    """The disc that the segment ``a``-``b`` passes within ``reach`` of first (nearest ``a``
    along it): (index, foot point) or None."""
    ab = b - a
    den = max(float(ab @ ab), 1e-12)
    t = np.clip(((xz - a) @ ab) / den, 0.0, 1.0)
    foot = a + t[:, None] * ab
    d = np.hypot(*(xz - foot).T)
    hit = np.flatnonzero((d < reach) & ~skip)
    if len(hit) == 0:
        return None
    k = hit[np.argmin(t[hit])]
    return int(k), foot[k]


def bend_around(points, xz, r, radius: float, env=None) -> np.ndarray:
    """``points`` (n, 2) with way points inserted so that every segment keeps ``r + radius``
    from the discs ``xz`` (M, 2) of radii ``r`` (M,), where it can (see the module docstring).

    Args:
        points: way points, start first; the first and last are kept as they are.
        xz, r: the discs of the characters who stand still.
        radius: the walking character's radius (margin included).
        env: the static obstacles (:class:`~runtime.crowd.environment.Environment`) or None.

    Returns:
        The way points (a new array; ``points`` itself when nothing is in the way).
    """
    pts = np.asarray(points, dtype=np.float64)
    xz = np.asarray(xz, dtype=np.float64).reshape(-1, 2)
    if len(xz) == 0 or len(pts) < 2:
        return pts
    reach = np.asarray(r, dtype=np.float64) + radius
    skip = (np.hypot(*(xz - pts[0]).T) < reach) | (np.hypot(*(xz - pts[-1]).T) < reach)
    if skip.all():
        return pts
    out = [pts[0]]
    todo = list(pts[1:][::-1])            # a stack: the next way point last
    bends = 0
    while todo:
        a, b = out[-1], todo[-1]
        hit = _first_hit(a, b, xz, reach, skip) if bends < MAX_BENDS else None
        if hit is None:
            out.append(todo.pop())
            continue
        k, foot = hit
        c = xz[k]
        away = foot - c
        n = float(np.hypot(*away))
        ab = (b - a) / max(float(np.hypot(*(b - a))), 1e-12)
        side = away / n if n > 1e-6 else np.array([-ab[1], ab[0]])
        for s in (side, -side):
            p = c + s * (reach[k] + BEND_EXTRA)
            if env is not None and (env.distance(p[None])[0] < radius
                                    or not env.segment_clear(a, p, radius) or not env.segment_clear(p, b, radius)):
                continue
            todo.append(p)
            break
        bends += 1
        skip = skip.copy()
        skip[k] = True                    # placed or not, this disc is dealt with
    return pts if len(out) == len(pts) else np.asarray(out)
