"""Planar geometry of obstacle footprints on the ground plane (x, z), metres.

Obstacles are reduced to their footprints: the orthographic projection onto the ground of
their world-space geometry. Because every primitive crowdweave reads is convex (cube,
cylinder/frustum, capsule, sphere, cone) or is replaced by its convex hull (meshes), a
footprint is the convex hull of the projected geometry; the projection of a convex body is
the hull of the projections of its points. Round parts are replaced by *circumscribed*
polygons (``n`` sides, radius / cos(pi/n)) so a footprint never under-covers the obstacle;
an upright, round cylinder/capsule/sphere stays an exact circle.

Distances are exact Euclidean distances in the plane, vectorized over query points and
obstacle edges at once (``(N, E)`` arrays, chunked to bound memory):

* point to segment: ``|p - a - t (b - a)|`` with ``t = clip(<p - a, b - a> / |b - a|^2, 0, 1)``;
* segment to segment: 0 if they properly cross (orientation test), else the least of the four
  endpoint-to-segment distances;
* point in polygon: crossing number (ray towards +x) per polygon, via ``np.add.reduceat`` over
  the flat edge list.

Nothing here knows about USD; ``usd_io.world`` hands world matrices and primitive parameters
to the ``footprint_*`` functions below.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "GeometryError", "Footprint", "PolygonSet", "polygon_area", "convex_hull", "circle_polygon",
    "point_segment_distance", "point_segment_distance_xz", "segment_segment_distance", "units_matrix", "footprint_points",
    "footprint_cube", "footprint_sphere", "footprint_cylinder", "footprint_capsule", "chunk_rows", "BoxGrid",
]

CIRCLE_SIDES = 32          # sides of the circumscribed polygon replacing a round outline
_ROUND_TOL = 1e-7          # relative tolerance deciding "this projected outline is a circle"
_AREA_TOL = 1e-9           # relative (to the squared diameter) tolerance for "zero area"
_CHUNK_ELEMENTS = 1 << 21  # elements per (N, E) temporary; bounds memory of vectorized queries


class GeometryError(ValueError):
    """A footprint cannot be made (zero area, bad parameters)."""


def chunk_rows(n: int, width: int, budget: int = _CHUNK_ELEMENTS):
    """Yield ``slice`` objects splitting ``n`` rows so each ``(rows, width)`` block has about
    ``budget`` elements."""
    step = max(1, budget // max(1, width))
    for s in range(0, n, step):
        yield slice(s, min(n, s + step))


# -- polygons -----------------------------------------------------------------------------------

def polygon_area(poly) -> float:
    """Signed area (shoelace): positive for counter-clockwise vertex order in the (x, z) plane."""
    p = np.asarray(poly, dtype=np.float64)
    x, z = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(z, -1)) - np.dot(np.roll(x, -1), z))


def convex_hull(points) -> np.ndarray:
    """Counter-clockwise convex hull ``(K, 2)`` of planar points; GeometryError if the points
    span no area (all equal or collinear)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(p) < 3 or not np.all(np.isfinite(p)):
        raise GeometryError("zero footprint area" if len(p) else "no points")
    span = np.ptp(p, axis=0)
    diam2 = float(span @ span)
    if diam2 == 0.0:
        raise GeometryError("zero footprint area (all points project to one spot)")
    from scipy.spatial import ConvexHull, QhullError
    try:
        # centre first: qhull's precision is relative to the coordinates' magnitude
        c = p.mean(axis=0)
        hull = ConvexHull(p - c)
    except QhullError:
        raise GeometryError("zero footprint area (the points project onto a line)") from None
    poly = p[hull.vertices]  # counter-clockwise for 2-D hulls
    if polygon_area(poly) <= _AREA_TOL * diam2:
        raise GeometryError("zero footprint area (the points project onto a line)")
    return np.ascontiguousarray(poly)


