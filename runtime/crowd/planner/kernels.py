"""Compiled splice-cost kernel for the randomized search (Sung, Kovar and Gleicher 2005, section 3.3, Eq. 1-2).

:meth:`runtime.crowd.synthesis.SegmentPlanner.pair_costs` costs every pair (prefix i of M_f,
suffix j of M_b) of n_m perturbed motion pairs per iteration. In numpy that is about forty
whole-array passes over (pairs x positions) and (pairs x positions x positions) arrays plus a
sparse gather -- 1.4-8 ms per iteration of 200 pairs (``bench/splice_costs.py``), most of a
character's planning time. This kernel
does the same arithmetic in one loop per pair: the forward configurations by accumulating the
clips' planar displacements from the start, the backward ones from the goal, then every (i, j)
meeting at the same node, keeping the row-major first minimum (the numpy path's tie rule).

Same formula as the numpy path (sequential sums in the same order); ``tests/test_synthesis.py``
checks both agree. numba is optional: without it :data:`AVAILABLE` is False and the numpy path
runs. Compiled on first use and cached on disk.
"""
from __future__ import annotations

import numpy as np

from ..clearance import sdf_bilinear

try:  # pragma: no cover - depends on the environment
    import numba as _nb
    AVAILABLE = True
except Exception:
    _nb = None
    AVAILABLE = False

__all__ = ["AVAILABLE", "ENABLED", "pair_costs", "lookahead_errors", "edge_samples", "pairs_static_clear", "perturb"]

ENABLED = AVAILABLE     # new planners use the kernels (set False to run the numpy paths)

if AVAILABLE:
    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _pair_costs(F, nf, B, nb, disp, dur, edge_src, edge_dst, start, goal, start_node, goal_node,
                    a1, a2, has_window, w0, w1, best, bi, bj):  # pragma: no cover - compiled
        P, Lf = F.shape
        Lb = B.shape[1]
        two_pi = 2.0 * np.pi
        xF = np.empty(Lf + 1)
        zF = np.empty(Lf + 1)
        hF = np.empty(Lf + 1)
        tF = np.empty(Lf + 1)
        nodeF = np.empty(Lf + 1, np.int64)
        xB = np.empty(Lb + 1)
        zB = np.empty(Lb + 1)
        hB = np.empty(Lb + 1)
        tB = np.empty(Lb + 1)
        nodeB = np.empty(Lb + 1, np.int64)
        for p in range(P):
            # forward: configuration at node k (k clips from the start)
            ax = 0.0
            az = 0.0
            at = 0.0
            ah = 0.0
            xF[0] = start[0]
            zF[0] = start[1]
            hF[0] = start[2]
            tF[0] = 0.0
            nodeF[0] = start_node
            for k in range(Lf):
                e = F[p, k]
                hk = start[2] + ah
                if e >= 0:
                    c = np.cos(hk)
                    s = np.sin(hk)
                    ax += c * disp[e, 0] + s * disp[e, 1]
                    az += -s * disp[e, 0] + c * disp[e, 1]
                    ah += disp[e, 2]
                    at += dur[e]
                    nodeF[k + 1] = edge_dst[e]
                else:
                    nodeF[k + 1] = -3
                xF[k + 1] = start[0] + ax
                zF[k + 1] = start[1] + az
                hF[k + 1] = start[2] + ah
                tF[k + 1] = at
            # backward: configuration at position k (the goal at Lb), sums from the end
            ax = 0.0
            az = 0.0
            at = 0.0
            ah = 0.0
            xB[Lb] = goal[0]
            zB[Lb] = goal[1]
            hB[Lb] = goal[2]
            tB[Lb] = 0.0
            nodeB[Lb] = goal_node
            for k in range(Lb - 1, -1, -1):
                e = B[p, k]
                if e >= 0:
                    ah += disp[e, 2]
                    hk = goal[2] - ah
                    c = np.cos(hk)
                    s = np.sin(hk)
                    ax += c * disp[e, 0] + s * disp[e, 1]
                    az += -s * disp[e, 0] + c * disp[e, 1]
                    at += dur[e]
                    nodeB[k] = edge_src[e]
                else:
                    hk = goal[2] - ah
                    nodeB[k] = -4
                hB[k] = hk
                xB[k] = goal[0] - ax
                zB[k] = goal[1] - az
                tB[k] = at
            b = np.inf
            ib = 0
            jb = Lb
            j0 = Lb - nb[p]
            for i in range(nf[p] + 1):
                ni = nodeF[i]
                for j in range(j0, Lb + 1):
                    if nodeB[j] != ni:
                        continue
                    Np = tF[i] + tB[j]
                    if not Np > 0.2:
                        continue
                    dx = xF[i] - xB[j]
                    dz = zF[i] - zB[j]
                    # a lower bound of the cost first (|dx|, |dz| <= E_p, the other terms >= 0):
                    # a match that cannot beat the best so far skips the hypot and the wrap
                    # (the margin is far above rounding, so the minimum found is the same)
                    lb = max(abs(dx), abs(dz))
                    if has_window:
                        lb += a2 * max(0.0, max(w0 - Np, Np - w1))
                    if lb > b * Np * (1.0 + 1e-9):
                        continue
                    Ep = np.hypot(dx, dz)
                    dh = hF[i] - hB[j]
                    Eh = abs(dh - two_pi * np.rint(dh * (1.0 / two_pi)))
                    cst = Ep + a1 * Eh
                    if has_window:
                        cst += a2 * max(0.0, max(w0 - Np, Np - w1))
                    cst /= Np
                    if cst < b:
                        b = cst
                        ib = i
                        jb = j
            best[p] = b
            bi[p] = ib
            bj[p] = jb


