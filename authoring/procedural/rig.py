"""Rig controls -> joint rotations: analytic two-bone IK for legs and arms, spine and neck.

Activities describe the performer with a few per-frame *controls* (:class:`Controls`):
the root (pelvis) position and its tilt relative to the body heading, totals of spine
flexion / lateral bend / twist, a gaze direction, world targets for both ankles (position
and foot orientation, usually from planted footprints), and for each arm either swing
angles (pendulum arm swing) or a wrist target (on a box, in the thorax frame while
carrying). :func:`solve` turns them into the 31 local joint rotations, vectorized over all
frames of a take:

* legs: two-bone IK (law of cosines) from the hip joint to the ankle target, knee in the
  plane of a pole vector along the foot's forward direction, so a planted ankle target is
  met exactly whenever it is within reach (``reach_error`` reports by how much it was not);
  the foot then takes its target orientation and the toes their flexion;
* spine: the totals are split over LowerBack / Spine / Spine1;
* neck: the rotation that brings the head to its gaze target is split over Neck / Neck1 /
  Head (fractional powers of one quaternion, so they compose exactly);
* arms: pendulum swing angles define a wrist position (elbow flexion forward, elbows
  pointing back), target mode blends the wrist towards a world or thorax-relative target;
  either way the same two-bone IK gives upper arm and forearm.

Bone frames are built from two orthonormal axes (bone direction and the direction the
middle joint points) and compared with the same axes in the rest pose:
``R = [a' b' a'xb'] [a b axb]^T``.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from runtime.motion import quat

from . import body

__all__ = ["Controls", "solve", "qx", "qy", "qz", "two_bone"]


def qx(a):
    return quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.asarray(a, dtype=np.float64))


def qy(a):
    return quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), np.asarray(a, dtype=np.float64))


def qz(a):
    return quat.from_axis_angle(np.array([0.0, 0.0, 1.0]), np.asarray(a, dtype=np.float64))


def _unit(v, fallback=None):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    if fallback is None:
        return v / np.maximum(n, 1e-12)
    return np.where(n > 1e-9, v / np.maximum(n, 1e-12), fallback)


def _dot(a, b):
    return np.sum(a * b, axis=-1, keepdims=True)


def frame_quat(a_t, b_t, a_r, b_r):
    """Rotation taking the rest axes (a_r, b_r) to the target axes (a_t, b_t)."""
    c_t = np.cross(a_t, b_t)
    a_r = np.broadcast_to(a_r, a_t.shape)
    b_r = np.broadcast_to(b_r, a_t.shape)
    c_r = np.cross(a_r, b_r)
    T = np.stack([a_t, b_t, c_t], axis=-1)
    R = np.stack([a_r, b_r, c_r], axis=-1)
    return quat.from_matrix(T @ np.swapaxes(R, -1, -2))


def two_bone(p0, target, l1, l2, pole, max_ext=0.9995):
    """Analytic two-bone IK. Returns (middle joint, reached end, unit pole in the limb
    plane, reach error = distance from the target to the reached end)."""
    d = target - p0
    D = np.linalg.norm(d, axis=-1, keepdims=True)
    dn = d / np.maximum(D, 1e-12)
    Dc = np.clip(D, abs(l1 - l2) + 1e-4, max_ext * (l1 + l2))
    a = (l1 * l1 - l2 * l2 + Dc * Dc) / (2.0 * Dc)
    r = np.sqrt(np.maximum(l1 * l1 - a * a, 0.0))
    pp = _unit(pole - _dot(pole, dn) * dn)
    mid = p0 + dn * a + pp * r
    end = p0 + dn * Dc
    return mid, end, pp, np.abs(D - Dc)[..., 0]


def _slerp_id(q, t):
    """q ** t for unit quaternions (fraction of the rotation)."""
    ident = np.zeros_like(q)
    ident[..., 0] = 1.0
    return quat.slerp(ident, q, t)


@dataclass
class Controls:
    """Per-frame rig controls of a stretch of motion (all arrays have F frames first).

    Feet and arms are indexed 0 = left, 1 = right. Angles are radians. ``head`` pitch is
    positive looking down; arm ``swing`` is positive forward; ``elbow`` is flexion.
    """
    root_pos: np.ndarray      # (F, 3) world position of the Hips joint
    heading: np.ndarray       # (F,) body heading (0 faces +Z)
    pelvis: np.ndarray        # (F, 3) yaw offset, pitch (forward tilt), roll (left side up)
    spine: np.ndarray         # (F, 3) flexion (forward), lateral bend (towards left), twist (to the left)
    head: np.ndarray          # (F, 2) gaze pitch (world, down positive), yaw relative to heading
    ankle: np.ndarray         # (F, 2, 3) world ankle targets
    foot_q: np.ndarray        # (F, 2, 4) world foot orientations
    toe: np.ndarray           # (F, 2) toe flexion (toes up positive)
    arm: np.ndarray           # (F, 2, 3) swing, abduction, elbow flexion
    hand_w: np.ndarray        # (F, 2) weight of the wrist target (0 = swing mode)
    hand_attach: np.ndarray   # (F, 2) 0 = world target, 1 = thorax-relative target
    hand_world: np.ndarray    # (F, 2, 3) world wrist targets
    hand_thorax: np.ndarray   # (F, 2, 3) wrist targets in the thorax (Spine1) frame
    clav: np.ndarray          # (F, 2, 2) clavicle elevation, protraction
    wrist: np.ndarray         # (F, 2) wrist flexion

    @property
    def num_frames(self) -> int:
        return len(self.heading)

    @classmethod
    def empty(cls, F: int) -> "Controls":
        fq = np.zeros((F, 2, 4))
        fq[..., 0] = 1.0
        return cls(
            root_pos=np.zeros((F, 3)), heading=np.zeros(F), pelvis=np.zeros((F, 3)),
            spine=np.zeros((F, 3)), head=np.zeros((F, 2)), ankle=np.zeros((F, 2, 3)),
            foot_q=fq, toe=np.zeros((F, 2)), arm=np.zeros((F, 2, 3)), hand_w=np.zeros((F, 2)),
            hand_attach=np.zeros((F, 2)), hand_world=np.zeros((F, 2, 3)),
            hand_thorax=np.zeros((F, 2, 3)), clav=np.zeros((F, 2, 2)), wrist=np.zeros((F, 2)))

    @classmethod
    def concat(cls, parts) -> "Controls":
        return cls(**{f.name: np.concatenate([getattr(p, f.name) for p in parts], axis=0)
                      for f in fields(cls)})

    def slice(self, a, b) -> "Controls":
        return Controls(**{f.name: getattr(self, f.name)[a:b] for f in fields(self)})


# rest-pose bone axes: (bone direction, direction the middle joint points)
_LEG_A = np.array([0.0, -1.0, 0.0])
_LEG_B = np.array([0.0, 0.0, 1.0])           # knee points forward
_ARM_A = (np.array([1.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]))
_ARM_B = np.array([0.0, 0.0, -1.0])          # elbow points back
_SPINE_SPLIT = (0.35, 0.35, 0.30)
_NECK_SPLIT = (0.35, 0.35, 0.30)

_LEGS = ((body.J.LHipJoint, body.J.LeftUpLeg, body.J.LeftLeg, body.J.LeftFoot, body.J.LeftToeBase),
         (body.J.RHipJoint, body.J.RightUpLeg, body.J.RightLeg, body.J.RightFoot, body.J.RightToeBase))
_ARMS = ((body.J.LeftShoulder, body.J.LeftArm, body.J.LeftForeArm, body.J.LeftHand,
          body.J.LeftFingerBase, body.J.LeftHandIndex1, body.J.LThumb),
         (body.J.RightShoulder, body.J.RightArm, body.J.RightForeArm, body.J.RightHand,
          body.J.RightFingerBase, body.J.RightHandIndex1, body.J.RThumb))


@dataclass
class Solved:
    root_pos: np.ndarray       # (F, 3)
    local: np.ndarray          # (F, J, 4) local rotations, entry 0 = root world rotation
    leg_reach_error: np.ndarray   # (F, 2) metres the ankle target was out of reach
    arm_reach_error: np.ndarray   # (F, 2)
    knee_flexion: np.ndarray   # (F, 2) radians


def solve(skel, c: Controls) -> Solved:
    F = c.num_frames
    off = skel.offsets
    Jn = skel.num_joints
    local = np.zeros((F, Jn, 4))
    local[..., 0] = 1.0

    # -- root ---------------------------------------------------------------------------
    root_rot = quat.mul(qy(c.heading + c.pelvis[:, 0]), quat.mul(qx(c.pelvis[:, 1]), qz(c.pelvis[:, 2])))
    local[:, 0] = root_rot
    root_pos = c.root_pos

    # -- spine ----------------------------------------------------------------------------
    world = root_rot
    pos = root_pos
    spine_world = []
    for frac, j in zip(_SPINE_SPLIT, (body.J.LowerBack, body.J.Spine, body.J.Spine1)):
        lq = quat.mul(qy(c.spine[:, 2] * frac), quat.mul(qz(-c.spine[:, 1] * frac), qx(c.spine[:, 0] * frac)))
        pos = pos + quat.rotate(world, np.broadcast_to(off[j], (F, 3)))
        world = quat.mul(world, lq)
        local[:, j] = lq
        spine_world.append(world)
    chest_rot, chest_pos = world, pos                      # Spine1

    # -- neck and head: bring the head to the gaze target ---------------------------------
    head_target = quat.mul(qy(c.heading + c.head[:, 1]), qx(c.head[:, 0]))
    total = quat.mul(quat.inv(chest_rot), head_target)
    total = quat.canonical(total)
    for frac, j in zip(_NECK_SPLIT, (body.J.Neck, body.J.Neck1, body.J.Head)):
        local[:, j] = _slerp_id(total, np.full(F, frac))

    # -- legs -----------------------------------------------------------------------------
    leg_err = np.zeros((F, 2))
    knee = np.zeros((F, 2))
    fwd = np.array([0.0, 0.0, 1.0])
    for s, (jh, ju, jl, jf, jt) in enumerate(_LEGS):
        hip = root_pos + quat.rotate(root_rot, np.broadcast_to(off[ju] + off[jh], (F, 3)))
        foot_fwd = quat.rotate(c.foot_q[:, s], np.broadcast_to(fwd, (F, 3)))
        body_fwd = quat.rotate(qy(c.heading), np.broadcast_to(fwd, (F, 3)))
        pole = foot_fwd * np.array([1.0, 0.0, 1.0]) * 0.75 + body_fwd * 0.25
        side = quat.rotate(qy(c.heading), np.broadcast_to(np.array([1.0 - 2 * s, 0.0, 0.0]), (F, 3)))
        pole = _unit(pole + 0.12 * side)                  # knees point slightly outwards
        l1 = -off[jl][1]
        l2 = -off[jf][1]
        kpos, end, pp, err = two_bone(hip, c.ankle[:, s], l1, l2, pole)
        a_t = _unit(kpos - hip)
        b_t = _unit(pp - _dot(pp, a_t) * a_t)
        thigh = frame_quat(a_t, b_t, _LEG_A, _LEG_B)
        a_s = _unit(end - kpos)
        b_s = np.cross(np.cross(a_t, b_t), a_s)
        shank = frame_quat(a_s, b_s, _LEG_A, _LEG_B)
        local[:, jh] = quat.identity((F,))
        local[:, ju] = quat.mul(quat.inv(root_rot), thigh)
        local[:, jl] = quat.mul(quat.inv(thigh), shank)
        local[:, jf] = quat.mul(quat.inv(shank), c.foot_q[:, s])
        local[:, jt] = qx(-c.toe[:, s])
        leg_err[:, s] = err
        knee[:, s] = np.arccos(np.clip(np.sum(a_t * a_s, axis=-1), -1.0, 1.0))

    # -- arms -----------------------------------------------------------------------------
    arm_err = np.zeros((F, 2))
    chest_yaw = quat.yaw(chest_rot)
    yaw_frame = qy(chest_yaw)
    down = np.array([0.0, -1.0, 0.0])
    for s, (jc, ja, jf, jh, jfb, jfi, jth) in enumerate(_ARMS):
        sg = 1.0 - 2 * s                                   # +1 left, -1 right
        clav = quat.mul(qz(sg * c.clav[:, s, 0]), qy(-sg * c.clav[:, s, 1]))
        clav_world = quat.mul(chest_rot, clav)
        sh = chest_pos + quat.rotate(chest_rot, np.broadcast_to(off[jc], (F, 3))) \
            + quat.rotate(clav_world, np.broadcast_to(off[ja], (F, 3)))
        l1 = abs(off[jf][0])
        l2 = abs(off[jh][0])
        # pendulum swing -> wrist position in the chest's yaw frame
        swing, abd, elbow = c.arm[:, s, 0], c.arm[:, s, 1], c.arm[:, s, 2]
        u_loc = quat.rotate(quat.mul(qx(-swing), qz(sg * abd)), np.broadcast_to(down, (F, 3)))
        u = quat.rotate(yaw_frame, u_loc)
        f = quat.rotate(yaw_frame, np.broadcast_to(fwd, (F, 3)))
        fp = _unit(f - _dot(f, u) * u)
        fd = np.cos(elbow)[:, None] * u + np.sin(elbow)[:, None] * fp
        w_fk = sh + l1 * u + l2 * fd
        pole_fk = -fp
        # target mode
        thorax_t = chest_pos + quat.rotate(chest_rot, c.hand_thorax[:, s])
        att = c.hand_attach[:, s][:, None]
        w_t = (1.0 - att) * c.hand_world[:, s] + att * thorax_t
        pole_t = quat.rotate(yaw_frame, np.broadcast_to(np.array([sg * 0.7, -1.0, -0.35]), (F, 3)))
        w = c.hand_w[:, s][:, None]
        wrist_target = (1.0 - w) * w_fk + w * w_t
        # soft reach limit: beyond 93 % of the arm's reach the wrist approaches full
        # extension asymptotically (no snap of the elbow when a target gets out of reach)
        reach = 0.995 * (l1 + l2)
        soft = 0.93 * reach
        vec = wrist_target - sh
        dist = np.linalg.norm(vec, axis=-1, keepdims=True)
        eff = np.where(dist > soft, soft + (reach - soft) * (1.0 - np.exp(-(dist - soft) / (reach - soft))), dist)
        clamped = sh + vec * (eff / np.maximum(dist, 1e-12))
        short = np.linalg.norm(clamped - wrist_target, axis=-1)      # how far the hand falls short
        wrist_target = clamped
        pole = _unit((1.0 - w) * pole_fk + w * _unit(pole_t))
        epos, end, pp, err = two_bone(sh, wrist_target, l1, l2, pole, max_ext=0.999)
        a_t = _unit(epos - sh)
        b_t = _unit(pp - _dot(pp, a_t) * a_t)
        upper = frame_quat(a_t, b_t, _ARM_A[s], _ARM_B)
        a_f = _unit(end - epos)
        b_f = np.cross(np.cross(a_t, b_t), a_f)
        fore = frame_quat(a_f, b_f, _ARM_A[s], _ARM_B)
        local[:, jc] = clav
        local[:, ja] = quat.mul(quat.inv(clav_world), upper)
        local[:, jf] = quat.mul(quat.inv(upper), fore)
        local[:, jh] = qz(-sg * c.wrist[:, s])
        local[:, jfb] = qz(np.full(F, -sg * np.radians(10.0)))
        local[:, jfi] = qz(np.full(F, -sg * np.radians(18.0)))
        local[:, jth] = qy(np.full(F, sg * np.radians(15.0)))
        arm_err[:, s] = np.where(c.hand_w[:, s] > 0.99, np.maximum(err, short), 0.0)

    return Solved(root_pos=root_pos, local=local, leg_reach_error=leg_err,
                  arm_reach_error=arm_err, knee_flexion=knee)


def chest_transforms(skel, c: Controls):
    """World rotation (F, 4) and position (F, 3) of the Spine1 (thorax) joint implied by
    the root and spine controls (the frame that carried objects ride in)."""
    F = c.num_frames
    world = quat.mul(qy(c.heading + c.pelvis[:, 0]), quat.mul(qx(c.pelvis[:, 1]), qz(c.pelvis[:, 2])))
    pos = c.root_pos
    for frac, j in zip(_SPINE_SPLIT, (body.J.LowerBack, body.J.Spine, body.J.Spine1)):
        lq = quat.mul(qy(c.spine[:, 2] * frac), quat.mul(qz(-c.spine[:, 1] * frac), qx(c.spine[:, 0] * frac)))
        pos = pos + quat.rotate(world, np.broadcast_to(skel.offsets[j], (F, 3)))
        world = quat.mul(world, lq)
    return world, pos


def hip_positions(skel, c: Controls) -> np.ndarray:
    """(F, 2, 3) world hip-joint centres implied by the root controls."""
    F = c.num_frames
    root_rot = quat.mul(qy(c.heading + c.pelvis[:, 0]), quat.mul(qx(c.pelvis[:, 1]), qz(c.pelvis[:, 2])))
    out = np.empty((F, 2, 3))
    for s, (jh, ju, *_rest) in enumerate(_LEGS):
        out[:, s] = c.root_pos + quat.rotate(root_rot, np.broadcast_to(skel.offsets[ju] + skel.offsets[jh], (F, 3)))
    return out
