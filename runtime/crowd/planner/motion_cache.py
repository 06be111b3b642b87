"""Reuse of searched motions between characters with the same task.

A segment's search (Sung, Kovar and Gleicher 2005, section 3.3) depends on where the character starts only through
the obstacles and the characters around it: its motion, relative to its start configuration,
is a function of the start node, the goal relative to the start (position and heading in the
start's frame), the goal's pose nodes and its time window relative to the start. Crowds are
full of repeated tasks -- the paper's grids send 300 and 500 characters the same few offsets
(Figure 10: 3 distinct tasks among grid500's 500 characters) -- so a motion found for one
character is tried first for the next with the same task: placed rigidly at its start (a
rotation about +Y and a translation, which changes neither the clips, the displacement maps'
per-frame adjustment nor the timing), corrected by the residual of the key's rounding (at most
``QUANTUM`` m and rad, spread linearly over the motion so the goal is met exactly), and given
the same final collision test (section 3.3) as any searched splice. Only if every stored motion
for the task collides does the character search; a clean search result is stored in turn.

Limits (beside the code, Recast style):

* ``QUANTUM`` = 1e-6 (m, rad, s): tasks closer than this share a key. The correction it may
  need is <= 1e-6 m / 1e-6 rad over the whole motion -- 1/1000 of the checker's 1 mm and
  1/1700 of its 0.1 deg.
* ``PER_TASK`` = 8 motions per task, most recently used first (a crowd of crossing tasks needs
  a few variants: one that passes its neighbour on the left, one on the right ...).

The cache lives for one :func:`~runtime.crowd.scheduler.plan_scenario` call and is filled in
planning order, so a scenario and seed still give the same plans, byte for byte.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...motion.planar import wrap_angle
from .types import Config, SegmentResult

__all__ = ["MotionCache", "task_key", "QUANTUM", "PER_TASK"]

QUANTUM = 1e-6
PER_TASK = 8


def _q(v: float) -> int:
    return int(round(float(v) / QUANTUM))


def task_key(start, goal, fps: float):
    """The task of a segment from ``start`` (a :class:`~.types.Config`) to
    ``goal`` (a :class:`~.types.Goal`) in the start's frame, rounded to
    ``QUANTUM``: (start node, goal x, goal z, goal heading or None, pose nodes or None,
    window or None)."""
    h0 = float(start.heading)
    c, s = math.cos(h0), math.sin(h0)
    dx = float(goal.position[0]) - float(start.x)
    dz = float(goal.position[1]) - float(start.z)
    lx, lz = c * dx - s * dz, s * dx + c * dz           # Ry(h0)^-1 (dx, dz), see planar.compose
    hk = None if goal.heading is None else _q(wrap_angle(float(goal.heading) - h0))
    nodes = None if goal.nodes is None else tuple(sorted(int(n) for n in np.asarray(goal.nodes).ravel()))
    t0 = start.frame / fps
    wk = None if goal.window is None else (_q(goal.window[0] - t0), _q(goal.window[1] - t0))
    return (int(start.node), _q(lx), _q(lz), hk, nodes, wk)


@dataclass
class _Stored:
    root: np.ndarray        # (m, 3) in the start's frame: start at the origin, heading 0
    frames_a: np.ndarray
    frames_b: np.ndarray
    frames_t: np.ndarray
    end_node: int
    cost: float
    rates: tuple
    edges: list


class MotionCache:
    """Motions found by the search, by :func:`task_key`; see the module docstring."""

    def __init__(self, per_task: int = PER_TASK):
        self.per_task = int(per_task)
        self._store: dict = {}
        self.hits = 0           # motions reused
        self.misses = 0         # lookups where no stored motion was clear (or none was stored)

    def __len__(self) -> int:
        return sum(len(v) for v in self._store.values())

    def store(self, key, start, res) -> None:
        """Keep ``res`` (a clean :class:`~.types.SegmentResult` from ``start``)
        for ``key``, first in its list; the oldest beyond ``per_task`` is dropped."""
        h0 = float(start.heading)
        c, s = math.cos(h0), math.sin(h0)
        d = res.root[:, :2] - np.array([start.x, start.z])
        root = np.empty_like(res.root)
        root[:, 0] = c * d[:, 0] - s * d[:, 1]
        root[:, 1] = s * d[:, 0] + c * d[:, 1]
        root[:, 2] = res.root[:, 2] - h0
        item = _Stored(root, res.frames_a.copy(), res.frames_b.copy(), res.frames_t.copy(), int(res.end.node),
                       float(res.cost), tuple(res.rates), list(res.edges))
        lst = self._store.setdefault(key, [])
        lst.insert(0, item)
        del lst[self.per_task:]

    def candidates(self, key, start, goal):
        """Each stored motion for ``key`` placed at ``start`` and corrected onto ``goal``:
        yields (list position, SegmentResult)."""
        h0 = float(start.heading)
        c, s = math.cos(h0), math.sin(h0)
        for k, it in enumerate(self._store.get(key, ())):
            m = len(it.root)
            root = np.empty_like(it.root)
            root[:, 0] = start.x + c * it.root[:, 0] + s * it.root[:, 1]
            root[:, 1] = start.z - s * it.root[:, 0] + c * it.root[:, 1]
            root[:, 2] = it.root[:, 2] + h0
            # the key's rounding, spread over the motion (<= QUANTUM)
            ramp = np.arange(m) / max(m - 1, 1)
            root[:, 0] += ramp * (float(goal.position[0]) - root[-1, 0])
            root[:, 1] += ramp * (float(goal.position[1]) - root[-1, 1])
            if goal.heading is not None:
                root[:, 2] += ramp * wrap_angle(float(goal.heading) - root[-1, 2])
            end = Config(it.end_node, float(root[-1, 0]), float(root[-1, 1]), float(root[-1, 2]),
                         int(start.frame) + m - 1)
            yield k, SegmentResult(True, it.frames_a.copy(), it.frames_b.copy(), it.frames_t.copy(), root, int(start.frame), end,
                                   it.cost, it.rates, 0, list(it.edges))

    def used(self, key, k: int) -> None:
        """Motion ``k`` of ``key`` was reused: it goes first (most recently used)."""
        lst = self._store[key]
        lst.insert(0, lst.pop(k))
        self.hits += 1
