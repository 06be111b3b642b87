"""Clip coordinates of a flock recording and the rigid motions that keep world up.

A recording stores agent positions as ``(x, z)`` on the ground plane (``dim == 2``) or
``(x, y, z)`` with +Y up (``dim == 3``), metres. The rigid motions a DDG uses are a yaw about +Y
followed by a translation, ``X p = R_y(yaw) p + t`` (Lai, Chenney and Fan 2005, section 4.2:
in 2D every rigid motion, in 3D those that never tilt or roll a flock). The rotation of the
horizontal part is :func:`runtime.motion.planar.rotate_xz`.
"""
from __future__ import annotations

import numpy as np

from ..motion.planar import rotate_xz

__all__ = ["horizontal_axes", "to_xyz", "yaw_rotate", "apply_transform", "invert_transform",
           "compose_transforms"]


def horizontal_axes(dim: int) -> tuple[int, int]:
    """Column indices of x and z in a ``dim``-D point: (0, 1) in 2D, (0, 2) in 3D."""
    if dim == 2:
        return 0, 1
    if dim == 3:
        return 0, 2
    raise ValueError(f"configurations are 2D or 3D, got dimension {dim}")


def to_xyz(p) -> np.ndarray:
    """Clip coordinates (..., D) as world coordinates (..., 3), float64: ``(x, z)`` becomes
    ``(x, 0, z)``. Always a new array."""
    p = np.asarray(p, dtype=np.float64)
    if p.shape[-1] == 3:
        return p.copy()
    out = np.zeros(p.shape[:-1] + (3,))
    out[..., 0] = p[..., 0]
    out[..., 2] = p[..., 1]
    return out


def yaw_rotate(p: np.ndarray, yaw) -> np.ndarray:
    """Rotate points ``p`` (..., D) about +Y by ``yaw`` (broadcast over ``p[..., 0]``); the
    result keeps ``p``'s floating type (integers become float64)."""
    p = np.asarray(p)
    ix, iz = horizontal_axes(p.shape[-1])
    out = p.copy() if p.dtype.kind == "f" else p.astype(np.float64)
    out[..., [ix, iz]] = rotate_xz(p[..., [ix, iz]], yaw)
    return out


def apply_transform(yaw, t, p: np.ndarray) -> np.ndarray:
    """``X p = R_y(yaw) p + t`` for points (..., D)."""
    return yaw_rotate(p, yaw) + np.asarray(t)


def invert_transform(yaw, t):
    """Inverse of ``(yaw, t)``: ``p = R^-1 (q - t)``."""
    yaw = np.asarray(yaw, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    return -yaw, -yaw_rotate(t, -yaw)


def compose_transforms(yaw1, t1, yaw2, t2):
    """``X1 o X2`` (apply ``X2`` first), in 2D or 3D. (Not :func:`runtime.motion.planar.compose`:
    that one is 2D only and adds the translation first, which rounds differently.)"""
    return np.asarray(yaw1) + np.asarray(yaw2), yaw_rotate(np.asarray(t2, dtype=np.float64), yaw1) + t1
