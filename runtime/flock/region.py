"""Regions that constrain a flock's centroid (Lai, Chenney and Fan 2005, section 5.2).

A region answers ``contains(points)`` for world points (..., 3) (metres, Y up), vectorized.

- :class:`Polygon`: a simple polygon (convex or not) in the ground plane, given by its (x, z)
  vertices, extruded vertically (optionally between ``y_min`` and ``y_max``). The 2D region of the
  paper; also usable for 3D flocks as a vertical prism.
- :class:`Box`: an axis-aligned box, the 3D region.

Points exactly on the boundary count as inside for boxes; for polygons the crossing-number rule
decides (boundary points may go either way, so keep a margin in practice).
"""
from __future__ import annotations

import math
from array import array

import numpy as np

__all__ = ["Region", "Polygon", "Box", "region_from_dict"]


class Region:
    """Base class: ``contains(points (..., 3)) -> bool (...)``."""

    kind = "region"

    def contains(self, points: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def depth(self, points: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        """Distance from each point to the boundary, positive inside and negative outside."""
        raise NotImplementedError

    def depth_bound(self):
        """``(fn, err)``: a plain-Python ``fn(x, y, z)`` with ``fn <= depth <= fn + err`` (for
        look-ahead loops that test a handful of points at a time)."""
        raise NotImplementedError  # pragma: no cover - abstract

    def inradius(self) -> float:  # pragma: no cover - abstract
        """Depth of the deepest point (radius of the largest ball inside), approximately."""
        raise NotImplementedError

    def contains_point(self, x: float, y: float, z: float) -> bool:  # pragma: no cover - abstract
        """:meth:`contains` for a single point, plain Python."""
        raise NotImplementedError

    def depth_point(self, x: float, y: float, z: float) -> float:  # pragma: no cover - abstract
        """:meth:`depth` for a single point, plain Python."""
        raise NotImplementedError

    @property
    def centre(self) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def to_dict(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError


class Polygon(Region):
    kind = "polygon"

    def __init__(self, vertices_xz, y_min: float = -np.inf, y_max: float = np.inf):
        v = np.asarray(vertices_xz, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3:
            raise ValueError(f"a polygon needs at least 3 (x, z) vertices, got shape {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError("polygon vertices must be finite")
        if len(v) > 3 and np.allclose(v[0], v[-1]):
            v = v[:-1]                                    # closed rings: drop the repeat
        area2 = np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])
        if abs(area2) < 1e-12:
            raise ValueError("polygon has zero area")
        if not y_min < y_max:
            raise ValueError(f"y_min {y_min} must be below y_max {y_max}")
        self.vertices = v
        self.y_min = float(y_min)
        self.y_max = float(y_max)
        self._x0 = v[:, 0]
        self._z0 = v[:, 1]
        self._x1 = np.roll(v[:, 0], -1)
        self._z1 = np.roll(v[:, 1], -1)
        dz = self._z1 - self._z0
        self._slope = np.where(dz != 0, (self._x1 - self._x0) / np.where(dz != 0, dz, 1.0), 0.0)
        self._bound = None          # depth_bound(), built on first use
        self._edges_list = None     # _edges_py(), built on first use

    @classmethod
    def from_points(cls, points_xyz, y_min: float = -np.inf, y_max: float = np.inf) -> "Polygon":
        """From 3D points (e.g. a region prim's points): uses their x and z."""
        p = np.asarray(points_xyz, dtype=np.float64)
        return cls(p[:, [0, 2]], y_min, y_max)

    @classmethod
    def rectangle(cls, x0, z0, x1, z1, y_min: float = -np.inf, y_max: float = np.inf) -> "Polygon":
        return cls([[x0, z0], [x1, z0], [x1, z1], [x0, z1]], y_min, y_max)

    def contains(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64)
        x = p[..., 0, None]
        z = p[..., 2, None]
        crosses = (self._z0 > z) != (self._z1 > z)
        xi = self._x0 + (z - self._z0) * self._slope
        inside = (np.count_nonzero(crosses & (x < xi), axis=-1) & 1).astype(bool)
        if np.isfinite(self.y_min) or np.isfinite(self.y_max):
            y = p[..., 1]
            inside &= (y >= self.y_min) & (y <= self.y_max)
        return inside

    def depth(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64)
        x = p[..., 0, None]
        z = p[..., 2, None]
        ex, ez = self._x1 - self._x0, self._z1 - self._z0
        t = np.clip(((x - self._x0) * ex + (z - self._z0) * ez) / (ex * ex + ez * ez), 0.0, 1.0)
        dx, dz = x - (self._x0 + t * ex), z - (self._z0 + t * ez)
        d = np.sqrt((dx * dx + dz * dz).min(axis=-1))
        if np.isfinite(self.y_min):
            d = np.minimum(d, np.abs(p[..., 1] - self.y_min))
        if np.isfinite(self.y_max):
            d = np.minimum(d, np.abs(self.y_max - p[..., 1]))
        return np.where(self.contains(p), d, -d)

    def depth_bound(self, cells: int = 128):
        """Depth sampled on a ``cells`` x ``cells`` grid over the polygon's bounding box (cell
        ``h``): a cell holds the depth at its centre minus half its diagonal, never above the
        depth of any point in it and at most ``h * sqrt(2)`` below. Outside the grid: -inf."""
        if self._bound is None:
            lo = self.vertices.min(axis=0)
            hi = self.vertices.max(axis=0)
            h = float(max(hi - lo)) / cells
            nx = int(np.ceil((hi[0] - lo[0]) / h)) + 1
            nz = int(np.ceil((hi[1] - lo[1]) / h)) + 1
            gx = lo[0] + (np.arange(nx) + 0.5) * h
            gz = lo[1] + (np.arange(nz) + 0.5) * h
            P = np.zeros((nx, nz, 3))
            P[..., 0] = gx[:, None]
            P[..., 2] = gz[None, :]
            flat = Polygon(self.vertices).depth(P.reshape(-1, 3)) - h * np.sqrt(0.5)
            grid = array("d", flat.tolist())          # plain floats, cheap to index from Python
            x0, z0, inv, y0, y1 = float(lo[0]), float(lo[1]), 1.0 / h, self.y_min, self.y_max
            limited = bool(np.isfinite(y0) or np.isfinite(y1))
            ninf = float("-inf")

            def fn(x, y, z):
                if x < x0 or z < z0:
                    return ninf
                i = int((x - x0) * inv)
                j = int((z - z0) * inv)
                if i >= nx or j >= nz:
                    return ninf
                d = grid[i * nz + j]
                if limited:
                    d = min(d, y - y0, y1 - y)
                return d

            self._bound = (fn, h * np.sqrt(2.0))
        return self._bound

    def inradius(self) -> float:
        """Largest depth on a 64 x 64 grid over the bounding box (within 1/45 of the size)."""
        lo = self.vertices.min(axis=0)
        hi = self.vertices.max(axis=0)
        g = np.linspace(0, 1, 64)
        P = np.zeros((64, 64, 3))
        P[..., 0] = lo[0] + (hi[0] - lo[0]) * g[:, None]
        P[..., 2] = lo[1] + (hi[1] - lo[1]) * g[None, :]
        if np.isfinite(self.y_min) and np.isfinite(self.y_max):
            P[..., 1] = 0.5 * (self.y_min + self.y_max)
        return float(self.depth(P.reshape(-1, 3)).max())

    def depth_point(self, x: float, y: float, z: float) -> float:
        """:meth:`depth` for one point, in plain Python."""
        inside = False
        best = float("inf")
        for x0, z0, z1, slope, ex, ez, il in self._edges_py():
            if (z0 > z) != (z1 > z) and x < x0 + (z - z0) * slope:
                inside = not inside
            t = ((x - x0) * ex + (z - z0) * ez) * il
            t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
            dx = x - x0 - t * ex
            dz = z - z0 - t * ez
            d2 = dx * dx + dz * dz
            if d2 < best:
                best = d2
        d = best ** 0.5
        if np.isfinite(self.y_min):
            d = min(d, abs(y - self.y_min))
        if np.isfinite(self.y_max):
            d = min(d, abs(self.y_max - y))
        inside = inside and self.y_min <= y <= self.y_max
        return d if inside else -d

    def contains_point(self, x: float, y: float, z: float) -> bool:
        """:meth:`contains` for one point, in plain Python (cheaper for a handful of points)."""
        if y < self.y_min or y > self.y_max:
            return False
        inside = False
        for x0, z0, z1, slope, _, _, _ in self._edges_py():
            if (z0 > z) != (z1 > z) and x < x0 + (z - z0) * slope:
                inside = not inside
        return inside

    def _edges_py(self):
        e = self._edges_list
        if e is None:
            ex, ez = self._x1 - self._x0, self._z1 - self._z0
            e = self._edges_list = list(zip(self._x0.tolist(), self._z0.tolist(), self._z1.tolist(),
                                            self._slope.tolist(), ex.tolist(), ez.tolist(),
                                            (1.0 / (ex * ex + ez * ez)).tolist()))
        return e

    @property
    def centre(self) -> np.ndarray:
        v = self.vertices
        x, z = v[:, 0], v[:, 1]
        xn, zn = np.roll(x, -1), np.roll(z, -1)
        cr = x * zn - xn * z
        a = cr.sum() / 2.0
        cx = ((x + xn) * cr).sum() / (6.0 * a)
        cz = ((z + zn) * cr).sum() / (6.0 * a)
        y = 0.0
        if np.isfinite(self.y_min) and np.isfinite(self.y_max):
            y = 0.5 * (self.y_min + self.y_max)
        return np.array([cx, y, cz])

    def to_dict(self) -> dict:
        return {"kind": self.kind, "vertices": self.vertices.tolist(), "y_min": self.y_min, "y_max": self.y_max}


class Box(Region):
    kind = "box"

    def __init__(self, lo, hi):
        lo = np.asarray(lo, dtype=np.float64).reshape(3)
        hi = np.asarray(hi, dtype=np.float64).reshape(3)
        if not np.all(lo < hi):
            raise ValueError(f"box corners must satisfy lo < hi on every axis, got {lo} and {hi}")
        self.lo = lo
        self.hi = hi
        self._lo = [float(a) for a in lo]
        self._hi = [float(a) for a in hi]

    def contains(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64)
        return np.all((p >= self.lo) & (p <= self.hi), axis=-1)

    def depth(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64)
        inside = np.minimum(p - self.lo, self.hi - p).min(axis=-1)
        outside = np.sqrt((np.maximum(np.maximum(self.lo - p, p - self.hi), 0.0) ** 2).sum(-1))
        return np.where(inside >= 0, inside, -outside)

    def depth_bound(self):
        lo = [float(a) for a in self.lo]
        hi = [float(a) for a in self.hi]

        def fn(x, y, z):
            return min(x - lo[0], hi[0] - x, y - lo[1], hi[1] - y, z - lo[2], hi[2] - z)

        return fn, 0.0

    @property
    def centre(self) -> np.ndarray:
        c = 0.5 * (self.lo + self.hi)
        return np.where(np.isfinite(c), c, 0.0)

    def depth_point(self, x: float, y: float, z: float) -> float:
        """:meth:`depth` for one point, in plain Python."""
        lo, hi = self._lo, self._hi
        p = (x, y, z)
        inside = min(min(p[k] - lo[k], hi[k] - p[k]) for k in range(3))
        if inside >= 0:
            return inside
        return -math.sqrt(sum(max(lo[k] - p[k], p[k] - hi[k], 0.0) ** 2 for k in range(3)))

    def inradius(self) -> float:
        ext = self.hi - self.lo
        return float(0.5 * ext[np.isfinite(ext)].min())

    def contains_point(self, x: float, y: float, z: float) -> bool:
        lo, hi = self.lo, self.hi
        return bool(lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and lo[2] <= z <= hi[2])

    def to_dict(self) -> dict:
        return {"kind": self.kind, "lo": self.lo.tolist(), "hi": self.hi.tolist()}


def region_from_dict(d: dict) -> Region:
    kind = d.get("kind")
    if kind == "polygon":
        return Polygon(d["vertices"], d.get("y_min", -np.inf), d.get("y_max", np.inf))
    if kind == "box":
        return Box(d["lo"], d["hi"])
    raise ValueError(f"unknown region kind {kind!r} (expected 'polygon' or 'box')")
