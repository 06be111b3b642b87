"""Character tracks: what synthesis produces and everything downstream consumes.

A track is, per output frame on the fixed clock, a pair of library frames and a blend
(``frames_a``, ``frames_b``, ``frames_t``: the pose is ``slerp(a, b, t)``) and the root's
planar configuration (``root``: x, z, heading in radians, continuous). Root height, joint
rotations and bounding cylinders come from the library, so a track is small and any number
of them can be evaluated in one vectorized pass (:func:`evaluate_poses`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion import quat
from ..motion.fk import forward_kinematics

__all__ = ["Track", "evaluate_poses", "joint_positions", "concat_tracks", "track_contacts"]


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
    roots = [parts[0].root]
    for p in parts[1:]:
        q = p.slice(1, None) if drop_shared_first else p
        out.append(q)
        # headings continue without 2*pi jumps (each segment is planned in its own winding)
        r = q.root.copy()
        if len(r):
            ref = p.root[0, 2] if drop_shared_first else r[0, 2]
            r[:, 2] += 2 * np.pi * np.round((roots[-1][-1, 2] - ref) / (2 * np.pi))
        roots.append(r)
    return Track(np.concatenate([p.frames_a for p in out]), np.concatenate([p.frames_b for p in out]),
                 np.concatenate([p.frames_t for p in out]).astype(np.float32),
                 np.concatenate(roots), parts[0].start_frame)


def evaluate_poses(graph, frames_a, frames_b, frames_t, root):
    """Root positions (..., 3) and local rotations (..., J, 4) (entry 0 = root world rotation)
    for any leading shape (characters, frames): gather library frames, slerp, place the root."""
    t = np.asarray(frames_t, dtype=np.float32)
    rot = graph.frame_rotations[frames_a]                 # float32 (a copy: fancy indexing)
    # library frames shown as they are (t == 0) need no slerp; the rest slerp in float32
    mid = t != 0.0
    if mid.all():
        rot = quat.slerp(rot, graph.frame_rotations[frames_b], np.broadcast_to(t[..., None], rot.shape[:-1]))
    elif mid.any():
        ra = rot[mid]
        rb = graph.frame_rotations[np.asarray(frames_b)[mid]]
        rot[mid] = quat.slerp(ra, rb, np.broadcast_to(t[mid][..., None], ra.shape[:-1]))
    rot = rot.astype(np.float64)
    t = t.astype(np.float64)
    h = graph.frame_height[frames_a] * (1 - t) + graph.frame_height[frames_b] * t
    rot[..., 0, :] = quat.mul(quat.from_yaw(root[..., 2]), rot[..., 0, :])
    pos = np.stack([root[..., 0], h, root[..., 1]], axis=-1)
    return pos, rot


def track_contacts(graph, frames_a, frames_b, frames_t) -> np.ndarray:
    """Foot contacts ``(..., 4)`` bool of blended library frames (any leading shape): those of
    the nearer of the two frames (``frames_a`` while ``frames_t < 0.5``), from the library's
    ``frame_contacts``."""
    near = np.where(np.asarray(frames_t) < 0.5, frames_a, frames_b)
    return graph.frame_contacts[near]


def joint_positions(graph, track: Track) -> np.ndarray:
    pos, rot = evaluate_poses(graph, track.frames_a, track.frames_b, track.frames_t, track.root)
    return forward_kinematics(graph.skeleton, pos, rot)[1]


def box_trajectories(scenario, results, graph, env, num_frames: int, box_size: float = 0.4):
    """Where every box marker is on every frame: at its marker until the character that picks
    it up arrives there, then between that character's hands until it is put down, then where
    it was put down. Returns {marker path: (positions (F, 3) box centres, headings (F,))}."""
    if env is None:
        return {}
    sk = graph.skeleton
    hands = [sk.index(n) for n in ("LeftHand", "RightHand") if sk.has(n)]
    boxes = {}
    for m in env.markers_with_role("box"):
        pos = np.tile([m.position[0], box_size / 2, m.position[1]], (num_frames, 1)).astype(np.float64)
        boxes[m.path] = (pos, np.full(num_frames, m.heading))
    for spec, res in zip(scenario.characters, results):
        carrying, start = None, 0
        for gi, g in enumerate(spec.goals):
            f = int(res.arrivals[gi]) if gi < len(res.arrivals) else num_frames - 1
            if g.kind == "box" and g.marker in boxes:
                carrying, start = g.marker, f
            elif carrying is not None and g.pose in ("stand", None):
                _carry(boxes[carrying], graph, res.track, hands, start, f, num_frames, box_size)
                carrying = None
        if carrying is not None:
            _carry(boxes[carrying], graph, res.track, hands, start, num_frames - 1, num_frames, box_size, hold=True)
    return boxes


def _carry(box, graph, track, hands, f0, f1, num_frames, size, hold=False):
    pos, head = box
    f1 = min(f1, len(track) - 1, num_frames - 1)
    if f1 <= f0:
        return
    sub = track.slice(f0, f1 + 1)
    jp = joint_positions(graph, sub)
    if hands:
        centre = jp[:, hands].mean(axis=1)
    else:
        fwd = np.stack([np.sin(sub.root[:, 2]), np.cos(sub.root[:, 2])], axis=1)
        centre = np.column_stack([sub.root[:, 0] + 0.35 * fwd[:, 0], np.full(len(sub), 0.85),
                                  sub.root[:, 1] + 0.35 * fwd[:, 1]])
    pos[f0:f1 + 1] = centre
    head[f0:f1 + 1] = sub.root[:, 2]
    if not hold:
        # put down: it stays on the ground below where the hands let go
        pos[f1 + 1:] = [centre[-1, 0], size / 2, centre[-1, 2]]
        head[f1 + 1:] = sub.root[-1, 2]
