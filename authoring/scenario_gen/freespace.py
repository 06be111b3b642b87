"""The free space of a world on a grid: which points are reachable from which, and how far
apart they are walking round the obstacles.

A cell is free when its centre keeps ``radius + cell / 2`` from every obstacle (exact
distances, :meth:`runtime.crowd.environment.Environment.distance`): the straight move between
the centres of two free cells side by side then keeps ``radius`` everywhere (the distance is
1-Lipschitz). Reachability is 4-connectivity of free cells; a point joins the grid through a
free cell whose straight segment to it keeps ``radius`` (exactly tested). Geodesic distances
are Dijkstra on the 8-connected free cells (a diagonal step only between two free side
neighbours), plus the straight ends to the points: never shorter than a real path.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

__all__ = ["FreeSpace"]


class FreeSpace:
    """Free cells of ``env`` inside ``bounds`` (x0, z0, x1, z1) for a character of ``radius``."""

    def __init__(self, env, bounds, radius: float = 0.6, cell: float = 0.25):
        self.env, self.radius, self.cell = env, float(radius), float(cell)
        x0, z0, x1, z1 = bounds
        self.origin = np.array([x0 + cell / 2, z0 + cell / 2])
        self.nx = max(1, int(math.floor((x1 - x0) / cell)))
        self.nz = max(1, int(math.floor((z1 - z0) / cell)))
        ix, iz = np.meshgrid(np.arange(self.nx), np.arange(self.nz), indexing="ij")
        self.centres = self.origin + np.stack([ix.ravel(), iz.ravel()], axis=1) * cell
        d = env.distance(self.centres) if env.num_obstacles else np.full(len(self.centres), np.inf)
        self.free = (d >= self.radius + cell / 2).reshape(self.nx, self.nz)
        self.labels, self.n_components = ndimage.label(self.free)
        self._graph = None
        self._memo = {}

    # -- points ---------------------------------------------------------------------------------
    def attach(self, p) -> int:
        """Flat index of a free cell joined to point ``p`` by a straight move keeping ``radius``
        from the obstacles, or -1 (then ``p`` is not in the free space)."""
        p = np.asarray(p, float)
        dp = float(self.env.distance(p[None])[0]) if self.env.num_obstacles else math.inf
        if dp < self.radius:
            return -1
        k = np.floor((p - self.origin) / self.cell).astype(int)
        cand = []
        for dx in range(-2, 4):
            for dz in range(-2, 4):
                i, j = k[0] + dx, k[1] + dz
                if 0 <= i < self.nx and 0 <= j < self.nz and self.free[i, j]:
                    c = self.origin + np.array([i, j]) * self.cell
                    cand.append((float(np.hypot(*(c - p))), i * self.nz + j, c))
        cand.sort(key=lambda t: t[0])
        for dist, flat, c in cand[:6]:
            # close enough that the distance field alone proves the move clear, else test it
            if dist <= dp - self.radius or bool(self.env.segment_clear(p[None], c[None], self.radius)[0]):
                return flat
        return -1

    def component(self, p) -> int:
        """The free component holding point ``p`` (0: none)."""
        flat = self.attach(p)
        return 0 if flat < 0 else int(self.labels.ravel()[flat])

    def cell_centre(self, flat: int) -> np.ndarray:
        return self.origin + np.array(divmod(int(flat), self.nz)) * self.cell

    # -- distances ------------------------------------------------------------------------------
    def graph(self):
        """The 8-connected free-cell graph (CSR, edge weights in metres)."""
        if self._graph is None:
            f = self.free
            idx = np.arange(self.nx * self.nz).reshape(self.nx, self.nz)
            rows, cols, w = [], [], []

            def link(ma, a, b, length):
                rows.append(a[ma]), cols.append(b[ma]), w.append(np.full(int(ma.sum()), length))

            link(f[:-1] & f[1:], idx[:-1], idx[1:], self.cell)
            link(f[:, :-1] & f[:, 1:], idx[:, :-1], idx[:, 1:], self.cell)
            diag = self.cell * math.sqrt(2.0)
            # a diagonal step only where both side neighbours are free too
            d1 = f[:-1, :-1] & f[1:, 1:] & f[1:, :-1] & f[:-1, 1:]
            link(d1, idx[:-1, :-1], idx[1:, 1:], diag)
            link(d1, idx[1:, :-1], idx[:-1, 1:], diag)
            r, c, ww = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
            n = self.nx * self.nz
            self._graph = coo_matrix((ww, (r, c)), shape=(n, n)).tocsr()
        return self._graph

    def geodesic(self, a, targets) -> np.ndarray:
        """Walking distances (m) from point ``a`` to each of ``targets`` (K, 2) round the
        obstacles; inf where a target is not reachable. Remembered per (a, targets)."""
        targets = np.asarray(targets, float).reshape(-1, 2)
        a = np.asarray(a, float)
        key = (a.tobytes(), targets.tobytes())
        if key not in self._memo:
            self._memo[key] = self._geodesic(a, targets)
        return self._memo[key].copy()

    def _geodesic(self, a, targets) -> np.ndarray:
        out = np.full(len(targets), math.inf)
        fa = self.attach(a)
        if fa < 0:
            return out
        ends = [self.attach(t) for t in targets]
        ok = [i for i, e in enumerate(ends) if e >= 0]
        if not ok:
            return out
        d = dijkstra(self.graph(), directed=False, indices=fa)
        ca = self.cell_centre(fa)
        for i in ok:
            e = ends[i]
            if np.isfinite(d[e]):
                out[i] = float(np.hypot(*(a - ca))) + float(d[e]) + float(np.hypot(*(targets[i] - self.cell_centre(e))))
        # a straight walk can be shorter than the grid's staircase
        straight = np.hypot(*(targets - a).T)
        clear = self.env.segment_clear(np.repeat(a[None], len(targets), 0), targets, self.radius) \
            if self.env.num_obstacles else np.ones(len(targets), bool)
        return np.where(clear, np.minimum(out, straight), out)
