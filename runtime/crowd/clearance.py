"""Clearance from static obstacles, read from a sampled signed-distance grid, compiled.

:class:`~runtime.crowd.environment.SDFGrid` samples the environment's signed distance on a
grid; :func:`sample_grid` is its bilinear lookup (outside the grid: the distance to the grid
plus the grid's margin, a lower bound), one compiled loop over the points when numba is
installed. :class:`Clearance` is the planners' static test: the sampled distance minus an
offset (the grid's interpolation error bound, so clearance is never overestimated), a
callable that also exposes its grid so compiled kernels (the randomized search's static
filter, :func:`runtime.crowd.planner.kernels.pairs_static_clear`) read it directly.
"""
from __future__ import annotations

import math

import numpy as np

try:  # pragma: no cover - depends on the environment
    import numba as _nb
except Exception:
    _nb = None

__all__ = ["AVAILABLE", "ENABLED", "Clearance", "sample_grid", "sdf_bilinear", "with_discs"]

AVAILABLE = _nb is not None
ENABLED = AVAILABLE


def _bilinear(x, z, ox, oz, res, values, margin):
    """Signed distance at (x, z) from the grid ``values`` (origin, resolution); outside the
    grid, the distance to it plus ``margin``."""
    nx, nz = values.shape
    fx = (x - ox) / res
    fz = (z - oz) / res
    if 0.0 <= fx <= nx - 1 and 0.0 <= fz <= nz - 1:
        i = min(int(math.floor(fx)), nx - 2) if nx > 1 else 0
        j = min(int(math.floor(fz)), nz - 2) if nz > 1 else 0
        u = fx - i
        v = fz - j
        i1 = min(i + 1, nx - 1)
        j1 = min(j + 1, nz - 1)
        return ((1 - u) * (1 - v) * values[i, j] + u * (1 - v) * values[i1, j]
                + (1 - u) * v * values[i, j1] + u * v * values[i1, j1])
    hx = ox + res * (nx - 1)
    hz = oz + res * (nz - 1)
    dx = max(max(ox - x, x - hx), 0.0)
    dz = max(max(oz - z, z - hz), 0.0)
    return math.hypot(dx, dz) + margin


if AVAILABLE:
    sdf_bilinear = _nb.njit(cache=True, boundscheck=False, nogil=True)(_bilinear)

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _sample_points(p, ox, oz, res, values, margin, out):  # pragma: no cover - compiled
        for k in range(len(p)):
            out[k] = sdf_bilinear(p[k, 0], p[k, 1], ox, oz, res, values, margin)
else:  # pragma: no cover - without numba
    sdf_bilinear = _bilinear
    _sample_points = None


def sample_grid(points: np.ndarray, origin, resolution: float, values: np.ndarray, margin: float):
    """Bilinear signed distance at ``points`` (n, 2) (compiled; None when numba is not in use,
    and the caller runs its numpy path)."""
    if not ENABLED:
        return None
    out = np.empty(len(points))
    _sample_points(np.ascontiguousarray(points, dtype=np.float64), float(origin[0]), float(origin[1]),
                   float(resolution), values, float(margin), out)
    return out


class Clearance:
    """Clearance from static obstacles: ``grid.sample(xz) - offset`` (metres, ``xz`` (..., 2)).

    Args:
        grid: an :class:`~runtime.crowd.environment.SDFGrid`.
        offset: subtracted from every sample (use ``grid.max_error``: never overestimate).
    """

    def __init__(self, grid, offset: float):
        self.grid = grid
        self.offset = float(offset)

    def __call__(self, xz) -> np.ndarray:
        return self.grid.sample(xz) - self.offset

    @property
    def compiled_args(self):
        """(origin x, origin z, resolution, values, outside margin, offset) for compiled
        kernels, or None when the grid cannot be read by them (no margin: exact distance
        outside; no obstacles)."""
        g = self.grid
        if g.margin is None or g.env.num_obstacles == 0:
            return None
        return (float(g.origin[0]), float(g.origin[1]), float(g.resolution), g.values, float(g.margin), self.offset)


def with_discs(base: Clearance, xz, radius, pad: float) -> Clearance:
    """``base`` with discs added as obstacles (centres ``xz`` (M, 2), ``radius`` (M,)): the
    union's distance, min(base, |p - c| - r), written into a copy of the grid within ``pad``
    of each disc's edge. Beyond ``pad`` the copy may overestimate the distance to a disc,
    so a caller must not read it there for a decision that a disc closer than ``pad`` would
    change (the static filter's parts reach less than ``pad`` from where they are read).
    Discs outside the grid are left out."""
    g = base.grid
    vals = g.values.copy()
    h = g.resolution
    nx, nz = vals.shape
    for (cx, cz), r in zip(np.asarray(xz, dtype=np.float64), np.asarray(radius, dtype=np.float64)):
        reach = r + pad
        i0 = max(int(np.floor((cx - reach - g.origin[0]) / h)), 0)
        i1 = min(int(np.ceil((cx + reach - g.origin[0]) / h)) + 1, nx)
        j0 = max(int(np.floor((cz - reach - g.origin[1]) / h)), 0)
        j1 = min(int(np.ceil((cz + reach - g.origin[1]) / h)) + 1, nz)
        if i0 >= i1 or j0 >= j1:
            continue
        px = g.origin[0] + h * np.arange(i0, i1)
        pz = g.origin[1] + h * np.arange(j0, j1)
        d = np.hypot(px[:, None] - cx, pz[None, :] - cz) - r
        np.minimum(vals[i0:i1, j0:j1], d, out=vals[i0:i1, j0:j1])
    return Clearance(type(g)(g.origin, h, vals, g.env, g.margin), base.offset)
