"""What the known BVH releases do: file units by skeleton family, synthetic first frames.

* **Scale** (metres per file unit) by skeleton family (:attr:`Skeleton.family`, joint names
  + topology):

  ============  ==========  =====================================================
  family        scale       why
  ============  ==========  =====================================================
  cmu-mb        0.05644     CMU units, "inches x 0.45" (1 / 0.45 in = 0.05644 m)
  cmu-3dsmax    0.05644     CMU units
  cmu-daz       0.01        DAZ/Poser figure, roughly centimetres
  anything else 1.0         file assumed to be in metres (crowdweave's own exports)
  ============  ==========  =====================================================

* **Synthetic first frame.** cgspeed MotionBuilder-friendly and DAZ-friendly files start
  with a hand-made T-pose / rest pose. Frame 0 counts as synthetic when its largest
  joint-rotation change to frame 1 is more than ``T0_MIN_DEGREES`` (5 degrees) *and* more
  than ``T0_RATIO`` (3) times the 99th percentile of the same quantity (largest per-joint
  change) over all later frame pairs. The ratio sits about a factor 2 from both the files
  with a synthetic frame (T-poses and DAZ rest poses, whose rest pose blends into the
  motion over frames 1-4) and the files without one; the figures are in docs/decisions.md.
* **Frame rate.** ``1 / Frame Time`` is snapped to the nearest integer when within 0.01 %
  (``.0083333`` -> 120, ``0.0166667`` -> 60; 29.97 stays 29.97).
"""
from __future__ import annotations

import numpy as np

from runtime.motion import quat

__all__ = ["FAMILY_SCALES", "default_scale", "T0_MIN_DEGREES", "T0_RATIO", "detect_synthetic_first_frame",
           "snap_fps"]

#: metres per file unit for the known skeleton families (see the module docstring).
FAMILY_SCALES: dict[str, float] = {"cmu-mb": 0.05644, "cmu-3dsmax": 0.05644, "cmu-daz": 0.01}

# Synthetic-first-frame detector thresholds (module docstring).
T0_MIN_DEGREES = 5.0
T0_RATIO = 3.0
# Snap 1 / frame_time to an integer rate when the relative difference is below this.
_FPS_SNAP_REL = 1e-4


def default_scale(family: str) -> float:
    """Metres per file unit for a skeleton family (1.0 for families not listed)."""
    return FAMILY_SCALES.get(family, 1.0)


def snap_fps(frame_time: float) -> float:
    """``1 / frame_time``, snapped to the nearest whole rate when that close (see above)."""
    fps = 1.0 / frame_time
    r = round(fps)
    if r >= 1 and abs(fps - r) <= _FPS_SNAP_REL * r:
        return float(r)
    return fps


def detect_synthetic_first_frame(rot: np.ndarray) -> bool:
    """Frame 0 is synthetic if its largest joint-rotation change to frame 1 is far above the
    typical frame-to-frame change (thresholds T0_MIN_DEGREES, T0_RATIO).

    Args:
        rot: (F, J, 4) joint rotations (unit quaternions) of every frame in the file.
    """
    if len(rot) < 3:
        return False
    step = np.degrees(quat.angle(rot[:-1], rot[1:])).max(axis=1)   # (F-1,) largest per-joint change
    first = step[0]
    typical = np.percentile(step[1:], 99)
    return bool(first > T0_MIN_DEGREES and first > T0_RATIO * typical)