def pair_costs(F, nf, B, nb, disp, dur, edge_src, edge_dst, start, goal, start_node, goal_node, a1, a2,
               window_rel):
    """(cost (P,), i (P,), j (P,)) as :meth:`SegmentPlanner.pair_costs` returns them."""
    P = F.shape[0]
    best = np.empty(P)
    bi = np.empty(P, np.int64)
    bj = np.empty(P, np.int64)
    w0, w1 = (float(window_rel[0]), float(window_rel[1])) if window_rel is not None else (0.0, 0.0)
    _pair_costs(np.ascontiguousarray(F, np.int64), np.asarray(nf, np.int64), np.ascontiguousarray(B, np.int64),
                np.asarray(nb, np.int64), disp, dur, edge_src, edge_dst, np.asarray(start, np.float64),
                np.asarray(goal, np.float64), int(start_node), int(goal_node), float(a1), float(a2),
                window_rel is not None, w0, w1, best, bi, bj)
    return best, bi, bj


if AVAILABLE:
    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _wrap(a):  # pragma: no cover - compiled
        return (a + np.pi) % (2.0 * np.pi) - np.pi

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _err(x, z, h, tp0, tp1, final, has_fh, fh, face_w, face_off, approach, a1):  # pragma: no cover
        dx = tp0 - x
        dz = tp1 - z
        e = np.hypot(dx, dz)
        if final and has_fh and e < approach:
            return e + a1 * abs(_wrap(h - fh))         # near the goal: its heading counts instead
        facing = face_w * abs(_wrap(h + face_off - np.arctan2(dx, dz))) * min(e, 1.0)
        if final and has_fh:
            return e + (a1 * np.pi + facing)
        return e + facing

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _lookahead_errors(cfg, disp_out, comb, dur_out, dur2, tp0, tp1, final, has_fh, fh, face_w, face_off,
                          approach, a1, e, span, end_xz, ends):  # pragma: no cover - compiled
        d1, d2 = dur2.shape
        cx, cz, h = cfg[0], cfg[1], cfg[2]
        ch, sh = np.cos(h), np.sin(h)
        for r in range(d1):
            x = cx + ch * disp_out[r, 0] + sh * disp_out[r, 1]
            z = cz - sh * disp_out[r, 0] + ch * disp_out[r, 1]
            hh = h + disp_out[r, 2]
            ends[r, 0] = x
            ends[r, 1] = z
            ends[r, 2] = hh
            e1 = _err(x, z, hh, tp0, tp1, final, has_fh, fh, face_w, face_off, approach, a1)
            best2 = np.inf
            k2 = 0
            bx = bz = 0.0
            for k in range(d2):
                if np.isnan(comb[r, k, 0]):
                    continue                            # padding: fewer continuations here
                x2 = cx + ch * comb[r, k, 0] + sh * comb[r, k, 1]
                z2 = cz - sh * comb[r, k, 0] + ch * comb[r, k, 1]
                # the error is this distance plus terms >= 0: a continuation that cannot beat
                # the row's best so far, nor the single edge, changes nothing (squared, with a
                # margin far above rounding)
                lim = min(best2, e1)
                if (tp0 - x2) * (tp0 - x2) + (tp1 - z2) * (tp1 - z2) > lim * lim * (1.0 + 1e-9):
                    continue
                v = _err(x2, z2, h + comb[r, k, 2], tp0, tp1, final, has_fh, fh, face_w, face_off, approach, a1)
                if np.isnan(v):
                    v = np.inf
                if v < best2:
                    best2 = v
                    k2 = k
                    bx = x2
                    bz = z2
            if best2 < e1:
                e[r] = best2
                span[r] = dur_out[r] + dur2[r, k2]
                end_xz[r, 0] = bx
                end_xz[r, 1] = bz
            else:
                e[r] = e1
                span[r] = dur_out[r]
                end_xz[r, 0] = x
                end_xz[r, 1] = z
        return _err(cx, cz, h, tp0, tp1, final, has_fh, fh, face_w, face_off, approach, a1)


