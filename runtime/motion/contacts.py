"""Foot contacts: which leg joints a skeleton has, and when each foot is on the ground.

Contacts are per frame and per contact point, a boolean array ``(F, 4)`` whose columns are
:data:`CONTACT_POINTS`: left heel, left toe, right heel, right toe. The heel point is the ankle
joint; the toe point is the toe joint (or, on skeletons without one, the ankle's end site).
A foot is *planted* on a frame when either of its two points is in contact
(:func:`planted`).

Detection (:func:`detect_contacts`) follows the usual height-and-speed test with hysteresis
(e.g. Kovar, Schreiner and Gleicher 2002, "Footskate cleanup"): a point enters contact when
it is within ``enter_height`` of its floor and slower than ``enter_speed``, and leaves it
only when it rises above ``exit_height`` or moves faster than ``exit_speed``; contacts shorter
than ``min_frames`` are dropped. The floor of a point is a low percentile of its own heights
over the clip, so captures whose toe joints rest a few centimetres above y = 0 are read
correctly.

Limits: contacts are detected on flat ground (one floor height per point per clip); a foot
that slides fast while loaded (ice, a shuffle) is read as not in contact.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import quat
from .skeleton import Skeleton

__all__ = ["CONTACT_POINTS", "LegJoints", "leg_joints", "knee_flexion", "contact_point_positions", "detect_contacts", "clip_contacts",
           "planted", "contacts_of", "contact_summary", "planted_speeds", "slide_figures", "SLIDING"]

SLIDING = 0.10          # m/s: a planted point moving faster than this is sliding

CONTACT_POINTS = ("left_heel", "left_toe", "right_heel", "right_toe")

# (hip, knee, ankle, toe-or-None) joint names per side, for each skeleton family of the CMU set
# (../shared/mocap/cmu/README.md) and the procedural generator (family A names).
_FAMILIES = (
    (("LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"), ("RightUpLeg", "RightLeg", "RightFoot", "RightToeBase")),
    (("LeftHip", "LeftKnee", "LeftAnkle", "LeftToe"), ("RightHip", "RightKnee", "RightAnkle", "RightToe")),
    (("lThigh", "lShin", "lFoot", None), ("rThigh", "rShin", "rFoot", None)),
)


@dataclass(frozen=True)
class LegJoints:
    """Joint indices of both legs; row 0 is the left leg, row 1 the right.

    ``toe`` is -1 where the skeleton has no toe joint; then ``toe_offset`` (2, 3) is the
    ankle's end-site offset (metres, in the ankle's frame) used as the toe point.
    """
    hip: np.ndarray
    knee: np.ndarray
    ankle: np.ndarray
    toe: np.ndarray
    toe_offset: np.ndarray


def leg_joints(skeleton: Skeleton) -> LegJoints:
    """The hip-knee-ankle(-toe) chains of ``skeleton``.

    Raises:
        ValueError: the skeleton has none of the known leg layouts (the message lists them).
    """
    for left, right in _FAMILIES:
        names = [n for n in left + right if n is not None]
        if all(skeleton.has(n) for n in names):
            idx = np.array([[skeleton.index(n) if n else -1 for n in side] for side in (left, right)])
            off = np.zeros((2, 3))
            if left[3] is None:
                sites = dict(skeleton.end_sites)
                for s in range(2):
                    if idx[s, 2] not in sites:
                        raise ValueError(f"skeleton has no toe joint and no end site after {(left, right)[s][2]!r}")
                    off[s] = sites[idx[s, 2]]
            return LegJoints(idx[:, 0].copy(), idx[:, 1].copy(), idx[:, 2].copy(), idx[:, 3].copy(), off)
    known = "; ".join("/".join(n for n in left if n) for left, _ in _FAMILIES)
    raise ValueError(f"skeleton has no known leg joints (expected one of: {known})")


def knee_flexion(legs: LegJoints, global_positions: np.ndarray) -> np.ndarray:
    """Knee flexion (radians, 0 = straight) of both legs, ``(..., 2)`` (left, right): the angle
    between thigh (hip to knee) and shin (knee to ankle), from global joint positions."""
    gp = global_positions
    t = gp[..., legs.knee, :] - gp[..., legs.hip, :]
    s = gp[..., legs.ankle, :] - gp[..., legs.knee, :]
    c = np.sum(t * s, axis=-1) / np.maximum(np.linalg.norm(t, axis=-1) * np.linalg.norm(s, axis=-1), 1e-12)
    return np.arccos(np.clip(c, -1.0, 1.0))


def contact_point_positions(legs: LegJoints, global_rotations: np.ndarray, global_positions: np.ndarray) -> np.ndarray:
    """World positions ``(..., 4, 3)`` of the contact points, in :data:`CONTACT_POINTS` order.

    Args:
        legs: from :func:`leg_joints`.
        global_rotations: ``(..., J, 4)`` w-x-y-z world rotations (from forward kinematics).
        global_positions: ``(..., J, 3)`` world joint positions.
    """
    heel = global_positions[..., legs.ankle, :]
    if np.all(legs.toe >= 0):
        toe = global_positions[..., legs.toe, :]
    else:
        toe = heel + quat.rotate(global_rotations[..., legs.ankle, :], legs.toe_offset)
    return np.stack([heel[..., 0, :], toe[..., 0, :], heel[..., 1, :], toe[..., 1, :]], axis=-2)


def detect_contacts(points: np.ndarray, fps: float, *, enter_height: float = 0.05, exit_height: float = 0.08,
                    enter_speed: float = 0.25, exit_speed: float = 0.45, min_frames: int = 3,
                    floor_percentile: float = 2.0) -> np.ndarray:
    """Contact flags ``(F, P)`` bool from contact-point trajectories ``points`` ``(F, P, 3)``.

    Args:
        points: world positions of the contact points (metres, Y up), e.g. from
            :func:`contact_point_positions`.
        fps: frames per second of ``points``.
        enter_height, exit_height: height above the point's floor to enter / stay in contact (m).
        enter_speed, exit_speed: speed to enter / stay in contact (m/s).
        min_frames: contacts shorter than this are dropped.
        floor_percentile: the floor of a point is this percentile of its heights.
    """
    p = np.asarray(points, dtype=np.float64)
    F = p.shape[0]
    if F == 0:
        return np.zeros(p.shape[:2], dtype=bool)
    h = p[..., 1] - np.percentile(p[..., 1], floor_percentile, axis=0)
    v = np.zeros(p.shape[:2])
    if F > 1:
        d = np.linalg.norm(np.diff(p, axis=0), axis=-1) * fps
        v[1:-1] = 0.5 * (d[1:] + d[:-1])
        v[0], v[-1] = d[0], d[-1]
    enter = (h < enter_height) & (v < enter_speed)
    stay = (h < exit_height) & (v < exit_speed)
    out = np.zeros_like(enter)
    state = enter[0].copy()
    out[0] = state
    for f in range(1, F):       # hysteresis: a scan over frames, vectorized over points
        state = np.where(state, stay[f], enter[f])
        out[f] = state
    if min_frames > 1:
        out = _drop_short(out, min_frames)
    return out


def _drop_short(flags: np.ndarray, min_frames: int) -> np.ndarray:
    out = flags.copy()
    for c in range(flags.shape[1]):
        col = np.concatenate([[False], flags[:, c], [False]]).astype(np.int8)
        starts = np.flatnonzero(np.diff(col) == 1)
        ends = np.flatnonzero(np.diff(col) == -1)
        for s, e in zip(starts, ends):
            if e - s < min_frames:
                out[s:e, c] = False
    return out


def planted(contacts: np.ndarray) -> np.ndarray:
    """Per-foot planted flags ``(..., 2)`` (left, right) from point contacts ``(..., 4)``."""
    c = np.asarray(contacts, dtype=bool)
    return c[..., 0::2] | c[..., 1::2]


def clip_contacts(clip, **kw) -> np.ndarray:
    """Detected contacts ``(F, 4)`` of a :class:`~runtime.motion.clip.Clip` (keywords as in
    :func:`detect_contacts`)."""
    gr, gp = clip.fk()
    return detect_contacts(contact_point_positions(leg_joints(clip.skeleton), gr, gp), clip.fps, **kw)


def contacts_of(clip) -> np.ndarray:
    """``clip.contacts`` when the clip carries them, else the detected ones (:func:`clip_contacts`);
    all False for a skeleton without known leg joints. ``(F, 4)`` bool."""
    if getattr(clip, "contacts", None) is not None:
        return clip.contacts
    try:
        return clip_contacts(clip)
    except ValueError:                       # no known leg joints
        return np.zeros((clip.num_frames, len(CONTACT_POINTS)), dtype=bool)


def contact_summary(contacts: np.ndarray, source: str) -> dict:
    """JSON-ready figures of contacts ``(F, 4)``: where they come from (``source``), the share of
    frames each point is on the ground, and the shares of frames with both, one and no foot
    planted."""
    c = np.asarray(contacts, dtype=bool)
    n = max(len(c), 1)
    feet = planted(c).sum(axis=1)
    return {"source": source, **{p: round(float(c[:, k].sum()) / n, 3) for k, p in enumerate(CONTACT_POINTS)},
            "both_feet": round(float((feet == 2).sum()) / n, 3), "one_foot": round(float((feet == 1).sum()) / n, 3),
            "no_foot": round(float((feet == 0).sum()) / n, 3)}


def planted_speeds(points: np.ndarray, contacts: np.ndarray, fps: float) -> np.ndarray:
    """Horizontal speed (m/s) ``(F-1, P)`` of each contact point between consecutive frames on
    which it is in contact on both; NaN elsewhere. ``points`` ``(F, P, 3)``, ``contacts`` ``(F, P)``."""
    p = np.asarray(points, dtype=np.float64)
    c = np.asarray(contacts, dtype=bool)
    v = np.linalg.norm(np.diff(p[..., [0, 2]], axis=0), axis=-1) * fps
    return np.where(c[1:] & c[:-1], v, np.nan)


def slide_figures(speeds: np.ndarray) -> dict:
    """Mean and 95th percentile (cm/s) of planted-point speeds (NaN = not planted, ignored) and
    the share of them over :data:`SLIDING`."""
    v = np.asarray(speeds, dtype=np.float64)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return {"mean_cm_s": 0.0, "p95_cm_s": 0.0, "sliding": 0.0, "samples": 0}
    return {"mean_cm_s": round(100 * float(v.mean()), 2), "p95_cm_s": round(100 * float(np.percentile(v, 95)), 2),
            "sliding": round(float((v > SLIDING).mean()), 4), "samples": int(len(v))}
