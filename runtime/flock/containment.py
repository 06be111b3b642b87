"""Which out-edges of a node keep a flock's centroid inside a region (the test behind the
region-constrained walk, Lai, Chenney and Fan 2005, section 5.2).

An edge's centroid track (:meth:`runtime.flock.ddg.DDG.derived`, blends included, in the
coordinates of the clip arriving at the edge's source node) is placed in the world by the
flock's yaw and translation and must stay inside at every frame. Cheap bounding circles settle
most edges: one around the whole track, then one around each run of :attr:`EdgeContainment.CHUNK`
frames, each tested against a plain-Python lower bound of the region's depth
(:meth:`~runtime.flock.region.Region.depth_bound`). A circle counts as inside when the bound at
its centre is at least its radius.

- ``frame_exact=False``: an inconclusive bound counts as outside, so no exact test runs; this
  keeps flocks a circle radius plus a grid cell (typically about a metre) off the boundary.
- ``frame_exact=True``: an inconclusive circle's centre is settled with the exact depth, and
  frames of runs near the boundary are bounded one by one, the few within the bound's error of
  the boundary getting the exact containment test; then exactly the edges that stay inside
  are accepted.

Either way an accepted edge never leaves the region. The loops are plain Python over a handful
of points at a time (a numpy call per point would cost microseconds), so the placement
``R_y(yaw) p + t`` is written out in scalar arithmetic here.
"""
from __future__ import annotations

import math

import numpy as np

from .ddg import DDG

__all__ = ["EdgeContainment"]


class EdgeContainment:
    """Containment of a DDG's edges in regions, with per-node circle data built on first use.

    Args:
        ddg: the graph (validated).
        frame_exact: settle inconclusive circles exactly (see the module docstring).
    """

    CHUNK = 8     # centroid samples per bounding circle

    def __init__(self, ddg: DDG, frame_exact: bool = False):
        d = ddg.derived()
        self.frame_exact = bool(frame_exact)
        self._out_start = d["out_start"]
        self._out_edges = d["out_edges"]
        # per node: centroid samples (s = 1..L) of all its out-edges, in the source clip's coordinates
        ts, track = d["track_start"], d["track"]
        pieces, starts = [], np.zeros(ddg.n_edges, dtype=np.int64)
        pos = 0
        for k, e in enumerate(self._out_edges):
            a, b = ts[e] + 1, ts[e + 1]
            pieces.append(track[a:b])
            starts[k] = pos
            pos += b - a
        self._samp = np.concatenate(pieces)
        self._oe_samp = starts                                   # indexed like out_edges
        self._node_samp = np.append(starts[self._out_start[:-1]], pos)   # validate(): no dead ends
        self._info: dict = {}
        self._bounds: dict = {}

    def node_info(self, v: int):
        """Per-node data (cached): out-edge ids, the centroid samples of all of them (coordinates
        of the clip arriving at ``v``) and, per out-edge, its runs of :attr:`CHUNK` samples, each
        with a bounding circle ``(cx, cy, cz, radius, first, stop)``; the distance from the last
        run's centre to the last sample; and a circle around the whole edge
        ``(cx, cy, cz, radius, distance to the last sample)``."""
        info = self._info.get(v)
        if info is None:
            o0, o1 = int(self._out_start[v]), int(self._out_start[v + 1])
            a, b = int(self._node_samp[v]), int(self._node_samp[v + 1])
            S = self._samp[a:b]
            starts = list(self._oe_samp[o0:o1] - a) + [b - a]
            per_edge = []
            for i, j in zip(starts[:-1], starts[1:]):
                chunks = []
                for c0 in range(i, j, self.CHUNK):
                    c1 = min(j, c0 + self.CHUNK)
                    cen = S[c0:c1].mean(axis=0)
                    r = float(np.sqrt(((S[c0:c1] - cen) ** 2).sum(-1)).max())
                    chunks.append((float(cen[0]), float(cen[1]), float(cen[2]), r, c0, c1))
                rend = float(np.sqrt(((S[j - 1] - cen) ** 2).sum()))
                whole = S[i:j].mean(axis=0)
                R = float(np.sqrt(((S[i:j] - whole) ** 2).sum(-1)).max())
                Rend = float(np.sqrt(((S[j - 1] - whole) ** 2).sum()))
                per_edge.append((chunks, rend, (float(whole[0]), float(whole[1]), float(whole[2]), R, Rend)))
            edges = [int(e) for e in self._out_edges[o0:o1]]
            info = (edges, [tuple(p) for p in S.tolist()], per_edge)
            self._info[v] = info
        return info

    def depth_bound(self, region):
        """``region.depth_bound()``, computed once per region."""
        key = id(region)
        b = self._bounds.get(key)
        if b is None:
            b = self._bounds[key] = region.depth_bound()
        return b

    def inside_edges(self, region, v: int, yaw: float, tx: float, ty: float, tz: float):
        """Out-edges of node ``v`` whose centroid stays inside ``region`` at every frame, with
        a lower bound of how deep inside each ends.

        Args:
            region: a :class:`~runtime.flock.region.Region`.
            v: the node.
            yaw, tx, ty, tz: the placement of the clip arriving at ``v`` (yaw about +Y, then
                the translation).

        Returns:
            ``(edges, depths)``: lists, in out-edge order.
        """
        edges, S, per_edge = self.node_info(v)
        fn, err = self.depth_bound(region)
        c, s = math.cos(yaw), math.sin(yaw)
        ok, depth = [], []
        exact = region.depth_point
        fine = self.frame_exact
        for k, (chunks, rend, (ex, ey, ez, R, Rend)) in enumerate(per_edge):
            wx, wy, wz = c * ex + s * ez + tx, ey + ty, -s * ex + c * ez + tz
            d = fn(wx, wy, wz)
            if fine and d < R and d + err >= R:          # inconclusive: settle the centre exactly
                d = exact(wx, wy, wz)
            if d >= R:                                   # the whole edge's circle is inside
                ok.append(edges[k])
                depth.append(d - Rend)
                continue
            if d + err <= -R:
                continue
            good = True
            unsure = []
            for cx, cy, cz, r, i0, i1 in chunks:
                wx, wy, wz = c * cx + s * cz + tx, cy + ty, -s * cx + c * cz + tz
                d = fn(wx, wy, wz)
                if fine and d < r and d + err >= r:
                    d = exact(wx, wy, wz)
                if d >= r:
                    continue
                if d + err <= -r or not fine:
                    good = False
                    break
                for i in range(i0, i1):
                    px, py, pz = S[i]
                    wx, wy, wz = c * px + s * pz + tx, py + ty, -s * px + c * pz + tz
                    ds = fn(wx, wy, wz)
                    if ds >= 0.0:
                        continue
                    if ds + err <= 0.0:
                        good = False
                        break
                    unsure.append((wx, wy, wz))
                if not good:
                    break
            if good and unsure:
                if len(unsure) <= 16:
                    good = all(region.contains_point(*q) for q in unsure)
                else:
                    good = bool(region.contains(np.array(unsure)).all())
            if good:
                ok.append(edges[k])
                depth.append(d - rend)
        return ok, depth