def circle_polygon(center, radius: float, n: int = CIRCLE_SIDES) -> np.ndarray:
    """Counter-clockwise ``n``-gon circumscribing the circle (contains it)."""
    t = (np.arange(n) + 0.5) * (2 * np.pi / n)
    r = float(radius) / np.cos(np.pi / n)
    return np.asarray(center, dtype=np.float64)[None, :] + r * np.stack([np.cos(t), np.sin(t)], axis=1)


def _unit_circle(n: int) -> np.ndarray:
    """Vertices of the ``n``-gon circumscribing the unit circle, (n, 2)."""
    t = (np.arange(n) + 0.5) * (2 * np.pi / n)
    return np.stack([np.cos(t), np.sin(t)], axis=1) / np.cos(np.pi / n)


# -- distances ------------------------------------------------------------------------------------

def point_segment_distance(p, a, b) -> np.ndarray:
    """Distance from points ``p`` to segments ``a``-``b`` (all ``(..., 2)``, broadcast)."""
    p, a, b = (np.asarray(v, dtype=np.float64) for v in (p, a, b))
    ab = b - a
    den = np.sum(ab * ab, axis=-1)
    t = np.sum((p - a) * ab, axis=-1) / np.where(den > 0, den, 1.0)
    t = np.clip(np.where(den > 0, t, 0.0), 0.0, 1.0)
    d = p - (a + t[..., None] * ab)
    return np.hypot(d[..., 0], d[..., 1])


def point_segment_distance_xz(px, pz, ax, az, abx, abz, inv):
    """Point-segment distance on components (``inv`` = 1/|ab|^2, 0 for a degenerate segment)."""
    dx = px - ax
    dz = pz - az
    t = np.clip((dx * abx + dz * abz) * inv, 0.0, 1.0)
    return np.hypot(dx - t * abx, dz - t * abz)


def _inv_len2(abx, abz):
    l2 = abx * abx + abz * abz
    return np.divide(1.0, l2, out=np.zeros_like(l2), where=l2 > 0)


def _segseg(p0x, p0z, p1x, p1z, q0x, q0z, q1x, q1z):
    """Segment-segment distance on components (broadcast)."""
    dpx, dpz = p1x - p0x, p1z - p0z
    dqx, dqz = q1x - q0x, q1z - q0z
    ip = _inv_len2(dpx, dpz)
    iq = _inv_len2(dqx, dqz)
    d = np.minimum(point_segment_distance_xz(p0x, p0z, q0x, q0z, dqx, dqz, iq),
                   point_segment_distance_xz(p1x, p1z, q0x, q0z, dqx, dqz, iq))
    d = np.minimum(d, point_segment_distance_xz(q0x, q0z, p0x, p0z, dpx, dpz, ip))
    d = np.minimum(d, point_segment_distance_xz(q1x, q1z, p0x, p0z, dpx, dpz, ip))
    o1 = dpx * (q0z - p0z) - dpz * (q0x - p0x)
    o2 = dpx * (q1z - p0z) - dpz * (q1x - p0x)
    o3 = dqx * (p0z - q0z) - dqz * (p0x - q0x)
    o4 = dqx * (p1z - q0z) - dqz * (p1x - q0x)
    crossing = (o1 * o2 < 0) & (o3 * o4 < 0)
    return np.where(crossing, 0.0, d)


def segment_segment_distance(p0, p1, q0, q1) -> np.ndarray:
    """Distance between segments ``p0``-``p1`` and ``q0``-``q1`` (all ``(..., 2)``, broadcast);
    0 where they intersect."""
    p0, p1, q0, q1 = (np.asarray(v, dtype=np.float64) for v in (p0, p1, q0, q1))
    return _segseg(p0[..., 0], p0[..., 1], p1[..., 0], p1[..., 1], q0[..., 0], q0[..., 1], q1[..., 0], q1[..., 1])


