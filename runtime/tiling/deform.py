"""Laplacian path deformation of motion patches (Kim, Hwang, Hyun and Lee 2012, section 3; the
multi-character motion editing it builds on: Kim, Hyun, Kim and Lee 2009, "Synchronized
multi-character motion editing").

Every frame ``i`` of every fragment of a patch carries four unknowns, its displacement from the
rest patch: planar position ``u_i = (ux, uz)``, a heading change ``phi_i`` and a time change
``tau_i``. The deformation energy is the sum of squared Laplacian (first-difference) residuals
along each motion path, linearised about the rest path so that rigid motions cost nothing::

    segment   w_s / max(|d_i|, 2 cm) * ((u_{i+1} - u_i) - phi_i * J d_i)
              d_i = p_{i+1} - p_i (rest), J d = (d_z, -d_x)
    bend      w_b * (phi_{i+1} - phi_i)
    timing    w_t * (tau_{i+1} - tau_i)
    anchor    eps * (u_i, phi_i, tau_i)                       (makes the system definite)

(``J d`` is the derivative of the heading rotation, so ``u_i = phi * J (p_i - c)`` with constant
``phi`` -- a small rigid rotation -- has zero residual.) The unknowns live in the *patch* frame,
so one factorisation serves every placement of the patch.

Linear constraints ``C u = r`` (hard, by Lagrange multipliers):

* interpersonal constraints of the patch (``Constraint``): b's root minus a's root in a's heading
  frame, the relative heading and the time offset stay as captured (linearised: ``u_b - u_a -
  phi_a J (p_b - p_a) = 0``, ``phi_b - phi_a = 0``, ``tau_b - tau_a = 0``), always with ``r = 0``;
* handle rows of every entry/exit port: position ``(x, z)`` of the port frame, position of its
  neighbour frame (so ``p_1 - p_0`` / ``p_N - p_{N-1}`` can be prescribed: stitching Eq. 2),
  heading and time (Eq. 1 and Eq. 3 prescribe position and time). A port that is not being
  stitched is held where the placement puts it (``r = 0``).

Two steps (as in the Laplacian motion editing the paper builds on): step 1 solves the linear
system above; with ``A = D^T D`` factored once per patch (scipy ``splu``) its solution for any
handle offsets is ``u = A^-1 C^T (C A^-1 C^T)^+ r``, and :class:`PatchDeformer` keeps the dense map
``H = G K^+`` (``G = A^-1 C^T``, ``K = C G``) for the port rows, so a stitch or a jitter costs a
small matrix-vector product. Step 1's headings ``phi`` and times
are kept; step 2 fixes the rotations and solves the positions again -- segment rows
``(u_{i+1} - u_i) - (R(phi) - I) d_i``, port position rows, and the interpersonal offsets
``u_b - u_a = (R(phi_a) - I)(p_b - p_a)`` exactly (no small-angle error) -- with its own matrix,
also factored once per patch (one sparse solve per deformation). ``energy(r) = r^T K^+ r`` is the
step-1 energy.

Limits (section 5.1), per frame: positional stretch ``| |p'_{i+1} - p'_i| - |p_{i+1} - p_i| |``
at most 3 cm, bending (change of the heading increment, and of the path-direction increment on
segments longer than 1 cm) at most 7 degrees, time shift ``| dt'_i - dt_i |`` at most 0.018 s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..motion.planar import rotate_xz, wrap_angle

__all__ = ["Limits", "DEFAULT_LIMITS", "FOOT_LEVER", "PatchDeformer", "PORT_ROWS", "deformation_measures", "port_row_targets"]

PORT_ROWS = 6        # x, z, x_nb, z_nb, heading, time per port


@dataclass(frozen=True)
class Limits:
    """Per-frame deformation limits of a patch's motion paths. ``stretch``, ``bend_deg`` and
    ``time_shift`` are Kim, Hwang, Hyun and Lee (2012)'s (3 cm, 7 deg, 0.018 s per frame). ``glide``
    bounds how far a *standing* frame (rest segment shorter than ``min_segment``) carries the
    feet: its stretch plus its heading bend times :data:`FOOT_LEVER`. A standing character moved
    3 cm a frame glides at 0.9 m/s, turned 7 deg a frame it pivots its toes at 1.1 m/s, with both
    feet planted, which no foot lock can hide; 1 cm a frame keeps the baked tilings' planted feet
    within the foot check's limits (docs/decisions.md)."""
    stretch: float = 0.03          # m per frame
    bend_deg: float = 7.0          # degrees per frame
    time_shift: float = 0.018      # s per frame
    min_segment: float = 0.01      # m: shorter segments have no path direction (standing)
    glide: float = 0.01            # m per frame: stretch of a standing frame

    def ok(self, stretch: float, bend_deg: float, shift: float, glide: float = 0.0) -> bool:
        return (stretch <= self.stretch + 1e-9 and bend_deg <= self.bend_deg + 1e-9
                and shift <= self.time_shift + 1e-9 and glide <= self.glide + 1e-9)