def lookahead_errors(cfg, disp_out, comb, dur_out, dur2, tp, final, final_heading, face_w, face_off, approach, a1):
    """One step of the greedy seed planner's two-edge lookahead (Sung, Kovar and Gleicher 2005, section 3.2),
    compiled: for each out-edge, the error to the target after it or after the best
    continuation (whichever is lower), the seconds that takes, where it ends, and the error
    now. Returns (e (d1,), span (d1,), end_xz (d1, 2), ends (d1, 3), cur) -- the numpy path of
    :meth:`SegmentPlanner.greedy_steps` computes the same (``tests/test_synthesis.py``)."""
    d1 = len(dur_out)
    e = np.empty(d1)
    span = np.empty(d1)
    end_xz = np.empty((d1, 2))
    ends = np.empty((d1, 3))
    cur = _lookahead_errors(np.asarray(cfg, np.float64), disp_out, comb, dur_out, dur2, float(tp[0]), float(tp[1]),
                            bool(final), final_heading is not None,
                            0.0 if final_heading is None else float(final_heading), float(face_w), float(face_off),
                            float(approach), float(a1), e, span, end_xz, ends)
    return e, span, end_xz, ends, cur


if AVAILABLE:
    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _edge_samples(edges, cfg, frames0, samp_ptr, samp_frame, samp_off, frame_xz, frame_heading, frame_radius,
                      margin, xz, rad, frames):  # pragma: no cover - compiled
        m = 0
        for k in range(len(edges)):
            e = edges[k]
            ch, sh = np.cos(cfg[k, 2]), np.sin(cfg[k, 2])
            for s in range(samp_ptr[e], samp_ptr[e + 1]):
                gf = samp_frame[s]
                lx = np.float64(frame_xz[gf, 0])
                lz = np.float64(frame_xz[gf, 1])
                xz[m, 0] = cfg[k, 0] + ch * lx + sh * lz
                xz[m, 1] = cfg[k, 1] - sh * lx + ch * lz
                rad[m] = np.float64(frame_radius[gf]) + margin
                frames[m] = frames0[k] + samp_off[s]
                m += 1


