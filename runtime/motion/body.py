"""A simple body for a skeleton: one closed prism ("capsule limb") per bone in the rest pose,
rigidly bound to the bone's parent joint — enough for a DCC viewport to show people, not
bones. Built once per skeleton; the USD writer only copies the arrays.
"""
from __future__ import annotations

import numpy as np

from . import quat
from .fk import end_site_positions, forward_kinematics
from .skeleton import Skeleton

__all__ = ["body_mesh"]

# radius by joint-name fragment (first match wins); joints matching SKIP get no limb
_RADII = (("Head", 0.095), ("Neck", 0.05), ("Spine", 0.11), ("LowerBack", 0.12), ("Hips", 0.12),
          ("UpLeg", 0.075), ("Leg", 0.055), ("Foot", 0.045), ("Toe", 0.035), ("Arm", 0.045),
          ("ForeArm", 0.038), ("Hand", 0.035), ("Shoulder", 0.05))
_SKIP = ("Thumb", "Index", "Finger", "HipJoint")


def _radius(name: str) -> float:
    best = 0.05
    for frag, r in _RADII:
        if frag in name:
            best = r
    return best


def body_mesh(skeleton: Skeleton, sides: int = 8):
    """Rest-pose mesh: (points (P, 3) float32, face_counts (F,), face_indices (I,),
    joint_indices (P,) int: the joint each vertex follows)."""
    J = skeleton.num_joints
    gr, gp = forward_kinematics(skeleton, skeleton.offsets[0], quat.identity((J,)))
    ends = end_site_positions(skeleton, gr, gp)
    segs = []   # (a, b, radius, joint)
    for j in range(1, J):
        p = skeleton.parents[j]
        name = skeleton.names[p]
        if any(s in name for s in _SKIP) or any(s in skeleton.names[j] for s in _SKIP):
            continue
        if np.linalg.norm(gp[j] - gp[p]) < 0.03:
            continue
        segs.append((gp[p], gp[j], _radius(name), p))
    for k, (j, _) in enumerate(skeleton.end_sites):
        name = skeleton.names[j]
        if any(s in name for s in _SKIP) or np.linalg.norm(ends[k] - gp[j]) < 0.03:
            continue
        segs.append((gp[j], ends[k], _radius(name), j))
    pts, counts, idx, jidx = [], [], [], []
    ang = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    for a, b, r, joint in segs:
        axis = b - a
        L = np.linalg.norm(axis)
        d = axis / L
        ref = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        u = np.cross(d, ref)
        u /= np.linalg.norm(u)
        v = np.cross(d, u)
        ring = np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * v
        a2, b2 = a - 0.5 * r * d, b + 0.5 * r * d          # rounded-off ends overlap the joints
        base = sum(len(p) for p in pts)
        ring_a = a2 + r * ring
        ring_b = b2 + r * ring
        pts.append(np.concatenate([ring_a, ring_b, [a2 - 0.5 * r * d, b2 + 0.5 * r * d]]))
        jidx.append(np.full(2 * sides + 2, joint))
        for s in range(sides):
            t = (s + 1) % sides
            counts.append(4)
            idx += [base + s, base + t, base + sides + t, base + sides + s]
            counts.append(3)
            idx += [base + 2 * sides, base + t, base + s]                  # cap at a
            counts.append(3)
            idx += [base + 2 * sides + 1, base + sides + s, base + sides + t]  # cap at b
    return (np.concatenate(pts).astype(np.float32), np.array(counts, dtype=np.int32),
            np.array(idx, dtype=np.int32), np.concatenate(jidx).astype(np.int32))