DEFAULT_LIMITS = Limits()
FOOT_LEVER = 0.15    # m: how far from the root's vertical axis a standing character's feet are


def deformation_measures(rest_xz, rest_heading, rest_time, xz, heading, time, seg_valid, min_segment=0.01):
    """Per-segment deformation of paths (any placement: rigid motions measure zero).

    Arrays are flat over frames; ``seg_valid`` (N-1,) marks consecutive frames of one fragment.
    Returns (stretch (N-1,) m, bend (N-1,) deg, shift (N-1,) s, glide (N-1,) m), zero where not
    ``seg_valid``; glide is how far standing segments (rest length under ``min_segment``) carry
    the feet -- stretch plus heading bend times :data:`FOOT_LEVER` -- zero elsewhere. Bend at segment i compares segments i-1 and i (0 at a fragment's first segment).
    """
    d0 = np.diff(rest_xz, axis=0)
    d1 = np.diff(xz, axis=0)
    l0 = np.hypot(d0[:, 0], d0[:, 1])
    l1 = np.hypot(d1[:, 0], d1[:, 1])
    stretch = np.where(seg_valid, np.abs(l1 - l0), 0.0)
    shift = np.where(seg_valid, np.abs(np.diff(time) - np.diff(rest_time)), 0.0)
    # heading bend: change of the per-frame heading increment
    dh = np.diff(heading) - np.diff(rest_heading)
    bend = np.where(seg_valid, np.abs(dh), 0.0)
    # path-direction bend: rotation of each segment relative to rest, differenced along the path
    rot = np.arctan2(d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0], np.sum(d0 * d1, axis=1))
    moving = seg_valid & (l0 > min_segment) & (l1 > min_segment)
    if len(rot) > 1:
        both = moving[1:] & moving[:-1]
        drot = np.abs(wrap_angle(rot[1:] - rot[:-1]))
        pb = np.zeros_like(bend)
        pb[1:] = np.where(both, drot, 0.0)
        bend = np.maximum(bend, pb)
    glide = np.where(seg_valid & (l0 < min_segment), stretch + np.abs(dh) * FOOT_LEVER, 0.0)
    return stretch, np.degrees(bend), shift, glide


def _pinv_sym(K):
    """Pseudo-inverse of a symmetric PSD matrix. Redundant rows (e.g. a constraint on a port
    frame) are consistent; K spans ~1/eps^2 on rigid motions, so the cutoff is relative to double
    precision only."""
    K = 0.5 * (K + K.T)
    w, V = np.linalg.eigh(K)
    keep = w > w.max() * 1e-14
    return (V[:, keep] / w[keep]) @ V[:, keep].T