def edge_samples(lib, edges, cfg, frames0, margin):
    """The collision samples of candidate clips ``edges`` placed at the configuration ``cfg``
    (x, z, heading; (3,) for all, or (n, 3) one per clip: where each starts), clip k starting at
    absolute frame ``frames0[k]``: (xz (S, 2), radius + ``margin`` (S,), frames (S,), samples per
    clip (n,)), in clip order -- what the seed planner's clear test
    (:meth:`SegmentPlanner._clear`) gathers with numpy, in one compiled loop (same arithmetic:
    the planar composition of ``synthesis.compose``)."""
    edges = np.asarray(edges, np.int64)
    cnt = lib.samp_ptr[edges + 1] - lib.samp_ptr[edges]
    S = int(cnt.sum())
    xz = np.empty((S, 2))
    rad = np.empty(S)
    frames = np.empty(S, np.int64)
    g = lib.g
    cfgs = np.ascontiguousarray(np.broadcast_to(np.asarray(cfg, np.float64), (len(edges), 3)))
    _edge_samples(edges, cfgs, np.asarray(frames0, np.int64), lib.samp_ptr, lib.samp_frame,
                  lib.samp_off, g.frame_cxz, g.frame_heading, g.frame_radius, float(margin), xz, rad, frames)
    return xz, rad, frames, cnt


if AVAILABLE:
    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _edge_static_clear(e, x, z, h, samp_ptr, samp_frame, frame_xz, frame_heading, frame_radius, need, ox, oz,
                           res, values, gmargin, offset, reach, far):  # pragma: no cover - compiled
        # the whole clip is clear when its start is farther from every obstacle than its
        # samples reach (see _parts_clear for why ``far`` makes that exact)
        if sdf_bilinear(x, z, ox, oz, res, values, gmargin) >= reach[e] + far:
            return True
        ch, sh = np.cos(h), np.sin(h)
        for s in range(samp_ptr[e], samp_ptr[e + 1]):
            gf = samp_frame[s]
            lx = np.float64(frame_xz[gf, 0])
            lz = np.float64(frame_xz[gf, 1])
            d = sdf_bilinear(x + ch * lx + sh * lz, z - sh * lx + ch * lz, ox, oz, res, values, gmargin) - offset
            if d < np.float64(frame_radius[gf]) + need:
                return False
        return True

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _part_static_clear(rows, p, cut, forward, cfg0, disp, samp_ptr, samp_frame, frame_xz, frame_heading,
                           frame_radius, need, ox, oz, res, values, gmargin, offset, reach,
                           far):  # pragma: no cover - compiled
        """Row ``p``: its forward part rows[p, :cut] placed at ``cfg0`` (``forward``), or its
        backward part rows[p, cut:] ending at ``cfg0``, clears the static obstacles."""
        L = rows.shape[1]
        x, z, h = cfg0[0], cfg0[1], cfg0[2]
        if forward:
            for c in range(cut):
                e = rows[p, c]
                if e < 0:
                    continue
                if not _edge_static_clear(e, x, z, h, samp_ptr, samp_frame, frame_xz, frame_heading,
                                          frame_radius, need, ox, oz, res, values, gmargin, offset, reach, far):
                    return False
                ch, sh = np.cos(h), np.sin(h)
                x, z, h = (x + ch * disp[e, 0] + sh * disp[e, 1], z - sh * disp[e, 0] + ch * disp[e, 1],
                           h + disp[e, 2])
        else:
            for c in range(L - 1, max(cut, 0) - 1, -1):
                e = rows[p, c]
                if e < 0:
                    break
                h = h - disp[e, 2]
                ch, sh = np.cos(h), np.sin(h)
                x = x - (ch * disp[e, 0] + sh * disp[e, 1])
                z = z - (-sh * disp[e, 0] + ch * disp[e, 1])
                if not _edge_static_clear(e, x, z, h, samp_ptr, samp_frame, frame_xz, frame_heading,
                                          frame_radius, need, ox, oz, res, values, gmargin, offset, reach, far):
                    return False
        return True

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _part_key(rows, p, a, b):  # pragma: no cover - compiled
        """A 64-bit FNV-1a hash of rows[p, a:b] and its length (never 0: 0 marks an empty slot)."""
        h = np.int64(-3750763034362895579) ^ np.int64(b - a)
        for c in range(a, b):
            h = (h ^ (rows[p, c] + 2)) * np.int64(1099511628211)
        return h if h != 0 else np.int64(1)

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _memo_slot(keys, k):  # pragma: no cover - compiled
        """The slot of key ``k`` in the open-addressed table ``keys`` (its own, or the empty
        one where it would go)."""
        mask = len(keys) - 1
        s = (k ^ (k >> 29)) & mask
        while keys[s] != 0 and keys[s] != k:
            s = (s + 1) & mask
        return s

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _parts_static_clear(rows, cut, forward, cfg0, disp, samp_ptr, samp_frame, frame_xz, frame_heading,
                            frame_radius, need, ox, oz, res, values, gmargin, offset, reach, far,
                            keys, vals, out):  # pragma: no cover
        """Per row, :func:`_part_static_clear`, remembered in the hash table (``keys``,
        ``vals``) by the part's clips: a part found there is not tested again. Returns the
        number of parts added to the table (the caller keeps it at most half full)."""
        P, L = rows.shape
        added = 0
        for p in range(P):
            k = _part_key(rows, p, 0, cut[p]) if forward else _part_key(rows, p, max(cut[p], 0), L)
            s = _memo_slot(keys, k)
            if keys[s] == k:
                out[p] = vals[s]
                continue
            ok = _part_static_clear(rows, p, cut[p], forward, cfg0, disp, samp_ptr, samp_frame, frame_xz,
                                    frame_heading, frame_radius, need, ox, oz, res, values, gmargin, offset,
                                    reach, far)
            out[p] = ok
            keys[s] = k
            vals[s] = ok
            added += 1
        return added

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _memo_rehash(keys, vals, keys2, vals2):  # pragma: no cover - compiled
        for s in range(len(keys)):
            if keys[s] != 0:
                t = _memo_slot(keys2, keys[s])
                keys2[t] = keys[s]
                vals2[t] = vals[s]


