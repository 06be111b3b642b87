"""The standing hub pose and the performer's body frame.

Every activity group starts and ends standing still in the canonical ``stand`` pose: feet
side by side under the hips (:func:`standing_prints`), weight centred, trunk, head and arms
at the :data:`NEUTRAL` angles (:func:`neutral_controls`); carrying a box changes the trunk to
:data:`CARRY_NEUTRAL` and puts the wrists at :data:`CARRY_WRIST` in the thorax frame
(:func:`set_carry`). Poses are keyed in the *body frame* of a standing place ``(x0, z0,
heading)``: x to the performer's left, y up, z forward (:func:`body_to_world`).

The legs are solved by analytic IK to their ankle targets; :func:`limit_reach` lowers the
root wherever a leg could not reach (hip-ankle distance over :data:`LEG_EXT`).
"""
from __future__ import annotations

import numpy as np

from . import body
from .curves import lower_envelope
from .gait import WALK, Footprint, foot_q
from .rig import Controls, hip_positions

__all__ = ["H_STAND", "NEUTRAL", "CARRY_NEUTRAL", "CARRY_WRIST", "LEG_EXT", "LEG_EXT_WALK",
           "body_to_world", "standing_prints", "neutral_controls", "set_carry", "allowed_root_height",
           "limit_reach"]

H_STAND = body.standing_root_height(7.0)
# wrist targets when carrying, in the Spine1 (thorax) frame
CARRY_WRIST = np.array([[0.225, -0.22, 0.34], [-0.225, -0.22, 0.34]])

LEG_EXT = 0.9985 * body.leg_length()     # longest hip-ankle distance the planner allows
LEG_EXT_WALK = 0.998 * body.leg_length()  # ... while walking (knees never quite straight)

NEUTRAL = {
    "pitch": 0.02, "flex": 0.03, "hpitch": 0.08,
    "swing": 0.05, "abd": 0.12, "elbow": 0.22, "wrist": 0.12, "clav": 0.0,
}
CARRY_NEUTRAL = {"pitch": 0.0, "flex": -0.06, "hpitch": 0.18, "clav": 0.06}


def body_to_world(local_xyz, x0, z0, heading):
    """Points in a body frame (x left, y up, z forward) at (x0, z0, heading) to world."""
    p = np.asarray(local_xyz, dtype=np.float64)
    c, s = np.cos(heading), np.sin(heading)
    wx = x0 + c * p[..., 0] + s * p[..., 2]
    wz = z0 - s * p[..., 0] + c * p[..., 2]
    return np.stack([wx, p[..., 1], wz], axis=-1)


def standing_prints(x0, z0, heading, width=WALK.stand_width, toe_out=WALK.toe_out):
    """The two footprints (left, right) of standing at ``(x0, z0, heading)``, planted for
    all time (the caller sets lift and landing times when a foot steps)."""
    out = []
    for side in (0, 1):
        sg = 1.0 if side == 0 else -1.0
        p = body_to_world(np.array([sg * width, 0.0, 0.0]), x0, z0, heading)
        out.append(Footprint(side, float(p[0]), float(p[2]), float(heading + sg * toe_out),
                             -np.inf, -np.inf, np.inf, np.inf))
    return out


def neutral_controls(N, x0, z0, heading, carry=False) -> Controls:
    """``N`` frames of standing still in the hub pose (carrying a box when ``carry``)."""
    c = Controls.empty(N)
    c.root_pos[:] = [x0, H_STAND, z0]
    c.heading[:] = heading
    c.pelvis[:, 1] = NEUTRAL["pitch"]
    c.spine[:, 0] = NEUTRAL["flex"]
    c.head[:, 0] = NEUTRAL["hpitch"]
    c.arm[:, :, 0] = NEUTRAL["swing"]
    c.arm[:, :, 1] = NEUTRAL["abd"]
    c.arm[:, :, 2] = NEUTRAL["elbow"]
    c.wrist[:] = NEUTRAL["wrist"]
    prints = standing_prints(x0, z0, heading)
    c.ankle[:] = np.array([p.flat_ankle() for p in prints])
    c.foot_q[:] = np.array([foot_q(p.yaw, 0.0) for p in prints])
    if carry:
        set_carry(c)
    return c


def set_carry(c: Controls, w=None):
    """Arms on the box held in front of the thorax; trunk leaning back slightly.

    Args:
        c: controls to change in place.
        w: per-frame weight of the carrying pose (default 1 on every frame).
    """
    w = np.ones(c.num_frames) if w is None else w
    c.pelvis[:, 1] = c.pelvis[:, 1] * (1 - w) + CARRY_NEUTRAL["pitch"] * w
    c.spine[:, 0] = c.spine[:, 0] * (1 - w) + CARRY_NEUTRAL["flex"] * w
    c.head[:, 0] = c.head[:, 0] * (1 - w) + CARRY_NEUTRAL["hpitch"] * w
    c.clav[:, :, 0] = c.clav[:, :, 0] * (1 - w[:, None]) + CARRY_NEUTRAL["clav"] * w[:, None]
    c.hand_w[:] = np.maximum(c.hand_w, w[:, None])
    c.hand_attach[:] = np.maximum(c.hand_attach, w[:, None])
    c.hand_thorax[:] = CARRY_WRIST


def allowed_root_height(skel, c: Controls, ext) -> np.ndarray:
    """Highest root height per frame at which both hip-ankle distances are <= ext."""
    hips = hip_positions(skel, c)
    rel = hips - c.root_pos[:, None, :]           # hip offsets from the root
    dxz = np.linalg.norm((c.root_pos[:, None, [0, 2]] + rel[..., [0, 2]]) - c.ankle[..., [0, 2]], axis=-1)
    ext = np.asarray(ext, dtype=np.float64)
    ext = np.broadcast_to(ext if ext.ndim == 2 else ext.reshape(-1, 1) if ext.ndim == 1 else ext, (c.num_frames, 2))
    room = np.sqrt(np.maximum(ext * ext - dxz * dxz, 0.0))
    return (c.ankle[..., 1] - rel[..., 1] + room).min(axis=1)


def limit_reach(skel, c: Controls, ext=LEG_EXT, sigma=2.0) -> float:
    """Lower the root where a leg could not reach its ankle target (one-sided smoothing),
    leaving frames that are within reach alone. Returns the largest lowering (m)."""
    allow = allowed_root_height(skel, c, ext)
    corr = np.minimum(allow - c.root_pos[:, 1], 0.0)
    sm = lower_envelope(corr, sigma)
    c.root_pos[:, 1] += sm
    return float(-sm.min()) if len(sm) else 0.0
