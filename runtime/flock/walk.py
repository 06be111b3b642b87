"""Walking a DDG with many flocks at once (paper 004, section 5).

:class:`FlockSystem` advances any number of flocks that share one :class:`~runtime.flock.ddg.DDG`.
Per-tick work is numpy over all flocks (state arrays: current edge, phase, yaw/translation of
the clip in the world, cumulative correspondence); Python runs per flock only when a flock
needs a new stretch of path, which is rare and amortised.

Correspondence (section 5). ``perm[f, i]`` is the clip slot that agent ``i`` of flock ``f`` uses
(``M_current``); it starts as the identity and becomes ``M_e[perm]`` on entering edge ``e``, so
row ``i`` of :meth:`FlockSystem.positions` is the same agent for the whole walk.

Random walk (5.1): at each node an outgoing edge uniformly at random (vectorized).

Region-constrained walk (5.2): a depth-first look-ahead from the node a flock reaches next.
At each node of the search the out-edges whose centroid track stays inside the region at every
frame (blends included) are tried in random order -- biased towards edges that end deeper
inside (``depth_jitter`` metres of random slack) -- and the first path found is the flock's plan.
A path counts when it runs ``2 * horizon`` beyond its first edge and ends ``safe_depth`` inside,
so the plan after the edge being committed is always a verified way to stay inside for at least
``horizon`` (a "backup"). A new look-ahead runs when less than ``horizon`` is left; a failed one
keeps the backup and tries again at the next node. Look-ahead runs ahead of time, under a
per-tick budget of node expansions (a flock with nothing verified left at a node searches at
once); if even that fails the flock takes the longest inside path, or the edge leaving the region
last (``stats["fallbacks"]``, zero in the tests and benchmarks).

The search tests cheap bounding circles (whole edge, then runs of 8 frames) against a
plain-Python lower bound of the region's depth (:meth:`Region.depth_bound`; an inconclusive
bound counts as outside, or, with ``frame_exact``, is refined exactly); an edge is accepted only when every run is certified inside (or, with
``frame_exact``, every frame), so an accepted path never leaves the region.

Randomness is a counter-based hash of ``(seed, flock, counter)``: every flock's walk is
reproducible, independent of the other flocks, and (while the look-ahead budget keeps up) the
same for any tick size.
"""
from __future__ import annotations

import math
import random

import numpy as np

from ..motion import quat
from .ddg import DDG
from .region import Region

__all__ = ["FlockSystem"]

_M64 = np.uint64(0xFFFFFFFFFFFFFFFF)


def _splitmix(x: np.ndarray) -> np.ndarray:
    x = (x + np.uint64(0x9E3779B97F4A7C15)) & _M64
    x = ((x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)) & _M64
    x = ((x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)) & _M64
    return x ^ (x >> np.uint64(31))


def _uniform(seed: int, flock, counter, salt=0) -> np.ndarray:
    """Deterministic uniforms in [0, 1) from (seed, flock, counter, salt), vectorized."""
    with np.errstate(over="ignore"):
        h = _splitmix(np.asarray(seed, dtype=np.uint64) ^ np.uint64(0x5851F42D4C957F2D))
        h = _splitmix(h ^ np.asarray(flock, dtype=np.uint64))
        h = _splitmix(h ^ np.asarray(counter, dtype=np.uint64))
        h = _splitmix(h ^ np.asarray(salt, dtype=np.uint64))
    return (h >> np.uint64(11)).astype(np.float64) * (1.0 / 9007199254740992.0)


