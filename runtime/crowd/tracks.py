"""Character tracks: what synthesis produces and everything downstream consumes.

A track is, per output frame on the fixed clock, a pair of library frames and a blend
(``frames_a``, ``frames_b``, ``frames_t``: the pose is ``slerp(a, b, t)``) and the root's
planar configuration (``root``: x, z, heading in radians, continuous). Root height, joint
rotations and bounding cylinders come from the library, so a track is small and any number
of them can be evaluated in one vectorized pass (:func:`evaluate_poses`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..motion import quat
from ..motion.fk import forward_kinematics

__all__ = ["Track", "evaluate_poses", "joint_positions", "concat_tracks"]


@dataclass
class Track:
    frames_a: np.ndarray   # (F,) int64 global library frame
    frames_b: np.ndarray   # (F,) int64
    frames_t: np.ndarray   # (F,) float32 in [0, 1]
    root: np.ndarray       # (F, 3) float64 x, z, heading (rad)
    start_frame: int = 0   # clock frame of entry 0

    def __len__(self):
        return len(self.frames_a)

    def slice(self, a, b) -> "Track":
        return Track(self.frames_a[a:b], self.frames_b[a:b], self.frames_t[a:b], self.root[a:b], self.start_frame + a)


def concat_tracks(parts: list[Track], drop_shared_first: bool = True) -> Track:
    """Join consecutive tracks; each part's first frame repeats the previous part's last."""
    out = [parts[0]]
    for p in parts[1:]:
        out.append(p.slice(1, None) if drop_shared_first else p)
    return Track(np.concatenate([p.frames_a for p in out]), np.concatenate([p.frames_b for p in out]),
                 np.concatenate([p.frames_t for p in out]).astype(np.float32),
                 np.concatenate([p.root for p in out]), parts[0].start_frame)


def evaluate_poses(graph, frames_a, frames_b, frames_t, root):
    """Root positions (..., 3) and local rotations (..., J, 4) (entry 0 = root world rotation)
    for any leading shape (characters, frames): gather library frames, slerp, place the root."""
    ra = graph.frame_rotations[frames_a].astype(np.float64)
    rb = graph.frame_rotations[frames_b].astype(np.float64)
    t = np.asarray(frames_t, dtype=np.float64)
    rot = quat.slerp(ra, rb, np.broadcast_to(t[..., None], ra.shape[:-1]))
    h = graph.frame_height[frames_a] * (1 - t) + graph.frame_height[frames_b] * t
    rot[..., 0, :] = quat.mul(quat.from_yaw(root[..., 2]), rot[..., 0, :])
    pos = np.stack([root[..., 0], h, root[..., 1]], axis=-1)
    return pos, rot


def joint_positions(graph, track: Track) -> np.ndarray:
    pos, rot = evaluate_poses(graph, track.frames_a, track.frames_b, track.frames_t, track.root)
    return forward_kinematics(graph.skeleton, pos, rot)[1]
