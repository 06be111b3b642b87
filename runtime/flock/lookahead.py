"""The region-constrained look-ahead (Lai, Chenney and Fan 2005, section 5.2) and the recovery
walks that bring a flock back into its region.

:meth:`LookAhead.search` is a depth-first search from the node a flock reaches next. At each
node of the search the out-edges whose centroid track stays inside the region at every frame
(:class:`~runtime.flock.containment.EdgeContainment`) are tried in random order, biased towards
edges that end deeper inside (``depth_jitter`` metres of random slack), and the first path that
runs far enough beyond its first edge and ends ``safe_depth`` inside is the result; an
accepted path never leaves the region. The search can extend a given path (the flock's plan)
from its end instead of starting afresh.

Why search far ahead: a region has dead ends -- states (node, position, heading) from which
every path of the graph leaves the region sooner or later, e.g. a flock skimming a wall on a
run of single-exit nodes. They can be tens of seconds deep, and a look-ahead that sees only
part of the way commits to them and finds out when no choice is left. The walk therefore asks
for paths of ``search_factor * horizon`` (80 s by default; see
:class:`~runtime.flock.walk.FlockSystem`).

:meth:`LookAhead.recovery_path` is the last resort when no out-edge stays inside (a flock about
to leave, or already outside, e.g. after a region change): the best of :attr:`LookAhead.ROLLOUTS`
random walks by time-averaged depth. Such a path is not verified; the walk looks ahead again at
every node while it follows one.

Placements are ``(yaw, x, y, z)``: the clip arriving at a node is rotated by ``yaw`` about +Y
and then translated. Following an edge composes the placement with the edge's transform
(:func:`runtime.motion.planar.compose1` on the ground plane, plus the height).
"""
from __future__ import annotations

import math

from ..motion.planar import compose1
from .containment import EdgeContainment
from .ddg import DDG

__all__ = ["LookAhead", "place_after"]


def place_after(y: float, tx: float, ty: float, tz: float, e_yaw: float, e_trans) -> tuple:
    """The placement ``(yaw, x, y, z)`` of the clip after an edge with transform ``(e_yaw,
    e_trans)`` (``e_trans`` = (x, y, z) in the arriving clip's coordinates), entered with the
    placement ``(y, tx, ty, tz)``."""
    ex, ey, ez = e_trans
    x, z, yaw = compose1((tx, tz, y), (ex, ez, e_yaw)).tolist()
    return yaw, x, ty + ey, z


