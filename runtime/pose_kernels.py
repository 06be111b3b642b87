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

__all__ = ["AVAILABLE", "blend_place", "lerp"]


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
