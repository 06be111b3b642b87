"""Fused pose-evaluation kernels (numba) for :mod:`runtime.pose`.

The numpy path of :class:`runtime.pose.PoseBatch` runs about thirty whole-array passes per tick
(gathers, the blend, the root placement, the interpolation), each over N * J floats per
component: at 10,000 characters that is memory traffic, not arithmetic, and it does not fit in
3 ms on this machine. These kernels do the same arithmetic in one pass per character (read the
two library frames' rows of the position table, blend, rotate by the heading, translate, write),
spread over the cores with ``prange``. They compute exactly what the numpy path computes (same
formula, float32), which tests/test_pose.py checks against it and against the exact evaluator.

numba (``numba.pydata.org``) is used because a fused, parallel loop is the one thing numpy cannot
express; it is optional -- if it cannot be imported, :data:`AVAILABLE` is False and the numpy
path is used. Kernels compile on first use and are cached on disk (``cache=True``).
"""
from __future__ import annotations

import numpy as np

try:  # pragma: no cover - depends on the environment
    import numba as _nb
    AVAILABLE = True
except Exception:  # numba missing or incompatible with this numpy
    _nb = None
    AVAILABLE = False

__all__ = ["AVAILABLE", "blend_place", "lerp", "skel_arrays"]


if AVAILABLE:
    @_nb.njit(parallel=True, cache=True, boundscheck=False, nogil=True)
    def _blend_place(local, fa, fb, t, root, out):  # pragma: no cover - compiled
        # local (3, T, J) f32; fa, fb (n,) i64; t (n,) f32; root (n, 3) f64; out (3, n, J) f32
        n = fa.shape[0]
        J = local.shape[2]
        for i in _nb.prange(n):
            a = fa[i]
            b = fb[i]
            w = t[i]
            h = root[i, 2]
            c = np.float32(np.cos(h))
            s = np.float32(np.sin(h))
            x0 = np.float32(root[i, 0])
            z0 = np.float32(root[i, 1])
            blend = b != a and w != 0
            for j in range(J):
                lx = local[0, a, j]
                ly = local[1, a, j]
                lz = local[2, a, j]
                if blend:
                    lx = lx + w * (local[0, b, j] - lx)
                    ly = ly + w * (local[1, b, j] - ly)
                    lz = lz + w * (local[2, b, j] - lz)
                out[0, i, j] = lx * c + lz * s + x0
                out[1, i, j] = ly
                out[2, i, j] = lz * c - lx * s + z0

    @_nb.njit(parallel=True, cache=True, boundscheck=False, nogil=True)
    def _lerp(p, q, alpha, out):  # pragma: no cover - compiled
        n = p.shape[1]
        J = p.shape[2]
        for i in _nb.prange(n):
            for k in range(3):
                for j in range(J):
                    out[k, i, j] = p[k, i, j] + alpha * (q[k, i, j] - p[k, i, j])


    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _skel_arrays(rot, height, offsets, fa, fb, t, root, trans, quats, rootv):  # pragma: no cover
        # rot (T, J, 4) f32 w-x-y-z local rotations; height (T,) f64; offsets (J, 3) f64;
        # out: trans (M, J, 3) f32, quats (M, J, 4) f32 x-y-z-w, rootv (M, 3) f64
        M = fa.shape[0]
        J = rot.shape[1]
        one = np.float32(1.0)
        for m in range(M):
            a = fa[m]
            b = fb[m]
            w = t[m]
            for j in range(J):
                aw = rot[a, j, 0]
                ax = rot[a, j, 1]
                ay = rot[a, j, 2]
                az = rot[a, j, 3]
                if w != 0:
                    bw = rot[b, j, 0]
                    bx = rot[b, j, 1]
                    by = rot[b, j, 2]
                    bz = rot[b, j, 3]
                    d = aw * bw + ax * bx + ay * by + az * bz
                    sign = one
                    if d < 0:
                        sign = -one
                        d = -d
                    if d > one:
                        d = one
                    theta = np.arccos(d)
                    sn = np.sin(theta)
                    if sn < np.float32(1e-5):
                        wa = one - w
                        wb = w * sign
                    else:
                        wa = np.sin((one - w) * theta) / sn
                        wb = np.sin(w * theta) / sn * sign
                    aw = wa * aw + wb * bw
                    ax = wa * ax + wb * bx
                    ay = wa * ay + wb * by
                    az = wa * az + wb * bz
                    nrm = np.sqrt(aw * aw + ax * ax + ay * ay + az * az)
                    aw /= nrm
                    ax /= nrm
                    ay /= nrm
                    az /= nrm
                if j == 0:   # the root: heading about +Y first (q = yaw(h) * q), in float64
                    hh = 0.5 * root[m, 2]
                    cw = np.cos(hh)
                    cy = np.sin(hh)
                    qw = cw * aw - cy * ay
                    qx = cw * ax + cy * az
                    qy = cw * ay + cy * aw
                    qz = cw * az - cy * ax
                    quats[m, 0, 0] = qx
                    quats[m, 0, 1] = qy
                    quats[m, 0, 2] = qz
                    quats[m, 0, 3] = qw
                    tt = np.float64(w)
                    trans[m, 0, 0] = root[m, 0]
                    trans[m, 0, 1] = height[a] * (1.0 - tt) + height[b] * tt
                    trans[m, 0, 2] = root[m, 1]
                else:
                    quats[m, j, 0] = ax
                    quats[m, j, 1] = ay
                    quats[m, j, 2] = az
                    quats[m, j, 3] = aw
                    trans[m, j, 0] = offsets[j, 0]
                    trans[m, j, 1] = offsets[j, 1]
                    trans[m, j, 2] = offsets[j, 2]
            rootv[m, 0] = root[m, 0]
            rootv[m, 1] = root[m, 1]
            rootv[m, 2] = np.degrees(root[m, 2])


