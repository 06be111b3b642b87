"""Turning on the spot in small steps: the lead foot opens, the other foot closes.

A turn by ``dth`` is split into pairs of steps of at most 65 degrees; each step lifts a foot
and puts it down beside the other at the next heading. The heading follows a smootherstep
over the stepping, the pelvis shifts over the stance foot while the other foot steps, and
the head and thorax look ahead into the turn.
"""
from __future__ import annotations

import numpy as np

from .curves import smootherstep, smoothstep
from .gait import WALK, Footprint, foot_tracks
from .keyframes import frame_times
from .stance import body_to_world, limit_reach, neutral_controls, standing_prints

__all__ = ["turn_on_spot"]

STEP_TURN = np.radians(65.0)   # largest heading change of one pair of steps
WEIGHT_SHIFT = 0.3             # s of shifting the weight before the first step
DOUBLE_SUPPORT = 0.12          # s between one foot landing and the other lifting


def turn_on_spot(skel, state, dth, swing, fps, carry=False):
    """Controls of turning on the spot from ``state`` = (x, z, heading) by ``dth`` rad.

    Args:
        skel: the performer's skeleton.
        state: the standing place and heading at the start.
        dth: heading change (rad, positive to the left); the left foot leads when positive.
        swing: seconds of each foot's swing.
        fps: frame rate.
        carry: turning while holding a box.
    Returns:
        ``(controls, N)``: ``N + 1`` frames of controls, ending standing at heading
        ``state[2] + dth``.
    """
    x0, z0, th0 = state
    pairs = max(1, int(np.ceil(abs(dth) / STEP_TURN)))
    lead = 0 if dth > 0 else 1
    prints = standing_prints(x0, z0, th0)
    t = WEIGHT_SHIFT
    steps = []
    for i in range(pairs):
        th_i = th0 + dth * (i + 1) / pairs
        for side in (lead, 1 - lead):
            sg = 1.0 if side == 0 else -1.0
            p = body_to_world(np.array([sg * WALK.stand_width, 0.0, 0.0]), x0, z0, th_i)
            steps.append((side, t, t + swing, p, th_i + sg * WALK.toe_out))
            t += swing + DOUBLE_SUPPORT
    T = t + 0.35
    N, times = frame_times(T, fps)
    # footprint list with timing
    last = {0: prints[0], 1: prints[1]}
    allp = list(prints)
    for side, t_lift, t_land, p, yaw in steps:
        last[side].t_lift = t_lift
        last[side].t_heeloff = t_lift
        fp = Footprint(side, float(p[0]), float(p[2]), float(yaw), t_land, t_land, np.inf, np.inf,
                       clearance=0.05)
        allp.append(fp)
        last[side] = fp
    allp.sort(key=lambda q: (q.side, q.t_land))
    ankle, fq, toe, _, _ = foot_tracks(allp, times)
    t_first, t_last = steps[0][1], steps[-1][2]
    head = th0 + dth * smootherstep((times - t_first + 0.1) / (t_last - t_first + 0.1))
    c = neutral_controls(N + 1, x0, z0, th0, carry=carry)
    c.heading[:] = head
    c.ankle[:] = ankle
    c.foot_q[:] = fq
    c.toe[:] = toe
    # pelvis shifts over the stance foot while the other foot steps
    sway = np.zeros(N + 1)
    for side, t_lift, t_land, p, yaw in steps:
        stance_sg = -1.0 if side == 0 else 1.0
        m = smoothstep((times - t_lift + 0.18) / 0.2) * (1 - smoothstep((times - t_land + 0.05) / 0.2))
        sway += stance_sg * 0.025 * m
    c.root_pos[:, 0] = x0 + np.cos(head) * sway
    c.root_pos[:, 2] = z0 - np.sin(head) * sway
    c.pelvis[:, 2] = 0.8 * sway
    c.spine[:, 1] = 0.6 * sway
    look = np.interp(np.minimum(times + 0.35, times[-1]), times, head) - head
    c.head[:, 1] = 0.8 * look
    c.spine[:, 2] = 0.3 * look
    limit_reach(skel, c)
    return c, N
