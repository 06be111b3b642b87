"""Reactions: a shoulder bump that makes the other performer stagger, a dash and a dodge.

A shoulder bump is a straight walk run that passes the other performer's shoulder; the
bumped performer staggers two steps back, twisting, :data:`REACTION_DELAY` after the contact
frame. A dash is a fast straight run (gait :data:`DASH`) past a standing performer who
side-steps out of the way when the dasher is about 2.5 m away.
"""
from __future__ import annotations

import numpy as np

from ..curves import ramp, smootherstep
from ..gait import WALK, GaitStyle, foot_tracks
from ..group import Group
from ..keyframes import apply_keys, frame_times, keyed, neutral_key
from ..locomotion import run_controls
from ..stance import H_STAND, NEUTRAL, body_to_world, limit_reach, neutral_controls, standing_prints
from .choreography import Performer, heading_away, look_yaw, run_to, start_state, straight_run, walk_off
from .scene import Event, Scene, finish_scene

__all__ = ["DASH", "REACTION_DELAY", "stagger", "sidestep", "scene_bump", "scene_dash_dodge"]

DASH = GaitStyle("dash", 2.0, 1.2, 0.06, 0.10, np.radians(5.0), 0.6, 2.4,
                 np.radians(16.0), np.radians(62.0), 0.07, ("dash_l", "dash_r"), "dash")
REACTION_DELAY = 0.12          # s from a bump contact to the bumped performer's first response


def _step_to(start, end, steps, clearance, times):
    """Feet of stepping from standing at ``start`` to standing at ``end`` (each (x, z,
    heading)), one foot after the other.

    Args:
        start: standing place at the beginning.
        end: standing place at the end.
        steps: ``((side, t_lift, t_land), (side, t_lift, t_land))`` in stepping order.
        clearance: height of the swing arcs (m).
        times: frame times (s).
    Returns:
        ``(ankle, foot_q, toe)`` per frame (see :func:`..gait.foot_tracks`).
    """
    prints = standing_prints(*start)
    finals = standing_prints(*end)
    for side, ta, tb in steps:
        prints[side].t_lift = ta
        prints[side].t_heeloff = ta
        fp = finals[side]
        fp.t_land, fp.t_flat = tb, tb
        fp.clearance = clearance
        prints.append(fp)
    prints.sort(key=lambda q: (q.side, q.t_land))
    ankle, fq, toe, _, _ = foot_tracks(prints, times)
    return ankle, fq, toe


def _moving_keyed(keys, N, fps, times, state, xz, head, feet):
    """Controls of a keyed action (keys as in :func:`..keyframes.keyed`) whose standing place
    moves: the keyed pelvis offsets ride on the root path ``xz`` (N + 1, 2) with headings
    ``head`` (N + 1,), starting from ``state``; ``feet`` from :func:`_step_to`."""
    x0, z0, th0 = state
    k = keyed(keys, N / fps, times)
    c = neutral_controls(N + 1, x0, z0, th0)
    apply_keys(c, k, x0, z0, th0)
    # re-place the keyed pelvis offsets along the moving root
    loc = np.stack([k["px"], k["py"], k["pz"]], axis=-1)
    for i in range(N + 1):
        c.root_pos[i] = body_to_world(loc[i], xz[i, 0], xz[i, 1], head[i])
    ankle, fq, toe = feet
    c.heading[:] = head
    c.ankle[:] = ankle
    c.foot_q[:] = fq
    c.toe[:] = toe
    return c