class PolygonSet:
    """Many simple polygons as one flat edge list, for queries vectorized over points and edges.

    Edge ``k`` runs from ``(ax, az)[k]`` to ``(bx, bz)[k]``; polygon ``i`` owns edges
    ``starts[i] : starts[i] + counts[i]``. Each polygon also has a bounding circle
    (``center``, ``bound``) used to cull: for any point ``p`` the signed distance ``s_i(p)``
    satisfies ``|p - c_i| - R_i <= s_i(p) <= |p - c_i| + R_i`` (the polygon lies in the disk,
    so the boundary is reached within ``R_i - |p - c_i|`` from inside, and some vertex lies
    within ``|p - c_i| + R_i``). Queries evaluate exact edge distances only for (point,
    polygon) pairs the bounds cannot rule out, as one flat array of (pair, edge) rows.
    """

    def __init__(self, polygons):
        polys = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in polygons]
        self.count = len(polys)
        self.counts = np.array([len(p) for p in polys], dtype=np.int64)
        if not polys:
            a = b = np.zeros((0, 2))
            self.starts = np.zeros(0, dtype=np.int64)
            self.center = np.zeros((0, 2))
            self.bound = np.zeros(0)
        else:
            a = np.concatenate(polys)
            b = np.concatenate([np.roll(p, -1, axis=0) for p in polys])
            self.starts = (np.cumsum(self.counts) - self.counts).astype(np.int64)
            self.center = np.array([0.5 * (p.min(axis=0) + p.max(axis=0)) for p in polys])
            self.bound = np.array([np.sqrt(((p - c) ** 2).sum(axis=1).max()) for p, c in zip(polys, self.center)])
            self.bound *= 1.0 + 1e-12  # keep the bounds conservative under rounding
        self.num_edges = len(a)
        self.ax, self.az = a[:, 0].copy(), a[:, 1].copy()
        self.bx, self.bz = b[:, 0].copy(), b[:, 1].copy()
        self.abx, self.abz = self.bx - self.ax, self.bz - self.az
        self.inv = _inv_len2(self.abx, self.abz)
        dz = self.bz - self.az
        self.dxdz = np.divide(self.abx, dz, out=np.zeros_like(dz), where=dz != 0)
        self._table = np.stack([self.ax, self.az, self.abx, self.abz, self.inv, self.bz, self.dxdz])

    # -- dense (every point against every edge); used for small problems and as a reference --
    def _inside(self, px, pz):
        """(n, P) bool: crossing-number point-in-polygon test for column vectors px, pz (n, 1)."""
        straddle = (self.az > pz) != (self.bz > pz)
        cross = straddle & (px < self.ax + (pz - self.az) * self.dxdz)
        return (np.add.reduceat(cross.view(np.uint8), self.starts, axis=1) & 1).astype(bool)

    def signed_distance(self, px, pz) -> np.ndarray:
        """(n, P) signed distance of points (column vectors (n, 1)) to each polygon (negative inside)."""
        d = point_segment_distance_xz(px, pz, self.ax, self.az, self.abx, self.abz, self.inv)
        d = np.minimum.reduceat(d, self.starts, axis=1)
        return np.where(self._inside(px, pz), -d, d)

    # -- culled (pairs the bounding circles cannot rule out) -----------------------------------
    def _expand(self, polys):
        """Flat (pair, edge) rows for candidate polygons ``polys`` (one per pair): (pair index
        per row, edge index per row, offset of each pair's first row)."""
        cnt = self.counts[polys]
        off = np.cumsum(cnt) - cnt
        pair = np.repeat(np.arange(len(polys)), cnt)
        edge = np.repeat(self.starts[polys] - off, cnt) + np.arange(int(off[-1] + cnt[-1]) if len(cnt) else 0)
        return pair, edge, off

    def pair_signed(self, qx, qz, polys):
        """Signed distance of point ``(qx[k], qz[k])`` to polygon ``polys[k]`` for each pair k
        (exact; one flat array of (pair, edge) rows)."""
        if len(polys) == 0:
            return np.zeros(0)
        pair, e, off = self._expand(polys)
        ax, az, abx, abz, inv, bz, dxdz = np.take(self._table, e, axis=1)
        qx, qz = qx[pair], qz[pair]
        dx = qx - ax
        dz = qz - az
        t = np.clip((dx * abx + dz * abz) * inv, 0.0, 1.0)
        ex = dx - t * abx
        ez = dz - t * abz
        d = np.sqrt(np.minimum.reduceat(ex * ex + ez * ez, off))
        cross = ((az > qz) != (bz > qz)) & (dx < dz * dxdz)
        inside = (np.add.reduceat(cross.view(np.uint8), off) & 1).astype(bool)
        return np.where(inside, -d, d)

    def segments_blocked(self, p0x, p0z, p1x, p1z, radius) -> np.ndarray:
        """(n,) bool: segment k comes closer than ``radius[k]`` to some polygon or starts inside
        one (then, crossing no edge, it lies inside)."""
        n = len(p0x)
        bad = np.zeros(n, dtype=bool)
        if self.count == 0 or n == 0:
            return bad
        dx, dz = p1x - p0x, p1z - p0z
        l2 = dx * dx + dz * dz
        inv = np.divide(1.0, l2, out=np.zeros_like(l2), where=l2 > 0)
        dc = point_segment_distance_xz(self.center[None, :, 0], self.center[None, :, 1], p0x[:, None], p0z[:, None],
                 dx[:, None], dz[:, None], inv[:, None])
        rows, polys = np.nonzero(dc <= self.bound[None, :] + radius[:, None])
        bad[self.pairs_blocked(p0x, p0z, p1x, p1z, radius, rows, polys)] = True
        return bad

    def pairs_blocked(self, p0x, p0z, p1x, p1z, radius, rows, polys) -> np.ndarray:
        """Segments (of ``rows``) that come closer than ``radius`` to polygon ``polys[k]`` or
        start inside it, over candidate pairs ``(rows[k], polys[k])``; returns segment indices
        (with repeats)."""
        if len(rows) == 0:
            return np.zeros(0, dtype=np.int64)
        pair, e, off = self._expand(polys)
        rp = rows[pair]
        ax, az, bx, bz = self.ax[e], self.az[e], self.bx[e], self.bz[e]
        d = _segseg(p0x[rp], p0z[rp], p1x[rp], p1z[rp], ax, az, bx, bz)
        near = rp[(d < radius[rp]) | (d <= 0.0)]  # touching counts as blocked, also for radius 0
        qx, qz = p0x[rp], p0z[rp]
        cross = ((az > qz) != (bz > qz)) & (qx < ax + (qz - az) * self.dxdz[e])
        inside = (np.add.reduceat(cross.view(np.uint8), off) & 1).astype(bool)
        return np.concatenate([near, rows[inside]])

    def segment_distance(self, p0x, p0z, p1x, p1z) -> np.ndarray:
        """(n,) distance from segments (column vectors (n, 1)) to the nearest polygon edge (dense)."""
        d = _segseg(p0x, p0z, p1x, p1z, self.ax, self.az, self.bx, self.bz)
        return d.min(axis=1)

    def inside_any(self, px, pz) -> np.ndarray:
        """(n,) bool: the point (column vectors (n, 1)) lies inside at least one polygon (dense)."""
        return self._inside(px, pz).any(axis=1)


