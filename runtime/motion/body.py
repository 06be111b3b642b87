"""A simple body for a skeleton: one closed prism ("capsule limb") per bone in the rest pose,
rigidly bound to the bone's parent joint — enough for a DCC viewport to show people, not
bones. Built once per skeleton; the USD writer only copies the arrays.

:func:`body_parts` splits the same limbs by what they wear (skin, shirt, trousers, shoes; the
parts of :mod:`runtime.appearance`) and gives each vertex its offset from its limb's axis, so a
body width factor can thicken the limbs without moving a joint; :func:`prop_mesh` builds the
props (a hat on the head, a bag in the right hand) in the same form.
"""
from __future__ import annotations

import numpy as np

from . import quat
from .fk import end_site_positions, forward_kinematics
from .skeleton import Skeleton

__all__ = ["body_mesh", "body_parts", "prop_mesh", "prop_joint", "part_of_joint", "PROP_JOINTS"]

# radius by joint-name fragment (first match wins); joints matching SKIP get no limb
_RADII = (("Head", 0.095), ("Neck", 0.05), ("Spine", 0.11), ("LowerBack", 0.12), ("Hips", 0.12),
          ("UpLeg", 0.075), ("Leg", 0.055), ("Foot", 0.045), ("Toe", 0.035), ("Arm", 0.045),
          ("ForeArm", 0.038), ("Hand", 0.035), ("Shoulder", 0.05))
_SKIP = ("Thumb", "Index", "Finger", "HipJoint")
# the joint each prop is bound to, by preference (the first the skeleton has)
PROP_JOINTS = {"hat": ("Head",), "bag": ("RightHand", "RightForeArm", "Spine1", "Spine")}


def _radius(name: str) -> float:
    best = 0.05
    for frag, r in _RADII:
        if frag in name:
            best = r
    return best


def part_of_joint(name: str) -> int:
    """The part (index into ``runtime.appearance.PARTS``: 0 skin, 1 shirt, 2 trousers, 3 shoes)
    that a limb bound to joint ``name`` wears."""
    if any(s in name for s in ("Head", "Neck", "Hand", "Thumb", "Finger")):
        return 0
    if any(s in name for s in ("Foot", "Toe")):
        return 3
    if "Leg" in name:
        return 2
    return 1


def _rest(skeleton: Skeleton):
    J = skeleton.num_joints
    gr, gp = forward_kinematics(skeleton, skeleton.offsets[0], quat.identity((J,)))
    return gp, end_site_positions(skeleton, gr, gp)


def _segments(skeleton: Skeleton):
    """(a, b, radius, joint) of every limb in the rest pose."""
    gp, ends = _rest(skeleton)
    segs = []
    for j in range(1, skeleton.num_joints):
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
    return segs


def _prisms(segs, sides: int, caps: float = 0.5):
    """Closed prisms around ``segs`` ((a, b, radius, joint), ...): points (P, 3) float32, face
    counts, face indices, joint per point and each point's offset from its prism's axis (P, 3)."""
    pts, radial, counts, idx, jidx = [], [], [], [], []
    ang = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    base = 0
    for a, b, r, joint in segs:
        a, b = np.asarray(a, float), np.asarray(b, float)
        axis = b - a
        d = axis / np.linalg.norm(axis)
        ref = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        u = np.cross(d, ref)
        u /= np.linalg.norm(u)
        v = np.cross(d, u)
        ring = np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * v
        a2, b2 = a - caps * r * d, b + caps * r * d          # rounded-off ends overlap the joints
        pts.append(np.concatenate([a2 + r * ring, b2 + r * ring, [a2 - caps * r * d, b2 + caps * r * d]]))
        radial.append(np.concatenate([r * ring, r * ring, np.zeros((2, 3))]))
        jidx.append(np.full(2 * sides + 2, joint))
        for s in range(sides):
            t = (s + 1) % sides
            counts.append(4)
            idx += [base + s, base + t, base + sides + t, base + sides + s]
            counts.append(3)
            idx += [base + 2 * sides, base + t, base + s]                  # cap at a
            counts.append(3)
            idx += [base + 2 * sides + 1, base + sides + s, base + sides + t]  # cap at b
        base += 2 * sides + 2
    return (np.concatenate(pts).astype(np.float32), np.array(counts, dtype=np.int32),
            np.array(idx, dtype=np.int32), np.concatenate(jidx).astype(np.int32),
            np.concatenate(radial).astype(np.float32))


def body_mesh(skeleton: Skeleton, sides: int = 8):
    """Rest-pose mesh: (points (P, 3) float32, face_counts (F,), face_indices (I,),
    joint_indices (P,) int: the joint each vertex follows)."""
    return _prisms(_segments(skeleton), sides)[:4]


def body_parts(skeleton: Skeleton, sides: int = 8) -> dict:
    """The body of :func:`body_mesh` split by part: ``{part index: (points, face_counts,
    face_indices, joint_indices, radial)}`` for the parts that have limbs (0 skin, 1 shirt,
    2 trousers, 3 shoes), ``radial`` (P, 3) float32 being each point's offset from its limb's
    axis (a body ``w`` times as wide moves the point by ``(w - 1) * radial``)."""
    by_part: dict = {}
    for seg in _segments(skeleton):
        by_part.setdefault(part_of_joint(skeleton.names[seg[3]]), []).append(seg)
    return {k: _prisms(segs, sides) for k, segs in sorted(by_part.items())}


def prop_joint(skeleton: Skeleton, kind: str) -> int | None:
    """The joint a prop of ``kind`` ("hat", "bag") is bound to, or None if the skeleton has none."""
    for name in PROP_JOINTS[kind]:
        if skeleton.has(name):
            return skeleton.index(name)
    return None


def prop_mesh(skeleton: Skeleton, kind: str, sides: int = 10):
    """A prop in the rest pose, rigidly bound to one joint, in the form of :func:`body_parts`'s
    values, or None when the skeleton lacks the joint. ``"hat"``: a flat-topped cap on the head
    (a short wide prism past the top of the head, along the neck-head direction); ``"bag"``: a
    bag held in the right hand (a prism hanging on from the hand along the forearm)."""
    j = prop_joint(skeleton, kind)
    if j is None:
        return None
    gp, ends = _rest(skeleton)
    p = skeleton.parents[j]
    d = gp[j] - gp[p] if p >= 0 else np.array([0.0, 1.0, 0.0])
    d = d / max(np.linalg.norm(d), 1e-9)
    if kind == "hat":
        tip = next((ends[k] for k, (jj, _) in enumerate(skeleton.end_sites) if jj == j), gp[j] + 0.19 * d)
        top = gp[j] + np.dot(tip - gp[j], d) * d
        seg = (top - 0.05 * d, top + 0.05 * d, 0.11, j)
        return _prisms([seg], sides, caps=0.0)
    start = gp[j] + 0.06 * d
    seg = (start, start + 0.32 * d, 0.08, j)
    return _prisms([seg], 4, caps=0.0)