def stagger(skel, rng, state, fps, push_dir, hit_side, delay) -> Group:
    """Pushed at one shoulder: the body twists, two quick steps back along ``push_dir``
    (world unit vector) catch the fall, arms go out, then the performer settles standing.
    ``hit_side`` 0 = left shoulder, 1 = right; ``delay`` s of standing before the reaction."""
    x0, z0, th0 = state
    T = delay + float(rng.uniform(1.9, 2.3))
    N, t = frame_times(T, fps)
    dist = float(rng.uniform(0.28, 0.4))
    sg = 1.0 if hit_side == 0 else -1.0
    dth = sg * float(np.radians(rng.uniform(18.0, 30.0)))      # hit shoulder goes back
    th1 = th0 + dth
    p1 = np.array([x0, z0]) + dist * np.asarray(push_dir)
    # root: quick shove (overshoot) then settle
    s = ramp(t, delay, delay + 0.55)
    over = 0.07 * np.sin(np.pi * np.clip((t - delay) / 0.9, 0, 1)) ** 2
    xz = np.array([x0, z0]) + (s * dist + over)[:, None] * np.asarray(push_dir)
    head = th0 + dth * ramp(t, delay, delay + 0.6)
    # steps: hit-side foot first (it is unloaded by the push), then the other
    first = hit_side
    feet = _step_to(state, (p1[0], p1[1], th1),
                    ((first, delay + 0.08, delay + 0.36), (1 - first, delay + 0.3, delay + 0.62)), 0.045, t)
    keys = [(0.0, neutral_key()), (delay / T, {}),
            ((delay + 0.22) / T, {"pitch": NEUTRAL["pitch"] - 0.12, "flex": NEUTRAL["flex"] - 0.08,
                                  "twist": 0.25 * sg, "lat": 0.08 * sg, "roll": 0.05 * sg, "hpitch": 0.0,
                                  "hyaw": 0.35 * sg, "abdL": 0.55, "abdR": 0.55, "elbowL": 0.6, "elbowR": 0.6,
                                  "swingL": 0.2, "swingR": 0.2}),
            ((delay + 0.6) / T, {"pitch": NEUTRAL["pitch"] + 0.08, "flex": NEUTRAL["flex"] + 0.06,
                                 "twist": 0.1 * sg, "lat": 0.0, "roll": 0.0, "hpitch": 0.2, "hyaw": 0.5 * sg,
                                 "abdL": 0.35, "abdR": 0.35}),
            ((delay + 1.2) / T, {**neutral_key(), "hyaw": 0.4 * sg}),
            (1.0, neutral_key())]
    c = _moving_keyed(keys, N, fps, t, state, xz, head, feet)
    limit_reach(skel, c)
    return Group(c, [(0, int(round(delay * fps)), "wait"), (int(round(delay * fps)), N, "stagger")],
                 [(0, "stand")], [], (float(p1[0]), float(p1[1]), float(th1)))


def _pass_by(skel, rng, fps, spread_deg):
    """The set-up of a pass-by: a line along a random heading ``axis`` through a random
    ``centre``, and B's walk run (``gb``, not yet on B's timeline) to stand at the centre
    facing back along the line (within +-``spread_deg``).

    Returns:
        ``(A, B, gb, centre, axis, fwd, left)``: the passer A (timeline empty), B (state at
        the start of ``gb``), the walk run, and the line's direction and A's left (x, z).
    """
    centre = rng.uniform(-1.0, 1.0, size=2)
    axis = float(rng.uniform(-np.pi, np.pi))            # direction the passer walks
    fwd = np.array([np.sin(axis), np.cos(axis)])
    left = np.array([np.cos(axis), -np.sin(axis)])      # the passer's left in the world
    A = Performer("A", (0, 0, 0))
    B = Performer("B", (0, 0, 0))
    gb = run_to(skel, rng, (centre[0], centre[1], axis + np.pi + np.radians(rng.uniform(-spread_deg, spread_deg))),
                fps, WALK, int(rng.integers(1, 3)))
    B.state = start_state(gb)
    return A, B, gb, centre, axis, fwd, left


def _line_up(rng, fps, A, B, ga, gb, a_start, f_event, b_stand):
    """Put a pass-by on the shared clock: B waits a few frames, walks in (``gb``) and stands
    for ``b_stand`` = (low, high) frames (drawn) before A's run ``ga``, starting at
    ``a_start`` = (x, z, heading), reaches its frame ``f_event``. Returns A's first frame
    of ``ga`` on the clock."""
    B.wait(int(rng.integers(6, 20)), fps)
    B.add(gb)
    ready = B.frames + int(rng.integers(*b_stand))
    start_a = max(ready - f_event, int(rng.integers(6, 20)))
    A.state = (float(a_start[0]), float(a_start[1]), a_start[2])
    A.wait(start_a, fps)
    A.add(ga)
    return start_a


