"""The splice cost of the randomized search (Sung, Kovar and Gleicher 2005, section 3.3).

For a forward motion M_f from the start and a backward motion M_b into the goal, the cost of
splicing the prefix M_f[:i] with the suffix M_b[j:] at a node they share is Eq. 1,

    C(i, j) = (E_p + a1 E_theta + a2 E_t) / N(i, j),

the position, orientation and timing mismatch spread over the spliced motion's duration, and a
pair's cost is the minimum over (i, j) (Eq. 2). Everything here is vectorized over many pairs
(the n_m perturbed pairs of one iteration); with numba, :mod:`.kernels` runs the same arithmetic
in one compiled loop per pair.
"""
from __future__ import annotations

import numpy as np

from ...motion.planar import TWO_PI, compose
from . import kernels
from .library import MotionLibrary
from .params import SearchParams

__all__ = ["forward_configs", "backward_configs", "pair_costs", "pairs_static_clear"]


def forward_configs(lib: MotionLibrary, F: np.ndarray, start: np.ndarray):
    """(x, z, heading), each (P, Lf + 1): configurations at the nodes of left-aligned
    forward motions F (padded -1) placed at ``start``."""
    P = len(F)
    fv = F >= 0
    dF = np.where(fv[..., None], lib.disp[np.where(fv, F, 0)], 0.0)
    h = start[2] + np.concatenate([np.zeros((P, 1)), np.cumsum(dF[..., 2], axis=1)], axis=1)
    c, s = np.cos(h[:, :-1]), np.sin(h[:, :-1])
    x = start[0] + np.concatenate([np.zeros((P, 1)), np.cumsum(c * dF[..., 0] + s * dF[..., 1], axis=1)], axis=1)
    z = start[1] + np.concatenate([np.zeros((P, 1)), np.cumsum(-s * dF[..., 0] + c * dF[..., 1], axis=1)], axis=1)
    return x, z, h

def backward_configs(lib: MotionLibrary, B: np.ndarray, goal: np.ndarray):
    """(x, z, heading), each (P, Lb + 1): configurations at the node positions of
    right-aligned motions B (walking order, padded -1) that end at ``goal`` (position Lb)."""
    P = len(B)
    bv = B >= 0
    dB = np.where(bv[..., None], lib.disp[np.where(bv, B, 0)], 0.0)
    h = goal[2] - np.concatenate([np.cumsum(dB[:, ::-1, 2], axis=1)[:, ::-1], np.zeros((P, 1))], axis=1)
    c, s = np.cos(h[:, :-1]), np.sin(h[:, :-1])
    x = goal[0] - np.concatenate([np.cumsum((c * dB[..., 0] + s * dB[..., 1])[:, ::-1], axis=1)[:, ::-1],
                                  np.zeros((P, 1))], axis=1)
    z = goal[1] - np.concatenate([np.cumsum((-s * dB[..., 0] + c * dB[..., 1])[:, ::-1], axis=1)[:, ::-1],
                                  np.zeros((P, 1))], axis=1)
    return x, z, h


