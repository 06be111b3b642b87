"""A segment's way points: the probabilistic roadmap's path from the start to the goal (Sung,
Kovar and Gleicher 2005, section 3.2), optionally through a point in front of a seat."""
from __future__ import annotations

import numpy as np

from ...motion.graph import STATES
from .library import MotionLibrary
from .params import SearchParams
from .types import Config, Goal

__all__ = ["segment_waypoints"]


def segment_waypoints(lib: MotionLibrary, params: SearchParams, roadmap, env, start: Config, goal: Goal) -> np.ndarray:
    """The segment's way points (n, 2): the roadmap's path from the start to the goal (a
    straight line without one), passing ``approach_point`` metres in front of a seat
    before sitting down on it and after getting up from it."""
    g = lib.g
    gxz = np.asarray(goal.position, float)
    via = None
    if params.approach_point > 0 and goal.heading is not None and goal.nodes is not None \
            and np.all(g.node_state[goal.nodes] == STATES.index("sitting")):
        # one sits down from in front of the seat: the way points pass a point that far in
        # front first, so the seeds come in square rather than across the neighbours'
        # places
        via = gxz + params.approach_point * np.array([np.sin(goal.heading), np.cos(goal.heading)])
        if env is not None and env.distance(via[None])[0] < 0.5 * params.approach_point:
            via = None
        if via is not None and np.hypot(*(via - [start.x, start.z])) < 2 * params.approach_point:
            via = None
    dep = None
    if params.approach_point > 0 and g.node_state[start.node] == STATES.index("sitting"):
        # and one gets up to in front of the seat: the way points leave through the same
        # point, so a character walks off down the middle of the aisle, not along the
        # seated row's knees
        dep = np.array([start.x, start.z]) + params.approach_point * np.array([np.sin(start.heading), np.cos(start.heading)])
        if (env is not None and env.distance(dep[None])[0] < 0.5 * params.approach_point) \
                or np.hypot(*(dep - gxz)) < 2 * params.approach_point:
            dep = None
    origin = np.array([start.x, start.z])
    a, b = (origin if dep is None else dep), (gxz if via is None else via)
    path = roadmap.waypoints(env, a, b) if roadmap is not None and env is not None \
        else np.array([a, b], dtype=np.float64)
    return np.concatenate([origin[None]] * (dep is not None) + [path] + [gxz[None]] * (via is not None))