def scene_bump(skel, rng, fps) -> Scene:
    """A walks past B, who is standing, close enough that their right shoulders collide;
    B staggers back."""
    # B stands at the centre facing the bumper (heading axis + pi), so B's right is the bumper's
    # left; the bumper's line is offset to its left, so the two right shoulders meet.
    A, B, gb, centre, axis, fwd, left = _pass_by(skel, rng, fps, 10)
    lateral = float(rng.uniform(0.36, 0.42))
    n_steps = int(rng.integers(7, 10))
    first = int(rng.integers(0, 2))
    p0 = straight_run(WALK, n_steps, first, fps)
    # distance along the path where A's root is level with B (contact): about the middle
    s_path = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p0.path, axis=0), axis=1))])
    L = s_path[-1]
    s_contact = L * float(rng.uniform(0.5, 0.62))
    start_xz = centre + left * lateral - fwd * s_contact
    plan = straight_run(WALK, n_steps, first, fps, start_xz[0], start_xz[1], axis)
    ga = Group(run_controls(plan, skel), plan.segments, plan.hubs, [], plan.end_state)
    # contact frame: A's right shoulder level with B's right shoulder
    rel = np.sum((plan.path - centre) * fwd, axis=1)
    f_pass = int(np.argmin(np.abs(rel)))
    # timelines: B arrives and waits; A starts so that it passes B after B has stood a while
    start_a = _line_up(rng, fps, A, B, ga, gb, (start_xz[0], start_xz[1], axis), f_pass, (20, 45))
    f_contact = start_a + f_pass
    B.wait_until(f_contact - 1, fps)                 # B does not see it coming
    delay = 1.0 / fps + REACTION_DELAY
    push = fwd * 0.8 + left * 0.35                      # pushed along A's walk, a little aside
    push = push / np.linalg.norm(push)
    g = stagger(skel, rng, B.state, fps, push, 1, delay)
    B.add(g)
    stag0 = f_contact - 1 + int(round(delay * fps))
    ev_contact = Event("bump", "contact", (0, 1), f_contact - 2, f_contact + 2)
    ev_react = Event("stagger", "proximity", (0, 1), stag0, stag0 + int(round(0.7 * fps)))
    # A twists as it bumps; added on its controls around the contact frame
    def twist(ctl):
        c = ctl[0]
        t = (np.arange(c.num_frames) - f_contact) / fps
        bumpw = np.exp(-0.5 * ((t - 0.12) / 0.12) ** 2)
        c.spine[:, 2] -= 0.22 * bumpw                  # right shoulder driven back
        c.pelvis[:, 0] -= 0.08 * bumpw
        c.head[:, 1] += -0.3 * np.exp(-0.5 * ((t - 0.5) / 0.35) ** 2)
    walk_off(skel, rng, fps, B, heading_away(rng, B, plan.path[-1], 40.0), n_walk=1)
    return finish_scene(skel, "bump", [A, B], fps, [ev_contact, ev_react], fixups=[twist])


