"""A tiled interaction zone: interactive tiling (Kim, Hwang, Hyun and Lee 2012, section 5.3) as a
system of the runtime :class:`~runtime.world.World` tick.

A zone is a rectangle of the world where small teams of characters are animated by stitching
motion patches (:class:`~runtime.tiling.interactive.InteractiveTiling`): each team has a list of
target spots it visits in turn (``period`` seconds each, all teams switching together, so they
cross and meet), or a target set at run time (:meth:`TilingZone.set_target`, e.g. a right-click
in the viewer). The world steps every zone once per tick after the flocks; the zone's
characters are drawn with the crowd (their poses come from the patch library's pose tables)
and can be baked (:meth:`TilingZone.tracks`) and checked (:meth:`TilingZone.check`, the
independent checker of :mod:`runtime.tiling.check`).

Limits: characters never leave the zone rectangle (the tiler's region) and avoid the world's
obstacles inside it (their bounding boxes); the crowd planner does not see tiled characters, so
a zone should be fenced off in the world (its fence is an obstacle for the crowd's roadmap).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..motion.planar import rotate_xz_scalar
from ..pose import PoseState
from .check import check_tiling
from .interactive import InteractiveTiling
from .prepared import PreparedLibrary
from .region import Obstacle

__all__ = ["TeamSpec", "TilingZone", "environment_obstacles"]


@dataclass
class TeamSpec:
    """``count`` characters starting on a grid around ``start`` (x, z) facing ``heading``
    (radians, 0 = +Z), visiting ``targets`` [(x, z), ...] in turn (empty: stand by)."""
    count: int
    start: tuple
    heading: float = 0.0
    targets: list = field(default_factory=list)


def environment_obstacles(env, bounds, margin: float = 0.5) -> list:
    """The world's obstacles near the zone as the tiler's oriented boxes (axis-aligned boxes
    around each footprint: conservative)."""
    if env is None:
        return []
    x0, z0, x1, z1 = bounds
    out = []
    for k, poly in enumerate(env.polygons):
        lo, hi = poly.min(0), poly.max(0)
        if hi[0] < x0 - margin or lo[0] > x1 + margin or hi[1] < z0 - margin or lo[1] > z1 + margin:
            continue
        out.append(Obstacle((lo + hi) / 2, tuple((hi - lo) / 2), 0.0, 2.0, env.obstacle_paths[k]))
    for k, (cx, cz, r) in enumerate(env.circles):
        if cx + r < x0 - margin or cx - r > x1 + margin or cz + r < z0 - margin or cz - r > z1 + margin:
            continue
        out.append(Obstacle((cx, cz), (r, r), 0.0, 2.0, env.obstacle_paths[len(env.polygons) + k]))
    return out


class TilingZone:
    """One zone: an :class:`InteractiveTiling` over ``bounds`` (x0, z0, x1, z1) with its teams."""

    def __init__(self, name: str, library, bounds, teams, period: float = 8.0, horizon: float = 1.5,
                 seed: int = 0, obstacles=(), start_time: float = 0.0, **tiling_kw):
        x0, z0, x1, z1 = (float(v) for v in bounds)
        if not (x1 > x0 and z1 > z0):
            raise ValueError(f"tiling zone {name!r}: bounds {bounds} are empty")
        if period <= 0:
            raise ValueError(f"tiling zone {name!r}: period must be positive, got {period}")
        self.name = name
        self.bounds = (x0, z0, x1, z1)
        self.period = float(period)
        prepared = library if isinstance(library, PreparedLibrary) else PreparedLibrary(library)
        self.library = prepared.library
        kw = dict(interaction_labels=("meet",))
        kw.update(tiling_kw)
        self.tiling = InteractiveTiling(prepared, horizon=horizon, seed=seed, obstacles=list(obstacles),
                                        bounds=self.bounds, **kw)
        self.tiling.step(t=start_time)
        self.teams = [t if isinstance(t, TeamSpec) else TeamSpec(**t) for t in teams]
        self.names: list[str] = []
        for ti, team in enumerate(self.teams):
            side = int(math.ceil(math.sqrt(max(team.count, 1))))
            rows = int(math.ceil(team.count / side)) if team.count else 0
            for k in range(team.count):
                r, c = divmod(k, side)
                off = np.array([1.5 * (c - 0.5 * (side - 1)), 1.5 * (r - 0.5 * (rows - 1))])
                # the grid is laid out across the heading (x lateral, z forward)
                pos = np.asarray(team.start, float) + rotate_xz_scalar(off, team.heading)
                if not (x0 < pos[0] < x1 and z0 < pos[1] < z1):
                    raise ValueError(f"tiling zone {name!r}: team {ti} character {k} starts at "
                                     f"({pos[0]:.2f}, {pos[1]:.2f}), outside the zone {self.bounds}")
                self.tiling.add_character(tuple(pos), team.heading, ti)
                self.names.append(f"{name}_{ti}_{k}")
        self._leg = -1
        self._override: dict = {}
        self.step_ms = 0.0

    def __len__(self):
        return self.tiling.n

    # -- control -------------------------------------------------------------------------------
    def set_target(self, team: int, xz) -> None:
        """Send a team to ``xz`` (clamped into the zone); it stays there until the schedule's
        next leg."""
        x0, z0, x1, z1 = self.bounds
        p = (min(max(float(xz[0]), x0 + 1.0), x1 - 1.0), min(max(float(xz[1]), z0 + 1.0), z1 - 1.0))
        self._override[int(team)] = p
        self.tiling.set_target(int(team), p)

    def team_of(self, i: int) -> int:
        return int(self.tiling.team[i])

    def _schedule(self, t: float) -> None:
        leg = int(t // self.period)
        if leg == self._leg:
            return
        self._leg = leg
        self._override.clear()
        for ti, team in enumerate(self.teams):
            if team.targets:
                self.tiling.set_target(ti, team.targets[leg % len(team.targets)])

    # -- the tick ------------------------------------------------------------------------------
    def step(self, t: float) -> None:
        """Advance to world time ``t`` and fill the horizon (the world calls this every tick)."""
        self._schedule(t)
        self.tiling.step(t=t)
        self.step_ms = self.tiling.last_tick_ms

    def frame_at(self, t: float) -> int:
        return int(round(t * self.tiling.fps))

    def pose_state(self, frame: int | None = None):
        """(frames_a, frames_b, blend, root) of every character at tiling clock ``frame``
        (default: now) into the patch library's pose tables (a ``runtime.pose.PoseState``)."""
        a, b, w, root = self.tiling.pose_refs(frame)
        return PoseState(a.copy(), b.copy(), w.copy(), root.copy())

    def roots(self, frame: int | None = None) -> np.ndarray:
        return self.tiling.root_states(frame)

    # -- output --------------------------------------------------------------------------------
    def tracks(self) -> dict:
        """name -> :class:`~runtime.crowd.tracks.Track` (patch-library frames) of every character
        from its start to the last committed frame."""
        return {self.names[i]: tr.to_track() for i, tr in enumerate(self.tiling.tracks())}

    def check(self):
        """The independent checker's report (:func:`runtime.tiling.check.check_tiling`) of
        everything tiled so far."""
        return check_tiling(self.tiling.result())
