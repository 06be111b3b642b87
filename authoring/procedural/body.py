"""The generated performer: a 31-joint CMU MotionBuilder-family skeleton with adult proportions.

Joint names and parents are exactly ``runtime.motion.skeleton.CMU_MB_NAMES`` /
``CMU_MB_PARENTS`` (family ``"cmu-mb"``), so generated takes mix with the CMU family-A files.
The rest pose is a T-pose facing +Z with the performer's left along +X, legs straight down,
feet flat and pointing +Z, arms along +-X with the palms down, like the family-A T-pose
frame. Offsets are in metres here; takes are written in CMU units (1 unit = 0.05644 m) so
the BVH loader's family default scale applies.

Proportions are those of a ~1.72 m adult: hip-joint centres 0.18 m apart, thigh 0.42 m,
shank 0.41 m, ankle 0.075 m above the sole, foot 0.24 m heel to toe, shoulder joints 0.36 m
apart, upper arm 0.29 m, forearm 0.26 m.
"""
from __future__ import annotations

import numpy as np

from runtime.motion.skeleton import CMU_MB_NAMES, CMU_MB_PARENTS, Skeleton

__all__ = [
    "CMU_UNIT", "THIGH", "SHANK", "ANKLE_HEIGHT", "HIP_OFFSET", "BALL", "HEEL", "TOE_TIP",
    "UPPER_ARM", "FOREARM", "J", "make_skeleton", "leg_length", "standing_root_height",
]

CMU_UNIT = 0.05644            # metres per CMU file unit ("inches x 0.45")

THIGH = 0.42
SHANK = 0.41
ANKLE_HEIGHT = 0.075          # ankle joint above the sole when the foot is flat
HIP_OFFSET = np.array([0.09, -0.06, 0.0])        # Hips -> LeftUpLeg (mirror x for right)
BALL = np.array([0.0, -0.055, 0.13])            # ankle -> ball of the foot (LeftToeBase)
TOE_TIP = np.array([0.0, 0.0, 0.06])            # ball -> toe tip (end site)
HEEL = np.array([0.0, -ANKLE_HEIGHT, -0.05])    # ankle -> heel contact point (not a joint)
UPPER_ARM = 0.29
FOREARM = 0.26
SHOULDER = np.array([0.02, 0.14, 0.0])          # Spine1 -> LeftShoulder (clavicle root)
ARM = np.array([0.15, 0.02, -0.01])             # LeftShoulder -> LeftArm (shoulder joint)


class _Index:
    """Joint indices by name (J.LeftUpLeg etc.)."""

    def __init__(self, names):
        for i, n in enumerate(names):
            setattr(self, n, i)


J = _Index(CMU_MB_NAMES)


def _offsets() -> np.ndarray:
    off = {
        "Hips": (0, 0, 0),
        "LHipJoint": (0, 0, 0), "LeftUpLeg": tuple(HIP_OFFSET), "LeftLeg": (0, -THIGH, 0),
        "LeftFoot": (0, -SHANK, 0), "LeftToeBase": tuple(BALL),
        "LowerBack": (0, 0, 0), "Spine": (0, 0.12, -0.01), "Spine1": (0, 0.13, 0.0),
        "Neck": (0, 0.18, -0.01), "Neck1": (0, 0.07, 0.015), "Head": (0, 0.07, 0.0),
        "LeftShoulder": tuple(SHOULDER), "LeftArm": tuple(ARM), "LeftForeArm": (UPPER_ARM, 0, 0),
        "LeftHand": (FOREARM, 0, 0), "LeftFingerBase": (0.045, 0, 0), "LeftHandIndex1": (0.045, 0, 0),
        "LThumb": (0.02, -0.005, 0.025),
    }
    out = np.zeros((len(CMU_MB_NAMES), 3))
    for i, n in enumerate(CMU_MB_NAMES):
        if n in off:
            out[i] = off[n]
        else:  # right side: mirror of the left
            left = n.replace("Right", "Left").replace("RHip", "LHip").replace("RThumb", "LThumb")
            out[i] = np.array(off[left]) * np.array([-1.0, 1.0, 1.0])
    return out


def make_skeleton() -> Skeleton:
    """The generator's skeleton (metres)."""
    ends = (
        (J.LeftToeBase, tuple(TOE_TIP)), (J.RightToeBase, tuple(TOE_TIP)),
        (J.Head, (0.0, 0.19, 0.02)),
        (J.LeftHandIndex1, (0.08, 0.0, 0.0)), (J.LThumb, (0.03, 0.0, 0.03)),
        (J.RightHandIndex1, (-0.08, 0.0, 0.0)), (J.RThumb, (-0.03, 0.0, 0.03)),
    )
    return Skeleton(CMU_MB_NAMES, np.array(CMU_MB_PARENTS), _offsets(), ends)


def leg_length() -> float:
    return THIGH + SHANK


def standing_root_height(knee_flex_deg: float = 6.0) -> float:
    """Root (Hips) height with the feet flat under the hips and the knees flexed this much."""
    d = np.sqrt(THIGH ** 2 + SHANK ** 2 + 2 * THIGH * SHANK * np.cos(np.radians(knee_flex_deg)))
    return float(ANKLE_HEIGHT + d - HIP_OFFSET[1])