class BoxGrid:
    """Axis-aligned boxes binned on a uniform grid: which boxes a query box overlaps, in time that
    grows with the number of answers rather than with the number of boxes.

    Each box is registered in every cell it overlaps; a query visits the cells its own box
    overlaps and reports a (query, box) pair once, in the cell where both boxes' lower corners
    meet (the lowest cell of the overlap), so no pair needs de-duplicating. A query box covering
    more cells than there are boxes is tested against every box instead. The cell is the larger
    of the median box size and the side of a square holding one box on average over the boxes'
    bounds, so one box rarely spans many cells and a query box of about a box's size few.
    """

    MAX_CELLS_PER_SIDE = 4096

    def __init__(self, lo, hi):
        self.lo = np.ascontiguousarray(lo, dtype=np.float64).reshape(-1, 2)
        self.hi = np.ascontiguousarray(hi, dtype=np.float64).reshape(-1, 2)
        self.count = k = len(self.lo)
        if k == 0:
            return
        self.origin = self.lo.min(axis=0)
        span = np.maximum(self.hi.max(axis=0) - self.origin, 1e-9)
        size = float(np.median(np.max(self.hi - self.lo, axis=1)))
        self.cell = max(size, float(np.sqrt(span[0] * span[1] / k)), float(span.max()) / self.MAX_CELLS_PER_SIDE, 1e-9)
        self.shape = (np.floor(span / self.cell).astype(np.int64) + 1)
        c0, c1 = self._cells(self.lo), self._cells(self.hi)
        self.first = c0                                   # (k, 2) lowest cell of each box
        w = c1 - c0 + 1
        n = w[:, 0] * w[:, 1]
        box = np.repeat(np.arange(k), n)
        j = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
        key = (c0[box, 0] + j // w[box, 1]) * self.shape[1] + c0[box, 1] + j % w[box, 1]
        order = np.argsort(key, kind="stable")
        self.items = box[order]
        self.start = np.zeros(int(self.shape[0] * self.shape[1]) + 1, dtype=np.int64)
        np.cumsum(np.bincount(key, minlength=len(self.start) - 1), out=self.start[1:])
        self.per_cell = max(1.0, len(self.items) / max(1, int(np.count_nonzero(np.diff(self.start)))))

    def _cells(self, p):
        return np.clip(np.floor((p - self.origin) / self.cell).astype(np.int64), 0, self.shape - 1)

    def pairs(self, qlo, qhi, budget: int = _CHUNK_ELEMENTS):
        """Yield ``(rows, ids)``: every pair of query box ``rows[k]`` (``qlo``, ``qhi`` (n, 2)) and
        box ``ids[k]`` that overlap (closed boxes), each pair once, rows ascending; in chunks of
        about ``budget`` pairs."""
        qlo = np.asarray(qlo, dtype=np.float64).reshape(-1, 2)
        qhi = np.asarray(qhi, dtype=np.float64).reshape(-1, 2)
        n = len(qlo)
        if self.count == 0 or n == 0:
            return
        c0, c1 = self._cells(qlo), self._cells(qhi)
        w = c1 - c0 + 1
        ncell = w[:, 0] * w[:, 1]
        dense = ncell > self.count
        cost = np.where(dense, self.count, np.ceil(ncell * self.per_cell)).astype(np.int64)
        csum = np.cumsum(cost)
        q0 = 0
        while q0 < n:
            base = csum[q0 - 1] if q0 else 0
            q1 = max(q0 + 1, int(np.searchsorted(csum, base + budget, side="right")))
            q = np.arange(q0, min(q1, n))
            q0 = q[-1] + 1
            rows, ids = self._chunk(q[~dense[q]], c0, w, ncell)
            qd = q[dense[q]]
            if len(qd):
                rows = np.concatenate([rows, np.repeat(qd, self.count)])
                ids = np.concatenate([ids, np.tile(np.arange(self.count), len(qd))])
                order = np.argsort(rows, kind="stable")
                rows, ids = rows[order], ids[order]
            keep = np.all((self.lo[ids] <= qhi[rows]) & (self.hi[ids] >= qlo[rows]), axis=1)
            yield rows[keep], ids[keep]

    def _chunk(self, q, c0, w, ncell):
        """Pairs of the queries ``q`` through the cells they overlap (each pair once)."""
        if len(q) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        nc = ncell[q]
        rq = np.repeat(q, nc)
        j = np.arange(int(nc.sum())) - np.repeat(np.cumsum(nc) - nc, nc)
        cx = c0[rq, 0] + j // w[rq, 1]
        cz = c0[rq, 1] + j % w[rq, 1]
        key = cx * self.shape[1] + cz
        cnt = self.start[key + 1] - self.start[key]
        rows = np.repeat(rq, cnt)
        off = np.cumsum(cnt) - cnt
        ids = self.items[np.repeat(self.start[key] - off, cnt) + np.arange(int(cnt.sum()))]
        # report the pair only in the lowest cell of the two boxes' overlap
        cx, cz = np.repeat(cx, cnt), np.repeat(cz, cnt)
        f = self.first[ids]
        own = (cx == np.maximum(c0[rows, 0], f[:, 0])) & (cz == np.maximum(c0[rows, 1], f[:, 1]))
        return rows[own], ids[own]


# -- footprints of primitives ------------------------------------------------------------------

@dataclass
class Footprint:
    """Ground footprint of one obstacle: ``kind`` "polygon" (``polygon`` (K, 2) CCW) or
    "circle" (``circle`` = (x, z, radius))."""
    kind: str
    polygon: np.ndarray | None = None
    circle: np.ndarray | None = None

    @property
    def area(self) -> float:
        if self.kind == "circle":
            return float(np.pi * self.circle[2] ** 2)
        return polygon_area(self.polygon)

    def as_polygon(self, n: int = CIRCLE_SIDES) -> np.ndarray:
        if self.kind == "circle":
            return circle_polygon(self.circle[:2], self.circle[2], n)
        return self.polygon


def units_matrix(meters_per_unit: float, up_axis: str) -> np.ndarray:
    """4x4 (column-vector convention) taking a stage's world coordinates to crowdweave's:
    metres, Y up. A Z-up stage is rotated -90 degrees about X: (x, y, z)_Z-up -> (x, z, -y)."""
    m = float(meters_per_unit)
    if not (np.isfinite(m) and m > 0):
        raise GeometryError(f"metersPerUnit must be positive, got {meters_per_unit}")
    K = np.eye(4)
    if str(up_axis).upper() == "Z":
        K[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    elif str(up_axis).upper() != "Y":
        raise GeometryError(f"upAxis must be 'Y' or 'Z', got {up_axis!r}")
    K[:3, :3] *= m
    return K


def _check_matrix(T):
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise GeometryError("transform is not a finite 4x4 matrix")
    return T


def _project(T, pts):
    """World (x, z) of local points (N, 3) under the 4x4 ``T``."""
    w = np.asarray(pts, dtype=np.float64) @ T[:3, :3].T + T[:3, 3]
    return w[:, [0, 2]]


def _round_radius(S):
    """sqrt(lambda) if the 2x2 PSD matrix S is (close to) lambda * I, else None."""
    lam = 0.5 * (S[0, 0] + S[1, 1])
    if lam <= 0:
        return None
    if abs(S[0, 1]) <= _ROUND_TOL * lam and abs(S[0, 0] - S[1, 1]) <= _ROUND_TOL * lam:
        return float(np.sqrt(lam))
    return None


def _sqrtm2(S):
    w, V = np.linalg.eigh(S)
    return (V * np.sqrt(np.clip(w, 0.0, None))) @ V.T


def _finite_nonneg(name, v):
    v = float(v)
    if not np.isfinite(v):
        raise GeometryError(f"{name} is not finite ({v})")
    if v < 0:
        raise GeometryError(f"{name} is negative ({v:g})")
    return v


_AXES = {"X": (np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0])),
         "Y": (np.array([0, 1.0, 0]), np.array([0, 0, 1.0]), np.array([1.0, 0, 0])),
         "Z": (np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))}


