"""TrackScene: a stand-in scene source for the viewer, its tests and benchmarks.

N characters walk the default library's motion graph: each plays a walking-state edge at the
library rate and, at the edge's end hub, takes (among 32 out edges sampled at random) the one
whose end lands closest to the character's current way point (random points in the free space;
a ``command_go_to`` replaces it), avoiding edges whose middle or end is within the clearance of
an obstacle, with a little noise for variety. Roots are
composed from the graph's per-frame root path (``frame_xz``, ``frame_heading``) and edge
displacements (``edge_disp``). It is a greedy wander, not a planner: characters do not avoid
each other and may clip corners. Everything is vectorized over characters; random choices
come from one seeded ``numpy.random.Generator``.

Poses are rendered through :class:`runtime.pose.PoseBatch` (interpolated between ticks), on
the fixed-step clock the World uses (:class:`runtime.clock.FixedStep`). The scene implements
every member of :class:`runtime.view.InteractiveSceneView`, so the viewer code paths
exercised here are the ones a :class:`runtime.World` uses.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..clock import FixedStep
from ..crowd.environment import Environment
from ..motion.planar import compose
from ..pose import PoseBatch, PoseState

__all__ = ["TrackScene"]


class TrackScene:
    """``n`` characters wandering an :class:`Environment` on the library ``graph``.

    ``area`` (xmin, zmin, xmax, zmax) bounds the way points (default: the environment's bounds
    grown by 2 m, or a 30 m square for open ground). ``flock`` adds that many flock agents
    circling the area in a loose formation (exercises the viewer's flock batch). ``dt`` is
    the tick (default 1/30 s). ``obstacle_heights`` is passed through to the viewer."""

    def __init__(self, graph, n: int, environment: Environment | None = None, seed: int = 0,
                 dt: float = 1.0 / 30.0, area=None, flock: int = 0, obstacle_heights=None,
                 clearance: float = 0.45):
        self.graph = graph
        self.skeleton = graph.skeleton
        self.environment = environment if environment is not None else Environment.open_ground()
        self.obstacle_heights = obstacle_heights
        self.dt = float(dt)
        self.rng = np.random.default_rng(seed)
        self.clearance = float(clearance)
        env = self.environment
        if area is None:
            area = env.bounds(2.0) if (env.num_obstacles or env.markers) else (-15.0, -15.0, 15.0, 15.0)
        self.area = tuple(float(v) for v in area)
        self._sdf = env.sdf(resolution=0.1, margin=3.0) if env.num_obstacles else None
        if self._sdf is not None:
            lo = self._sdf.origin
            self._sdf_box = (lo, lo + (np.array(self._sdf.shape) - 1) * self._sdf.resolution)
        self._build_choices()
        self.n = int(n)
        self.time = 0.0
        self.ticks = 0
        self.clock = FixedStep(self.dt)
        self.selected: int | None = None
        self.commands: list[tuple[int, np.ndarray]] = []
        self._tick_ms = 0.0
        self._pose_ms = 0.0
        # initial state: random walking edge, random position along it, free spot, random heading
        walk = self._walk_edges
        self.edge = walk[self.rng.integers(0, len(walk), self.n)]
        frames = graph.edge_frames[self.edge]
        self.u = self.rng.random(self.n) * (frames - 1)
        pos = self._free_points(self.n)
        self.origin = np.column_stack([pos, self.rng.uniform(-math.pi, math.pi, self.n)])
        # shift the origin so the current frame (not the edge start) sits at the free spot
        here = self._root_at(self.edge, self.u, self.origin)
        self.origin[:, :2] += pos - here[:, :2]
        self.goal = self._free_points(self.n)
        self.commanded = np.zeros(self.n, dtype=bool)
        self.batch = PoseBatch(graph)
        self.batch.push(self.pose_state())
        # flock agents
        self.m = int(flock)
        self._flock_phase = self.rng.uniform(0, 2 * math.pi, self.m)
        self._flock_offset = self.rng.normal(size=(self.m, 2)) * 1.2

    # -- graph tables ------------------------------------------------------------------------------
    def _build_choices(self):
        g = self.graph
        walking = g.state_index("walking")
        edges = np.flatnonzero((g.edge_state == walking) & (g.node_state[g.edge_src] == walking)
                               & (g.node_state[g.edge_dst] == walking))
        if len(edges) == 0:
            edges = np.arange(g.num_edges)
        self._walk_edges = edges
        # padded candidate table: cand[node, k] = k-th allowed out edge of node, -1 padding
        src = g.edge_src[edges]
        counts = np.bincount(src, minlength=g.num_nodes)
        # nodes without a walking out edge fall back to all their out edges
        lacking = np.flatnonzero(counts == 0)
        extra = np.flatnonzero(np.isin(g.edge_src, lacking))
        allowed = np.concatenate([edges, extra])
        src = g.edge_src[allowed]
        order = np.argsort(src, kind="stable")
        allowed, src = allowed[order], src[order]
        counts = np.bincount(src, minlength=g.num_nodes)
        K = max(1, int(counts.max()))
        start = np.cumsum(counts) - counts
        col = np.arange(len(allowed)) - start[src]
        cand = np.full((g.num_nodes, K), -1, dtype=np.int64)
        cand[src, col] = allowed
        self._cand = cand
        self._cand_count = counts
        self._mid = (g.edge_start[:-1] + g.edge_start[1:]) // 2

    # -- state ---------------------------------------------------------------------------------------
    def _root_at(self, edge, u, origin):
        g = self.graph
        a = np.floor(u).astype(np.int64)
        a = np.minimum(a, g.edge_frames[edge] - 2)
        t = u - a
        fa = g.edge_start[edge] + a
        fb = fa + 1
        xz = g.frame_xz[fa] * (1 - t)[:, None] + g.frame_xz[fb] * t[:, None]
        h = g.frame_heading[fa] * (1 - t) + g.frame_heading[fb] * t
        return compose(origin, np.column_stack([xz, h]))

    def pose_state(self, root=None) -> PoseState:
        g = self.graph
        a = np.minimum(np.floor(self.u).astype(np.int64), g.edge_frames[self.edge] - 2)
        t = (self.u - a).astype(np.float32)
        fa = g.edge_start[self.edge] + a
        return PoseState(fa, fa + 1, t, self.roots() if root is None else root)

    def roots(self) -> np.ndarray:
        """Current planar roots (N, 3): x, z, heading."""
        return self._root_at(self.edge, self.u, self.origin)

    def _clearance(self, xz) -> np.ndarray:
        """Distance to the nearest obstacle from the SDF grid; points outside the grid (which
        covers the obstacles with a 3 m margin) count as clear."""
        xz = np.asarray(xz, dtype=np.float64)
        out = np.full(xz.shape[:-1], 1e9)
        if self._sdf is None:
            return out
        lo, hi = self._sdf_box
        inside = np.all((xz >= lo) & (xz <= hi), axis=-1)
        if inside.any():
            out[inside] = self._sdf.sample(xz[inside])
        return out

    def _free_points(self, k: int, tries: int = 8) -> np.ndarray:
        x0, z0, x1, z1 = self.area
        pts = np.column_stack([self.rng.uniform(x0, x1, (k, tries)).ravel(),
                               self.rng.uniform(z0, z1, (k, tries)).ravel()]).reshape(k, tries, 2)
        if self._sdf is None:
            return pts[:, 0]
        ok = self._clearance(pts) > self.clearance + 0.2
        first = np.where(ok.any(axis=1), ok.argmax(axis=1), 0)
        return pts[np.arange(k), first]

    # -- ticking -------------------------------------------------------------------------------------
    def tick(self) -> None:
        """One fixed step: advance every character one tick along its edge, choosing next
        edges for those that reached an end hub."""
        t0 = time.perf_counter()
        g = self.graph
        self.u += self.dt * g.fps
        for _ in range(8):  # edges are >= 1 frame long: a tick crosses at most a few hubs
            last = g.edge_frames[self.edge] - 1
            done = np.flatnonzero(self.u >= last)
            if len(done) == 0:
                break
            e = self.edge[done]
            self.origin[done] = compose(self.origin[done], g.edge_disp[e])
            self.u[done] -= last[done]
            self.edge[done] = self._choose(done, g.edge_dst[e])
        # new way points for those that arrived
        r = self.roots()
        near = np.flatnonzero(np.hypot(r[:, 0] - self.goal[:, 0], r[:, 1] - self.goal[:, 1]) < 1.5)
        if len(near):
            self.goal[near] = self._free_points(len(near))
            self.commanded[near] = False
        t1 = time.perf_counter()
        self.batch.push(self.pose_state(r))
        self._pose_ms = (time.perf_counter() - t1) * 1e3
        self._tick_ms = (time.perf_counter() - t0) * 1e3
        self.ticks += 1
        self.time += self.dt

    def _choose(self, idx, nodes, samples: int = 32):
        """Next edge for characters ``idx`` standing at hub ``nodes``: among ``samples`` random
        out edges (with replacement; hubs can have a hundred), the one ending nearest the way
        point, avoiding obstacles."""
        g = self.graph
        cnt = self._cand_count[nodes]
        pick = np.floor(self.rng.random((len(idx), samples)) * cnt[:, None]).astype(np.int64)
        cand = self._cand[nodes[:, None], pick]                    # (M, S)
        valid = cand >= 0
        ce = np.where(valid, cand, 0)
        org = self.origin[idx][:, None, :]
        end = compose(org, g.edge_disp[ce])                        # (M, K, 3)
        mid_local = np.concatenate([g.frame_xz[self._mid[ce]], g.frame_heading[self._mid[ce]][..., None]], axis=-1)
        mid = compose(org, mid_local)
        score = np.hypot(*(end[..., :2] - self.goal[idx][:, None, :]).transpose(2, 0, 1))
        score += self.rng.random(score.shape) * 0.6
        if self._sdf is not None:
            clear = np.minimum(self._clearance(end[..., :2]), self._clearance(mid[..., :2]))
            score += np.where(clear < self.clearance, 100.0 + 10.0 * (self.clearance - clear), 0.0)
        score[~valid] = np.inf
        return cand[np.arange(len(idx)), np.argmin(score, axis=1)]

    # -- the scene protocol --------------------------------------------------------------------------
    def step(self, dt: float) -> None:
        """Advance ``dt`` seconds: whole ticks from the clock, the rest is interpolation."""
        for _ in range(self.clock.advance(dt)):
            self.tick()

    @property
    def alpha(self) -> float:
        """Fraction of a tick since the last tick (render interpolation)."""
        return self.clock.alpha

    def joint_positions(self) -> np.ndarray:
        return self.batch.positions(self.alpha)

    def flock_positions(self):
        if self.m == 0:
            return np.zeros((0, 3)), np.zeros(0)
        x0, z0, x1, z1 = self.area
        cx, cz = (x0 + x1) / 2, (z0 + z1) / 2
        R = 0.35 * min(x1 - x0, z1 - z0)
        w = 0.12
        th = w * (self.time + self.alpha * self.dt)
        centre = np.array([cx + R * math.cos(th), cz + R * math.sin(th)])
        vel = np.array([-math.sin(th), math.cos(th)])
        wob = 0.3 * np.stack([np.sin(1.3 * th * 10 + self._flock_phase), np.cos(1.1 * th * 10 + self._flock_phase)], -1)
        pos = centre + self._flock_offset + wob
        heading = math.atan2(vel[0], vel[1]) + 0.15 * np.sin(th * 7 + self._flock_phase)
        return np.column_stack([pos[:, 0], np.zeros(self.m), pos[:, 1]]), heading

    def hud_stats(self) -> dict:
        return {"tick ms": self._tick_ms, "synthesis ms": 0.0, "pose ms": self._pose_ms,
                "characters": self.n, "agents": self.m, "queue": int(self.commanded.sum()),
                "sim time": self.time}

    def select(self, i) -> None:
        self.selected = None if i is None else int(i)

    def command_go_to(self, i: int, xz) -> None:
        xz = np.asarray(xz, dtype=np.float64).reshape(2)
        self.commands.append((int(i), xz.copy()))
        self.goal[int(i)] = xz
        self.commanded[int(i)] = True
