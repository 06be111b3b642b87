"""Walking a DDG with many flocks at once (Lai, Chenney and Fan 2005, section 5).

:class:`FlockSystem` advances any number of flocks that share one :class:`~runtime.flock.ddg.DDG`.
Per-tick work is numpy over all flocks (state arrays: current edge, phase, yaw/translation of
the clip in the world, cumulative correspondence); Python runs per flock only when a flock
needs a new stretch of path, which is rare and amortised. The frames are played by
:class:`~runtime.flock.playback.FramePool`.

Correspondence (section 5). ``perm[f, i]`` is the clip slot that agent ``i`` of flock ``f`` uses
(``M_current``); it starts as the identity and becomes ``M_e[perm]`` on entering edge ``e``, so
row ``i`` of :meth:`FlockSystem.positions` is the same agent for the whole walk.

Random walk (section 5.1): at each node an outgoing edge uniformly at random (vectorized).

Region-constrained walk (section 5.2): a flock follows a verified *plan*, a path whose centroid
stays inside its region (:class:`~runtime.flock.lookahead.LookAhead`). A look-ahead for the node
a flock reaches next asks for a path that runs ``search_factor * horizon`` (80 s by default)
beyond its first edge and ends ``safe_depth`` inside. The plan is kept about that long: once
less than ``(search_factor - 1) * horizon`` of it would be left beyond the edge taken at the
next node, a look-ahead *extends* it from its end, so every edge a flock commits to is followed
by at least that much verified future (regions have dead ends tens of seconds deep; see
:mod:`runtime.flock.lookahead`). When the plan's end has no continuation, the plan leads into a
dead end: a fresh search from the next node replaces it (``stats["replans"]`` counts these)
while the dead end is still a plan's length away. A failed look-ahead keeps the plan (or a
verified path lasting longer) and tries again at the next node.

Look-ahead runs ahead of time, under a per-tick budget of node expansions (a flock with nothing
verified left at a node searches at once); if even that fails the flock takes the longest
inside path, or else a recovery path (:meth:`~runtime.flock.lookahead.LookAhead.recovery_path`,
not verified, re-aimed at every node until a verified plan exists), which also brings back a
flock that is outside, e.g. after :meth:`FlockSystem.set_region` (``stats["fallbacks"]``).

Randomness is counter-based (:mod:`runtime.flock.streams`): every flock's walk is reproducible,
independent of the other flocks, and (while the look-ahead budget keeps up) the same for any
tick size.
"""
from __future__ import annotations

import numpy as np

from ..motion import quat
from .containment import EdgeContainment
from .coords import to_xyz, yaw_rotate
from .ddg import DDG
from .lookahead import LookAhead
from .playback import FramePool
from .region import Region
from .streams import (SALT_RANDOM_WALK, SALT_RECOVERY, SALT_SEARCH, SALT_START_NODE, python_random,
                      uniform)

__all__ = ["FlockSystem"]


