"""Frame distance of Kovar, Gleicher and Pighin (Motion Graphs, 2002), chunked.

For frames ``i`` and ``j`` the distance compares two point clouds: the joint positions of a
window of frames around ``i`` and around ``j``. It is the weighted sum of squared distances
after the planar rigid transform (rotation ``theta`` about Y, translation ``x0, z0``) that
best aligns the second cloud to the first::

    D(i, j) = min_{theta, x0, z0}  sum_k w_k || p_k - T_{theta, x0, z0} p'_k ||^2

The window spans ``2 * half_window + 1`` frames, so the distance sees velocities: a
left-foot-forward frame that is moving the left foot back does not match the same pose
moving the other way, and mid-strides of opposite feet differ.

Closed form (Kovar et al. 2002, Eq. 1 and its appendix): with the clouds centred at their
weighted x-z centroids (y is not translated),

    A = sum w (x x' + z z'),   B = sum w (x z' - z x'),   C = sum w y y'
    D = S + S' - 2 C - 2 sqrt(A^2 + B^2),      theta = atan2(B, A)

where ``S = sum w |p|^2`` of the centred cloud. ``A``, ``B`` and ``C`` are dot products of
per-frame feature vectors, so all pairs of a chunk of rows come out of three matrix
products. Rows are processed in chunks so memory stays ``O(chunk * frames)``; an hour of
data (108,000 frames) never needs the full matrix.

The products run on one BLAS thread: OpenBLAS splits a product between its threads in a way
that changes the rounding of the sums, so the same rows would come out a few ulps apart on
machines with other core counts, or on cluster workers (which run one BLAS thread each). With
one thread a block of rows has the same bits wherever it is computed; the cores are used by
computing blocks in parallel instead (``find_candidates(map_blocks=...)``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_BLAS = None       # threadpoolctl controller, made on first use (after numpy has loaded its BLAS)


def _one_blas_thread():
    global _BLAS
    if _BLAS is None:
        from threadpoolctl import ThreadpoolController
        _BLAS = ThreadpoolController()
    return _BLAS.limit(limits=1, user_api="blas")


__all__ = ["FrameFeatures", "frame_features", "pair_distance", "distance_rows", "aligned_distance_reference", "DEFAULT_JOINT_WEIGHTS"]

# Relative joint weights (by name; joints not listed get 1). Fingers and thumbs are not
# captured in CMU data (README quirk 2): they get no weight.
DEFAULT_JOINT_WEIGHTS = {
    "LHipJoint": 0.0, "RHipJoint": 0.0, "LeftFingerBase": 0.0, "RightFingerBase": 0.0,
    "LeftHandIndex1": 0.0, "RightHandIndex1": 0.0, "LThumb": 0.0, "RThumb": 0.0,
    "LeftFoot": 2.0, "RightFoot": 2.0, "LeftToeBase": 2.0, "RightToeBase": 2.0,
    "LeftLeg": 1.5, "RightLeg": 1.5, "Hips": 2.0,
}


@dataclass
class FrameFeatures:
    """Per-frame window point clouds, weighted and centred, flattened for matrix products."""
    xz: np.ndarray       # (N, 2K) sqrt(w) * (x, z) centred, interleaved per point
    xz_perp: np.ndarray  # (N, 2K) sqrt(w) * (z, -x)  (so A = xz . xz', B = xz . xz_perp')
    y: np.ndarray        # (N, K) sqrt(w) * y
    sq: np.ndarray       # (N,) S = sum w |p|^2 (centred)
    valid: np.ndarray    # (N,) bool: the full window lies inside the take
    take: np.ndarray     # (N,) take index of each frame
    weight_sum: float    # sum of weights of one cloud (to turn D into an RMS distance)


def frame_features(positions_per_take, joint_weights: np.ndarray, half_window: int = 4,
                   dtype=np.float64) -> FrameFeatures:
    """Build features for all frames of all takes.

    positions_per_take: list of (F, J, 3) world joint positions (metres).
    joint_weights: (J,) non-negative weights. Window frames get a tent weight.
    Frames whose window would cross the take boundary use a clamped window and are
    marked invalid (they are never transition candidates).
    """
    offs = np.arange(-half_window, half_window + 1)
    tw = (half_window + 1 - np.abs(offs)).astype(np.float64)
    tw /= tw.sum()
    jw = np.asarray(joint_weights, dtype=np.float64)
    w = (tw[:, None] * jw[None, :]).reshape(-1)  # (K,)
    keep = w > 0
    w = w[keep] / w[keep].sum()
    sw = np.sqrt(w)
    xzs, perps, ys, sqs, valids, takes = [], [], [], [], [], []
    for t, P in enumerate(positions_per_take):
        P = np.asarray(P, dtype=np.float64)
        F = len(P)
        idx = np.clip(np.arange(F)[:, None] + offs[None, :], 0, F - 1)     # (F, W)
        cloud = P[idx].reshape(F, -1, 3)[:, keep]                         # (F, K, 3)
        cx = np.einsum("k,fk->f", w, cloud[..., 0])
        cz = np.einsum("k,fk->f", w, cloud[..., 2])
        x = cloud[..., 0] - cx[:, None]
        z = cloud[..., 2] - cz[:, None]
        y = cloud[..., 1]
        xz = np.stack([x * sw, z * sw], axis=-1).reshape(F, -1)
        perp = np.stack([z * sw, -x * sw], axis=-1).reshape(F, -1)
        xzs.append(xz)
        perps.append(perp)
        ys.append(y * sw)
        sqs.append(np.einsum("k,fk->f", w, x * x + y * y + z * z))
        v = np.ones(F, dtype=bool)
        v[:half_window] = False
        v[F - half_window:] = False
        valids.append(v)
        takes.append(np.full(F, t, dtype=np.int64))
    return FrameFeatures(np.concatenate(xzs).astype(dtype), np.concatenate(perps).astype(dtype),
                         np.concatenate(ys).astype(dtype), np.concatenate(sqs), np.concatenate(valids),
                         np.concatenate(takes), 1.0)


def distance_rows(f: FrameFeatures, rows: slice | np.ndarray, cols: slice | np.ndarray = slice(None),
                  with_angle: bool = True):
    """D for a block of rows x cols (RMS-normalised: metres^2 per unit weight).

    Returns (D, theta) where theta is the best alignment angle (rotation of the column frame's
    cloud onto the row frame's cloud about +Y), or None when ``with_angle`` is False.
    """
    with _one_blas_thread():          # the same bits wherever the block is computed (module docstring)
        A = f.xz[rows] @ f.xz[cols].T
        B = f.xz[rows] @ f.xz_perp[cols].T
        C = f.y[rows] @ f.y[cols].T
    r = np.sqrt(A * A + B * B)
    D = f.sq[rows][:, None] + f.sq[cols][None, :] - 2.0 * C - 2.0 * r
    np.maximum(D, 0.0, out=D)
    return D, (np.arctan2(B, A) if with_angle else None)


def pair_distance(f: FrameFeatures, i: int, j: int) -> float:
    return float(distance_rows(f, slice(i, i + 1), slice(j, j + 1))[0][0, 0])


def aligned_distance_reference(P: np.ndarray, Q: np.ndarray, w: np.ndarray):
    """Plain per-pair reference: brute-force the closed form for two clouds (K, 3).

    Used by tests and by the benchmark's per-pair baseline. Returns (D, theta, x0, z0) with
    ``T p' = Ry(theta) p' + (x0, 0, z0)`` aligning Q onto P.
    """
    w = np.asarray(w, dtype=np.float64) / np.sum(w)
    xb, zb = np.sum(w * P[:, 0]), np.sum(w * P[:, 2])
    xb2, zb2 = np.sum(w * Q[:, 0]), np.sum(w * Q[:, 2])
    num = np.sum(w * (P[:, 0] * Q[:, 2] - Q[:, 0] * P[:, 2])) - (xb * zb2 - xb2 * zb)
    den = np.sum(w * (P[:, 0] * Q[:, 0] + P[:, 2] * Q[:, 2])) - (xb * xb2 + zb * zb2)
    theta = np.arctan2(num, den)
    c, s = np.cos(theta), np.sin(theta)
    # Ry(theta) (x, z) = (c x + s z, -s x + c z)
    x0 = xb - (c * xb2 + s * zb2)
    z0 = zb - (-s * xb2 + c * zb2)
    Qx = c * Q[:, 0] + s * Q[:, 2] + x0
    Qz = -s * Q[:, 0] + c * Q[:, 2] + z0
    d = np.sum(w * ((P[:, 0] - Qx) ** 2 + (P[:, 1] - Q[:, 1]) ** 2 + (P[:, 2] - Qz) ** 2))
    return float(d), float(theta), float(x0), float(z0)
