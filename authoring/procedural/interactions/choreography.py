"""Choreography shared by the scenes: performers' timelines, walking to places, meeting, leaving.

A :class:`Performer` is a timeline of activity groups (:class:`~..group.Group`) with the
state (x, z, heading) where it ends. Scenes are built by planning groups and lining them up
on the shared clock: :func:`run_to` plans a walk run at the origin and then rotates and
translates it so that it ends exactly at a wanted standing place and heading; the performer
who arrives first waits there (:meth:`Performer.wait_until`), so an interaction starts on the
same frame for everybody. :func:`meet` brings two performers face to face this way;
:func:`walk_off` turns a performer away and walks off.
"""
from __future__ import annotations

import numpy as np

from runtime.motion.planar import rotate_xz, wrap_angle

from ..curves import smootherstep
from ..gait import CARRY, WALK, plan_run
from ..group import Group
from ..keyframes import apply_keys, frame_times, keyed
from ..locomotion import run_controls
from ..stance import neutral_controls
from ..turning import turn_on_spot

__all__ = ["look_yaw", "heading_to", "hold", "run_to", "run_from", "straight_run", "turn_to", "keyed_group",
           "start_state", "Performer", "meet", "walk_off", "heading_away"]


def look_yaw(state, target):
    """Head yaw (relative to the body heading) that looks from ``state`` at ``target``."""
    x, z, th = state
    want = np.arctan2(target[0] - x, target[1] - z)
    return float(np.clip(wrap_angle(want - th), -1.1, 1.1))


def heading_to(a, b):
    """Heading (rad) of the direction from point ``a`` to point ``b`` (x, z)."""
    return float(np.arctan2(b[0] - a[0], b[1] - a[1]))


def hold(state, n, fps, carry=False, look=None, label="wait") -> Group:
    """Standing still in the hub pose for ``n`` frames (controls n + 1); when ``look`` is a
    point, the head turns towards it in the middle and back to neutral at both ends."""
    x0, z0, th0 = state
    c = neutral_controls(n + 1, x0, z0, th0, carry=carry)
    if look is not None and n >= 24:
        t = np.arange(n + 1) / fps
        T = n / fps
        w = smootherstep(t / 0.6) * smootherstep((T - t) / 0.6)
        c.head[:, 1] = look_yaw(state, look) * w
    hub = "carry_stand" if carry else "stand"
    return Group(c, [(0, n, "carry" if carry and label == "wait" else label)], [(0, hub)], [], state)


def _edges(rng, n_walk, max_turn_deg, start_turn_deg=15.0):
    """Random edges of a short run: start, ``n_walk`` walk edges (small turns and speed
    changes), stop."""
    edges = [("start", int(rng.integers(2, 4)), float(np.radians(rng.uniform(-start_turn_deg, start_turn_deg))))]
    for _ in range(n_walk):
        n = int(rng.integers(2, 5))
        edges.append(("walk", n, float(np.radians(rng.uniform(-max_turn_deg, max_turn_deg))),
                      float(rng.uniform(-0.2, 0.15))))
    edges.append(("stop", int(rng.integers(2, 4)), float(np.radians(rng.uniform(-10.0, 10.0)))))
    return edges


def _fix_labels(plan, style):
    """The plan's segments, relabelled with the style's own label (carry) when it has one."""
    if style.label is None:
        return plan.segments
    return [(a, b, style.label) for a, b, _ in plan.segments]


def run_to(skel, rng, target, fps, style=WALK, n_walk=1, max_turn_deg=30.0) -> Group:
    """A walk run (start, walk edges, stop) that ends standing exactly at ``target`` =
    (x, z, heading): planned at the origin, then rotated and translated into place."""
    edges = _edges(rng, n_walk, max_turn_deg)
    first = int(rng.integers(0, 2))
    p0 = plan_run(style, edges, 0.0, 0.0, 0.0, first, fps)
    ex, ez, eth = p0.end_state
    th0 = target[2] - eth
    off = rotate_xz(np.array([ex, ez]), th0)
    plan = plan_run(style, edges, target[0] - off[0], target[1] - off[1], th0, first, fps)
    c = run_controls(plan, skel)
    return Group(c, _fix_labels(plan, style), plan.hubs, [], tuple(float(v) for v in plan.end_state))


def run_from(skel, rng, state, fps, style=WALK, n_walk=1, max_turn_deg=30.0) -> Group:
    """A walk run starting from standing at ``state``; returns the group (end in ``.end``)."""
    edges = _edges(rng, n_walk, max_turn_deg)
    plan = plan_run(style, edges, state[0], state[1], state[2], int(rng.integers(0, 2)), fps)
    c = run_controls(plan, skel)
    return Group(c, _fix_labels(plan, style), plan.hubs, [], tuple(float(v) for v in plan.end_state))