class FlockSystem:
    """Many flocks walking one DDG. See the module docstring.

    Args:
        ddg: the graph (validated here).
        seed: the walk's seed.
        horizon: seconds; a look-ahead extends a region flock's verified plan by at least this
            much.
        plan_budget: DFS node expansions per :meth:`step` for look-ahead ahead of time.
        search_limit: node expansions per search.
        max_depth: edges a plan may hold; default: twice a search path of
            ``search_factor + 1`` horizons of the graph's shortest edges, at least 96.
        depth_jitter: metres of random slack in the inward bias of the look-ahead.
        safe_depth: metres inside the region a look-ahead path must end, at most half the
            region's inradius.
        search_factor: a look-ahead path must run ``search_factor * horizon`` beyond its first
            edge, and a new look-ahead runs when the plan beyond the edge taken next would be
            shorter than ``(search_factor - 1) * horizon``: with the defaults a flock always
            knows 70-80 s of its future, which is what lets it turn away from dead ends of the
            region in time.
        frame_exact: how edges are tested against a region
            (:class:`~runtime.flock.containment.EdgeContainment`): False, by bounding circles
            and the region's depth grid alone (cheaper; flocks keep about a metre off the
            boundary); True, settling inconclusive circles and frames exactly.

    Outputs (all flocks at once): :meth:`positions`, :meth:`velocities`, :meth:`headings`,
    :meth:`orientations`, :meth:`centroids`; :meth:`slots` and :meth:`current_edges` expose the
    correspondence and graph state, :meth:`planned_frames` the verified plans; ``stats`` counts
    transitions, searches and fallbacks.
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
        self.n_agents = ddg.n_agents
        self.horizon_frames = max(1, int(round(horizon * self.fps)))
        self.search_frames = int(round(search_factor * self.horizon_frames))
        # a plan is extended once it would run less than this beyond the edge taken next
        self.keep_frames = max(self.horizon_frames, self.search_frames - self.horizon_frames)
        if max_depth is None:
            # room for twice a search path (search_factor + 1 horizons) of the shortest edges
            shortest = max(1, int(d["edge_len"].min()))
            max_depth = max(96, 2 * -(-(self.search_frames + self.horizon_frames) // shortest))
        self.cap = int(max_depth)
        self.plan_budget = int(plan_budget)
        self.pool = FramePool(ddg)
        self.pool_bytes = self.pool.nbytes
        self.lookahead = LookAhead(ddg, EdgeContainment(ddg, frame_exact), depth_jitter=depth_jitter,
                                   safe_depth=safe_depth, max_edges=self.cap, search_limit=search_limit,
                                   recovery_frames=2 * self.horizon_frames)
        # graph arrays used per tick
        self._elen = d["edge_len"].astype(np.int64)
        self._eperm = ddg.edge_perm.astype(np.int64)
        self._eyaw = ddg.edge_yaw
        self._etr = d["edge_trans3"]
        self._edst = ddg.edge_dst.astype(np.int64)
        self._out_start = d["out_start"]
        self._out_edges = d["out_edges"]
        self._node_centroid = d["node_centroid"]
        self._node_heading = d["node_heading"]
        # flock state
        self.regions: list[Region] = []
        self._region_ids: dict = {}
        self._alloc(0)
        self.time = 0.0
        self.stats = {"transitions": 0, "searches": 0, "expansions": 0, "replans": 0,
                      "search_failures": 0, "fallbacks": 0}
        self._cache = None

    # ------------------------------------------------------------------ state
    _STATE = ("_edge", "_phase", "_yaw", "_trans", "_perm", "_plan", "_plan_len", "_plan_frames",
              "_pending", "_stuck", "_recover", "_counter", "_region")

    def _alloc(self, n):
        self._edge = np.zeros(n, np.int64)          # current edge
        self._phase = np.zeros(n)                   # frames played of it (fractional)
        self._yaw = np.zeros(n)                     # its segment -> world: yaw about +Y ...
        self._trans = np.zeros((n, 3))              # ... then this translation
        self._perm = np.zeros((n, self.n_agents), np.int64)   # cumulative correspondence
        self._plan = np.zeros((n, self.cap), np.int64)        # verified path after the current edge
        self._plan_len = np.zeros(n, np.int64)      # edges in the plan
        self._plan_frames = np.zeros(n, np.int64)   # frames in the plan
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
            tries += [int(x * V) for x in uniform(self.seed, f, np.arange(32, dtype=np.uint64), SALT_START_NODE)]
            for t, v in enumerate(tries):
                # place node v's configuration: centroid at the position, mean velocity along heading
                yaw0 = float(headings[j] - self._node_heading[v])
                tr0 = positions[j] - yaw_rotate(to_xyz(self._node_centroid[v])[None], np.array([yaw0]))[0]
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
        """Random walk (section 5.1): a uniformly random out-edge of each node (vectorized)."""
        deg = self._out_start[nodes + 1] - self._out_start[nodes]
        u = uniform(self.seed, flocks.astype(np.uint64), self._counter[flocks], SALT_RANDOM_WALK)
        self._counter[flocks] += np.uint64(1)
        return self._out_edges[self._out_start[nodes] + np.minimum((u * deg).astype(np.int64), deg - 1)]

    def _set_plan(self, f, path):
        path = list(path)[: self.cap]
        self._plan[f, :len(path)] = path
        self._plan_len[f] = len(path)
        self._plan_frames[f] = int(self._elen[path].sum()) if path else 0
        self._stuck[f] = False
        self._recover[f] = False

    def _take_next(self, flocks):
        """Pop the first planned edge of each flock (all have a plan)."""
        e = self._plan[flocks, 0].copy()
        self._plan[flocks, :-1] = self._plan[flocks, 1:]
        self._plan_len[flocks] -= 1
        self._plan_frames[flocks] -= self._elen[e]
        return e

    def _random(self, f, salt):
        """Flock ``f``'s next :class:`random.Random` (advances its stream)."""
        rnd = python_random(self.seed, f, self._counter[f], salt)
        self._counter[f] += np.uint64(1)
        return rnd

    def _search(self, f, region, v, yaw, trans, need, prefix=()):
        self.stats["searches"] += 1
        path, found, spent = self.lookahead.search(self._random(f, SALT_SEARCH), region, v, yaw, trans,
                                                   need, prefix)
        self.stats["expansions"] += spent
        return path, found

    def _follow_recovery_path(self, f, region, v, yaw, trans):
        path, spent = self.lookahead.recovery_path(self._random(f, SALT_RECOVERY), region, v, yaw, trans)
        self.stats["expansions"] += spent
        self._set_plan(f, path)
        self._recover[f] = True

    def _look_ahead(self, f, v, yaw, trans, forced=False) -> bool:
        """Keep flock ``f``'s verified plan long (the clip arriving at node ``v`` placed by
        ``yaw, trans``; the plan's first edge is the one taken at ``v``). First the plan is
        extended from its end, so that it runs ``search_factor * horizon`` beyond its first
        edge and ends ``safe_depth`` inside. If its end has no such continuation (the plan
        leads towards a dead end of the region: a place from which every path leaves it), a
        fresh search from ``v`` replaces the plan while the flock is still far from that end
        (``stats['replans']`` counts these fresh searches). Without either the remaining
        (verified) plan is kept, or a verified path lasting longer, and the next node tries
        again; a flock with no plan left (``forced``) takes the longest inside path, or a
        recovery path (``stats['fallbacks']``). Returns whether a full path was found."""
        region = self.regions[self._region[f]]
        need = self.search_frames
        if self._recover[f]:
            # on a recovery path: back to a verified plan as soon as there is one (a horizon of it
            # is enough to start with: the next look-ahead extends it), else re-aim
            path, found = self._search(f, region, v, yaw, trans, self.horizon_frames)
            if found:
                self._set_plan(f, path)
                return True
            self._follow_recovery_path(f, region, v, yaw, trans)
            return False
        n = int(self._plan_len[f])
        if n and not self._stuck[f]:
            path, found = self._search(f, region, v, yaw, trans, need, self._plan[f, :n].tolist())
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
        if path and int(self._elen[path].sum()) > int(self._plan_frames[f]) and not forced:
            self._set_plan(f, path)
        if forced and self._plan_len[f] == 0:
            self.stats["fallbacks"] += 1
            if path:
                self._set_plan(f, path)
            else:
                self._follow_recovery_path(f, region, v, yaw, trans)
        return False

    def _plan_ahead(self):
        """Budgeted look-ahead for the node each region flock reaches next (soonest first)."""
        todo = np.nonzero(self._pending)[0]
        if todo.size == 0:
            return
        # most urgent first: the flock whose verified plan runs out soonest
        left = self._plan_frames[todo] + self._elen[self._edge[todo]] - self._phase[todo]
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
        """Flocks at the end of their edge enter edge ``e`` (section 5: M' = M_e(M))."""
        y = self._yaw[flocks]
        self._trans[flocks] += yaw_rotate(self._etr[e], y)
        self._yaw[flocks] = y + self._eyaw[e]
        self._perm[flocks] = np.take_along_axis(self._eperm[e], self._perm[flocks], axis=1)
        self._edge[flocks] = e
        # look ahead when the verified plan beyond the edge taken at the next node (the edge
        # this look-ahead commits) would be shorter than keep_frames; on a recovery path, always
        cnt = self._plan_len[flocks]
        nxt = np.where(cnt > 0, self._elen[self._plan[flocks, 0]], 0)
        short = (self._plan_frames[flocks] - nxt < self.keep_frames) | self._recover[flocks]
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
                for f in reg[self._plan_len[reg] == 0]:  # nothing verified left: look ahead now
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
        if self._cache is None:
            self._cache = self.pool.evaluate(self._edge, self._phase, self._perm, self._yaw, self._trans)
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

    def planned_frames(self) -> np.ndarray:
        """(flocks,) frames of each flock's plan beyond its current edge (verified unless the
        flock follows a recovery path; 0 for a free flock between nodes)."""
        return self._plan_frames.copy()
