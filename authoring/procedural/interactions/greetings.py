"""Greetings: handshake, high five, and bows of two and of three performers.

The partners meet face to face (:func:`~.choreography.meet`), greet with a keyframed
action on the spot and walk off. Hands that meet drive the right arm's IK with a world wrist
target; a fix-up after the first solve moves it until the two hand centres are
:data:`PALM_GAP` apart (palm to palm) while in contact.
"""
from __future__ import annotations

import numpy as np

from ..curves import ramp
from ..gait import WALK
from ..group import Group
from ..keyframes import neutral_key
from ..stance import H_STAND, NEUTRAL, limit_reach
from .choreography import (Performer, heading_away, heading_to, keyed_group, look_yaw, meet, run_to,
                           start_state, walk_off)
from .scene import Event, Scene, finish_scene, hand_fixup

__all__ = ["PALM_GAP", "scene_handshake", "scene_high_five", "scene_bow", "scene_bow3"]

PALM_GAP = 0.03               # m between the two hand centres while hands are together


def _arm_shake_keys(lean, look_pitch):
    """Trunk key of a handshake: leaning towards the partner by ``lean``, looking down."""
    return {"flex": NEUTRAL["flex"] + lean, "pitch": NEUTRAL["pitch"] + 0.4 * lean, "hpitch": look_pitch}


def scene_handshake(skel, rng, fps) -> Scene:
    """Two performers meet face to face and shake right hands two or three times."""
    D = float(rng.uniform(0.82, 0.9))
    A, B, f0 = meet(skel, rng, fps, D)
    T = float(rng.uniform(2.8, 3.4))
    ta, tb = 0.12 * T, 0.36 * T           # reach
    tr0, tr1 = 0.74 * T, 0.94 * T         # release
    cycles = int(rng.integers(2, 4))
    pa, pb = np.array(A.state[:2]), np.array(B.state[:2])
    mid = 0.5 * (pa + pb)
    axis = A.state[2]
    groups, goals = [], []
    for P in (A, B):
        lean = float(rng.uniform(0.05, 0.1))
        keys = [(0.0, neutral_key()), (0.3, _arm_shake_keys(lean, 0.25)), (0.5, {}),
                (0.78, _arm_shake_keys(lean * 0.6, 0.15)), (1.0, neutral_key())]
        c, t = keyed_group(skel, P.state, T, keys, fps)
        w = ramp(t, ta, tb) * (1.0 - ramp(t, tr0, tr1))
        c.hand_w[:, 1] = w
        shake = 0.035 * np.sin(2 * np.pi * cycles * np.clip((t - tb) / (tr0 - tb), 0, 1)) * (t > tb) * (t < tr0)
        groups.append((P, c, t, shake))
    h = float(rng.uniform(0.98, 1.04))
    lat = np.array([np.cos(axis), -np.sin(axis)])        # A's left in the world
    n = len(groups[0][2])
    for i, (P, c, t, shake) in enumerate(groups):
        # hand centres side by side (palm to palm) across the line between the two
        goal_xz = mid + (1 if i == 0 else -1) * 0.5 * PALM_GAP * lat
        goal = np.stack([np.full(n, goal_xz[0]), h + shake, np.full(n, goal_xz[1])], axis=-1)
        toward = (pb - pa) if i == 0 else (pa - pb)
        toward = toward / np.linalg.norm(toward)
        wrist = goal - 0.085 * np.array([toward[0], 0.0, toward[1]])
        c.hand_world[:, 1] = wrist
        c.wrist[:, 1] = 0.0
        goals.append(goal)
        P.add(Group(c, [(0, n - 1, "handshake")], [(0, "stand")], [], P.state))
    full = np.flatnonzero((groups[0][1].hand_w[:, 1] > 0.999))
    ev = Event("handshake", "contact", (0, 1), f0 + int(full[0]), f0 + int(full[-1]))
    sl = slice(f0, f0 + n)
    fix = hand_fixup(skel, [(0, 1, sl, goals[0]), (1, 1, sl, goals[1])])
    for P, other in ((A, pb), (B, pa)):
        walk_off(skel, rng, fps, P, heading_away(rng, P, other), n_walk=1)
    return finish_scene(skel, "handshake", [A, B], fps, [ev], fixups=[fix])