class PartMemo:
    """The parts one search has tested against the static obstacles, and the answers: an
    open-addressed hash table of the parts' clips (64-bit keys; kept at most half full), read
    and written by the compiled filter without a Python step per part."""

    def __init__(self, capacity: int = 1024):
        self.keys = np.zeros(capacity, np.int64)
        self.vals = np.zeros(capacity, np.bool_)
        self.count = 0

    def __len__(self) -> int:
        return self.count

    def reserve(self, n: int) -> None:
        """Room for ``n`` more parts at most half full."""
        need = 2 * (self.count + n)
        if need <= len(self.keys):
            return
        cap = len(self.keys)
        while cap < need:
            cap *= 2
        keys2, vals2 = np.zeros(cap, np.int64), np.zeros(cap, np.bool_)
        _memo_rehash(self.keys, self.vals, keys2, vals2)
        self.keys, self.vals = keys2, vals2


def _parts_clear(lib, grid_args, need, rows, cut, cfg0, forward, memo):
    """:func:`_parts_static_clear` of the parts not in ``memo`` (a :class:`PartMemo`, or None).

    A clip is passed without testing its samples when the sampled distance at its start, d0,
    is at least its reach R (``lib.samp_reach``: the farthest sample plus its cylinder) plus
    ``far`` = need + 3 x offset. That decides exactly as the samples would: inside the grid the
    lookup is within ``offset`` of the true distance, which is 1-Lipschitz, so a sample s at
    |v| <= R - r_s from the start reads at least d0 - 2 offset - |v| >= r_s + need + offset.
    Outside the grid a lookup reads the grid's margin, so the shortcut is used only when that
    margin clears the largest cylinder plus need; otherwise every sample is tested."""
    if memo is None:
        memo = PartMemo()
    memo.reserve(len(rows))
    out = np.empty(len(rows), dtype=np.bool_)
    g = lib.g
    ox, oz, res, values, gmargin, offset = grid_args
    far = need + 3.0 * offset + 1e-9
    if gmargin - offset < lib.max_radius + need:
        far = np.inf        # a sample outside the grid might fail: test every sample
    memo.count += _parts_static_clear(np.ascontiguousarray(rows, np.int64), np.ascontiguousarray(cut, np.int64),
                                      forward, np.asarray(cfg0, np.float64), lib.disp, lib.samp_ptr,
                                      lib.samp_frame, g.frame_cxz, g.frame_heading, g.frame_radius, need, ox, oz,
                                      res, values, gmargin, offset, lib.samp_reach, far, memo.keys, memo.vals, out)
    return out


