"""Fused pose-evaluation kernels (numba) for :mod:`runtime.pose`.

The numpy path of :class:`runtime.pose.PoseBatch` runs about thirty whole-array passes per tick
(gathers, the blend, the root placement, the interpolation), each over N * J floats per
component: at 10,000 characters that is memory traffic, not arithmetic, and it does not fit in
3 ms on this machine. These kernels do the same arithmetic in one pass per character (read the
two library frames' rows of the position table, blend, rotate by the heading, translate, write),
spread over the cores with ``prange`` above :data:`SERIAL_MAX` characters. They compute exactly what the numpy path computes (same
formula, float32), which tests/test_pose.py checks against it and against the exact evaluator.
With the foot lock (:func:`blend_place_lock`) the same pass then pins the character's planted
feet (the arithmetic of :func:`runtime.motion.footlock.lock_positions`, in float64 from the
float32 positions; tests/test_footlock.py compares both paths).

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

__all__ = ["AVAILABLE", "SERIAL_MAX", "blend_place", "lerp", "skel_arrays", "blend_place_lock"]

# Up to this many characters the per-frame kernels (blend_place, blend_place_lock, lerp) run on
# the calling thread: a few hundred characters take well under a millisecond there, while
# waking the worker threads on a busy machine can take several (measured on 2 shared cores).
SERIAL_MAX = 1024


if AVAILABLE:
    @_nb.njit(cache=True, boundscheck=False, nogil=True, inline="always")
    def _place_one(local, fa, fb, t, root, out, i):  # pragma: no cover - compiled
        # character i: R_y(heading) lerp(L[a], L[b], t) + (x, 0, z) into out[:, i]
        J = local.shape[2]
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
    def _blend_place(local, fa, fb, t, root, out):  # pragma: no cover - compiled
        # local (3, T, J) f32; fa, fb (n,) i64; t (n,) f32; root (n, 3) f64; out (3, n, J) f32
        for i in _nb.prange(fa.shape[0]):
            _place_one(local, fa, fb, t, root, out, i)

    @_nb.njit(parallel=True, cache=True, boundscheck=False, nogil=True)
    def _lerp(p, q, alpha, out):  # pragma: no cover - compiled
        n = p.shape[1]
        J = p.shape[2]
        for i in _nb.prange(n):
            for k in range(3):
                for j in range(J):
                    out[k, i, j] = p[k, i, j] + alpha * (q[k, i, j] - p[k, i, j])

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _lerp_serial(p, q, alpha, out):  # pragma: no cover - compiled
        n = p.shape[1]
        J = p.shape[2]
        for i in range(n):
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


    @_nb.njit(cache=True, inline="always")
    def _reach_fraction(wx, wy, wz, dx, dz, r, outer):  # pragma: no cover - compiled
        a = dx * dx + dz * dz
        b = 2.0 * (wx * dx + wz * dz)
        c = wx * wx + wy * wy + wz * wz - r * r
        disc = b * b - 4.0 * a * c
        if a <= 0.0:
            return 1.0
        if outer:
            if c > 0.0 or a + b + c <= 0.0:      # outside from the start, or still inside at s = 1
                return 1.0
            root = (-b + np.sqrt(max(disc, 0.0))) / (2.0 * a)
        else:
            if c < 0.0 or b >= 0.0 or disc <= 0.0:   # inside from the start, or moving away
                return 1.0
            root = (-b - np.sqrt(disc)) / (2.0 * a)
            if root < 0.0:
                return 1.0
        return min(max(root, 0.0), 1.0)

    @_nb.njit(cache=True, inline="always")
    def _hip_drop(P, i, hip, ankle, dx, dz, r):  # pragma: no cover - compiled
        """How far the hip must come down (m) for a leg spanning ``r`` from hip to ankle to
        reach its ankle moved by (dx, dz) on the ground (negative: it reaches already)."""
        vx = np.float64(P[0, i, ankle]) + dx - P[0, i, hip]
        vy = np.float64(P[1, i, ankle]) - P[1, i, hip]
        vz = np.float64(P[2, i, ankle]) + dz - P[2, i, hip]
        return -vy - np.sqrt(max(r * r - vx * vx - vz * vz, 0.0))

    @_nb.njit(cache=True, boundscheck=False, nogil=True, inline="always")
    def _lock_one(P, i, planted, fa, fb, t, h, hip, knee, ankle, toe, foot, thigh, shin, rmin, rmax,
                  locked, target, res, kcount, blend, maxc, maxdrop):  # pragma: no cover - compiled
        # character i (heading h): P (3, n, J) f32 world positions, in place; planted (T, 2) bool;
        # state: locked (n, 2) bool, target, res (n, 2, 2) f64, kcount (n, 2) i32. The arithmetic
        # of footlock.lock_positions.
        J = P.shape[2]
        f = fa[i] if t[i] < 0.5 else fb[i]
        d0x = d0z = d1x = d1z = 0.0
        for s in range(2):
            tj = toe[s] if toe[s] >= 0 else ankle[s]
            px = np.float64(P[0, i, tj])
            pz = np.float64(P[2, i, tj])
            was = locked[i, s]
            kk = 1 if was else kcount[i, s] + 1
            if kk > blend + 1:
                kk = blend + 1
            w = min(max(1.0 - kk / (blend + 1.0), 0.0), 1.0)
            fx = res[i, s, 0] * w
            fz = res[i, s, 1] * w
            p = planted[f, s]
            if p and not was:
                target[i, s, 0] = px + fx
                target[i, s, 1] = pz + fz
            if p:
                dx = target[i, s, 0] - px
                dz = target[i, s, 1] - pz
                m = np.sqrt(dx * dx + dz * dz)
                if m > maxc:
                    sc = maxc / m
                    dx *= sc
                    dz *= sc
                    target[i, s, 0] = px + dx
                    target[i, s, 1] = pz + dz
                res[i, s, 0] = dx
                res[i, s, 1] = dz
            else:
                dx = fx
                dz = fz
            locked[i, s] = p
            kcount[i, s] = kk
            if s == 0:
                d0x = dx
                d0z = dz
            else:
                d1x = dx
                d1z = dz
        if d0x == 0 and d0z == 0 and d1x == 0 and d1z == 0:
            return
        need = 0.0
        room = 1e30
        for s in range(2):
            dx = d0x if s == 0 else d1x
            dz = d0z if s == 0 else d1z
            if dx != 0 or dz != 0:
                need = max(need, _hip_drop(P, i, hip[s], ankle[s], dx, dz, rmax[s]))
        drop = 0.0
        if need > 0.0:       # no lower than the most bent knee allows either leg
            for s in range(2):
                room = min(room, _hip_drop(P, i, hip[s], ankle[s], d0x if s == 0 else d1x, d0z if s == 0 else d1z,
                                           rmin[s]))
            drop = min(max(min(need, room), 0.0), maxdrop)
        for s in range(2):
            dx = d0x if s == 0 else d1x
            dz = d0z if s == 0 else d1z
            if dx == 0 and dz == 0 and drop == 0.0:       # this leg stays as it is
                continue
            hx = np.float64(P[0, i, hip[s]])
            hy = np.float64(P[1, i, hip[s]]) - drop
            hz = np.float64(P[2, i, hip[s]])
            ax = np.float64(P[0, i, ankle[s]])
            ay = np.float64(P[1, i, ankle[s]])
            az = np.float64(P[2, i, ankle[s]])
            wx = ax - hx
            wy = ay - hy
            wz = az - hz
            fr = min(_reach_fraction(wx, wy, wz, dx, dz, rmax[s], True),
                     _reach_fraction(wx, wy, wz, dx, dz, rmin[s], False))
            vx = wx + fr * dx
            vy = wy
            vz = wz + fr * dz
            D = np.sqrt(vx * vx + vy * vy + vz * vz)
            Dc = min(max(D, rmin[s]), rmax[s])
            rD = 1.0 / max(D, 1e-12)
            ux = vx * rD
            uy = vy * rD
            uz = vz * rD
            qx = np.float64(P[0, i, knee[s]]) - P[0, i, hip[s]]
            qy = np.float64(P[1, i, knee[s]]) - P[1, i, hip[s]]
            qz = np.float64(P[2, i, knee[s]]) - P[2, i, hip[s]]
            pr = qx * ux + qy * uy + qz * uz
            qx -= pr * ux
            qy -= pr * uy
            qz -= pr * uz
            fwx = np.sin(h)
            fwz = np.cos(h)
            pr = fwx * ux + fwz * uz
            fx_ = fwx - pr * ux                                    # forward, square to the leg
            fy_ = -pr * uy
            fz_ = fwz - pr * uz
            if np.sqrt(qx * qx + qy * qy + qz * qz) <= 1e-6:      # a straight leg: the knee faces forward
                qx = fx_
                qy = fy_
                qz = fz_
            else:                                                  # never behind the line: mirrored to the front
                rf = 1.0 / max(np.sqrt(fx_ * fx_ + fy_ * fy_ + fz_ * fz_), 1e-12)
                pf = (qx * fx_ + qy * fy_ + qz * fz_) * rf
                if pf < 0.0:
                    qx -= 2.0 * pf * fx_ * rf
                    qy -= 2.0 * pf * fy_ * rf
                    qz -= 2.0 * pf * fz_ * rf
            rq = 1.0 / max(np.sqrt(qx * qx + qy * qy + qz * qz), 1e-12)
            a = (thigh[s] * thigh[s] - shin[s] * shin[s] + Dc * Dc) / (2.0 * Dc)
            b = np.sqrt(max(thigh[s] * thigh[s] - a * a, 0.0))
            # knee and feet are placed absolutely; the drop of the whole body follows below
            P[0, i, knee[s]] = np.float32(hx + ux * a + qx * rq * b)
            P[1, i, knee[s]] = np.float32(hy + uy * a + qy * rq * b + drop)
            P[2, i, knee[s]] = np.float32(hz + uz * a + qz * rq * b)
            shx = np.float32(hx + ux * Dc - ax)
            shy = np.float32(hy + uy * Dc - ay + drop)
            shz = np.float32(hz + uz * Dc - az)
            for m in range(foot.shape[1]):
                j = foot[s, m]
                if j < 0:
                    break
                P[0, i, j] += shx
                P[1, i, j] += shy
                P[2, i, j] += shz
        if drop > 0.0:
            fd = np.float32(drop)
            for j in range(J):
                P[1, i, j] -= fd

    @_nb.njit(parallel=True, cache=True, boundscheck=False, nogil=True)
    def _blend_place_lock(local, fa, fb, t, root, out, planted, hip, knee, ankle, toe, foot, thigh, shin, rmin,
                          rmax, locked, target, res, kcount, blend, maxc, maxdrop):  # pragma: no cover - compiled
        # _blend_place then _lock_one per character, while its joints are in cache
        for i in _nb.prange(fa.shape[0]):
            _place_one(local, fa, fb, t, root, out, i)
            _lock_one(out, i, planted, fa, fb, t, root[i, 2], hip, knee, ankle, toe, foot, thigh, shin, rmin, rmax,
                      locked, target, res, kcount, blend, maxc, maxdrop)

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _blend_place_lock_serial(local, fa, fb, t, root, out, planted, hip, knee, ankle, toe, foot, thigh, shin,
                                 rmin, rmax, locked, target, res, kcount, blend, maxc,
                                 maxdrop):  # pragma: no cover - compiled
        for i in range(fa.shape[0]):
            _place_one(local, fa, fb, t, root, out, i)
            _lock_one(out, i, planted, fa, fb, t, root[i, 2], hip, knee, ankle, toe, foot, thigh, shin, rmin, rmax,
                      locked, target, res, kcount, blend, maxc, maxdrop)

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _blend_place_serial(local, fa, fb, t, root, out):  # pragma: no cover - compiled
        for i in range(fa.shape[0]):
            _place_one(local, fa, fb, t, root, out, i)


def blend_place(local, fa, fb, t, root, out):
    """World positions (3, n, J) into ``out``: ``R_y(heading) lerp(L[a], L[b], t) + (x, 0, z)``
    (parallel above :data:`SERIAL_MAX` characters). Frame indices must be valid (the caller
    checks them)."""
    (_blend_place if len(fa) > SERIAL_MAX else _blend_place_serial)(
        local, np.ascontiguousarray(fa, dtype=np.int64), np.ascontiguousarray(fb, dtype=np.int64),
        np.ascontiguousarray(t, dtype=np.float32), np.ascontiguousarray(root, dtype=np.float64), out)
    return out


def lerp(p, q, alpha: float, out):
    """``out = p + alpha (q - p)`` over (3, n, J) float32 arrays, in one pass (parallel above
    :data:`SERIAL_MAX` characters)."""
    (_lerp if p.shape[1] > SERIAL_MAX else _lerp_serial)(p, q, np.float32(alpha), out)
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


def blend_place_lock(local, fa, fb, t, root, out, model, state, blend: int, max_correction: float,
                     max_drop: float) -> None:
    """:func:`blend_place` and :func:`foot_lock` in one pass per character (the lock runs while
    the character's joints are in cache; parallel above :data:`SERIAL_MAX` characters)."""
    legs = model.legs
    (_blend_place_lock if len(fa) > SERIAL_MAX else _blend_place_lock_serial)(
        local, np.ascontiguousarray(fa, dtype=np.int64), np.ascontiguousarray(fb, dtype=np.int64),
        np.ascontiguousarray(t, dtype=np.float32), np.ascontiguousarray(root, dtype=np.float64), out,
        model.planted, legs.hip, legs.knee, legs.ankle, legs.toe, model.foot, model.thigh, model.shin,
        model.reach_min, model.reach_max, state.locked, state.target, state.res, state.k, int(blend),
        float(max_correction), float(max_drop))