def scene_high_five(skel, rng, fps) -> Scene:
    """Two performers meet face to face and clap right hands above their heads."""
    D = float(rng.uniform(0.78, 0.86))
    A, B, f0 = meet(skel, rng, fps, D)
    T = float(rng.uniform(1.8, 2.2))
    t_up0, t_hit = 0.12 * T, 0.45 * T
    hold_s = float(rng.uniform(0.1, 0.16))
    t_dn1 = 0.85 * T
    pa, pb = np.array(A.state[:2]), np.array(B.state[:2])
    mid = 0.5 * (pa + pb)
    toward = (pb - pa) / np.linalg.norm(pb - pa)
    h = float(rng.uniform(1.6, 1.68))
    goals, cs = [], []
    for i, P in enumerate((A, B)):
        keys = [(0.0, neutral_key()), (0.45, {"hpitch": -0.15, "pitch": NEUTRAL["pitch"] + 0.02,
                                                   "flex": NEUTRAL["flex"] + 0.04, "lat": -0.05}),
                (0.6, {}), (1.0, neutral_key())]
        c, t = keyed_group(skel, P.state, T, keys, fps)
        up = ramp(t, t_up0, t_hit)
        down = ramp(t, t_hit + hold_s, t_dn1)
        c.hand_w[:, 1] = up * (1.0 - down)
        sgn = 1.0 if i == 0 else -1.0
        goal_xz = mid - sgn * 0.5 * PALM_GAP * toward
        goal = np.tile([goal_xz[0], h, goal_xz[1]], (len(t), 1))
        # the wrist below and behind the hand centre (fingers up); the fix-up refines it
        back = np.array([toward[0], 0.0, toward[1]]) * sgn
        c.hand_world[:, 1] = goal - np.array([0.0, 0.07, 0.0]) - 0.03 * back
        c.wrist[:, 1] = -0.9 * up * (1.0 - down)
        c.clav[:, 1, 0] = 0.15 * up * (1.0 - down)
        goals.append(goal)
        cs.append((c, t))
        P.add(Group(c, [(0, len(t) - 1, "high_five")], [(0, "stand")], [], P.state))
    c0 = cs[0][0]
    full = np.flatnonzero(c0.hand_w[:, 1] > 0.999)
    ev = Event("high_five", "contact", (0, 1), f0 + int(full[0]), f0 + int(full[-1]))
    n = len(cs[0][1])
    sl = slice(f0, f0 + n)
    fix = hand_fixup(skel, [(0, 1, sl, goals[0]), (1, 1, sl, goals[1])])
    for P, other in ((A, pb), (B, pa)):
        walk_off(skel, rng, fps, P, heading_away(rng, P, other), n_walk=1)
    return finish_scene(skel, "high_five", [A, B], fps, [ev], fixups=[fix])


def _bow(skel, rng, P: Performer, fps, t_start, depth, T, look_at):
    """A bow starting ``t_start`` s into a group of length ``T``."""
    t_down, t_hold, t_up = t_start + 0.75, t_start + 0.75 + float(rng.uniform(0.4, 0.8)), None
    t_up = t_hold + 0.8
    f = lambda s: s / T  # noqa: E731
    bowed = {"pitch": NEUTRAL["pitch"] + 0.45 * depth, "flex": NEUTRAL["flex"] + 0.55 * depth,
             "hpitch": 0.55 + 0.5 * depth, "pz": -0.07 * depth, "py": H_STAND - 0.015,
             "swingL": 0.05, "swingR": 0.05, "elbowL": 0.15, "elbowR": 0.15}
    keys = [(0.0, neutral_key()), (f(t_start), {}), (f(t_down), bowed), (f(t_hold), {}),
            (f(t_up), neutral_key()), (1.0, {})]
    c, t = keyed_group(skel, P.state, T, keys, fps)
    w = ramp(t, 0.1, t_start) * (1.0 - ramp(t, t_up, min(t_up + 0.5, T)))
    c.head[:, 1] = look_yaw(P.state, look_at) * w
    limit_reach(skel, c)
    return c, t, (t_start, t_up)