def pair_costs(lib: MotionLibrary, params: SearchParams, F: np.ndarray, nf: np.ndarray, B: np.ndarray,
               nb: np.ndarray, start: np.ndarray, goal: np.ndarray, start_node: int, goal_node: int, window_rel,
               compiled: bool | None = None):
    """Splice costs of many (M_f, M_b) pairs.

    F: (P, Lf) forward edges left-aligned, padded -1, lengths nf; B: (P, Lb) backward edges
    right-aligned (walking order), lengths nb. Returns (cost (P,), i (P,), j (P,)) where
    the best splice joins M_f[:i] with M_b[j:] (columns of B). With numba the compiled
    kernel of :mod:`.kernels` computes it (the same formula; ``compiled=False`` runs the numpy
    passes below)."""
    g = lib.g
    if kernels.ENABLED if compiled is None else compiled:
        return kernels.pair_costs(F, nf, B, nb, lib.disp, lib.dur, g.edge_src, g.edge_dst, start, goal,
                                  start_node, goal_node, *params.alpha, window_rel)
    P, Lf = F.shape
    Lb = B.shape[1]
    a1, a2 = params.alpha
    fv = F >= 0
    bv = B >= 0
    Fe = np.where(fv, F, 0)
    Be = np.where(bv, B, 0)
    # forward configurations at nodes 0..Lf; backward ones at node positions 0..Lb
    # (position Lb = goal), right-aligned
    xF, zF, hF = forward_configs(lib, F, start)
    xB, zB, hB = backward_configs(lib, B, goal)
    tF = np.concatenate([np.zeros((P, 1)), np.cumsum(np.where(fv, lib.dur[Fe], 0.0), axis=1)], axis=1)
    nodeF = np.concatenate([np.full((P, 1), -2), np.where(fv, g.edge_dst[Fe], -3)], axis=1)
    nodeF[:, 0] = start_node
    tB = np.concatenate([np.cumsum(np.where(bv, lib.dur[Be], 0.0)[:, ::-1], axis=1)[:, ::-1], np.zeros((P, 1))], axis=1)
    nodeB = np.concatenate([np.where(bv, g.edge_src[Be], -4), np.full((P, 1), goal_node)], axis=1)
    validF = np.arange(Lf + 1)[None, :] <= nf[:, None]
    validB = np.arange(Lb + 1)[None, :] >= (Lb - nb)[:, None]
    nodeF = np.where(validF, nodeF, -5)
    nodeB = np.where(validB, nodeB, -6)
    same = nodeF[:, :, None] == nodeB[:, None, :]
    # only the pairs that meet at a node are costed (a sparse gather, C order: sorted by pair)
    pp, ii, jj = np.nonzero(same)
    Np = tF[pp, ii] + tB[pp, jj]
    keep = Np > 0.2
    if not keep.all():
        pp, ii, jj, Np = pp[keep], ii[keep], jj[keep], Np[keep]
    if len(pp) == 0:
        return np.full(P, np.inf), np.zeros(P, dtype=np.int64), np.full(P, Lb, dtype=np.int64)
    Ep = np.hypot(xF[pp, ii] - xB[pp, jj], zF[pp, ii] - zB[pp, jj])
    dh = hF[pp, ii] - hB[pp, jj]
    Eh = np.abs(dh - TWO_PI * np.rint(dh * (1.0 / TWO_PI)))
    c = Ep + a1 * Eh
    if window_rel is not None:
        c += a2 * np.maximum(0.0, np.maximum(window_rel[0] - Np, Np - window_rel[1]))
    c /= Np
    # per pair minimum (Eq. 2): entries are grouped by pair in (i, j) row-major order, so the
    # first entry equal to its group's minimum is the row-major argmin
    starts = np.flatnonzero(np.r_[True, pp[1:] != pp[:-1]])
    gmin = np.minimum.reduceat(c, starts)
    at_min = c == np.repeat(gmin, np.diff(np.r_[starts, len(c)]))
    cand = np.flatnonzero(at_min)
    pc = pp[cand]
    first = cand[np.r_[True, pc[1:] != pc[:-1]]]
    best = np.full(P, np.inf)
    bi = np.zeros(P, dtype=np.int64)
    bj = np.full(P, Lb, dtype=np.int64)
    best[pp[first]] = c[first]
    bi[pp[first]] = ii[first]
    bj[pp[first]] = jj[first]
    return best, bi, bj


def pairs_static_clear(lib: MotionLibrary, static, margin: float, F, B, i, j, start, goal,
                       slack: float = 0.0, memo: dict | None = None) -> np.ndarray:
    """Per pair: whether its two unspliced parts -- M_f[:i] placed at the start and
    M_b[j:] placed at the goal -- clear the static obstacles at the library's collision
    samples (bounding cylinder + ``margin``). A pair that fails cannot pass the final
    test once spliced (the displacement maps move it a few cm at most), so the search
    drops it before splicing, instead of converging on motions that cut a corner.
    F, B as in :meth:`pair_costs` (rows of the pairs to test). ``slack``: metres of
    overlap forgiven (the displacement maps may still move a grazing part clear). ``memo``: a
    dict one search keeps (fixed start and goal) so the compiled path tests each part once."""
    g = lib.g
    P = len(F)
    if static is None or P == 0:
        return np.ones(P, dtype=bool)
    grid = getattr(static, "compiled_args", None) if kernels.ENABLED else None
    if grid is not None:
        return kernels.pairs_static_clear(lib, grid, margin, F, B, i, j, start, goal, slack, memo)
    Lf, Lb = F.shape[1], B.shape[1]
    fv, bv = F >= 0, B >= 0
    # the configuration each edge starts from
    xF, zF, hF = (a[:, :-1] for a in forward_configs(lib, F, start))
    xB, zB, hB = (a[:, :-1] for a in backward_configs(lib, B, goal))
    # the edges in use, with the configuration each starts from
    useF = fv & (np.arange(Lf)[None, :] < np.asarray(i)[:, None])
    useB = bv & (np.arange(Lb)[None, :] >= np.asarray(j)[:, None])
    rF, cF = np.nonzero(useF)
    rB, cB = np.nonzero(useB)
    row = np.concatenate([rF, rB])
    e = np.concatenate([F[rF, cF], B[rB, cB]])
    base = np.stack([np.concatenate([xF[rF, cF], xB[rB, cB]]), np.concatenate([zF[rF, cF], zB[rB, cB]]),
                     np.concatenate([hF[rF, cF], hB[rB, cB]])], axis=1)
    if len(e) == 0:
        return np.ones(P, dtype=bool)
    cnt = lib.samp_ptr[e + 1] - lib.samp_ptr[e]
    which = np.repeat(np.arange(len(e)), cnt)
    first = np.concatenate([[0], np.cumsum(cnt)[:-1]])
    sidx = lib.samp_ptr[e][which] + (np.arange(int(cnt.sum())) - np.repeat(first, cnt))
    gf = lib.samp_frame[sidx]
    local = np.stack([g.frame_cxz[gf, 0], g.frame_cxz[gf, 1], g.frame_heading[gf]], axis=1)
    world = compose(base[which], local)
    bad = static(world[:, :2]) < g.frame_radius[gf].astype(np.float64) + margin - slack
    return np.bincount(row[which], weights=bad, minlength=P) == 0