def _axis(axis):
    a = str(axis).upper()
    if a not in _AXES:
        raise GeometryError(f"axis must be X, Y or Z, got {axis!r}")
    return _AXES[a]


def footprint_points(T, points) -> Footprint:
    """Convex hull of the projected points (a Mesh's points)."""
    T = _check_matrix(T)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        raise GeometryError("no points")
    if not np.all(np.isfinite(p)):
        raise GeometryError("points are not finite")
    return Footprint("polygon", polygon=convex_hull(_project(T, p)))


def footprint_cube(T, size: float) -> Footprint:
    """Cube of edge ``size`` centred at the origin: hull of its 8 projected corners (exact)."""
    T = _check_matrix(T)
    s = _finite_nonneg("size", size)
    if s == 0:
        raise GeometryError("zero footprint area (size is 0)")
    c = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64) * (s / 2)
    return Footprint("polygon", polygon=convex_hull(_project(T, c)))


def _ball_outline(T, center_local, r, n):
    """Projected outline of the ball ``|x - c| <= r`` under T: (center (2,), L (2, 2)) with the
    ellipse {center + L w : |w| <= 1}."""
    B = T[[0, 2], :3] * r
    return _project(T, center_local[None, :])[0], _sqrtm2(B @ B.T)


def footprint_sphere(T, radius: float, n: int = CIRCLE_SIDES) -> Footprint:
    """Sphere: an ellipse in general (non-uniform scale), a circle when the projection is round."""
    T = _check_matrix(T)
    r = _finite_nonneg("radius", radius)
    if r == 0:
        raise GeometryError("zero footprint area (radius is 0)")
    c, L = _ball_outline(T, np.zeros(3), r, n)
    rr = _round_radius(L @ L.T)
    if rr is not None:
        return Footprint("circle", circle=np.array([c[0], c[1], rr]))
    return Footprint("polygon", polygon=convex_hull(c + _unit_circle(n) @ L.T))