def straight_run(style, n_steps, first, fps, x0=0.0, z0=0.0, th0=0.0):
    """Plan of a straight run: start, walk edges (no turns, no speed change), stop."""
    n_start = 3
    n_stop = 3
    mids = []
    left = n_steps
    while left > 0:
        k = min(4, left)
        mids.append(("walk", k, 0.0, 0.0))
        left -= k
    edges = [("start", n_start, 0.0)] + mids + [("stop", n_stop, 0.0)]
    return plan_run(style, edges, x0, z0, th0, first, fps)


def turn_to(skel, rng, state, heading, fps, carry=False) -> Group:
    """Turning on the spot to ``heading`` (exactly) in small steps, like
    :func:`..activities.turn_in_place` but to a given heading and optionally carrying."""
    x0, z0, th0 = state
    dth = float(wrap_angle(heading - th0))
    c, N = turn_on_spot(skel, state, dth, float(rng.uniform(0.36, 0.44)), fps, carry=carry)
    hub = "carry_stand" if carry else "stand"
    return Group(c, [(0, N, "carry" if carry else "turn")], [(0, hub)], [], (x0, z0, float(th0 + dth)))


def keyed_group(skel, state, T, keys, fps, carry=False):
    """Standing keyframed action (feet planted at the standing footprints of ``state``)."""
    x0, z0, th0 = state
    N, times = frame_times(T, fps)
    k = keyed(keys, N / fps, times)
    c = neutral_controls(N + 1, x0, z0, th0, carry=carry)
    apply_keys(c, k, x0, z0, th0)
    return c, times


def start_state(g: Group) -> tuple:
    """(x, z, heading) of the root at the first frame of ``g``."""
    return tuple(float(v) for v in g.controls.root_pos[0, [0, 2]]) + (float(g.controls.heading[0]),)


class Performer:
    """One performer's timeline: activity groups one after another from ``state``.
    ``carry`` says whether the performer holds a box at the end of the timeline."""

    def __init__(self, name, state):
        self.name = name
        self.state = tuple(float(v) for v in state)
        self.groups: list[Group] = []
        self.carry = False

    @property
    def frames(self) -> int:
        return sum(g.num_frames for g in self.groups)

    def add(self, g: Group):
        self.groups.append(g)
        self.state = tuple(float(v) for v in g.end)
        return g

    def wait(self, n, fps, look=None, label="wait"):
        """Stand still for ``n`` frames (see :func:`hold`)."""
        if n > 0:
            self.add(hold(self.state, n, fps, carry=self.carry, look=look, label=label))

    def wait_until(self, frame, fps, look=None, label="wait"):
        """Stand still until the timeline reaches ``frame``."""
        n = frame - self.frames
        if n < 0:
            raise AssertionError(f"{self.name}: timeline already at {self.frames} > {frame}")
        self.wait(n, fps, look, label)


def meet(skel, rng, fps, D, names=("A", "B"), carry_a=False):
    """Two performers walk up to each other and stop ``D`` apart, facing. Returns the two
    persons (timelines up to the common start frame) and the meeting frame."""
    centre = rng.uniform(-1.0, 1.0, size=2)
    axis = float(rng.uniform(-np.pi, np.pi))
    d = np.array([np.sin(axis), np.cos(axis)])
    pa = centre - d * D / 2
    pb = centre + d * D / 2
    A = Performer(names[0], (0, 0, 0))
    B = Performer(names[1], (0, 0, 0))
    A.carry = carry_a
    ga = run_to(skel, rng, (pa[0], pa[1], axis), fps, CARRY if carry_a else WALK, int(rng.integers(1, 3)))
    gb = run_to(skel, rng, (pb[0], pb[1], axis + np.pi), fps, WALK, int(rng.integers(1, 3)))
    A.state = start_state(ga)
    B.state = start_state(gb)
    pad = int(rng.integers(6, 20))
    wait = [int(rng.integers(6, 25)) for _ in range(2)]
    f_meet = pad + max(ga.num_frames + wait[0], gb.num_frames + wait[1])
    for P, g, wt in ((A, ga, wait[0]), (B, gb, wait[1])):
        P.wait(f_meet - g.num_frames - wt, fps)
        P.add(g)
        P.wait_until(f_meet, fps)
    return A, B, f_meet


def walk_off(skel, rng, fps, P: Performer, away_heading, carry=False, n_walk=1):
    """Turn (if needed) towards ``away_heading`` and walk off."""
    if abs(wrap_angle(away_heading - P.state[2])) > np.radians(20.0):
        P.add(turn_to(skel, rng, P.state, away_heading, fps, carry=carry))
    P.add(run_from(skel, rng, P.state, fps, CARRY if carry else WALK, n_walk, max_turn_deg=20.0))


def heading_away(rng, P: Performer, other_xz, spread=35.0):
    """A heading pointing away from ``other_xz`` (with some spread)."""
    base = heading_to(other_xz, P.state[:2])
    return float(base + np.radians(rng.uniform(-spread, spread)))