class FlockSystem:
    """Many flocks walking one DDG. See the module docstring.

    Parameters: ``seed``; ``horizon`` (seconds of verified future a region flock keeps; a new
    look-ahead runs when less is left); ``search_factor`` (a look-ahead path must run
    ``search_factor * horizon`` beyond its first edge); ``safe_depth`` (metres inside the region
    a look-ahead path must end, at most half the region's inradius); ``depth_jitter``
    (metres of random slack in the inward bias); ``plan_budget`` (DFS node expansions per
    :meth:`step` for look-ahead ahead of time); ``search_limit`` (expansions per search);
    ``max_depth`` (edges a plan may hold); ``frame_exact`` (False: an edge counts as inside only
    if circles around runs of 8 frames of its centroid track are certified inside by the
    region's depth grid alone -- an inconclusive grid cell counts as outside, so no exact polygon
    test runs; cheaper, and it keeps flocks a circle radius plus a grid cell, typically about a
    metre, off the boundary; True: inconclusive circles are settled exactly and frames near the
    boundary are tested one by one).

    Outputs (all flocks at once): :meth:`positions`, :meth:`velocities`, :meth:`headings`,
    :meth:`orientations`, :meth:`centroids`; :meth:`slots` and :meth:`current_edges` expose the
    correspondence and graph state; ``stats`` counts transitions, searches and fallbacks.
    """

    def __init__(self, ddg: DDG, *, seed: int = 0, horizon: float = 10.0, plan_budget: int = 100,
                 search_limit: int = 800, max_depth: int = 96, depth_jitter: float = 10.0,
                 safe_depth: float = 10.0, search_factor: float = 2.0, frame_exact: bool = False):
        ddg.validate()
        self.ddg = ddg
        d = ddg.derived()
        self.seed = int(seed)
        self.dim = ddg.dim
        self.fps = ddg.fps
        self.n_agents = N = ddg.n_agents
        D = ddg.dim
        E = ddg.n_edges
        self.horizon_frames = max(1, int(round(horizon * self.fps)))
        self.search_frames = int(round(search_factor * self.horizon_frames))
        self.depth_jitter = float(depth_jitter)
        self.safe_depth = float(safe_depth)
        self.frame_exact = bool(frame_exact)
        self._safe: dict = {}
        self._info: dict = {}
        self._fast: dict = {}
        self.cap = int(max_depth)
        self.plan_budget = int(plan_budget)
        self.search_limit = int(search_limit)
        # graph arrays used per tick
        self._row0 = ddg.seg_start[ddg.edge_seg].astype(np.int64)
        self._elen = d["edge_len"].astype(np.int64)
        self._eblend = ddg.edge_blend.astype(np.int64)
        # Frames as structure of arrays (one flat float32 array per coordinate x, [y,] z). The
        # blended opening frames s = 0..K of every transition edge are appended once, so a tick
        # only gathers: edge e at frame s reads row blend_row0[e] + s while s < K, else row0[e] + s.
        blended, brow0 = [], np.full(E, -1, np.int64)
        nxt = ddg.frames.shape[0]
        for e in np.nonzero(ddg.edge_blend > 0)[0]:
            K = int(ddg.edge_blend[e])
            blended.append(ddg.edge_positions(int(e))[:K + 1].astype(np.float32))
            brow0[e] = nxt
            nxt += K + 1
        pool = np.concatenate([ddg.frames] + blended) if blended else ddg.frames
        self._fcomp = [np.ascontiguousarray(pool[..., k].reshape(-1)) for k in range(D)]
        self._brow0 = brow0
        self.pool_bytes = int(sum(a.nbytes for a in self._fcomp))
        self._eperm = ddg.edge_perm.astype(np.int64)
        self._eyaw = ddg.edge_yaw
        self._etr = d["edge_trans3"]
        self._edst = ddg.edge_dst.astype(np.int64)
        self._out_start = d["out_start"]
        self._out_edges = d["out_edges"]
        self._node_centroid = d["node_centroid"]
        self._node_heading = d["node_heading"]
        # per node: centroid samples (s = 1..L) of all its out-edges, in the source clip's coordinates
        ts, track = d["track_start"], d["track"]
        pieces, starts = [], np.zeros(E, dtype=np.int64)
        pos = 0
        for k, e in enumerate(self._out_edges):
            a, b = ts[e] + 1, ts[e + 1]
            pieces.append(track[a:b])
            starts[k] = pos
            pos += b - a
        self._samp = np.concatenate(pieces)
        self._oe_samp = starts                                   # indexed like out_edges
        self._node_samp = np.append(starts[self._out_start[:-1]], pos)   # validate(): no dead ends
        # plain-Python copies for the look-ahead loop
        self._elen_l = self._elen.tolist()
        self._eyaw_l = self._eyaw.tolist()
        self._etr_l = [tuple(r) for r in self._etr.tolist()]
        self._edst_l = self._edst.tolist()
        # flock state
        self.regions: list[Region] = []
        self._region_ids: dict = {}
        self._alloc(0)
        self.time = 0.0
        self.stats = {"transitions": 0, "searches": 0, "expansions": 0, "search_failures": 0,
                      "fallbacks": 0}
        self._cache = None

    # ------------------------------------------------------------------ state
    _STATE = ("_edge", "_phase", "_yaw", "_trans", "_perm", "_plan_buf", "_count", "_backup",
              "_pending", "_counter", "_region")

    def _alloc(self, n):
        self._edge = np.zeros(n, np.int64)          # current edge
        self._phase = np.zeros(n)                   # frames played of it (fractional)
        self._yaw = np.zeros(n)                     # its segment -> world: yaw about +Y ...
        self._trans = np.zeros((n, 3))              # ... then this translation
        self._perm = np.zeros((n, self.n_agents), np.int64)   # cumulative correspondence
        self._plan_buf = np.zeros((n, self.cap), np.int64)    # verified path after the current edge
        self._count = np.zeros(n, np.int64)
        self._backup = np.zeros(n, np.int64)        # frames in the plan
        self._pending = np.zeros(n, bool)           # look-ahead for the next node still to do
        self._counter = np.zeros(n, np.uint64)      # random stream position
        self._region = np.full(n, -1, np.int64)

    def _grow(self, k):
        n = self.n_flocks
        old = {name: getattr(self, name) for name in self._STATE}
        self._alloc(n + k)
        for name, a in old.items():
            getattr(self, name)[:n] = a

    @property
    def n_flocks(self) -> int:
        return len(self._edge)

    # ------------------------------------------------------------------ transforms
    @staticmethod
    def _rot3(yaw, v):
        """Rotate (k, 3) vectors by yaws (k,) about +Y."""
        c, s = np.cos(yaw), np.sin(yaw)
        out = np.empty_like(v)
        out[:, 0] = c * v[:, 0] + s * v[:, 2]
        out[:, 1] = v[:, 1]
        out[:, 2] = -s * v[:, 0] + c * v[:, 2]
        return out

    def _embed(self, p):
        """Clip coordinates (..., D) -> 3D (..., 3)."""
        p = np.asarray(p, dtype=np.float64)
        if self.dim == 3:
            return p
        out = np.zeros(p.shape[:-1] + (3,))
        out[..., 0] = p[..., 0]
        out[..., 2] = p[..., 1]
        return out

    # ------------------------------------------------------------------ adding flocks
    def add_flock(self, position=(0.0, 0.0, 0.0), heading: float = 0.0, region: Region | None = None,
                  node: int | None = None) -> int:
        """Start a flock with its centroid at ``position`` (x, y, z) and its mean velocity heading
        ``heading`` (radians about +Y, 0 = +Z). Returns the flock's index (its row in the outputs).
        For a 2D DDG the flock moves in the horizontal plane at height ``position[1]``."""
        return int(self.add_flocks([position], [heading], [region], None if node is None else [node])[0])

    def add_flocks(self, positions, headings=None, regions=None, nodes=None) -> np.ndarray:
        """Start several flocks (see :meth:`add_flock`); ``regions``: a list, or one region for all."""
        positions = np.atleast_2d(np.asarray(positions, dtype=np.float64))
        k = len(positions)
        if positions.shape[1] != 3:
            raise ValueError(f"positions must be (k, 3), got {positions.shape}")
        headings = np.zeros(k) if headings is None else np.broadcast_to(np.asarray(headings, float), (k,))
        if regions is None or isinstance(regions, Region):
            regions = [regions] * k
        if len(regions) != k:
            raise ValueError(f"{len(regions)} regions for {k} flocks")
        first = self.n_flocks
        self._grow(k)
        V = self.ddg.n_nodes
        for j in range(k):
            f = first + j
            reg = regions[j]
            if reg is not None:
                if not bool(reg.contains(positions[j][None])[0]):
                    raise ValueError(f"flock {f}: start position {positions[j].tolist()} is outside its region")
                self._region[f] = self._region_index(reg)
            tries = [int(nodes[j])] if nodes is not None else []
            tries += [int(x * V) for x in _uniform(self.seed, f, np.arange(32, dtype=np.uint64), 7)]
            for t, v in enumerate(tries):
                # place node v's configuration: centroid at the position, mean velocity along heading
                yaw0 = float(headings[j] - self._node_heading[v])
                tr0 = positions[j] - self._rot3(np.array([yaw0]), self._embed(self._node_centroid[v])[None])[0]
                if self.dim == 2:
                    tr0[1] = positions[j][1]
                self._count[f] = 0
                if reg is None:
                    self._set_plan(f, [self._random_edges(np.array([f]), np.array([v]))[0]])
                    break
                if self._look_ahead(f, v, yaw0, tr0, forced=(t == len(tries) - 1)):
                    break
            self._yaw[f], self._trans[f] = yaw0, tr0
            self._perm[f] = np.arange(self.n_agents)
            self._enter(np.array([f]), self._take_next(np.array([f])))
            self._phase[f] = 0.0
        self._cache = None
        return np.arange(first, first + k)

    def set_region(self, flock: int, region: Region | None) -> None:
        """Change a flock's region (``None``: random walk); decided again at its next node."""
        self._region[flock] = -1 if region is None else self._region_index(region)
        self._count[flock] = 0
        self._backup[flock] = 0
        self._pending[flock] = region is not None

    def _region_index(self, region) -> int:
        k = self._region_ids.get(id(region))
        if k is None:
            k = self._region_ids[id(region)] = len(self.regions)
            self.regions.append(region)
        return k

    # ------------------------------------------------------------------ choosing edges
    def _random_edges(self, flocks, nodes):
        """Random walk (5.1): a uniformly random out-edge of each node (vectorized)."""
        deg = self._out_start[nodes + 1] - self._out_start[nodes]
        u = _uniform(self.seed, flocks.astype(np.uint64), self._counter[flocks], 1)
        self._counter[flocks] += np.uint64(1)
        return self._out_edges[self._out_start[nodes] + np.minimum((u * deg).astype(np.int64), deg - 1)]

    def _set_plan(self, f, path):
        path = list(path)[: self.cap]
        self._plan_buf[f, :len(path)] = path
        self._count[f] = len(path)
        self._backup[f] = int(self._elen[path].sum()) if path else 0

    def _take_next(self, flocks):
        """Pop the first planned edge of each flock (all have count > 0)."""
        e = self._plan_buf[flocks, 0].copy()
        self._plan_buf[flocks, :-1] = self._plan_buf[flocks, 1:]
        self._count[flocks] -= 1
        self._backup[flocks] -= self._elen[e]
        return e

    _CHUNK = 8     # centroid samples per bounding circle in the look-ahead

    def _node_info(self, v):
        """Per-node look-ahead data (cached): out-edge ids and, per out-edge, its centroid samples
        (coordinates of the clip arriving at ``v``) cut into runs of ``_CHUNK`` frames, each run
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
                for c0 in range(i, j, self._CHUNK):
                    c1 = min(j, c0 + self._CHUNK)
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

    def _inside_edges(self, region, v, yaw, tx, ty, tz):
        """Out-edges of node ``v`` whose centroid stays inside the region at every frame, with a
        lower bound of how deep inside each ends. Circles around runs of samples settle most runs
        with one depth bound each; samples of runs near the boundary are bounded one by one, and
        only samples within the bound's error of the boundary get the exact polygon test."""
        edges, S, per_edge = self._node_info(v)
        fn, err = self._bounds(region)
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

    def _bounds(self, region):
        key = id(region)
        b = self._fast.get(key)
        if b is None:
            b = self._fast[key] = region.depth_bound()
        return b

    def _search(self, f, region, v, yaw, trans, need):
        """Depth-first look-ahead (paper 5.2) from node ``v`` with the clip placed by (yaw, trans):
        out-edges in random order (biased towards the inside), the first path whose centroid
        stays inside, that runs ``need`` frames beyond its first edge and ends at least the safe
        depth inside. Returns ``(path, found)``; when not found, the longest inside path seen."""
        self.stats["searches"] += 1
        rnd = random.Random(int(_uniform(self.seed, f, self._counter[f], 3) * 2.0 ** 53))
        self._counter[f] += np.uint64(1)
        jitter = self.depth_jitter
        elen, eyaw, etr, edst = self._elen_l, self._eyaw_l, self._etr_l, self._edst_l
        expansions = 0

        def children(node, y, tx, ty, tz):
            nonlocal expansions
            expansions += 1
            ok, depth = self._inside_edges(region, node, y, tx, ty, tz)
            if len(ok) > 1:
                keys = [d + jitter * rnd.random() for d in depth]
                order = sorted(range(len(keys)), key=keys.__getitem__, reverse=True)
                ok = [ok[i] for i in order]
                depth = [depth[i] for i in order]
            return ok, depth

        safe = self._safe_depth(region)
        tx, ty, tz = (float(a) for a in trans)
        # stack entries: [node, yaw, tx, ty, tz, frames, edges, end depths, next]
        stack = [[v, float(yaw), tx, ty, tz, 0, *children(v, float(yaw), tx, ty, tz), 0]]
        path: list[int] = []
        best: list[int] = []
        best_frames = -1
        found = False
        while stack:
            top = stack[-1]
            i = top[8]
            if i >= len(top[6]):
                stack.pop()
                if path:
                    path.pop()
                continue
            e = top[6][i]
            top[8] = i + 1
            frames = top[5] + elen[e]
            path.append(e)
            # the first edge is the one committed now; the rest must cover the horizon and end
            # well inside, so a verified continuation is left whatever the next look-ahead finds
            if frames - elen[path[0]] >= need and top[7][i] >= safe:
                best, found = list(path), True
                break
            if frames > best_frames:
                best, best_frames = list(path), frames
            if len(path) >= self.cap or expansions >= self.search_limit:
                path.pop()
                continue
            y = top[1]
            c, s = math.cos(y), math.sin(y)
            ex, ey, ez = etr[e]
            nx, ny, nz = top[2] + c * ex + s * ez, top[3] + ey, top[4] - s * ex + c * ez
            y2 = y + eyaw[e]
            w = edst[e]
            stack.append([w, y2, nx, ny, nz, frames, *children(w, y2, nx, ny, nz), 0])
        self.stats["expansions"] += expansions
        return best, found

    def _safe_depth(self, region) -> float:
        """How deep inside a look-ahead path must end: ``safe_depth`` metres, at most half the
        region's inradius."""
        key = id(region)
        if key not in self._safe:
            self._safe[key] = min(self.safe_depth, 0.5 * region.inradius())
        return self._safe[key]

    def _look_ahead(self, f, v, yaw, trans, forced=False) -> bool:
        """Choose what flock ``f`` does at node ``v`` (clip placed by ``yaw, trans``): a fresh
        path of >= horizon inside the region replaces the plan. Without one the remaining
        (already verified) plan is kept; a flock with no plan left takes the longest inside
        path, or the edge that leaves the region last (``stats['fallbacks']``)."""
        region = self.regions[self._region[f]]
        path, found = self._search(f, region, v, yaw, trans, self.search_frames)
        if found:
            self._set_plan(f, path)
            return True
        self.stats["search_failures"] += 1
        # no full path: still keep whichever verified way to stay inside lasts longer
        if path and int(self._elen[path].sum()) > int(self._backup[f]) and not forced:
            self._set_plan(f, path)
        if forced and self._count[f] == 0:
            self.stats["fallbacks"] += 1
            self._set_plan(f, path if path else [self._latest_exit(region, v, yaw, trans)])
        return False

    def _latest_exit(self, region, v, yaw, trans) -> int:
        """The out-edge of node ``v`` whose centroid stays inside the longest."""
        o0, o1 = self._out_start[v], self._out_start[v + 1]
        a, b = self._node_samp[v], self._node_samp[v + 1]
        S = self._samp[a:b]
        inside = region.contains(self._rot3(np.full(len(S), yaw), S) + trans)
        starts = np.append(self._oe_samp[o0:o1], b) - a
        runs = [len(seg) if seg.all() else int(np.argmin(seg))
                for seg in (inside[starts[k]:starts[k + 1]] for k in range(o1 - o0))]
        return int(self._out_edges[o0 + int(np.argmax(runs))])

    def _plan_ahead(self):
        """Budgeted look-ahead for the node each region flock reaches next (soonest first)."""
        todo = np.nonzero(self._pending)[0]
        if todo.size == 0:
            return
        # most urgent first: the flock whose verified plan runs out soonest
        left = self._backup[todo] + self._elen[self._edge[todo]] - self._phase[todo]
        todo = todo[np.lexsort((todo, left))]
        spent0 = self.stats["expansions"]
        for f in todo:
            if self.stats["expansions"] - spent0 >= self.plan_budget:
                break
            self._pending[f] = False
            e = self._edge[f]
            self._look_ahead(int(f), int(self._edst[e]), float(self._yaw[f]), self._trans[f])

    # ------------------------------------------------------------------ stepping
    def _enter(self, flocks, e):
        """Flocks at the end of their edge enter edge ``e`` (paper 5: M' = M_e(M))."""
        y = self._yaw[flocks]
        self._trans[flocks] += self._rot3(y, self._etr[e])
        self._yaw[flocks] = y + self._eyaw[e]
        self._perm[flocks] = np.take_along_axis(self._eperm[e], self._perm[flocks], axis=1)
        self._edge[flocks] = e
        self._pending[flocks] = (self._region[flocks] >= 0) & (self._backup[flocks] < self.horizon_frames)

    def step(self, dt: float) -> None:
        """Advance every flock by ``dt`` seconds."""
        if dt < 0:
            raise ValueError("dt must be non-negative")
        if self.n_flocks:
            self._phase += dt * self.fps
            while True:
                over = np.nonzero(self._phase >= self._elen[self._edge])[0]
                if over.size == 0:
                    break
                free = over[self._region[over] < 0]
                reg = over[self._region[over] >= 0]
                for f in reg:
                    if self._count[f] == 0:          # nothing verified left: look ahead now
                        self._pending[f] = False
                        e = self._edge[f]
                        self._look_ahead(int(f), int(self._edst[e]), float(self._yaw[f]),
                                         self._trans[f], forced=True)
                nxt = np.empty(over.size, np.int64)
                isfree = self._region[over] < 0
                if free.size:
                    nxt[isfree] = self._random_edges(free, self._edst[self._edge[free]])
                if reg.size:
                    nxt[~isfree] = self._take_next(reg)
                self._phase[over] -= self._elen[self._edge[over]]
                self._enter(over, nxt)
                self.stats["transitions"] += int(over.size)
            self._plan_ahead()
        self.time += dt
        self._cache = None

    # ------------------------------------------------------------------ outputs
    def _evaluate(self):
        """Positions and velocities of every agent of every flock, in one pass over structure-of-
        arrays data: gather the two frames around each flock's phase through its correspondence
        (blended frames while a transition blends), interpolate, place in the world."""
        if self._cache is not None:
            return self._cache
        N = self.n_agents
        e = self._edge
        k0 = np.minimum(np.floor(self._phase).astype(np.int64), self._elen[e] - 1)
        frac = self._phase - k0
        row = np.where(k0 < self._eblend[e], self._brow0[e], self._row0[e]) + k0
        idx = (row * N)[:, None] + self._perm
        idx1 = idx + N
        comps0 = [np.take(fc, idx) for fc in self._fcomp]
        deltas = [np.take(fc, idx1) for fc in self._fcomp]
        for c0, d in zip(comps0, deltas):
            np.subtract(d, c0, out=d)
        if np.any(frac):
            u = frac.astype(np.float32)[:, None]
            pts = [c0 + u * d for c0, d in zip(comps0, deltas)]
        else:
            pts = comps0
        c = np.cos(self._yaw).astype(np.float32)[:, None]
        s = np.sin(self._yaw).astype(np.float32)[:, None]
        t = self._trans.astype(np.float32)
        fps = np.float32(self.fps)
        x, z = pts[0], pts[-1]
        vx, vz = deltas[0], deltas[-1]
        X = c * x
        X += s * z
        X += t[:, 0:1]
        Z = c * z
        Z -= s * x
        Z += t[:, 2:3]
        cf, sf = c * fps, s * fps
        VX = cf * vx
        VX += sf * vz
        VZ = cf * vz
        VZ -= sf * vx
        if self.dim == 3:
            Y = pts[1] + t[:, 1:2]
            VY = deltas[1] * fps
        else:
            Y = np.broadcast_to(t[:, 1:2], X.shape)
            VY = np.zeros_like(X)
        self._cache = (np.stack([X, Y, Z], axis=-1), np.stack([VX, VY, VZ], axis=-1))
        return self._cache

    def positions(self) -> np.ndarray:
        """(flocks, agents, 3) world positions; row ``i`` is the same agent for the whole walk."""
        return self._evaluate()[0]

    def velocities(self) -> np.ndarray:
        """(flocks, agents, 3) world velocities (m/s) over the current frame interval."""
        return self._evaluate()[1]

    def headings(self) -> np.ndarray:
        """(flocks, agents) heading of each agent's velocity about +Y (0 = +Z), radians."""
        v = self._evaluate()[1]
        return np.arctan2(v[..., 0], v[..., 2])

    def orientations(self) -> np.ndarray:
        """(flocks, agents, 4) w-x-y-z rotations taking +Z to each agent's velocity direction
        (yaw about +Y, then pitch; no roll)."""
        v = self._evaluate()[1].astype(np.float64)
        yaw = np.arctan2(v[..., 0], v[..., 2])
        pitch = np.arctan2(v[..., 1], np.hypot(v[..., 0], v[..., 2]))
        qp = np.zeros(v.shape[:-1] + (4,))
        qp[..., 0] = np.cos(-0.5 * pitch)
        qp[..., 1] = np.sin(-0.5 * pitch)
        return quat.mul(quat.from_yaw(yaw), qp)

    def centroids(self) -> np.ndarray:
        """(flocks, 3) centre of mass of each flock."""
        return self.positions().mean(axis=1, dtype=np.float64)

    def slots(self) -> np.ndarray:
        """(flocks, agents) the clip slot each agent currently plays (cumulative correspondence)."""
        return self._perm.copy()

    def current_edges(self) -> np.ndarray:
        return self._edge.copy()