def scene_bow(skel, rng, fps) -> Scene:
    """Two performers meet 1.4-1.7 m apart and bow to each other, one slightly after the other."""
    D = float(rng.uniform(1.4, 1.7))
    A, B, f0 = meet(skel, rng, fps, D)
    pa, pb = np.array(A.state[:2]), np.array(B.state[:2])
    lead = float(rng.uniform(0.3, 0.5))
    lag = float(rng.uniform(0.08, 0.3))
    T = lead + lag + 3.0
    spans = []
    for P, other, ts in ((A, pb, lead), (B, pa, lead + lag)):
        c, t, span = _bow(skel, rng, P, fps, ts, float(rng.uniform(0.8, 1.1)), T, other)
        spans.append(span)
        P.add(Group(c, [(0, len(t) - 1, "bow")], [(0, "stand")], [], P.state))
    s0 = f0 + int(round(min(s[0] for s in spans) * fps))
    s1 = f0 + int(round(max(s[1] for s in spans) * fps))
    ev = Event("bow", "sync", (0, 1), s0, s1)
    for P, other in ((A, pb), (B, pa)):
        walk_off(skel, rng, fps, P, heading_away(rng, P, other), n_walk=1)
    return finish_scene(skel, "bow", [A, B], fps, [ev])


def scene_bow3(skel, rng, fps) -> Scene:
    """Three performers walk up to a circle, facing its centre, and bow together."""
    centre = rng.uniform(-1.0, 1.0, size=2)
    R = float(rng.uniform(0.85, 1.0))
    base = float(rng.uniform(-np.pi, np.pi))
    people, spots = [], []
    groups = []
    for i, name in enumerate(("A", "B", "C")):
        ang = base + i * 2 * np.pi / 3 + np.radians(rng.uniform(-8, 8))
        spot = centre + R * np.array([np.sin(ang), np.cos(ang)])
        face = heading_to(spot, centre)
        g = run_to(skel, rng, (spot[0], spot[1], face), fps, WALK, int(rng.integers(1, 3)))
        P = Performer(name, start_state(g))
        people.append(P)
        spots.append(spot)
        groups.append(g)
    pad = int(rng.integers(6, 20))
    meet = pad + max(g.num_frames for g in groups) + int(rng.integers(8, 20))
    for P, g in zip(people, groups):
        P.wait(meet - g.num_frames - int(rng.integers(3, 8)), fps)
        P.add(g)
        P.wait_until(meet, fps)
    leads = [0.3 + float(rng.uniform(0.0, 0.35)) for _ in people]
    T = max(leads) + 3.0
    spans = []
    for i, P in enumerate(people):
        look = spots[(i + 1) % 3] if rng.random() < 0.5 else spots[(i + 2) % 3]
        c, t, span = _bow(skel, rng, P, fps, leads[i], float(rng.uniform(0.8, 1.1)), T, look)
        spans.append(span)
        P.add(Group(c, [(0, len(t) - 1, "bow")], [(0, "stand")], [], P.state))
    s0 = meet + int(round(min(s[0] for s in spans) * fps))
    s1 = meet + int(round(max(s[1] for s in spans) * fps))
    ev = Event("bow", "sync", (0, 1, 2), s0, s1)
    for P in people:
        walk_off(skel, rng, fps, P, heading_away(rng, P, centre, 25.0), n_walk=1)
    return finish_scene(skel, "bow3", people, fps, [ev])