def pairs_static_clear(lib, grid_args, margin: float, F, B, i, j, start, goal, slack: float, memo=None):
    """The randomized search's static filter (:func:`runtime.crowd.planner.costs.pairs_static_clear`)
    in compiled loops, each part stopping at its first sample that cuts into an obstacle.
    ``grid_args``: :attr:`runtime.crowd.clearance.Clearance.compiled_args`. The forward part
    M_f[:i] (placed at the start) and the backward part M_b[j:] (ending at the goal) are tested
    apart; ``memo`` (a dict kept by one search: its start and goal are fixed) remembers every
    part tested, since the pairs of one search share most of their parts."""
    F = np.asarray(F, np.int64)
    B = np.asarray(B, np.int64)
    i = np.asarray(i, np.int64)
    j = np.asarray(j, np.int64)
    need = float(margin) - float(slack)
    fm = bm = None
    if memo is not None:
        fm = memo.setdefault("f", PartMemo())
        bm = memo.setdefault("b", PartMemo())
    ok = _parts_clear(lib, grid_args, need, F, i, start, True, fm)
    if ok.any():
        rest = np.flatnonzero(ok)
        ok[rest] = _parts_clear(lib, grid_args, need, B[rest], j[rest], goal, False, bm)
    return ok


if AVAILABLE:
    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _perturb(Fp, Bp, nfp, nbp, parent, r_use, r_f, r_b, u, has_alt, alt_cum, alt_ptr, alt_idx, Fn, Bn, nfn,
                 nbn):  # pragma: no cover - compiled
        P, Lf = Fn.shape
        Lb = Bn.shape[1]
        for p in range(P):
            q = parent[p]
            fa_any = False
            for c in range(Lf):
                e = Fp[q, c]
                Fn[p, c] = e
                fa_any = fa_any or (e >= 0 and has_alt[e])
            ba_any = False
            for c in range(Lb):
                e = Bp[q, c]
                Bn[p, c] = e
                ba_any = ba_any or (e >= 0 and has_alt[e])
            nfn[p] = nfp[q]
            nbn[p] = nbp[q]
            use_f = r_use[p] < 0.5
            if fa_any and not ba_any:
                use_f = True
            elif ba_any and not fa_any:
                use_f = False
            if use_f and fa_any:
                row, r, L = Fn, r_f, Lf
            elif not use_f and ba_any:
                row, r, L = Bn, r_b, Lb
            else:
                continue
            # argmax of the random numbers over the clips with an alternative (first maximum)
            col = 0
            top = -1.0
            for c in range(L):
                e = row[p, c]
                v = r[p, c] if (e >= 0 and has_alt[e]) else 0.0
                if v > top:
                    top = v
                    col = c
            e = row[p, col]
            k = np.searchsorted(alt_cum, e + u[p], side="right")
            k = min(max(k, alt_ptr[e]), alt_ptr[e + 1] - 1)
            row[p, col] = alt_idx[k]


def perturb(lib, Fp, Bp, nfp, nbp, parent, r_use, r_f, r_b, u):
    """The randomized search's perturbation (:meth:`RandomizedSearch._perturbed`) in one
    compiled loop per pair, from the same random draws: pair ``p`` copies kept pair
    ``parent[p]`` and replaces one clip that has parallel alternatives -- in M_f when
    ``r_use[p] < 0.5`` (or only M_f has such clips), else in M_b; the clip with the largest
    ``r_f[p]`` / ``r_b[p]`` among them -- by the alternative ``u[p]`` draws. Returns
    (F, B, nf, nb), the same arrays as the numpy path."""
    P = len(parent)
    Fn = np.empty((P, Fp.shape[1]), np.int64)
    Bn = np.empty((P, Bp.shape[1]), np.int64)
    nfn = np.empty(P, np.asarray(nfp).dtype)
    nbn = np.empty(P, np.asarray(nbp).dtype)
    _perturb(np.ascontiguousarray(Fp, np.int64), np.ascontiguousarray(Bp, np.int64), np.asarray(nfp),
             np.asarray(nbp), np.asarray(parent, np.int64), r_use, r_f, r_b, u, lib.has_alt, lib.alt_cum,
             lib.alt_ptr, lib.alt_idx, Fn, Bn, nfn, nbn)
    return Fn, Bn, nfn, nbn