class PatchDeformer:
    """Factorised Laplacian system of one patch (see the module docstring).

    Attributes: ``N`` frames (all fragments, flat), ``frag_start`` (K+1,), rest arrays
    ``xz`` (N, 2), ``heading`` (N,), ``time`` (N,) in the patch frame, ``port_frame`` /
    ``port_nb`` (2K,) flat frame of each port and its neighbour (port ``2k`` = entry of fragment
    ``k``, ``2k+1`` = its exit), ``H`` (4, N, 6*2K) the handle-to-displacement map (components
    x, z, heading, time), ``Kp`` the energy matrix of the handle rows.
    """

    def __init__(self, patch, w_segment: float = 1.0, w_bend: float = 1.0, w_time: float = 1.0,
                 eps: float = 1e-3, seg_floor: float = 0.02):
        frags = patch.fragments
        fps = patch.fps
        sizes = np.array([f.num_frames for f in frags])
        self.frag_start = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        N = int(self.frag_start[-1])
        self.N = N
        self.K = len(frags)
        self.xz = np.concatenate([f.root_xz for f in frags])
        self.heading = np.concatenate([f.heading for f in frags])
        self.time = np.concatenate([f.t0 + np.arange(f.num_frames) / fps for f in frags])
        self.frag_of = np.repeat(np.arange(self.K), sizes)
        seg = np.ones(N - 1, bool)
        seg[self.frag_start[1:-1] - 1] = False
        self.seg_valid = seg
        s = self.frag_start[:-1]
        e = self.frag_start[1:] - 1
        self.port_frame = np.stack([s, e], 1).reshape(-1)
        self.port_nb = np.stack([np.minimum(s + 1, e), np.maximum(e - 1, s)], 1).reshape(-1)
        P = 2 * self.K
        self.num_ports = P

        # --- Laplacian (first-difference) operator D ------------------------------------------
        iseg = np.flatnonzero(seg)
        d = self.xz[iseg + 1] - self.xz[iseg]
        # relative residuals: a segment turned or stretched by a given fraction costs the same
        # whatever its length (floor: standing frames are stiff against sliding)
        ws = w_segment / np.maximum(np.hypot(d[:, 0], d[:, 1]), seg_floor)
        X, Z, PH, T = 0, N, 2 * N, 3 * N
        rows, cols, vals = [], [], []
        nrow = 0

        def add(r, c, v):
            rows.append(np.asarray(r)), cols.append(np.asarray(c)), vals.append(np.broadcast_to(np.asarray(v, float), np.shape(r)))

        ns = len(iseg)
        r0 = np.arange(ns)
        # x component: ux_{i+1} - ux_i - phi_i * d_z
        add(nrow + r0, X + iseg + 1, ws); add(nrow + r0, X + iseg, -ws); add(nrow + r0, PH + iseg, -ws * d[:, 1])
        nrow += ns
        # z component: uz_{i+1} - uz_i + phi_i * d_x
        add(nrow + r0, Z + iseg + 1, ws); add(nrow + r0, Z + iseg, -ws); add(nrow + r0, PH + iseg, ws * d[:, 0])
        nrow += ns
        add(nrow + r0, PH + iseg + 1, w_bend); add(nrow + r0, PH + iseg, -w_bend)
        nrow += ns
        add(nrow + r0, T + iseg + 1, w_time); add(nrow + r0, T + iseg, -w_time)
        nrow += ns
        ra = np.arange(4 * N)
        add(nrow + ra, ra, eps)
        nrow += 4 * N
        D = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nrow, 4 * N))
        A = (D.T @ D).tocsc()

        # --- constraint rows C -----------------------------------------------------------------
        crow, ccol, cval = [], [], []
        m = 0
        for j in range(P):
            f, nb = self.port_frame[j], self.port_nb[j]
            for c in (X + f, Z + f, X + nb, Z + nb, PH + f, T + f):
                crow.append(m), ccol.append(c), cval.append(1.0)
                m += 1
        self.num_port_rows = m
        for con in patch.constraints:
            ia = self.frag_start[con.frag_a] + con.frame_a
            ib = self.frag_start[con.frag_b] + con.frame_b
            v = self.xz[ib] - self.xz[ia]
            # u_b - u_a - phi_a J v
            crow += [m, m, m]; ccol += [X + ib, X + ia, PH + ia]; cval += [1.0, -1.0, -v[1]]
            crow += [m + 1, m + 1, m + 1]; ccol += [Z + ib, Z + ia, PH + ia]; cval += [1.0, -1.0, v[0]]
            crow += [m + 2, m + 2]; ccol += [PH + ib, PH + ia]; cval += [1.0, -1.0]
            crow += [m + 3, m + 3]; ccol += [T + ib, T + ia]; cval += [1.0, -1.0]
            m += 4
        C = sp.csr_matrix((cval, (crow, ccol)), shape=(m, 4 * N))
        lu = spla.splu(A)
        G = lu.solve(np.asarray(C.T.todense()))                 # (4N, m)
        Kp = _pinv_sym(np.asarray(C @ G))
        mp = self.num_port_rows
        Hfull = G @ Kp                                           # (4N, m)
        self.H = np.ascontiguousarray(Hfull[:, :mp].reshape(4, N, mp))
        self.Kp = Kp[:mp, :mp]

        # --- step 2: positions for the now known rotations (exact constraints) -------------------
        # rows ws * ((u_{i+1} - u_i) - (R(phi_i) - I) d_i) per component, eps anchor
        self.iseg = iseg
        self.seg_d = d
        self.seg_w2 = ws * ws
        r1 = np.arange(ns)
        D2 = sp.csr_matrix((np.concatenate([ws, -ws, np.full(N, eps)]),
                            (np.concatenate([r1, r1, ns + np.arange(N)]), np.concatenate([iseg + 1, iseg, np.arange(N)]))),
                           shape=(ns + N, N))
        A2 = (D2.T @ D2).tocsc()                                 # same for x and z
        self._lu2 = spla.splu(A2)
        # constraint rows on one component: port frame, port neighbour; constraint b - a
        c2r, c2c, c2v = [], [], []
        m2 = 0
        for j in range(P):
            for c in (self.port_frame[j], self.port_nb[j]):
                c2r.append(m2), c2c.append(c), c2v.append(1.0)
                m2 += 1
        self.con_ab = []
        for con in patch.constraints:
            ia = self.frag_start[con.frag_a] + con.frame_a
            ib = self.frag_start[con.frag_b] + con.frame_b
            self.con_ab.append((ia, ib))
            c2r += [m2, m2]; c2c += [ib, ia]; c2v += [1.0, -1.0]
            m2 += 1
        C2 = sp.csr_matrix((c2v, (c2r, c2c)), shape=(m2, N))
        self._C2 = C2
        G2 = self._lu2.solve(np.asarray(C2.T.todense()))        # (N, m2)
        self._M2 = G2 @ _pinv_sym(np.asarray(C2 @ G2))          # (N, m2)
        self.con_ab = np.array(self.con_ab, np.int64).reshape(-1, 2)
        self.con_v = (self.xz[self.con_ab[:, 1]] - self.xz[self.con_ab[:, 0]]) if len(self.con_ab) else np.zeros((0, 2))

    # ------------------------------------------------------------------------------------------
    def displacement(self, r: np.ndarray, cols: np.ndarray | None = None):
        """Frame displacements (4, N) (x, z, heading, time in the patch frame) for handle
        offsets ``r`` (all port rows, or only the rows ``cols``)."""
        if cols is None:
            return self.H @ r
        return self.H[:, :, cols] @ r

    def energy(self, r: np.ndarray) -> float:
        return float(r @ self.Kp @ r)

    def deform(self, r, cols=None):
        """Deformed rest arrays (xz (N, 2), heading (N,), time (N,)) in the patch frame.

        Step 1 (linear, precomputed map) gives the heading and time changes; step 2 fixes the
        rotations and solves the positions again so that segments follow their rotated rest
        vectors and interpersonal offsets hold exactly (two-step Laplacian editing)."""
        if cols is None:
            cols = np.arange(self.num_port_rows)
            rc = r
        else:
            rc = r[cols]
        H = self.H[2:, :, cols]
        phi, tau = H @ rc
        # step 2 right-hand side: rotated rest segments
        ph = 0.5 * (phi[self.iseg] + phi[self.iseg + 1])
        e = rotate_xz(self.seg_d, ph) - self.seg_d
        b = np.zeros((self.N, 2))
        we = self.seg_w2[:, None] * e
        b[self.iseg + 1] += we                                  # indices unique per statement
        b[self.iseg] -= we
        u0 = self._lu2.solve(b)
        # port rows (held ports: zero offset) and constraint rows, per component
        P = self.num_ports
        rr = np.zeros(self.num_port_rows)
        rr[cols] = rc
        rp = rr.reshape(P, 6)[:, :4]                            # x, z, x_nb, z_nb
        tgt = np.empty((2 * P + len(self.con_ab), 2))
        tgt[0:2 * P:2] = rp[:, 0:2]
        tgt[1:2 * P:2] = rp[:, 2:4]
        if len(self.con_ab):
            pa = phi[self.con_ab[:, 0]]
            tgt[2 * P:] = rotate_xz(self.con_v, pa) - self.con_v
        u = u0 + self._M2 @ (tgt - self._C2 @ u0)
        return self.xz + u, self.heading + phi, self.time + tau

    def measures(self, xz, heading, time):
        """Per-segment (stretch, bend deg, shift, glide) of deformed patch-frame arrays."""
        return deformation_measures(self.xz, self.heading, self.time, xz, heading, time, self.seg_valid)


def port_row_targets(deformer: PatchDeformer, port: int, position, direction, time, step=None):
    """Handle offsets (6,) in the patch frame that move port ``port`` of the rest patch to
    ``position`` / ``direction`` / ``time`` (all already in the patch frame) with neighbour-frame
    offset ``step`` (Eq. 2: the neighbour frame sits at ``position + step``); ``step=None`` moves
    the neighbour rigidly with the port."""
    f = deformer.port_frame[port]
    nb = deformer.port_nb[port]
    dp = np.asarray(position, float) - deformer.xz[f]
    dth = float(direction) - deformer.heading[f]
    if step is None:
        rel = rotate_xz(deformer.xz[nb] - deformer.xz[f], dth)
        nbp = np.asarray(position, float) + rel
    else:
        nbp = np.asarray(position, float) + np.asarray(step, float)
    dnb = nbp - deformer.xz[nb]
    return np.array([dp[0], dp[1], dnb[0], dnb[1], dth, float(time) - deformer.time[f]])