def sidestep(skel, rng, state, fps, side, delay, look_at) -> Group:
    """Quick side-step to ``side`` (0 left, 1 right) by about half a metre, leaning away."""
    x0, z0, th0 = state
    T = delay + float(rng.uniform(1.5, 1.8))
    N, t = frame_times(T, fps)
    L = float(rng.uniform(0.6, 0.75))
    sg = 1.0 if side == 0 else -1.0
    dth = float(np.radians(rng.uniform(-12, 12)))
    th1 = th0 + dth
    shift = body_to_world(np.array([sg * L, 0.0, float(rng.uniform(-0.1, 0.05))]), x0, z0, th0)
    p1 = np.array([shift[0], shift[2]])
    lead = side
    feet = _step_to(state, (p1[0], p1[1], th1),
                    ((lead, delay + 0.06, delay + 0.34), (1 - lead, delay + 0.3, delay + 0.58)), 0.05, t)
    s = ramp(t, delay, delay + 0.5)
    xz = np.array([x0, z0]) + s[:, None] * (p1 - np.array([x0, z0]))
    head = th0 + dth * ramp(t, delay + 0.2, delay + 0.9)
    keys = [(0.0, neutral_key()), (delay / T, {}),
            ((delay + 0.25) / T, {"roll": -0.1 * sg, "lat": -0.12 * sg, "pitch": NEUTRAL["pitch"] + 0.08,
                                  "flex": NEUTRAL["flex"] + 0.1, "abdL": 0.35, "abdR": 0.35,
                                  "elbowL": 0.7, "elbowR": 0.7, "swingL": 0.25, "swingR": 0.25,
                                  "py": H_STAND - 0.05}),
            ((delay + 0.7) / T, {"roll": 0.0, "lat": 0.0, "py": H_STAND - 0.02}),
            (1.0, neutral_key())]
    c = _moving_keyed(keys, N, fps, t, state, xz, head, feet)
    # the head follows the dasher (look_at: (N+1, 2) positions over the group)
    yaw = np.array([look_yaw((xz[i, 0], xz[i, 1], head[i]), look_at[i]) for i in range(N + 1)])
    c.head[:, 1] = yaw * smootherstep(t / 0.3) * (1 - ramp(t, T - 0.5, T))
    limit_reach(skel, c)
    return Group(c, [(0, int(round(delay * fps)), "wait"), (int(round(delay * fps)), N, "dodge")],
                 [(0, "stand")], [], (float(p1[0]), float(p1[1]), float(th1)))


def scene_dash_dodge(skel, rng, fps) -> Scene:
    """A dashes past B, who side-steps out of the way when A is about 2.5 m away."""
    # B walks in and stands at the centre, facing roughly towards the dasher
    A, B, gb, centre, axis, fwd, leftA = _pass_by(skel, rng, fps, 25)
    n_steps = int(rng.integers(9, 12))
    first = int(rng.integers(0, 2))
    p0 = straight_run(DASH, n_steps, first, fps)
    s_path = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p0.path, axis=0), axis=1))])
    s_pass = s_path[-1] * float(rng.uniform(0.55, 0.65))
    offset = float(rng.uniform(-0.1, 0.1))
    start_xz = centre + leftA * offset - fwd * s_pass
    plan = straight_run(DASH, n_steps, first, fps, start_xz[0], start_xz[1], axis)
    ga = Group(run_controls(plan, skel), [(a, b, "dash") for a, b, _ in plan.segments],
               plan.hubs, [], plan.end_state)
    rel = np.sum((plan.path - centre) * fwd, axis=1)
    f_react_rel = int(np.argmin(np.abs(rel + float(rng.uniform(2.3, 2.8)))))   # dasher ~2.5 m away
    start_a = _line_up(rng, fps, A, B, ga, gb, (start_xz[0], start_xz[1], axis), f_react_rel, (15, 40))
    f_react = start_a + f_react_rel
    B.wait_until(f_react, fps, look=plan.path[max(f_react_rel - 10, 0)])
    # dodge away from the dasher's line: to the side B is on relative to it
    side_world = leftA if offset < 0 else -leftA                    # away from A's line
    bl = np.array([np.cos(B.state[2]), -np.sin(B.state[2])])       # B's left
    side = 0 if np.dot(side_world, bl) > 0 else 1
    delay = 0.15
    look = []
    n_g = int(round((delay + 1.9) * fps)) + 2          # frames of the side-step group (upper bound)
    for i in range(n_g):
        fa = min(f_react_rel + i, len(plan.path) - 1)
        look.append(plan.path[fa])
    g = sidestep(skel, rng, B.state, fps, side, delay, np.array(look))
    B.add(g)
    d0 = f_react + int(round(delay * fps))
    ev = Event("dodge", "proximity", (0, 1), d0, d0 + int(round(0.6 * fps)))
    walk_off(skel, rng, fps, B, heading_away(rng, B, plan.path[-1], 40.0), n_walk=1)
    return finish_scene(skel, "dash_dodge", [A, B], fps, [ev])