class LookAhead:
    """Depth-first look-ahead and recovery walks on one DDG. Holds no flock state: the caller
    passes each call its random stream and gets the node expansions spent back.

    Args:
        ddg: the graph (validated).
        containment: the edge containment test of that graph.
        depth_jitter: metres of random slack in the inward bias of the edge order.
        safe_depth: metres inside a path must end (at most half the region's inradius).
        max_edges: edges a path may hold.
        search_limit: node expansions per search.
        recovery_frames: frames a recovery walk runs.
    """

    ROLLOUTS = 32  # random walks a recovery path is chosen from

    def __init__(self, ddg: DDG, containment: EdgeContainment, *, depth_jitter: float,
                 safe_depth: float, max_edges: int, search_limit: int, recovery_frames: int):
        d = ddg.derived()
        self.containment = containment
        self.depth_jitter = float(depth_jitter)
        self.safe_depth = float(safe_depth)
        self.max_edges = int(max_edges)
        self.search_limit = int(search_limit)
        self.recovery_frames = int(recovery_frames)
        self._safe: dict = {}
        # plain-Python copies for the search loops
        track = d["track"]
        self._out_start = d["out_start"]
        self._out_edges = d["out_edges"]
        self._elen = d["edge_len"].tolist()
        self._eyaw = ddg.edge_yaw.tolist()
        self._etr = [tuple(r) for r in d["edge_trans3"].tolist()]
        self._edst = ddg.edge_dst.astype(int).tolist()
        self._eend = [tuple(r) for r in track[d["track_start"][1:] - 1].tolist()]   # centroid at each edge's end

    def region_safe_depth(self, region) -> float:
        """How deep inside a look-ahead path must end: ``safe_depth`` metres, at most half the
        region's inradius (computed once per region)."""
        key = id(region)
        if key not in self._safe:
            self._safe[key] = min(self.safe_depth, 0.5 * region.inradius())
        return self._safe[key]

    def search(self, rnd, region, v: int, yaw: float, trans, need: int, prefix=()):
        """Depth-first look-ahead from node ``v`` with the arriving clip placed by ``(yaw,
        trans)``: out-edges in random order (biased towards the inside), the first path whose
        centroid stays inside, that runs ``need`` frames beyond its first edge and ends at
        least the region's safe depth inside.

        Args:
            rnd: the flock's :class:`random.Random` for the edge order.
            region: the flock's region.
            v, yaw, trans: the node and the placement (trans: x, y, z).
            need: frames the path must run beyond its first edge.
            prefix: a verified path from ``v`` taken as given; the search extends it from its
                end.

        Returns:
            ``(path, found, expansions)``: ``path`` includes the prefix; when not ``found``, the
            longest inside path seen.
        """
        jitter = self.depth_jitter
        elen, eyaw, etr, edst = self._elen, self._eyaw, self._etr, self._edst
        inside_edges = self.containment.inside_edges
        expansions = 0

        def children(node, y, tx, ty, tz):
            nonlocal expansions
            expansions += 1
            ok, depth = inside_edges(region, node, y, tx, ty, tz)
            if len(ok) > 1:
                keys = [d + jitter * rnd.random() for d in depth]
                order = sorted(range(len(keys)), key=keys.__getitem__, reverse=True)
                ok = [ok[i] for i in order]
                depth = [depth[i] for i in order]
            return ok, depth

        safe = self.region_safe_depth(region)
        y = float(yaw)
        tx, ty, tz = (float(a) for a in trans)
        path = list(prefix)
        frames = 0
        for e in path:                       # the placement at the end of the prefix
            frames += elen[e]
            y, tx, ty, tz = place_after(y, tx, ty, tz, eyaw[e], etr[e])
            v = edst[e]
        base = len(path)
        best, best_frames = list(path), frames
        if base >= self.max_edges:
            return best, False, expansions
        # stack entries: [node, yaw, tx, ty, tz, frames, edges, end depths, next]
        stack = [[v, y, tx, ty, tz, frames, *children(v, y, tx, ty, tz), 0]]
        found = False
        while stack:
            top = stack[-1]
            i = top[8]
            if i >= len(top[6]):
                stack.pop()
                if len(path) > base:
                    path.pop()
                continue
            e = top[6][i]
            top[8] = i + 1
            frames = top[5] + elen[e]
            path.append(e)
            # the first edge is the one committed now; the rest must cover the look-ahead and
            # end well inside, so a verified continuation is left whatever the next search finds
            beyond = frames - elen[path[0]]
            if beyond >= need and top[7][i] >= safe:
                best, found = list(path), True
                break
            if frames > best_frames:
                best, best_frames = list(path), frames
            if len(path) >= self.max_edges or expansions >= self.search_limit:
                path.pop()
                continue
            y2, nx, ny, nz = place_after(top[1], top[2], top[3], top[4], eyaw[e], etr[e])
            w = edst[e]
            stack.append([w, y2, nx, ny, nz, frames, *children(w, y2, nx, ny, nz), 0])
        return best, found, expansions

    def recovery_path(self, rnd, region, v: int, yaw: float, trans):
        """Of :attr:`ROLLOUTS` random walks of ``recovery_frames`` from node ``v`` (the first
        always taking the edge ending deepest, the others a random edge or, half the time,
        that one), the one with the largest time-averaged depth (sampled at edge ends, counted
        up to the safe depth): it gets in soonest and stays in, rather than swinging out to end
        deep, and random walks find the turns a flock heading away needs (a depth-first search
        spends its budget on the last edges of one such walk).

        Args:
            rnd: the flock's :class:`random.Random`.
            region, v, yaw, trans: as for :meth:`search`.

        Returns:
            ``(path, evaluations)``: the edges, and the depth evaluations spent.
        """
        depth = region.depth_point
        elen, eyaw, etr, edst, eend = self._elen, self._eyaw, self._etr, self._edst, self._eend
        out_start, out_edges = self._out_start, self._out_edges
        limit = self.recovery_frames
        safe = self.region_safe_depth(region)
        y0 = float(yaw)
        t0 = tuple(float(a) for a in trans)
        best, best_score = None, float("-inf")
        evals = 0
        for r in range(self.ROLLOUTS):
            node, y, (tx, ty, tz) = v, y0, t0
            frames, acc, path = 0, 0.0, []
            while frames < limit and len(path) < self.max_edges:
                c, s = math.cos(y), math.sin(y)
                kids = out_edges[out_start[node]:out_start[node + 1]].tolist()
                ds = []
                for e in kids:
                    px, py, pz = eend[e]
                    ds.append(depth(c * px + s * pz + tx, py + ty, -s * px + c * pz + tz))
                evals += len(kids)
                k = max(range(len(kids)), key=ds.__getitem__)
                if r and rnd.random() < 0.5:
                    k = rnd.randrange(len(kids))
                e = kids[k]
                path.append(e)
                frames += elen[e]
                acc += min(ds[k], safe) * elen[e]
                y, tx, ty, tz = place_after(y, tx, ty, tz, eyaw[e], etr[e])
                node = edst[e]
            if acc / frames > best_score:
                best, best_score = path, acc / frames
        return best, evals
