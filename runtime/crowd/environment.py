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

from .geometry import PolygonSet, chunk_rows, point_segment_distance_xz, polygon_area

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

        Vectorized over points and obstacles: circles densely, polygons through bounding-circle
        culling (:class:`~runtime.crowd.geometry.PolygonSet`), exact for every point."""
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
            for rows, obs in self._tile_pairs(flat):
                d = self._pair_distance(flat[rows, 0], flat[rows, 1], obs)
                # pairs of one point are contiguous: reduce each run
                first = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
                mins = np.minimum.reduceat(d, first)
                out[rows[first]] = mins
                if return_index:
                    runs = np.diff(np.r_[first, len(rows)])
                    pos = np.where(d == np.repeat(mins, runs), np.arange(len(d)), len(d))
                    idx[rows[first]] = obs[np.minimum.reduceat(pos, first)]
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

    def _tile_pairs(self, flat, points_per_tile: int = 64, budget: int = 1 << 21):
        """Candidate (point, obstacle) pairs, in chunks: points are binned into square tiles; an
        obstacle is a candidate for a tile unless its lower bound over the tile exceeds the
        smallest upper bound over the tile (so the nearest obstacle of every point is kept).
        Yields (rows, obs) with each point's pairs contiguous; memory stays around ``budget``
        elements per chunk."""
        n = len(flat)
        c, lo, hi = self._obstacle_bounds()
        lo_pt, hi_pt = flat.min(axis=0), flat.max(axis=0)
        span = hi_pt - lo_pt
        tile = max(math.sqrt(float(span[0] * span[1]) * points_per_tile / n),
                   float(span.max()) * points_per_tile / n, 1e-6)
        ij = np.floor((flat - lo_pt) / tile).astype(np.int64)
        key = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]
        order = np.argsort(key, kind="stable")
        ks = key[order]
        tstart = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
        tcount = np.diff(np.r_[tstart, n])
        center = lo_pt + (ij[order[tstart]] + 0.5) * tile
        hd = tile * math.sqrt(0.5) * (1 + 1e-9) + 1e-12
        weight = np.concatenate([self._pset.counts, np.ones(len(self.circles), dtype=np.int64)])
        T = len(tstart)
        for b0 in range(0, T, max(1, budget // len(c))):
            blk = slice(b0, min(T, b0 + max(1, budget // len(c))))
            r = np.hypot(center[blk, None, 0] - c[:, 0], center[blk, None, 1] - c[:, 1])
            ub = (r + hi).min(axis=1) + hd
            trow, tobs = np.nonzero(r - lo - hd <= ub[:, None])
            del r
            tc = tcount[blk]
            ts = tstart[blk]
            ccount = np.bincount(trow, minlength=len(tc))
            cstart = np.cumsum(ccount) - ccount
            cost = tc * np.bincount(trow, weights=weight[tobs], minlength=len(tc)).astype(np.int64)
            k0 = 0
            while k0 < len(tc):
                csum = np.cumsum(cost[k0:])
                k1 = k0 + max(1, int(np.searchsorted(csum, budget, side="right")))
                kk = np.arange(k0, k1)
                npairs = tc[kk] * ccount[kk]
                tot = int(npairs.sum())
                tid = np.repeat(kk, npairs)
                j = np.arange(tot) - np.repeat(np.cumsum(npairs) - npairs, npairs)
                m = ccount[tid]
                yield order[ts[tid] + j // m], tobs[cstart[tid] + j % m]
                k0 = k1

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
    clearance subtracts ``max_error``. Outside the grid ``sample`` returns the exact
    ``env.distance`` (so it is never wrong there, only slower); with no obstacles it is +inf.
    """

    def __init__(self, origin, resolution: float, values: np.ndarray, env: Environment):
        self.origin = np.asarray(origin, dtype=np.float64).reshape(2)
        self.resolution = float(resolution)
        self.values = np.asarray(values, dtype=np.float64)
        self.env = env
        self.max_error = self.resolution / math.sqrt(2.0)

    @classmethod
    def build(cls, env: Environment, resolution: float = 0.05, margin: float = 2.0) -> "SDFGrid":
        if not resolution > 0:
            raise ValueError(f"resolution must be positive, got {resolution}")
        x0, z0, x1, z1 = env.bounds(margin)
        nx = int(math.ceil((x1 - x0) / resolution)) + 1
        nz = int(math.ceil((z1 - z0) / resolution)) + 1
        if env.num_obstacles == 0:
            return cls((x0, z0), resolution, np.full((nx, nz), np.inf), env)
        xs = x0 + resolution * np.arange(nx)
        zs = z0 + resolution * np.arange(nz)
        g = np.stack(np.meshgrid(xs, zs, indexing="ij"), axis=-1)
        return cls((x0, z0), resolution, env.distance(g), env)

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
            out[~inside] = self.env.distance(p[~inside])
        return out.reshape(shape)
