"""Probabilistic roadmap (PRM; Kavraki & Latombe 1994) over the free ground, as Sung, Kovar and Gleicher 2005
section 3.2 uses it to get way points for the seed motions.

The roadmap is built offline (``authoring.roadmap.build_roadmap``): nodes are random free
positions (clearance > ``radius`` from every obstacle, i.e. outside the obstacles grown by the
character radius) and edges join mutually visible nodes closer than ``connect_distance``
(the segment keeps ``radius`` from every obstacle). At query time (:meth:`Roadmap.waypoints`)
the start and goal are added as nodes joined to all their visible roadmap neighbours and
Dijkstra's algorithm (``scipy.sparse.csgraph.dijkstra``) gives the way points
``w_1 = p_s, ..., w_n = p_e``. The roadmap itself is never modified by a query.

Two practical details beyond the paper, both documented on :meth:`Roadmap.waypoints`: an end
point closer than ``radius`` to an obstacle (a seat beside a table) is joined with the clearance
it has, and the Dijkstra path is shortened greedily (a way point is dropped when the segment
skipping it is clear), which the greedy planner prefers to the zig-zag of a random roadmap.

Pack: kind ``"roadmap"``, version :data:`PACK_VERSION`; ``meta["env_fingerprint"]`` is the
:meth:`Environment.fingerprint` of the obstacles it was built for, so a stale cache is detected.
"""
from __future__ import annotations

import numpy as np

from ..assets import AssetError, load_pack, pack_fields, save_pack
from .environment import Environment

__all__ = ["Roadmap", "RoadmapError", "PACK_KIND", "PACK_VERSION"]

PACK_KIND = "roadmap"
PACK_VERSION = 1
# Extra nodes tried (nearest first) when an end point sees no node within connect_distance.
FALLBACK_NEIGHBOURS = 64
SEARCH_BOUND = 1.5         # a query first searches paths up to this times the straight distance (+ 2 connect distances)
SHORTCUT_EXTRA = 0.3      # m: straight and string-pulled segments keep radius + this clearance
PUSH_STEP = 0.1           # m: steps of moving a way point away from an obstacle (Roadmap._push_off)
PUSH_ITERS = 8            # ... at most this many per way point
PUSH_EXTRA = 0.6          # ... towards radius + this clearance (or the ridge between two obstacles:
                          # a 3 m door's middle); at 0.3 seeds still caught a door post turning in


class RoadmapError(ValueError):
    """No way points can be found (end point inside an obstacle, unreachable, stale roadmap)."""


def _fmt(p) -> str:
    return f"({float(p[0]):.3f}, {float(p[1]):.3f})"