def _round_solid(T, radius_bottom, radius_top, height):
    """The checked matrix, radii and height of a cylinder or capsule (not both radii 0)."""
    T = _check_matrix(T)
    rb = _finite_nonneg("radius", radius_bottom)
    rt = _finite_nonneg("radius", radius_top)
    h = _finite_nonneg("height", height)
    if max(rb, rt) == 0:
        raise GeometryError("zero footprint area (radius is 0)")
    return T, rb, rt, h


def footprint_cylinder(T, radius_bottom: float, radius_top: float, height: float, axis: str = "Y",
                       n: int = CIRCLE_SIDES) -> Footprint:
    """Cylinder or frustum (``radius_top`` may differ; a cone has ``radius_top = 0``) along the
    local ``axis``, centred at the origin. A circle when its world axis is vertical and its
    cross-section projects round; otherwise the hull of both end disks' circumscribed polygons."""
    T, rb, rt, h = _round_solid(T, radius_bottom, radius_top, height)
    e, u, v = _axis(axis)
    ends = np.stack([-0.5 * h * e, 0.5 * h * e])
    pe = _project(T, ends)
    Bd = T[[0, 2], :3] @ np.stack([u, v], axis=1)  # projected cross-section basis (2, 2)
    rr = _round_radius(Bd @ Bd.T)
    if rr is not None and np.hypot(*(pe[1] - pe[0])) <= 1e-6 * rr * max(rb, rt):
        c = pe.mean(axis=0)
        return Footprint("circle", circle=np.array([c[0], c[1], rr * max(rb, rt)]))
    ring = _unit_circle(n) @ Bd.T
    pts = np.concatenate([pe[0] + rb * ring, pe[1] + rt * ring])
    return Footprint("polygon", polygon=convex_hull(pts))


def footprint_capsule(T, radius_bottom: float, radius_top: float, height: float, axis: str = "Y",
                      n: int = CIRCLE_SIDES) -> Footprint:
    """Capsule: a spine of length ``height`` along ``axis`` with spherical caps (radii may
    differ); footprint = hull of the two caps' projected balls (a circle when upright and round)."""
    T, rb, rt, h = _round_solid(T, radius_bottom, radius_top, height)
    e, _, _ = _axis(axis)
    c0, L = _ball_outline(T, -0.5 * h * e, 1.0, n)
    c1, _ = _ball_outline(T, 0.5 * h * e, 1.0, n)
    rr = _round_radius(L @ L.T)
    if rr is not None and np.hypot(*(c1 - c0)) <= 1e-6 * rr * max(rb, rt):
        c = 0.5 * (c0 + c1)
        return Footprint("circle", circle=np.array([c[0], c[1], rr * max(rb, rt)]))
    ring = _unit_circle(n) @ L.T
    return Footprint("polygon", polygon=convex_hull(np.concatenate([c0 + rb * ring, c1 + rt * ring])))
