"""Minimum bounding cylinders of poses, the collision volume of goal-directed crowds (Sung,
Kovar and Gleicher 2005, section 3.2: "collisions are detected by placing minimum bounding
cylinders around each character ... precomputed").

A pose's cylinder is vertical; its footprint is the smallest circle holding every joint and
end site seen from above. Its axis is generally not the root's: a striding walker's leading
toe reaches about 0.4 m ahead of the hips and the trailing one less than 0.1 m behind, so a
circle about the root is about 40% wider than the pose needs. The library stores per frame
the axis as an offset from the root in the root's heading frame (``frame_axis``) and the
radius (``frame_radius``); :func:`blend_cylinders` places them for frames shown as a blend of
two library frames.

Limits: the circle is exact when at most :data:`SUPPORT` of the points farthest from an
approximate centre determine it (in practice always: the feet, hands and head); otherwise the
approximate centre is kept with the exact radius about it, still a bounding circle.
"""
from __future__ import annotations

from itertools import combinations

import numpy as np

from .fk import end_site_positions, forward_kinematics

try:        # optional, as in runtime.pose_kernels: one fused loop where numpy makes ~20 passes
    import numba as _nb
except Exception:  # pragma: no cover - numba missing or incompatible with this numpy
    _nb = None

__all__ = ["enclosing_circles", "pose_cylinders", "blend_cylinders", "SUPPORT"]

SUPPORT = 6            # points tried as the circle's support (the farthest from the first guess)
_ITERATIONS = 64       # first guess: Badoiu and Clarkson's (2003) farthest-point iteration


