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
A path counts when it runs ``search_factor * horizon`` (80 s by default) beyond its first edge
and ends ``safe_depth`` inside. The plan is kept about that long: once less than
``(search_factor - 1) * horizon`` of it would be left beyond the edge taken at the next node,
a look-ahead *extends* it from its end (a few expansions), so every edge a flock commits to is
followed by at least that much verified future.

Why so far ahead: a region has dead ends -- states (node, position, heading) from which every
path of the graph leaves the region sooner or later, e.g. a flock skimming a wall on a run of
single-exit nodes. They can be tens of seconds deep, and a look-ahead that sees only part of
the way commits to them and finds out when no choice is left. (Measured on the 3D test graph,
a 70 x 40 x 70 m box: one committed edge left a flock 24.5 s from certain exit; on sparser 3D
graphs and smaller boxes dead ends of 40 s and more occur. The previous walk verified 20 s
per search and searched again only once the plan *after the current edge* was under 10 s, so
an edge taken next could be followed by 5 s of verified future.) When the plan's end has no
continuation, the plan leads into a dead end: a fresh search from the next node replaces it
(``stats["replans"]`` counts these) while the dead end is still a plan's length away. A failed
look-ahead keeps the plan (or a verified path lasting longer) and tries again at the next node.
(Measured: 20 flocks for 10 minutes on graphs of 16 recordings per dimension, 5 walk seeds,
the test regions, plus 50 x 30 x 50 m boxes and a 60 m L: no flock left its region in 192 runs;
with the previous walk flocks left in 56 of 112 of those runs.)
Look-ahead runs ahead of time, under a per-tick budget of node expansions (a flock with nothing
verified left at a node searches at once); if even that fails the flock takes the longest
inside path, or else a recovery path (:meth:`FlockSystem._recovery_path`: the most time deep
inside over the next ``2 * horizon``, not verified, re-aimed at every node until a verified
plan exists), which also brings back a flock that is outside, e.g. after
:meth:`FlockSystem.set_region` (``stats["fallbacks"]``, zero in the tests and benchmarks).

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

    Parameters: ``seed``; ``horizon`` (seconds: a look-ahead extends a region flock's verified
    plan by at least this much); ``search_factor`` (a look-ahead path must run
    ``search_factor * horizon`` beyond its first edge, and a new look-ahead runs when the plan
    beyond the edge taken next would be shorter than ``(search_factor - 1) * horizon``: with
    the defaults a flock always knows 70-80 s of its future, which is what lets it turn away
    from dead ends of the region in time -- see the module docstring); ``safe_depth`` (metres
    inside the region a look-ahead path must end, at most half the region's inradius);
    ``depth_jitter`` (metres of random slack in the inward bias); ``plan_budget`` (DFS node
    expansions per :meth:`step` for look-ahead ahead of time); ``search_limit`` (expansions per
    search); ``max_depth`` (edges a plan may hold; default: twice a search path of
    ``search_factor + 1`` horizons of the graph's shortest edges, at least 96); ``frame_exact``
    (False: an edge counts as inside only if circles around runs of 8 frames of its centroid
    track are certified inside by the region's depth grid alone -- an inconclusive grid cell
    counts as outside, so no exact polygon test runs; cheaper, and it keeps flocks a circle
    radius plus a grid cell, typically about a
    metre, off the boundary; True: inconclusive circles are settled exactly and frames near the
    boundary are tested one by one).

    Outputs (all flocks at once): :meth:`positions`, :meth:`velocities`, :meth:`headings`,
    :meth:`orientations`, :meth:`centroids`; :meth:`slots` and :meth:`current_edges` expose the
    correspondence and graph state; ``stats`` counts transitions, searches and fallbacks.
    """

    def __init__(self, ddg: DDG, *, seed: int = 0, horizon: float = 10.0, plan_budget: int = 100,
                 search_limit: int = 800, max_depth: int | None = None, depth_jitter: float = 10.0,
                 safe_depth: float = 10.0, search_factor: float = 8.0, frame_exact: bool = False):
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
        # a plan is extended once it would run less than this beyond the edge taken next
        self.keep_frames = max(self.horizon_frames, self.search_frames - self.horizon_frames)
        self.depth_jitter = float(depth_jitter)
        self.safe_depth = float(safe_depth)
        self.frame_exact = bool(frame_exact)
        self._safe: dict = {}
        self._info: dict = {}
        self._fast: dict = {}
        if max_depth is None:
            # room for twice a search path (search_factor + 1 horizons) of the shortest edges
            shortest = max(1, int(d["edge_len"].min()))
            max_depth = max(96, 2 * -(-(self.search_frames + self.horizon_frames) // shortest))
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
        self._eend_l = [tuple(r) for r in track[ts[1:] - 1].tolist()]   # centroid at each edge's end
        # flock state
        self.regions: list[Region] = []
        self._region_ids: dict = {}
        self._alloc(0)
        self.time = 0.0
        self.stats = {"transitions": 0, "searches": 0, "expansions": 0, "replans": 0,
                      "search_failures": 0, "fallbacks": 0}
        self._cache = None

    # ------------------------------------------------------------------ state
    _STATE = ("_edge", "_phase", "_yaw", "_trans", "_perm", "_plan_buf", "_count", "_backup",
              "_pending", "_stuck", "_recover", "_counter", "_region")

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
        self._stuck = np.zeros(n, bool)             # the plan's end has no verified extension
        self._recover = np.zeros(n, bool)           # the plan is a recovery path (not verified)
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
                self._set_plan(f, [])
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
        self._set_plan(flock, [])
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
        self._stuck[f] = False
        self._recover[f] = False

    def _take_next(self, flocks):
        """Pop the first planned edge of each flock (all have count > 0)."""
        e = self._plan_buf[flocks, 0].copy()
        self._plan_buf[flocks, :-1] = self._plan_buf[flocks, 1:]
        self._count[flocks] -= 1
        self._backup[flocks] -= self._elen[e]
        return e

    _CHUNK = 8     # centroid samples per bounding circle in the look-ahead
    _ROLLOUTS = 32  # random walks a recovery path is chosen from

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

    def _search(self, f, region, v, yaw, trans, need, prefix=()):
        """Depth-first look-ahead (paper 5.2) from node ``v`` with the clip placed by (yaw, trans):
        out-edges in random order (biased towards the inside), the first path whose centroid
        stays inside, that runs ``need`` frames beyond its first edge and ends at least the safe
        depth inside. ``prefix`` (the flock's plan, verified already) is taken as given and the
        search extends it from its end. Returns ``(path, found)``, ``path`` including the
        prefix; when not found, the longest inside path seen."""
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
        y = float(yaw)
        tx, ty, tz = (float(a) for a in trans)
        path = list(prefix)
        frames = 0
        for e in path:                       # the placement at the end of the prefix
            frames += elen[e]
            c, s = math.cos(y), math.sin(y)
            ex, ey, ez = etr[e]
            tx, ty, tz = tx + c * ex + s * ez, ty + ey, tz - s * ex + c * ez
            y += eyaw[e]
            v = edst[e]
        base = len(path)
        best, best_frames = list(path), frames
        if base >= self.cap:
            return best, False
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
        """Keep flock ``f``'s verified plan long (the clip arriving at node ``v`` placed by
        ``yaw, trans``; the plan's first edge is the one taken at ``v``). First the plan is
        extended from its end, so that it runs ``search_factor * horizon`` beyond its first
        edge and ends ``safe_depth`` inside. If its end has no such continuation (the plan
        leads towards a dead end of the region: a place from which every path leaves it), a
        fresh search from ``v`` replaces the plan while the flock is still far from that end
        (``stats['replans']`` counts these fresh searches). Without either the remaining
        (verified) plan is kept, or a verified path lasting longer, and the next node tries
        again; a flock with no plan left takes the longest inside path, or a recovery path
        (``stats['fallbacks']``)."""
        region = self.regions[self._region[f]]
        need = self.search_frames
        if self._recover[f]:
            # on a recovery path: back to a verified plan as soon as there is one (a horizon of it
            # is enough to start with: the next look-ahead extends it), else re-aim
            path, found = self._search(f, region, v, yaw, trans, self.horizon_frames)
            if found:
                self._set_plan(f, path)
                return True
            self._set_plan(f, self._recovery_path(f, region, v, yaw, trans))
            self._recover[f] = True
            return False
        n = int(self._count[f])
        if n and not self._stuck[f]:
            path, found = self._search(f, region, v, yaw, trans, need, self._plan_buf[f, :n].tolist())
            if found:
                self._set_plan(f, path)
                return True
            self._stuck[f] = True            # the same end fails again: fresh searches until it changes
            self.stats["replans"] += 1
        path, found = self._search(f, region, v, yaw, trans, need)
        if found:
            self._set_plan(f, path)
            return True
        self.stats["search_failures"] += 1
        # no full path: still keep whichever verified way to stay inside lasts longer
        if path and int(self._elen[path].sum()) > int(self._backup[f]) and not forced:
            self._set_plan(f, path)
        if forced and self._count[f] == 0:
            self.stats["fallbacks"] += 1
            if path:
                self._set_plan(f, path)
            else:
                self._set_plan(f, self._recovery_path(f, region, v, yaw, trans))
                self._recover[f] = True
        return False

    def _recovery_path(self, f, region, v, yaw, trans) -> list:
        """Last resort, when no out-edge of node ``v`` stays inside (the flock is about to
        leave, or is outside already, e.g. after :meth:`set_region`): of ``_ROLLOUTS`` random
        walks of ``2 * horizon`` from ``v`` (the first one always taking the edge ending
        deepest, the others a random edge or, half the time, that one), the one with the
        largest time-averaged depth (sampled at edge ends, counted up to ``safe_depth``): it
        gets in soonest and stays in, rather than swinging out to end deep, and random walks
        find the turns a flock heading away needs (a depth-first search spends its budget on
        the last edges of one such walk). Such a plan is not verified: the flock looks ahead
        again at every node (a verified plan replaces it as soon as there is one, else a new
        recovery path), so it heads back in."""
        depth = region.depth_point
        elen, eyaw, etr, edst, eend = self._elen_l, self._eyaw_l, self._etr_l, self._edst_l, self._eend_l
        out_start, out_edges = self._out_start, self._out_edges
        limit = 2 * self.horizon_frames
        safe = self._safe_depth(region)
        rnd = random.Random(int(_uniform(self.seed, f, self._counter[f], 5) * 2.0 ** 53))
        self._counter[f] += np.uint64(1)
        y0 = float(yaw)
        t0 = tuple(float(a) for a in trans)
        best, best_score = None, float("-inf")
        evals = 0
        for r in range(self._ROLLOUTS):
            node, y, (tx, ty, tz) = v, y0, t0
            frames, acc, path = 0, 0.0, []
            while frames < limit and len(path) < self.cap:
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
                ex, ey, ez = etr[e]
                tx, ty, tz = tx + c * ex + s * ez, ty + ey, tz - s * ex + c * ez
                y += eyaw[e]
                node = edst[e]
            if acc / frames > best_score:
                best, best_score = path, acc / frames
        self.stats["expansions"] += evals
        return best

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
        # look ahead when the verified plan beyond the edge taken at the next node (the edge
        # this look-ahead commits) would be shorter than keep_frames; on a recovery path, always
        cnt = self._count[flocks]
        nxt = np.where(cnt > 0, self._elen[self._plan_buf[flocks, 0]], 0)
        short = (self._backup[flocks] - nxt < self.keep_frames) | self._recover[flocks]
        self._pending[flocks] = (self._region[flocks] >= 0) & (cnt < self.cap) & short

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
                for f in reg[self._count[reg] == 0]:  # nothing verified left: look ahead now
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
