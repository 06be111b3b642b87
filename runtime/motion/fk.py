"""Forward kinematics, vectorized over any leading axes (frames, agents) and over joints.

Joints are processed one depth level at a time: all joints at depth d are computed in one
numpy call from their parents at depth d-1, so the Python loop runs ``max depth`` times
(about 9 for the CMU skeleton), never once per joint or per frame.

    G_rot[j] = G_rot[parent(j)] * L_rot[j]
    G_pos[j] = G_pos[parent(j)] + G_rot[parent(j)] (offset[j])
"""
from __future__ import annotations

import numpy as np

from . import quat
from .skeleton import Skeleton

__all__ = ["forward_kinematics", "end_site_positions"]


def forward_kinematics(skeleton: Skeleton, root_position: np.ndarray, local_rotations: np.ndarray):
    """Global joint rotations and positions.

    root_position: (..., 3) world position of joint 0.
    local_rotations: (..., J, 4) w-x-y-z; entry 0 is the root's world rotation.
    Returns (global_rotations (..., J, 4) float64, global_positions (..., J, 3) float64).
    """
    lr = np.asarray(local_rotations, dtype=np.float64)
    lead = lr.shape[:-2]
    J = skeleton.num_joints
    if lr.shape[-2] != J:
        raise ValueError(f"rotations have {lr.shape[-2]} joints, skeleton has {J}")
    gr = np.empty(lead + (J, 4))
    gp = np.empty(lead + (J, 3))
    gr[..., 0, :] = lr[..., 0, :]
    gp[..., 0, :] = root_position
    par = skeleton.parents
    off = skeleton.offsets
    for lvl in skeleton.levels:
        p = par[lvl]
        prot = gr[..., p, :]
        gr[..., lvl, :] = quat.mul(prot, lr[..., lvl, :])
        gp[..., lvl, :] = gp[..., p, :] + quat.rotate(prot, np.broadcast_to(off[lvl], prot.shape[:-1] + (3,)))
    return gr, gp


def end_site_positions(skeleton: Skeleton, global_rotations: np.ndarray, global_positions: np.ndarray):
    """World positions (..., E, 3) of the skeleton's end sites (toe tips, head top, fingers)."""
    if not skeleton.end_sites:
        return np.zeros(global_positions.shape[:-2] + (0, 3))
    js = np.array([j for j, _ in skeleton.end_sites])
    offs = np.array([o for _, o in skeleton.end_sites], dtype=np.float64)
    r = global_rotations[..., js, :]
    return global_positions[..., js, :] + quat.rotate(r, np.broadcast_to(offs, r.shape[:-1] + (3,)))
