"""Foot contact labels of generated motion, from the generator's own foot targets.

The legs are solved to planned footprints (:mod:`.gait`): a planted ankle target does not move
horizontally from heel strike to heel off, and the ball of the foot (``*ToeBase``) stays fixed
through the toe rocker. So the contacts are known exactly from the rig controls, before any
solving: a contact point is on the ground while its target is horizontally still and its sole
point touches the floor. Columns follow :data:`runtime.motion.contacts.CONTACT_POINTS` (heel =
the ankle joint, toe = the toe joint).
"""
from __future__ import annotations

import numpy as np

from runtime.motion import quat

from . import body
from .rig import Controls

__all__ = ["contact_labels", "STILL_SPEED", "SOLE_HEIGHT"]

STILL_SPEED = 0.02     # m/s: a target slower than this is still (planted targets do not move at all)
SOLE_HEIGHT = 0.01     # m: a sole point this close to the floor touches it


def _speed(p: np.ndarray, fps: float) -> np.ndarray:
    """Horizontal speed (F, 2) of points (F, 2, 3): the larger of the steps before and after."""
    d = np.linalg.norm(np.diff(p[..., [0, 2]], axis=0), axis=-1) * fps
    if len(d) == 0:
        return np.zeros(p.shape[:2])
    return np.maximum(np.concatenate([d[:1], d]), np.concatenate([d, d[-1:]]))


def contact_labels(c: Controls, fps: float) -> np.ndarray:
    """Contacts ``(F, 4)`` bool of the controls ``c`` (left heel, left toe, right heel, right toe)."""
    F = c.num_frames
    q = c.foot_q
    heel_sole = c.ankle + quat.rotate(q, np.broadcast_to(body.HEEL, (F, 2, 3)))
    ball = c.ankle + quat.rotate(q, np.broadcast_to(body.BALL, (F, 2, 3)))
    ball_floor = body.ANKLE_HEIGHT + body.BALL[1]          # ball joint height on a flat foot
    heel = (heel_sole[..., 1] < SOLE_HEIGHT) & (_speed(c.ankle, fps) < STILL_SPEED)
    toe = (ball[..., 1] - ball_floor < SOLE_HEIGHT) & (_speed(ball, fps) < STILL_SPEED)
    return np.stack([heel[:, 0], toe[:, 0], heel[:, 1], toe[:, 1]], axis=1)
