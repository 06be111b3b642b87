"""The planner's data: configurations, goals, segment results and the kinds of planner step.

A *segment* takes a character from a start :class:`Config` (a motion-graph node, a planar
position and heading, a frame on the fixed clock) to a :class:`Goal` (a position, optionally a
heading, a set of allowed end nodes -- the pose constraint -- and an absolute time window); its
:class:`SegmentResult` is the motion, frame by frame (Sung, Kovar and Gleicher 2005, section 3).
"""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

__all__ = ["Config", "Goal", "SegmentResult", "Step"]


@dataclass
class Config:
    """Where a character stands on the motion graph and the ground at one frame.

    Attributes:
        node: motion-graph node.
        x, z: root position on the ground (m).
        heading: radians about +Y, 0 facing +Z.
        frame: absolute frame on the fps grid.
    """

    node: int
    x: float
    z: float
    heading: float
    frame: int

    @property
    def xzh(self):
        return np.array([self.x, self.z, self.heading])


@dataclass
class Goal:
    """A segment's constraints.

    Attributes:
        position: (2,) x, z to arrive at exactly.
        heading: radians to arrive facing, or None (free).
        nodes: allowed end nodes (the pose constraint), or None (free).
        window: absolute arrival window (t_a, t_b) in seconds, or None.
        label: what the goal is (a pose label or a command), for messages.
    """

    position: np.ndarray
    heading: float | None = None
    nodes: np.ndarray | None = None
    window: tuple | None = None
    label: str = ""


@dataclass
class SegmentResult:
    """A planned segment, one row per output frame from the start configuration.

    Attributes:
        ok: within eps and collision-free.
        frames_a, frames_b, frames_t: library frames and the blend of each output frame.
        root: (m, 3) x, z, heading (radians, continuous).
        start_frame: absolute frame of output frame 0 (the start configuration).
        end: the configuration reached (exactly the goal's).
        cost: the splice cost (Eq. 1) of the pair used, in metres per second.
        rates: the achieved per-frame adjustment (m/s, deg/s, s/s).
        iterations: search iterations spent.
        edges: library edges used, in order.
        warning: why the segment is not ok ("" when it is).
        collided: the motion used runs into an obstacle or another character.
    """

    ok: bool
    frames_a: np.ndarray
    frames_b: np.ndarray
    frames_t: np.ndarray
    root: np.ndarray
    start_frame: int
    end: Config
    cost: float
    rates: tuple
    iterations: int
    edges: list
    warning: str = ""
    collided: bool = False


class Step(Enum):
    """The kind of work the planner does next. The planner is a generator and every ``yield``
    names the work that the following ``next()`` runs, so a caller with a per-tick budget
    (the World) can predict the step's duration per kind before it starts it."""

    WAYPOINTS = "waypoints"      # a motion reused from the cache, or the roadmap's way points
    SEED_EDGE = "seed edge"      # one edge of a greedy seed: the lookahead and the clear tests
    SEED_PATH = "seed path"      # one edge of a fewest-edge path into or out of a state
    SEARCH = "search"            # one search iteration: the perturbed pairs and a sweep
    COSTS = "costs"              # the splice costs of an iteration's pairs (Eq. 1-2)
    SPLICE = "splice"            # one splice (steps 1-4) and its final collision test
