"""Per-frame features of a performer for patch construction (Kim, Hwang, Hyun and Lee 2012, section 4).

* **Pose vector** ``p_i``: every joint's position relative to the root's ground point, turned
  into the root's heading frame -- the "difference between two fullbody poses ignoring their
  horizontal translation and rotation about the vertical axis" of Eq. 4 (Lee, Choi, Lee 2006)
  is the Euclidean distance of these vectors.
* **Motion variation** ``V_i`` (Eq. 4)::

      V_i = sum_{j=-w}^{w} sum_{k=j+1}^{w} || p_{i+j} (-) p_{i+k} ||^2

  computed for all frames at once with the identity ``sum_{a<b} ||x_a - x_b||^2 =
  n sum_a ||x_a||^2 - ||sum_a x_a||^2`` over each window of ``n = 2w + 1`` frames (cumulative
  sums; the window is clipped at the ends of the take). Reported per joint (divided by the
  number of joints) so the threshold does not depend on the skeleton size.
* **Body points** with radii (hand centres, elbows, shoulders, head, chest, pelvis, knees,
  ankles) for contact tests, the **gaze** (head forward axis), the **face** and the
  **upper body** (thorax joint) for Eq. 5.
* **Boundary pose feature**: the pose vector plus the root-relative velocity of the joints
  (scaled by ``VELOCITY_WEIGHT`` seconds) and the root's planar speed and turning, so two
  frames are close only when the poses *and* the way they move match (used by the pose
  clustering of section 4.2).

Joint names are those of the CMU MotionBuilder family (procedural takes and CMU family A);
other skeletons need the same names for the body points.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from runtime.motion import quat
from runtime.motion.clip import Clip
from runtime.motion.fk import end_site_positions
from runtime.motion.planar import rotate_xz

__all__ = ["BODY_POINTS", "PersonFeatures", "person_features", "pose_vectors", "motion_variation",
           "boundary_features", "VELOCITY_WEIGHT"]

# (name, joint or (joint, end-site joint) midpoint, radius in metres)
BODY_POINTS = (
    ("hand_l", ("LeftHand", "LeftHandIndex1"), 0.05), ("hand_r", ("RightHand", "RightHandIndex1"), 0.05),
    ("elbow_l", "LeftForeArm", 0.05), ("elbow_r", "RightForeArm", 0.05),
    ("shoulder_l", "LeftArm", 0.07), ("shoulder_r", "RightArm", 0.07),
    ("head", ("Head", "Head"), 0.10), ("chest", "Spine1", 0.14), ("pelvis", "Hips", 0.14),
    ("knee_l", "LeftLeg", 0.06), ("knee_r", "RightLeg", 0.06),
    ("ankle_l", "LeftFoot", 0.05), ("ankle_r", "RightFoot", 0.05),
)
VELOCITY_WEIGHT = 0.25      # seconds: a velocity difference of 1 m/s weighs like 25 cm of pose


@dataclass
class PersonFeatures:
    root_xz: np.ndarray        # (F, 2) world
    heading: np.ndarray        # (F,) world, unwrapped
    pose: np.ndarray           # (F, J, 3) pose vectors (root-relative, heading-free)
    points: np.ndarray         # (F, P, 3) world body points
    radii: np.ndarray          # (P,)
    gaze: np.ndarray           # (F, 3) unit head forward
    face: np.ndarray           # (F, 3)
    chest: np.ndarray          # (F, 3)
    variation: np.ndarray      # (F,) Eq. 4 per joint, m^2
    fps: float


def pose_vectors(clip: Clip, positions: np.ndarray | None = None) -> np.ndarray:
    """(F, J, 3) joint positions relative to the root's ground point, in the heading frame."""
    gp = clip.positions() if positions is None else positions
    heading = clip.world_heading()
    rel = gp - np.concatenate([gp[:, :1, :1], np.zeros_like(gp[:, :1, :1]), gp[:, :1, 2:3]], axis=-1)
    xz = rotate_xz(rel[..., [0, 2]], -heading[:, None])
    return np.stack([xz[..., 0], rel[..., 1], xz[..., 1]], axis=-1)


def motion_variation(pose: np.ndarray, w: int) -> np.ndarray:
    """Eq. 4 for every frame, divided by the number of joints (m^2)."""
    F = pose.shape[0]
    x = pose.reshape(F, -1)
    s1 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
    s2 = np.concatenate([[0.0], np.cumsum(np.sum(x * x, axis=1))])
    i = np.arange(F)
    a = np.clip(i - w, 0, F)
    b = np.clip(i + w + 1, 0, F)
    n = (b - a).astype(np.float64)
    S1 = s1[b] - s1[a]
    S2 = s2[b] - s2[a]
    v = n * S2 - np.sum(S1 * S1, axis=1)
    return np.maximum(v, 0.0) / pose.shape[1]


def _point_index(skel, spec):
    if isinstance(spec, str):
        return ("j", skel.index(spec))
    joint, end = spec
    ends = [j for j, _ in skel.end_sites]
    je = skel.index(end)
    if je in ends:
        return ("m", skel.index(joint), ends.index(je))
    return ("j", skel.index(joint))


def person_features(clip: Clip, w: int = 5) -> PersonFeatures:
    sk = clip.skeleton
    gr, gp = clip.fk()
    es = end_site_positions(sk, gr, gp)
    pts = []
    for _, spec, _ in BODY_POINTS:
        ix = _point_index(sk, spec)
        if ix[0] == "j":
            pts.append(gp[:, ix[1]])
        else:
            pts.append(0.5 * (gp[:, ix[1]] + es[:, ix[2]]))
    points = np.stack(pts, axis=1)
    radii = np.array([r for _, _, r in BODY_POINTS])
    jh = sk.index("Head")
    gaze = quat.rotate(gr[:, jh], np.broadcast_to(np.array([0.0, 0.0, 1.0]), (clip.num_frames, 3)))
    pose = pose_vectors(clip, gp)
    xz, _ = clip.world_root()
    return PersonFeatures(root_xz=xz[:, [0, 2]], heading=clip.world_heading(), pose=pose, points=points,
                          radii=radii, gaze=gaze, face=points[:, 6], chest=gp[:, sk.index("Spine1")],
                          variation=motion_variation(pose, w), fps=clip.fps)


def boundary_features(feat: PersonFeatures, joints=None) -> np.ndarray:
    """(F, D) vectors whose Euclidean distance divided by sqrt(J) is an RMS pose distance
    in metres (pose + ``VELOCITY_WEIGHT`` x velocity, both root-relative and heading-free,
    plus the root's planar velocity in its own heading frame and its turning rate x 0.5 m)."""
    pose = feat.pose if joints is None else feat.pose[:, joints]
    fps = feat.fps
    vel = np.gradient(pose, axis=0) * fps
    rv = np.gradient(feat.root_xz, axis=0) * fps
    rv = rotate_xz(rv, -feat.heading)
    turn = np.gradient(np.unwrap(feat.heading)) * fps
    J = pose.shape[1]
    root = np.concatenate([rv, 0.5 * turn[:, None]], axis=1) * VELOCITY_WEIGHT * np.sqrt(J)
    return np.concatenate([pose.reshape(len(pose), -1), VELOCITY_WEIGHT * vel.reshape(len(pose), -1), root], axis=1)
