"""The environment of goal-directed crowds (Sung, Kovar and Gleicher 2005, section 3): obstacle footprints on the
ground plane and the world's markers (seats, boxes, spawn points, regions).

Obstacles are 2D footprints in (x, z) metres: simple counter-clockwise polygons and circles
(``usd_io.world`` builds them from a world stage; ``runtime.crowd.geometry`` has the maths).
Queries are vectorized over query points and over all obstacle edges at once:

* :meth:`Environment.distance` -- exact signed distance to the nearest obstacle (negative
  inside). Outside every obstacle it is the exact Euclidean distance to the union of the
  obstacles. Inside, it is minus the depth below the surface of the obstacle one is deepest in;
  where obstacles overlap the true depth below the union's surface can only be larger, so the
  value is never more negative than the truth and the sign is always right.
* :meth:`Environment.segment_clear` -- whether a straight move keeps a clearance ``radius``
  (the character's bounding cylinder) from every obstacle: exact segment-polygon and
  segment-circle distances (the roadmap's "mutually visible" test, section 3.2, with obstacles
  grown by the character radius).
* :meth:`Environment.sdf` -- the signed distance sampled on a regular grid (:class:`SDFGrid`)
  for cheap per-frame lookups, with a documented error bound.

An environment is immutable once built; :meth:`Environment.fingerprint` identifies its
obstacle geometry (cached roadmaps store it to detect staleness).
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass

import numpy as np

from .clearance import sample_grid
from .geometry import BoxGrid, PolygonSet, chunk_rows, point_segment_distance_xz, polygon_area

__all__ = ["Marker", "Environment", "SDFGrid", "MARKER_ROLES"]

MARKER_ROLES = ("seat", "box", "spawn", "region")
DICT_VERSION = 1
_DENSE_LIMIT = 1 << 15  # point-edge pairs below which distance() evaluates densely


@dataclass(eq=False)
class Marker:
    """A named spot in the world: ``role`` "seat" | "box" | "spawn" | "region".

    ``position`` (2,) is (x, z) metres; ``heading`` radians about +Y, 0 facing +Z (the
    marker's forward axis projected on the ground); ``polygon`` (K, 2) is the footprint of a
    region (None for other roles)."""
    path: str
    role: str
    position: np.ndarray
    heading: float
    polygon: np.ndarray | None = None

    def __post_init__(self):
        if self.role not in MARKER_ROLES:
            raise ValueError(f"marker {self.path}: unknown role {self.role!r} (expected one of {', '.join(MARKER_ROLES)})")
        self.position = np.asarray(self.position, dtype=np.float64).reshape(2)
        self.heading = float(self.heading)
        if self.polygon is not None:
            self.polygon = np.asarray(self.polygon, dtype=np.float64).reshape(-1, 2)

    def to_dict(self) -> dict:
        return {"path": self.path, "role": self.role, "position": [float(v) for v in self.position],
                "heading": self.heading, "polygon": None if self.polygon is None else self.polygon.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> "Marker":
        return cls(str(d["path"]), str(d["role"]), d["position"], d["heading"], d.get("polygon"))


def _as_points(xz):
    a = np.asarray(xz, dtype=np.float64)
    if a.shape[-1:] != (2,):
        raise ValueError(f"expected points shaped (..., 2), got {a.shape}")
    return a


class Environment:
    """Obstacle footprints and markers. See the module docstring for the queries' semantics."""

    def __init__(self, polygons=(), circles=None, markers=None, obstacle_paths=None):
        polys = []
        for i, p in enumerate(polygons):
            p = np.array(p, dtype=np.float64).reshape(-1, 2)
            if len(p) < 3 or not np.all(np.isfinite(p)):
                raise ValueError(f"obstacle polygon {i} needs at least 3 finite vertices")
            a = polygon_area(p)
            if a == 0:
                raise ValueError(f"obstacle polygon {i} has zero area")
            polys.append(np.ascontiguousarray(p if a > 0 else p[::-1]))
        self.polygons: list[np.ndarray] = polys
        c = np.zeros((0, 3)) if circles is None else np.array(circles, dtype=np.float64).reshape(-1, 3)
        if len(c) and (not np.all(np.isfinite(c)) or np.any(c[:, 2] <= 0)):
            raise ValueError("obstacle circles need finite centres and positive radii")
        self.circles: np.ndarray = c
        n = len(polys) + len(c)
        if obstacle_paths is None:
            obstacle_paths = [f"polygon[{i}]" for i in range(len(polys))] + [f"circle[{i}]" for i in range(len(c))]
        self.obstacle_paths: list[str] = [str(p) for p in obstacle_paths]
        if len(self.obstacle_paths) != n:
            raise ValueError(f"{len(self.obstacle_paths)} obstacle paths for {n} obstacles")
        if isinstance(markers, dict):
            markers = list(markers.values())
        self.markers: dict[str, Marker] = {m.path: m for m in (markers or [])}
        self._pset = PolygonSet(polys)
        self._fingerprint = None
        self._bounds_cache = None
        self._box_grid = None
        self._centre_tree = None

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def open_ground(cls) -> "Environment":
        """No obstacles, no markers."""
        return cls()

    def to_dict(self) -> dict:
        """Plain lists and floats (for packs and JSON)."""
        return {"version": DICT_VERSION,
                "polygons": [p.tolist() for p in self.polygons],
                "circles": self.circles.tolist(),
                "obstacle_paths": list(self.obstacle_paths),
                "markers": [m.to_dict() for m in self.markers.values()]}

    @classmethod
    def from_dict(cls, d: dict) -> "Environment":
        if not isinstance(d, dict) or d.get("version") != DICT_VERSION:
            raise ValueError(f"not an environment dict of version {DICT_VERSION}")
        return cls(d["polygons"], d["circles"], [Marker.from_dict(m) for m in d["markers"]], d["obstacle_paths"])

    def fingerprint(self) -> str:
        """sha256 (hex) of the obstacle geometry (polygons and circles, in order). Markers and
        prim paths do not change free space, so they are not part of it."""
        if self._fingerprint is None:
            body = json.dumps({"polygons": [p.tolist() for p in self.polygons], "circles": self.circles.tolist()},
                              sort_keys=True, separators=(",", ":"))
            self._fingerprint = hashlib.sha256(body.encode()).hexdigest()
        return self._fingerprint

    # -- simple queries ------------------------------------------------------------------------
    @property
    def num_obstacles(self) -> int:
        return len(self.polygons) + len(self.circles)

    def obstacle_area(self, i: int) -> float:
        if i < len(self.polygons):
            return polygon_area(self.polygons[i])
        return float(np.pi * self.circles[i - len(self.polygons), 2] ** 2)

    def markers_with_role(self, role: str) -> list[Marker]:
        if role not in MARKER_ROLES:
            raise ValueError(f"unknown marker role {role!r} (expected one of {', '.join(MARKER_ROLES)})")
        return [m for m in self.markers.values() if m.role == role]

    def bounds(self, margin: float = 0.0):
        """(xmin, zmin, xmax, zmax) of obstacles and markers, grown by ``margin``; an empty
        environment gives a box of half-size ``margin`` around the origin."""
        pts = list(self.polygons)
        if len(self.circles):
            c, r = self.circles[:, :2], self.circles[:, 2:]
            pts += [c - r, c + r]
        for m in self.markers.values():
            pts.append(m.position[None, :])
            if m.polygon is not None:
                pts.append(m.polygon)
        if not pts:
            return (-margin, -margin, margin, margin)
        p = np.concatenate(pts)
        lo, hi = p.min(axis=0) - margin, p.max(axis=0) + margin
        return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))

    # -- distances -------------------------------------------------------------------------------
    def distance(self, xz, return_index: bool = False):
        """Signed distance (...,) from points ``xz`` (..., 2) to the nearest obstacle, negative
        inside (see the module docstring); +inf with no obstacles. With ``return_index`` also
        the index (into ``obstacle_paths``) of the nearest obstacle (-1 with none).

        Vectorized over points and obstacles: few points against every obstacle, many through
        bounding-circle culling of the obstacles near each point (:meth:`_near_pairs`), exact
        for every point."""
        pts = _as_points(xz)
        shape = pts.shape[:-1]
        flat = pts.reshape(-1, 2)
        n = len(flat)
        out = np.full(n, np.inf)
        idx = np.full(n, -1, dtype=np.int64)
        if self.num_obstacles > 0 and 0 < n * (self._pset.num_edges + len(self.circles)) <= _DENSE_LIMIT:
            # few points: every point against every edge is cheaper than tiling
            px, pz = flat[:, 0:1], flat[:, 1:2]
            parts = [self._pset.signed_distance(px, pz)] if self.polygons else []
            if len(self.circles):
                parts.append(np.hypot(px - self.circles[:, 0], pz - self.circles[:, 1]) - self.circles[:, 2])
            d = np.concatenate(parts, axis=1) if len(parts) > 1 else parts[0]
            idx[:] = np.argmin(d, axis=1)
            out[:] = d[np.arange(n), idx]
        elif self.num_obstacles > 0 and n > 0:
            bad = ~np.all(np.isfinite(flat), axis=1)
            if bad.any():      # no nearest obstacle for a point that is nowhere
                out[bad] = np.nan
                flat = np.where(bad[:, None], 0.0, flat)
            for rows, obs in self._near_pairs(flat):
                if len(rows) == 0:
                    continue
                d = self._pair_distance(flat[rows, 0], flat[rows, 1], obs)
                # pairs of one point are contiguous: reduce each run
                first = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
                mins = np.minimum.reduceat(d, first)
                out[rows[first]] = mins
                if return_index:
                    runs = np.diff(np.r_[first, len(rows)])
                    pos = np.where(d == np.repeat(mins, runs), np.arange(len(d)), len(d))
                    idx[rows[first]] = obs[np.minimum.reduceat(pos, first)]
            if bad.any():
                out[bad], idx[bad] = np.nan, -1
        if return_index:
            return out.reshape(shape), idx.reshape(shape)
        return out.reshape(shape)

    # Bounding circles of all obstacles (polygons first): s_i(p) lies within
    # [|p - c_i| - lo_i, |p - c_i| + hi_i] for every point p.
    def _obstacle_bounds(self):
        if self._bounds_cache is None:
            c = np.concatenate([self._pset.center, self.circles[:, :2]])
            lo = np.concatenate([self._pset.bound, self.circles[:, 2]])
            hi = np.concatenate([self._pset.bound, -self.circles[:, 2]])
            self._bounds_cache = (c, lo, hi)
        return self._bounds_cache

    def _near_pairs(self, flat, budget: int = 1 << 21):
        """Candidate (point, obstacle) pairs, in chunks: an upper bound of each point's distance
        comes from the obstacles with the 4 nearest bounding-circle centres (``|p - c| + hi``);
        every obstacle whose bounding circle reaches within that bound (found through the
        obstacle grid) is a candidate, so the nearest obstacle of every point is kept and the
        work grows with the obstacles near each point, not with all of them. Yields (rows, obs)
        with each point's pairs contiguous; about ``budget`` (pair, edge) rows per chunk."""
        c, lo, hi = self._obstacle_bounds()
        if self._centre_tree is None:
            from scipy.spatial import cKDTree
            self._centre_tree = cKDTree(c)
        k = min(4, len(c))
        dk, ik = self._centre_tree.query(flat, k=k)
        dk, ik = dk.reshape(len(flat), k), ik.reshape(len(flat), k)
        ub = np.min(dk + hi[ik], axis=1)
        ub = ub + 1e-9 * (1.0 + np.abs(ub))          # the bound is used with rounding-safe slack
        reach = np.maximum(ub, 0.0)[:, None]
        per = max(1, self._pset.num_edges // max(1, len(self.polygons)))
        for rows, obs in self._grid().pairs(flat - reach, flat + reach, budget=max(1, budget // per)):
            r = np.hypot(flat[rows, 0] - c[obs, 0], flat[rows, 1] - c[obs, 1])
            keep = r - lo[obs] <= ub[rows]
            yield rows[keep], obs[keep]

    def _pair_distance(self, qx, qz, obs):
        """Signed distance of point k to obstacle ``obs[k]`` (polygon or circle index)."""
        P = len(self.polygons)
        d = np.empty(len(obs))
        isp = obs < P
        if isp.any():
            d[isp] = self._pset.pair_signed(qx[isp], qz[isp], obs[isp])
        if not isp.all():
            ci = obs[~isp] - P
            d[~isp] = np.hypot(qx[~isp] - self.circles[ci, 0], qz[~isp] - self.circles[ci, 1]) - self.circles[ci, 2]
        return d

    def segment_clear(self, a, b, radius) -> np.ndarray:
        """(...,) bool: the straight segment ``a`` -> ``b`` (each (..., 2), broadcast) keeps at
        least ``radius`` (scalar or broadcastable to (...)) from every obstacle and neither
        touches nor lies inside one. Exact segment-polygon and segment-circle distances, vectorized over
        segments and obstacles (polygons culled by their bounding circles)."""
        a, b = np.broadcast_arrays(_as_points(a), _as_points(b))
        shape = a.shape[:-1]
        r = np.broadcast_to(np.asarray(radius, dtype=np.float64), shape).reshape(-1)
        A, B = a.reshape(-1, 2), b.reshape(-1, 2)
        n = len(A)
        ok = np.ones(n, dtype=bool)
        P, M = len(self.polygons), len(self.circles)
        if P + M == 0 or n == 0:
            return ok.reshape(shape)
        if n * (P + M) > _DENSE_LIMIT:
            return ~self._segments_blocked_grid(A, B, r).reshape(shape)
        for sl in chunk_rows(n, P + M + self._pset.num_edges // 2):
            p0x, p0z, p1x, p1z = A[sl, 0], A[sl, 1], B[sl, 0], B[sl, 1]
            rr = r[sl]
            good = ~self._pset.segments_blocked(p0x, p0z, p1x, p1z, rr)
            if M:
                cx, cz, cr = self.circles[:, 0], self.circles[:, 1], self.circles[:, 2]
                abx, abz = (p1x - p0x)[:, None], (p1z - p0z)[:, None]
                l2 = abx * abx + abz * abz
                inv = np.divide(1.0, l2, out=np.zeros_like(l2), where=l2 > 0)
                d = point_segment_distance_xz(cx[None, :], cz[None, :], p0x[:, None], p0z[:, None], abx, abz, inv)
                good &= np.all((d >= cr[None, :] + rr[:, None]) & (d > cr[None, :]), axis=1)
            ok[sl] = good
        return ok.reshape(shape)

    def _grid(self) -> BoxGrid:
        """The obstacles' bounding boxes (polygons first, then circles) on a uniform grid."""
        if self._box_grid is None:
            P = len(self.polygons)
            lo, hi = np.zeros((P + len(self.circles), 2)), np.zeros((P + len(self.circles), 2))
            for i, p in enumerate(self.polygons):
                lo[i], hi[i] = p.min(axis=0), p.max(axis=0)
            lo[P:] = self.circles[:, :2] - self.circles[:, 2:]
            hi[P:] = self.circles[:, :2] + self.circles[:, 2:]
            self._box_grid = BoxGrid(lo, hi)
        return self._box_grid

    def _segments_blocked_grid(self, A, B, r) -> np.ndarray:
        """(n,) bool, the negation of :meth:`segment_clear` for many segments: candidate
        (segment, obstacle) pairs from the obstacle grid (bounding boxes within ``r`` of the
        segment's box), then the same bounding-circle cull and exact tests as the dense path.
        Work grows with the number of nearby pairs, not with segments x obstacles."""
        P = len(self.polygons)
        c, lo, _ = self._obstacle_bounds()
        bad = np.zeros(len(A), dtype=bool)
        rp = np.maximum(r, 0.0)[:, None]
        for rows, obs in self._grid().pairs(np.minimum(A, B) - rp, np.maximum(A, B) + rp):
            p0x, p0z = A[rows, 0], A[rows, 1]
            abx, abz = B[rows, 0] - p0x, B[rows, 1] - p0z
            l2 = abx * abx + abz * abz
            inv = np.divide(1.0, l2, out=np.zeros_like(l2), where=l2 > 0)
            d = point_segment_distance_xz(c[obs, 0], c[obs, 1], p0x, p0z, abx, abz, inv)
            rr = r[rows]
            isp = obs < P
            poly = isp & (d <= lo[obs] + rr)
            bad[self._pset.pairs_blocked(A[:, 0], A[:, 1], B[:, 0], B[:, 1], r, rows[poly], obs[poly])] = True
            cr = lo[obs]
            bad[rows[~isp & ~((d >= cr + rr) & (d > cr))]] = True
        return bad

    def segment_distance(self, a, b) -> np.ndarray:
        """(...,) distance from segments ``a`` -> ``b`` to the nearest obstacle (0 if a segment
        touches or enters one); +inf with no obstacles. Dense (every segment against every
        edge): meant for checks and tests, not hot paths."""
        a, b = np.broadcast_arrays(_as_points(a), _as_points(b))
        shape = a.shape[:-1]
        A, B = a.reshape(-1, 2), b.reshape(-1, 2)
        out = np.full(len(A), np.inf)
        P, M = len(self.polygons), len(self.circles)
        if P + M == 0:
            return out.reshape(shape)
        for sl in chunk_rows(len(A), 4 * self._pset.num_edges + M):
            p0x, p0z, p1x, p1z = A[sl, 0:1], A[sl, 1:2], B[sl, 0:1], B[sl, 1:2]
            d = np.full(p0x.shape[0], np.inf)
            if P:
                d = np.minimum(d, self._pset.segment_distance(p0x, p0z, p1x, p1z))
                d[self._pset.inside_any(p0x, p0z)] = 0.0
            if M:
                abx, abz = p1x - p0x, p1z - p0z
                l2 = abx * abx + abz * abz
                inv = np.divide(1.0, l2, out=np.zeros_like(l2), where=l2 > 0)
                dc = point_segment_distance_xz(self.circles[None, :, 0], self.circles[None, :, 1], p0x, p0z, abx, abz,
                                               inv) - self.circles[None, :, 2]
                d = np.minimum(d, np.maximum(dc, 0.0).min(axis=1))
            out[sl] = d
        return out.reshape(shape)

    def sdf(self, resolution: float = 0.05, margin: float = 2.0) -> "SDFGrid":
        """Signed distance sampled on a grid covering ``bounds(margin)`` (see :class:`SDFGrid`)."""
        return SDFGrid.build(self, resolution, margin)

    def __repr__(self):
        roles = {}
        for m in self.markers.values():
            roles[m.role] = roles.get(m.role, 0) + 1
        return (f"Environment({len(self.polygons)} polygons, {len(self.circles)} circles, "
                f"markers {roles or '{}'})")


class SDFGrid:
    """The environment's signed distance sampled at grid nodes ``origin + (i, j) * resolution``
    (``values[i, j]`` at x = x0 + i h, z = z0 + j h) with bilinear interpolation.

    Error bound: :meth:`Environment.distance` is 1-Lipschitz (a minimum of 1-Lipschitz signed
    distances), so the bilinear interpolant of its samples differs from it by at most
    ``sum_k w_k |c_k - p|`` over the cell corners, whose maximum (at a cell centre) is
    ``resolution / sqrt(2)``: inside the grid
    ``|sample(p) - env.distance(p)| <= max_error = resolution / sqrt(2)``. In particular
    ``sample(p) <= true distance + resolution``; a caller that must never overestimate
    clearance subtracts ``max_error``. Outside the grid ``sample`` returns a lower bound of the
    distance that is at least ``margin`` (the grid covers every obstacle grown by ``margin``, so a
    point outside is that far at least: its distance to the grid plus ``margin``): clearance
    tests against any distance below ``margin`` decide exactly as with the true distance, at a
    fraction of the cost. Without a ``margin`` (a grid built by hand) it is the exact
    ``env.distance``. With no obstacles it is +inf.
    """

    def __init__(self, origin, resolution: float, values: np.ndarray, env: Environment,
                 margin: float | None = None):
        self.origin = np.asarray(origin, dtype=np.float64).reshape(2)
        self.resolution = float(resolution)
        self.values = np.asarray(values, dtype=np.float64)
        self.env = env
        self.margin = margin
        self.max_error = self.resolution / math.sqrt(2.0)

    @classmethod
    def build(cls, env: Environment, resolution: float = 0.05, margin: float = 2.0) -> "SDFGrid":
        if not resolution > 0:
            raise ValueError(f"resolution must be positive, got {resolution}")
        x0, z0, x1, z1 = env.bounds(margin)
        nx = int(math.ceil((x1 - x0) / resolution)) + 1
        nz = int(math.ceil((z1 - z0) / resolution)) + 1
        if env.num_obstacles == 0:
            return cls((x0, z0), resolution, np.full((nx, nz), np.inf), env, margin)
        xs = x0 + resolution * np.arange(nx)
        zs = z0 + resolution * np.arange(nz)
        g = np.stack(np.meshgrid(xs, zs, indexing="ij"), axis=-1)
        return cls((x0, z0), resolution, env.distance(g), env, margin)

    @property
    def shape(self):
        return self.values.shape

    def sample(self, xz) -> np.ndarray:
        """Bilinear signed distance at points ``xz`` (..., 2); exact ``env.distance`` outside the
        grid; +inf with no obstacles. Error bound in the class docstring."""
        pts = _as_points(xz)
        shape = pts.shape[:-1]
        p = pts.reshape(-1, 2)
        if self.env.num_obstacles == 0:
            return np.full(shape, np.inf)
        if self.margin is not None:
            fast = sample_grid(p, self.origin, self.resolution, self.values, self.margin)
            if fast is not None:
                return fast.reshape(shape)
        nx, nz = self.values.shape
        f = (p - self.origin) / self.resolution
        inside = (f[:, 0] >= 0) & (f[:, 0] <= nx - 1) & (f[:, 1] >= 0) & (f[:, 1] <= nz - 1)
        out = np.empty(len(p))
        fi = f[inside]
        i = np.minimum(np.floor(fi[:, 0]).astype(np.int64), nx - 2) if nx > 1 else np.zeros(len(fi), np.int64)
        j = np.minimum(np.floor(fi[:, 1]).astype(np.int64), nz - 2) if nz > 1 else np.zeros(len(fi), np.int64)
        u = fi[:, 0] - i
        v = fi[:, 1] - j
        V = self.values
        i1 = np.minimum(i + 1, nx - 1)
        j1 = np.minimum(j + 1, nz - 1)
        out[inside] = ((1 - u) * (1 - v) * V[i, j] + u * (1 - v) * V[i1, j]
                       + (1 - u) * v * V[i, j1] + u * v * V[i1, j1])
        if not inside.all():
            q = p[~inside]
            if self.margin is None:
                out[~inside] = self.env.distance(q)
            else:
                hi = self.origin + self.resolution * (np.array(self.values.shape) - 1)
                d = np.maximum(np.maximum(self.origin - q, q - hi), 0.0)
                out[~inside] = np.hypot(d[:, 0], d[:, 1]) + self.margin
        return out.reshape(shape)
