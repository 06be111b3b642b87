"""Snapping takes to hub poses and cutting them into edges (Gleicher et al. 2003, section 4).

Every occurrence of a hub in a take is edited with a short smooth displacement so that the
pose there equals the hub pose *exactly*: for every joint (the root's heading-free tilt
included) the rotation offset ``delta = q_hub * q(f)^-1`` is applied with a weight that is 1
at the occurrence and falls smoothly (C1 smoothstep) to 0 within ``window`` frames::

    q'(t) = slerp(I, delta, w(t)) * q(t)

Root height gets the same treatment. Because the edit is made on the whole take before it
is cut, the frame shared by the edge that ends at an occurrence and the edge that starts
there is identical in both, and every edit is continuous across the cut.
"""
from __future__ import annotations

import numpy as np

from runtime.motion import Clip, ops, quat

__all__ = ["snap_take", "cut_edges"]


def _weights(n_frames: int, center: int, half: int) -> np.ndarray:
    t = np.arange(n_frames) - center
    x = np.clip(1.0 - np.abs(t) / max(half, 1), 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)  # smoothstep, 1 at the centre, 0 beyond ``half``


def snap_take(clip: Clip, occ_frames: np.ndarray, hub_rot: np.ndarray, hub_height: np.ndarray,
              window: int = 8) -> Clip:
    """Return ``clip`` edited so that frame ``occ_frames[k]`` has pose ``hub_rot[k]`` (J, 4)
    and root height ``hub_height[k]`` exactly. Windows shrink so neighbours never overlap."""
    occ = np.asarray(occ_frames, dtype=np.int64)
    order = np.argsort(occ)
    occ = occ[order]
    hub_rot = np.asarray(hub_rot, dtype=np.float64)[order]
    hub_height = np.asarray(hub_height, dtype=np.float64)[order]
    rot = clip.rotations.astype(np.float64)
    height = clip.root_height.copy()
    F = clip.num_frames
    gaps = np.diff(np.concatenate([[-10 ** 9], occ, [10 ** 9]]))
    for k, f in enumerate(occ):
        half = int(min(window, gaps[k] // 2, gaps[k + 1] // 2))
        lo, hi = max(0, f - half), min(F, f + half + 1)
        w = _weights(F, f, max(half, 1))[lo:hi]
        target = quat.canonical(hub_rot[k])
        cur = rot[f]
        target = np.where(np.sum(target * cur, -1, keepdims=True) < 0, -target, target)
        delta = quat.mul(target, quat.conj(cur))                       # (J, 4)
        d = quat.slerp(np.broadcast_to(quat.identity(), delta.shape), delta,
                       np.broadcast_to(w[:, None], (hi - lo, delta.shape[0])))
        rot[lo:hi] = quat.mul(d, rot[lo:hi])
        rot[f] = target  # exact, no round-off
        height[lo:hi] += w * (hub_height[k] - height[f])
        height[f] = hub_height[k]
    return clip.copy(rotations=quat.unroll(rot, axis=0).astype(np.float32), root_height=height)


def cut_edges(clip: Clip, occ_frames: np.ndarray, occ_hubs: np.ndarray):
    """Cut a snapped take between consecutive hub occurrences.

    Returns a list of (src_hub, dst_hub, start_frame, end_frame, Clip) where the clip holds
    frames ``[start, end]`` inclusive (both hub frames), local origin at its first frame."""
    order = np.argsort(occ_frames)
    f = np.asarray(occ_frames)[order]
    h = np.asarray(occ_hubs)[order]
    out = []
    for k in range(len(f) - 1):
        s, e = int(f[k]), int(f[k + 1])
        sub = ops.cut(clip, s, e + 1).copy(origin=np.zeros(3))
        out.append((int(h[k]), int(h[k + 1]), s, e, sub))
    return out