class Roadmap:
    """Nodes ``(M, 2)`` and a symmetric CSR adjacency (``indptr``, ``indices``, ``weights`` =
    edge lengths in metres); ``radius`` is the clearance every edge keeps from obstacles."""

    def __init__(self, nodes, indptr, indices, weights, radius: float, connect_distance: float,
                 env_fingerprint: str | None = None, meta: dict | None = None):
        self.nodes = np.ascontiguousarray(nodes, dtype=np.float64).reshape(-1, 2)
        self.indptr = np.ascontiguousarray(indptr, dtype=np.int64)
        self.indices = np.ascontiguousarray(indices, dtype=np.int64)
        self.weights = np.ascontiguousarray(weights, dtype=np.float64)
        self.radius = float(radius)
        self.connect_distance = float(connect_distance)
        self.env_fingerprint = env_fingerprint
        self.meta = dict(meta or {})
        self._tree = None
        self._csr = None

    # -- structure ------------------------------------------------------------------------------
    @property
    def num_nodes(self) -> int:
        return len(self.nodes)

    @property
    def num_edges(self) -> int:
        """Undirected edges (each is stored in both directions)."""
        return len(self.indices) // 2

    def neighbours(self, i: int) -> np.ndarray:
        return self.indices[self.indptr[i]:self.indptr[i + 1]]

    def matrix(self):
        """The adjacency as a ``scipy.sparse.csr_matrix`` (M, M) of edge lengths."""
        from scipy.sparse import csr_matrix
        M = self.num_nodes
        return csr_matrix((self.weights, self.indices, self.indptr), shape=(M, M))

    def components(self) -> np.ndarray:
        """(M,) connected-component label of each node."""
        from scipy.sparse.csgraph import connected_components
        if self.num_nodes == 0:
            return np.zeros(0, dtype=np.int64)
        return connected_components(self.matrix(), directed=False)[1].astype(np.int64)

    def summary(self) -> dict:
        comp = self.components()
        deg = np.diff(self.indptr)
        sizes = np.bincount(comp) if len(comp) else np.zeros(0, dtype=np.int64)
        return {"nodes": self.num_nodes, "edges": self.num_edges, "components": int(len(sizes)),
                "largest_component": int(sizes.max()) if len(sizes) else 0,
                "mean_degree": round(float(deg.mean()), 2) if len(deg) else 0.0,
                "isolated": int(np.sum(deg == 0)), "radius": self.radius,
                "connect_distance": self.connect_distance}

    def validate(self, path="<roadmap>") -> None:
        M = self.num_nodes
        problems = []
        if len(self.indptr) != M + 1 or (M + 1 and (self.indptr[0] != 0 or np.any(np.diff(self.indptr) < 0))):
            problems.append("indptr is not a valid CSR offset array")
        elif self.indptr[-1] != len(self.indices) or len(self.weights) != len(self.indices):
            problems.append("indices/weights lengths do not match indptr")
        if len(self.indices) and (self.indices.min() < 0 or self.indices.max() >= M):
            problems.append("edge endpoints out of range")
        if not np.all(np.isfinite(self.nodes)) or np.any(self.weights < 0):
            problems.append("non-finite node or negative edge weight")
        if not (self.radius >= 0 and self.connect_distance > 0):
            problems.append("radius/connect_distance invalid")
        if problems:
            raise AssetError(path, "roadmap pack is inconsistent: " + "; ".join(problems))

    # -- packs ------------------------------------------------------------------------------------
    def save(self, path) -> None:
        meta = dict(self.meta)
        meta.update({"radius": self.radius, "connect_distance": self.connect_distance,
                     "env_fingerprint": self.env_fingerprint or ""})
        save_pack(path, PACK_KIND, PACK_VERSION, meta,
                  {"nodes": self.nodes, "indptr": self.indptr, "indices": self.indices, "weights": self.weights})

    @classmethod
    def load(cls, path) -> "Roadmap":
        pk = load_pack(path, kind=PACK_KIND, version=PACK_VERSION)
        with pack_fields(path, "roadmap pack is inconsistent"):
            meta = dict(pk.meta)
            radius = float(meta.pop("radius"))
            cd = float(meta.pop("connect_distance"))
            fp = meta.pop("env_fingerprint") or None
            rm = cls(pk.arrays["nodes"], pk.arrays["indptr"], pk.arrays["indices"], pk.arrays["weights"],
                     radius, cd, fp, meta)
        rm.validate(path)
        return rm

    def matches(self, env: Environment) -> bool:
        """True if the roadmap was built for ``env``'s obstacles (or records no fingerprint)."""
        return self.env_fingerprint is None or self.env_fingerprint == env.fingerprint()

    # -- queries ----------------------------------------------------------------------------------
    def _kdtree(self):
        if self._tree is None:
            from scipy.spatial import cKDTree
            self._tree = cKDTree(self.nodes) if self.num_nodes else None
        return self._tree

    def _end_radius(self, env: Environment, p, name: str) -> float:
        """Clearance used for segments touching an end point: ``radius``, or less if the point
        itself is closer to an obstacle than that; RoadmapError if it is inside one."""
        d, k = env.distance(p, return_index=True)
        d = float(d)
        if d <= 0:
            raise RoadmapError(f"{name} {_fmt(p)} is inside obstacle {env.obstacle_paths[int(k)]}")
        return min(self.radius, 0.999 * d)

    def _visible(self, env: Environment, p, r_end: float):
        """Roadmap nodes visible from ``p`` (clear segment): indices and distances."""
        tree = self._kdtree()
        if tree is None:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        cand = np.array(sorted(tree.query_ball_point(p, self.connect_distance)), dtype=np.int64)
        if len(cand):
            ok = env.segment_clear(np.broadcast_to(p, (len(cand), 2)), self.nodes[cand], r_end)
            cand = cand[ok]
        if len(cand) == 0:
            k = min(FALLBACK_NEIGHBOURS, self.num_nodes)
            _, near = tree.query(p, k=k)
            near = np.atleast_1d(near).astype(np.int64)
            ok = env.segment_clear(np.broadcast_to(p, (len(near), 2)), self.nodes[near], r_end)
            cand = near[ok]
        return cand, np.hypot(*(self.nodes[cand] - p).T)

    def waypoints(self, env: Environment, start, goal, shortcut: bool = True) -> np.ndarray:
        """Way points ``(n, 2)`` from ``start`` to ``goal`` (both (2,) x, z), first and last
        exactly the given points.

        ``[start, goal]`` when the straight segment is clear (by ``radius + SHORTCUT_EXTRA``,
        or the end points' own clearance if smaller); otherwise start and goal join
        their visible roadmap neighbours (within ``connect_distance``; if none is visible there,
        the nearest ``FALLBACK_NEIGHBOURS`` nodes are tried) and Dijkstra gives the shortest
        path. Segments touching an end point closer than ``radius`` to an obstacle use that end
        point's clearance instead of ``radius``; every other segment keeps ``radius``. With
        ``shortcut`` (default) way points are dropped greedily while the skipping segment keeps
        ``radius + SHORTCUT_EXTRA`` (the path only gets shorter and never grazes a corner closer
        than the roadmap's own segments do).

        Raises RoadmapError naming the start and goal if an end point is inside an obstacle,
        the roadmap was built for other obstacles, or no path exists.
        """
        s = np.asarray(start, dtype=np.float64).reshape(2)
        g = np.asarray(goal, dtype=np.float64).reshape(2)
        if not self.matches(env):
            raise RoadmapError("the roadmap was built for other obstacles (environment fingerprint "
                               f"{self.env_fingerprint[:12]}... != {env.fingerprint()[:12]}...); rebuild it")
        rs = self._end_radius(env, s, "start")
        rg = self._end_radius(env, g, "goal")
        # the direct segment keeps radius + SHORTCUT_EXTRA, like every shortcut, unless an end
        # point is itself closer to an obstacle than that
        d_ends = env.distance(np.stack([s, g]))
        if env.segment_clear(s, g, min(self.radius + SHORTCUT_EXTRA, 0.999 * float(d_ends.min()))):
            return np.stack([s, g])
        ns, ds = self._visible(env, s, rs)
        ng, dg = self._visible(env, g, rg)
        where = f"from start {_fmt(s)} to goal {_fmt(g)}"
        if len(ns) == 0:
            raise RoadmapError(f"no path {where}: the start sees no roadmap node")
        if len(ng) == 0:
            raise RoadmapError(f"no path {where}: the goal sees no roadmap node")
        # a search bounded by a generous length first (the nodes it settles are exact), the
        # whole graph only when the bound was too short
        bound = SEARCH_BOUND * float(np.hypot(*(g - s))) + 2.0 * self.connect_distance
        dist, pred = self._dijkstra_from(ns, ds, bound)
        reach = dist[ng] + np.maximum(dg, 1e-12)
        if not reach.min() <= bound:
            dist, pred = self._dijkstra_from(ns, ds, np.inf)
            reach = dist[ng] + np.maximum(dg, 1e-12)
        if not np.isfinite(reach.min()):
            raise RoadmapError(f"no path {where}: they lie in parts of the free space the roadmap does not connect")
        M = self.num_nodes
        S = M
        path = [int(ng[int(np.argmin(reach))])]
        while path[-1] != S:
            path.append(int(pred[path[-1]]))
        path = [M + 1] + path
        path = path[::-1]
        pts = np.concatenate([s[None], self.nodes[path[1:-1]], g[None]])
        if shortcut and len(pts) > 2:
            pts = self._shortcut(env, pts, rs, rg)
            pts = self._push_off(env, pts, rs, rg)
        return pts

    def _dijkstra_from(self, ns: np.ndarray, ds: np.ndarray, limit: float):
        """Shortest distances and predecessors over the roadmap from a virtual start node
        (index ``num_nodes``) joined to the nodes ``ns`` by edges of lengths ``ds``.

        The roadmap's CSR arrays are kept once with room after them for the start's row, so a
        query builds no matrix of the whole graph (the graph is large: every node joins every
        visible node within ``connect_distance``). Nodes farther than ``limit`` are left
        unsettled (distance inf)."""
        from scipy.sparse import csr_matrix
        from scipy.sparse.csgraph import dijkstra
        M, nnz, n = self.num_nodes, len(self.indices), len(ns)
        if self._csr is None or len(self._csr[1]) < nnz + n:
            room = max(n, 256, 0 if self._csr is None else 2 * (len(self._csr[1]) - nnz))
            data = np.empty(nnz + room)
            data[:nnz] = np.maximum(self.weights, 1e-12)     # explicit zero lengths stay edges
            indices = np.empty(nnz + room, dtype=np.int32)
            indices[:nnz] = self.indices
            indptr = np.empty(M + 2, dtype=np.int32)
            indptr[:M + 1] = self.indptr
            self._csr = (data, indices, indptr)
        data, indices, indptr = self._csr
        data[nnz:nnz + n] = np.maximum(ds, 1e-12)
        indices[nnz:nnz + n] = ns
        indptr[M + 1] = nnz + n
        A = csr_matrix((data[:nnz + n], indices[:nnz + n], indptr), shape=(M + 1, M + 1), copy=False)
        return dijkstra(A, directed=True, indices=M, return_predecessors=True, limit=limit)

    def _push_off(self, env: Environment, pts: np.ndarray, rs: float, rg: float) -> np.ndarray:
        """Interior way points moved up the distance field's gradient, in steps of at most
        ``PUSH_STEP``, until ``radius + PUSH_EXTRA`` from every obstacle (or no step helps).
        String pulling leaves them on roadmap nodes at the corners it pulls round -- a door
        post, a row's end -- often barely ``radius`` away; seeds aiming there graze the corner.
        A step is kept only if both segments at the point keep the clearance rules of
        :meth:`waypoints`."""
        pts = np.array(pts, dtype=np.float64)
        n = len(pts)
        target = self.radius + PUSH_EXTRA
        h = 0.02
        for k in range(1, n - 1):
            for _ in range(PUSH_ITERS):
                p = pts[k]
                d = float(env.distance(p[None])[0])
                if d >= target:
                    break
                probe = p[None] + np.array([[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]])
                dd = env.distance(probe)
                grad = np.array([dd[0] - dd[1], dd[2] - dd[3]]) / (2 * h)
                gn = float(np.hypot(*grad))
                if not np.isfinite(gn) or gn < 1e-6:
                    break
                q = p + min(PUSH_STEP, target - d) * grad / gn
                r0 = min(self.radius, rs) if k == 1 else self.radius
                r1 = min(self.radius, rg) if k == n - 2 else self.radius
                if not (env.distance(q[None])[0] > d and
                        env.segment_clear(pts[k - 1], q, r0) and env.segment_clear(q, pts[k + 1], r1)):
                    break
                pts[k] = q
        return pts

    def _shortcut(self, env: Environment, pts: np.ndarray, rs: float, rg: float) -> np.ndarray:
        """Greedy string pulling: from each kept way point jump to the farthest later one that
        is visible with the clearance rules of :meth:`waypoints`."""
        n = len(pts)
        keep = [0]
        i = 0
        while i < n - 1:
            j = np.arange(i + 1, n)
            r = np.full(len(j), self.radius)
            if i == 0:
                r = np.minimum(r, rs)
            r[j == n - 1] = np.minimum(r[j == n - 1], rg)
            # string pulling keeps SHORTCUT_EXTRA more clearance than the roadmap's radius, so
            # that a pulled path does not graze door jambs and corners a stride-sized motion
            # cannot follow exactly; where it cannot, the roadmap's own segments are kept
            ok = env.segment_clear(np.broadcast_to(pts[i], (len(j), 2)), pts[j],
                                   np.where(r < self.radius, r, r + SHORTCUT_EXTRA))
            ok[0] = True  # the path's own next segment (already known to be clear)
            i = int(j[np.flatnonzero(ok)[-1]])
            keep.append(i)
        return pts[keep]