def enclosing_circles(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest circle holding each set of 2D points.

    Args:
        points: (..., P, 2) points.

    Returns:
        centres (..., 2) and radii (...): every point lies within its circle (the radius is the
        exact largest distance from the centre).
    """
    pts = np.asarray(points, dtype=np.float64)
    lead = pts.shape[:-2]
    P = pts.shape[-2]
    pts = pts.reshape(-1, P, 2)
    n = len(pts)
    rows = np.arange(n)
    # first guess: move towards the farthest point by 1/(i+1) (Badoiu and Clarkson 2003)
    c = pts.mean(axis=1)
    for i in range(1, _ITERATIONS):
        far = pts[rows, np.argmax(np.sum((pts - c[:, None]) ** 2, axis=-1), axis=1)]
        c = c + (far - c) / (i + 1)
    best_c = c
    best_r = np.sqrt(np.max(np.sum((pts - c[:, None]) ** 2, axis=-1), axis=1))
    # exact circle: through two or three of the points farthest from the guess
    k = min(SUPPORT, P)
    near = np.argsort(-np.sum((pts - c[:, None]) ** 2, axis=-1), axis=1)[:, :k]
    S = pts[rows[:, None], near]                                        # (n, k, 2)
    cands = []
    for i, j in combinations(range(k), 2):
        cands.append(0.5 * (S[:, i] + S[:, j]))
    for i, j, m in combinations(range(k), 3):
        a, b, d = S[:, i], S[:, j], S[:, m]
        ba, da = b - a, d - a
        den = 2.0 * (ba[:, 0] * da[:, 1] - ba[:, 1] * da[:, 0])
        ok = np.abs(den) > 1e-12
        den = np.where(ok, den, 1.0)
        nb, nd = np.sum(ba * ba, axis=1), np.sum(da * da, axis=1)
        ux = (da[:, 1] * nb - ba[:, 1] * nd) / den
        uz = (ba[:, 0] * nd - da[:, 0] * nb) / den
        cands.append(np.where(ok[:, None], a + np.stack([ux, uz], axis=1), np.nan))
    for cc in cands:
        r = np.sqrt(np.max(np.sum((pts - cc[:, None]) ** 2, axis=-1), axis=1))
        better = np.isfinite(r) & (r < best_r)
        best_c = np.where(better[:, None], cc, best_c)
        best_r = np.where(better, r, best_r)
    return best_c.reshape(lead + (2,)), best_r.reshape(lead)


def pose_cylinders(clip, also=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per frame of ``clip``, the minimum bounding cylinder of its joints and end sites.

    Args:
        clip: a :class:`~runtime.motion.clip.Clip`.
        also: another clip of the same length whose poses the cylinder must hold as well (a
            build that corrects feet after snapping keeps both bodies inside).

    Returns:
        axis (F, 2): the cylinder's axis from the root, in the root's heading frame (x, z);
        radius (F,); reach (F,): the radius about the root's own axis (a disc held where the
        character stands, whatever its heading); top (F,): the highest point.
    """
    local, top = _local_points(clip)
    if also is not None:
        l2, t2 = _local_points(also)
        local = np.concatenate([local, l2], axis=1)
        top = np.maximum(top, t2)
    axis, radius = enclosing_circles(local)
    reach = np.sqrt(np.max(np.sum(local * local, axis=-1), axis=1))
    return axis, radius, reach, top


def _local_points(clip):
    pos, _ = clip.world_root(origin=np.zeros(3))
    gr, gp = forward_kinematics(clip.skeleton, pos, clip.local_rotations_world_root(np.zeros(3)))
    pts = np.concatenate([gp, end_site_positions(clip.skeleton, gr, gp)], axis=1)
    d = pts[..., [0, 2]] - pos[:, None, [0, 2]]
    h = clip.root_heading[:, None]
    ch, sh = np.cos(h), np.sin(h)
    # world = Ry(h) local (runtime.motion.planar): local = Ry(-h) world
    local = np.stack([ch * d[..., 0] - sh * d[..., 1], sh * d[..., 0] + ch * d[..., 1]], axis=-1)
    return local, pts[..., 1].max(axis=1)


def blend_cylinders(graph, frames_a, frames_b, root) -> tuple[np.ndarray, np.ndarray]:
    """Where the cylinders of frames shown as a blend of library frames ``frames_a`` and
    ``frames_b`` stand, with the root at ``root`` (..., 3) = (x, z, heading): the circle holding
    both frames' circles. Returns centres (..., 2) and radii (...)."""
    root = np.asarray(root, dtype=np.float64)
    radius, axis = _tables(graph)
    if _nb is not None and axis is not None and root.ndim == 2 and np.ndim(frames_a) == 1 and np.ndim(frames_b) == 1:
        centre, r = np.empty((len(root), 2)), np.empty(len(root))
        _blend_compiled(np.asarray(frames_a, np.int64), np.asarray(frames_b, np.int64), root, radius, axis, centre, r)
        return centre, r
    ra, rb = radius[frames_a], radius[frames_b]
    if axis is None:
        return root[..., :2].copy(), np.maximum(ra, rb)
    ax, bx = axis[frames_a], axis[frames_b]
    # in the root's frame (the circle holding two circles does not depend on the heading): the
    # larger circle when it holds the other, else the one spanning both along their line
    dx, dz = bx[..., 0] - ax[..., 0], bx[..., 1] - ax[..., 1]
    d = np.sqrt(dx * dx + dz * dz)
    r = np.maximum(np.maximum(ra, rb), 0.5 * (d + ra + rb))
    t = np.clip((r - ra) / np.maximum(d, 1e-12), 0.0, 1.0)
    lx, lz = ax[..., 0] + t * dx, ax[..., 1] + t * dz
    ch, sh = np.cos(root[..., 2]), np.sin(root[..., 2])
    centre = np.empty(root.shape[:-1] + (2,))
    centre[..., 0] = root[..., 0] + ch * lx + sh * lz
    centre[..., 1] = root[..., 1] - sh * lx + ch * lz
    return centre, r


if _nb is not None:
    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _blend_compiled(fa, fb, root, radius, axis, centre, out_r):  # pragma: no cover - compiled
        for k in range(len(fa)):
            ra, rb = radius[fa[k]], radius[fb[k]]
            ax0, ax1 = axis[fa[k], 0], axis[fa[k], 1]
            dx, dz = axis[fb[k], 0] - ax0, axis[fb[k], 1] - ax1
            d = np.sqrt(dx * dx + dz * dz)
            r = max(max(ra, rb), 0.5 * (d + ra + rb))
            t = min(max((r - ra) / max(d, 1e-12), 0.0), 1.0)
            lx, lz = ax0 + t * dx, ax1 + t * dz
            ch, sh = np.cos(root[k, 2]), np.sin(root[k, 2])
            centre[k, 0] = root[k, 0] + ch * lx + sh * lz
            centre[k, 1] = root[k, 1] - sh * lx + ch * lz
            out_r[k] = r


def _tables(graph):
    """The graph's radii and axes as float64 (made once per graph)."""
    memo = graph.__dict__.get("_cylinder_tables")
    if memo is None:
        axis = getattr(graph, "frame_axis", None)
        memo = (np.asarray(graph.frame_radius, dtype=np.float64),
                None if axis is None else np.asarray(axis, dtype=np.float64))
        graph.__dict__["_cylinder_tables"] = memo
    return memo