def blend_place(local, fa, fb, t, root, out):
    """World positions (3, n, J) into ``out``: ``R_y(heading) lerp(L[a], L[b], t) + (x, 0, z)``.
    Frame indices must be valid (the caller checks them)."""
    _blend_place(local, np.ascontiguousarray(fa, dtype=np.int64), np.ascontiguousarray(fb, dtype=np.int64),
                 np.ascontiguousarray(t, dtype=np.float32), np.ascontiguousarray(root, dtype=np.float64), out)
    return out


def lerp(p, q, alpha: float, out):
    """``out = p + alpha (q - p)`` over (3, n, J) float32 arrays, in one parallel pass."""
    _lerp(p, q, np.float32(alpha), out)
    return out


def skel_arrays(rot, height, offsets, fa, fb, t, root):
    """SkelAnimation arrays of M frames in one parallel pass: translations (M, J, 3) float32
    (root: world position and height, others: rest offsets), rotations (M, J, 4) float32 in
    x-y-z-w memory order (local, slerped in float32; the root's with the heading applied) and
    crowdweave:root (M, 3) float64 (x, z, heading in degrees). Same arithmetic as
    :func:`runtime.crowd.tracks.evaluate_poses`."""
    fa = np.ascontiguousarray(fa, dtype=np.int64)
    M, J = len(fa), rot.shape[1]
    trans = np.empty((M, J, 3), np.float32)
    quats = np.empty((M, J, 4), np.float32)
    rootv = np.empty((M, 3), np.float64)
    _skel_arrays(np.ascontiguousarray(rot, dtype=np.float32), np.ascontiguousarray(height, dtype=np.float64),
                 np.ascontiguousarray(offsets, dtype=np.float64), fa, np.ascontiguousarray(fb, dtype=np.int64),
                 np.ascontiguousarray(t, dtype=np.float32), np.ascontiguousarray(root, dtype=np.float64),
                 trans, quats, rootv)
    return trans, quats, rootv
