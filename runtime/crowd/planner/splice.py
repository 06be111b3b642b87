"""The splice (Sung, Kovar and Gleicher 2005, section 3.3, steps 1-4): a forward prefix and a
backward suffix that meet at a motion-graph node are joined, and displacement maps spread the
position and orientation mismatch over both parts so the start and the goal hold exactly; the
result is resampled in time to a duration inside the goal's window, on the fixed frame grid."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...motion.planar import TWO_PI, compose, compose1, compose_inverse, wrap_angle
from .library import MotionLibrary
from .params import SearchParams
from .types import Config, SegmentResult

__all__ = ["splice", "splice_source", "output_steps", "fits", "resample", "resample_source",
           "resample_grid", "resample_rates", "resample_rows", "Source"]


class Source(NamedTuple):
    """A pair spliced but not yet resampled (steps 1-3): source frames and their adjusted roots."""

    frames: np.ndarray      # (n,) library frames in playing order
    root: np.ndarray        # (n, 3) adjusted root per source frame
    nff: int                # source frames of the forward part (the junction is its last)
    nbf: int                # ... of the backward part
    dp: np.ndarray          # (2,) the position mismatch the displacement maps spread
    dh: float               # ... and the heading mismatch
    N: float                # seconds of the two parts together
    edges: list             # library edges in order


def splice_source(lib: MotionLibrary, start: Config, goal_cfg, Frow, i, Brow, j) -> Source | None:
    """Steps 1-3 of section 3.3 for the pair (M_f[:i], M_b[j:]): the forward part placed at the
    start, the backward part ending at the goal, and the displacement maps that join them."""
    g = lib.g
    fe = [int(e) for e in Frow[:i]]
    be = [int(e) for e in Brow[j:] if e >= 0]
    edges = fe + be
    if not edges:
        return None
    # raw root per source frame, forward part from the start, backward part from the goal
    def part(edge_list, anchor, at_end):
        if not edge_list:
            return np.zeros((0,), np.int64), np.zeros((0, 3)), 0.0
        frames = [np.arange(g.edge_start[edge_list[0]], g.edge_start[edge_list[0] + 1])]
        cfg_starts = []
        c = np.zeros(3)
        for k, e in enumerate(edge_list):
            cfg_starts.append(c)
            c = compose1(c, lib.disp[e])
            if k:
                frames.append(np.arange(g.edge_start[e] + 1, g.edge_start[e + 1]))
        frames = np.concatenate(frames)
        # local root of each frame, composed with its edge's start configuration
        owner_edge = np.repeat(np.arange(len(edge_list)),
                               [lib.nframes[e] - (1 if k else 0) for k, e in enumerate(edge_list)])
        local = np.stack([g.frame_xz[frames, 0], g.frame_xz[frames, 1], g.frame_heading[frames]], axis=1)
        rel = compose(np.array(cfg_starts)[owner_edge], local)   # relative to the part's start
        if at_end:
            # place so that the last frame is the anchor: start = anchor o inverse(total)
            total = c
            st = compose_inverse(anchor, total)
            # compose_inverse gives the config before a displacement ending at anchor
            world = compose(st[None], rel)
        else:
            world = compose(anchor[None], rel)
        dur = float(sum(lib.dur[e] for e in edge_list))
        return frames, world, dur

    ff, fw, Nf = part(fe, start.xzh, False)
    bf, bw, Nb = part(be, goal_cfg, True)
    if len(ff) == 0:
        ff, fw = np.zeros(0, np.int64), np.zeros((0, 3))
        join_f = start.xzh
    else:
        join_f = fw[-1]
    join_b = bw[0] if len(bf) else goal_cfg
    dp = join_b[:2] - join_f[:2]
    dh = float(wrap_angle(join_b[2] - join_f[2]))
    N = Nf + Nb
    lam1, lam2 = Nf / N, Nb / N
    parts_f, parts_r = [], []
    if len(ff):
        k = np.arange(len(ff)) / max(len(ff) - 1, 1)
        adj = fw.copy()
        adj[:, :2] += (k * lam1)[:, None] * dp
        adj[:, 2] += k * lam1 * dh
        parts_f.append(ff)
        parts_r.append(adj)
    if len(bf):
        k = np.arange(len(bf)) / max(len(bf) - 1, 1)
        adj = bw.copy()
        adj[:, :2] -= ((1 - k) * lam2)[:, None] * dp
        adj[:, 2] -= (1 - k) * lam2 * dh
        if len(ff):
            # unwrap the backward part's headings to continue the forward part's
            adj[:, 2] += TWO_PI * np.round((parts_r[-1][-1, 2] - adj[0, 2]) / TWO_PI)
            parts_f.append(bf[1:])
            parts_r.append(adj[1:])
        else:
            parts_f.append(bf)
            parts_r.append(adj)
    return Source(np.concatenate(parts_f), np.concatenate(parts_r), len(ff), len(bf), dp, dh, N, edges)


def output_steps(params: SearchParams, n_src: int, window_rel, force: bool = False) -> int | None:
    """Step 4's duration: output steps nearest the raw ``n_src - 1`` inside the window (None
    when no whole number of frames is inside it, unless ``force``)."""
    fps = params.fps
    if window_rel is None:
        return n_src - 1
    D = (n_src - 1) / fps
    lo, hi = window_rel
    target = min(max(D, lo), hi)
    m1 = int(round(target * fps))
    if m1 / fps < lo - 1e-9:
        m1 += 1
    if m1 / fps > hi + 1e-9:
        m1 -= 1
    if not (lo - 1e-9 <= m1 / fps <= hi + 1e-9) and not force:
        return None
    return m1


def splice(lib: MotionLibrary, params: SearchParams, start: Config, goal_cfg, goal_node, Frow, i, Brow, j,
           window_rel, force: bool = False, frames=None):
    """Steps 1-4 of section 3.3 for the pair (M_f[:i], M_b[j:]). The result lasts the
    duration nearest the raw one inside the window, or ``frames`` output frames (None if
    outside the window); ``frames`` a sequence: a list of results, one per duration."""
    src = splice_source(lib, start, goal_cfg, Frow, i, Brow, j)
    if src is None:
        return None
    if frames is None:
        m1 = output_steps(params, len(src.frames), window_rel, force)
        return None if m1 is None else resample_source(params, src, goal_node, start, m1)
    out = [resample_source(params, src, goal_node, start, int(m)) if fits(params, window_rel, int(m)) else None
           for m in np.atleast_1d(frames)]
    return out if np.ndim(frames) else out[0]


def fits(params: SearchParams, window_rel, m: int) -> bool:
    """Whether ``m`` output steps are a duration inside the window (and at least one step)."""
    return m >= 1 and (window_rel is None or window_rel[0] - 1e-9 <= m / params.fps <= window_rel[1] + 1e-9)


def resample_source(params: SearchParams, src: Source, goal_node, start: Config, m1: int):
    """Step 4 for a :class:`Source`."""
    return resample(params, src.frames, src.root, src.nff, src.nbf, src.dp, src.dh, src.N, goal_node, start,
                    src.edges, m1)


def resample_grid(params: SearchParams, n_src: int, nff: int, nbf: int, m1: int):
    """Step 4's time warp: for each of the ``m1 + 1`` output frames, the two source frames it
    blends and the blend weight, (a, b, t), and the parts' time scales (source steps per
    output step)."""
    p = params
    m1 = max(int(m1), 1)
    # Each part is resampled on its own so that the junction lands exactly on an output
    # frame: an output frame straddling it would mix the two parts' displacement maps (whose
    # raw paths meet at an angle, the heading error not yet spread) into one step.
    jf = nff - 1 if nff and nbf else -1          # junction index in the source
    if 0 < jf < n_src - 1 and m1 >= 2 and p.split_resample:
        # the junction's output frame: the one that keeps both parts' warps smallest
        ideal = m1 * jf / (n_src - 1)
        cands = np.clip(np.arange(int(np.floor(ideal)) - 1, int(np.ceil(ideal)) + 2), 1, m1 - 1)
        warp = np.maximum(np.abs(jf / cands - 1.0), np.abs((n_src - 1 - jf) / (m1 - cands) - 1.0))
        mf = int(cands[np.argmin(warp)])
        u = np.concatenate([np.arange(mf) * (jf / mf),
                            jf + np.arange(m1 - mf + 1) * ((n_src - 1 - jf) / (m1 - mf))])
        s_parts = (jf / mf, (n_src - 1 - jf) / (m1 - mf))
    else:
        u = np.arange(m1 + 1) * ((n_src - 1) / m1)
        s_parts = ((n_src - 1) / m1,)
    u[-1] = n_src - 1
    a = np.floor(u + 1e-9).astype(np.int64)
    a = np.minimum(a, n_src - 2) if n_src > 1 else a
    t = np.clip(u - a, 0.0, 1.0)
    b = np.minimum(a + 1, n_src - 1)
    return a, b, t, s_parts


def resample_rates(dp, dh, N, s_parts) -> tuple:
    """The per-frame adjustment (m/s, deg/s, s/s) of a splice resampled with time scales
    ``s_parts``: what :func:`~.search.within_eps` compares with eps."""
    s = max(s_parts)
    return (float(np.hypot(*dp) * s / N), float(np.degrees(abs(dh)) * s / N),
            float(max(abs(x - 1.0) for x in s_parts)))


def resample_rows(src: Source, a, b, t, rows) -> np.ndarray:
    """The resampled root at output frames ``rows`` only (the same numbers as
    :func:`resample`'s rows)."""
    last = len(a) - 1
    ra, rb, rt = a[rows], b[rows], t[rows]
    root = src.root[ra] * (1 - rt)[:, None] + src.root[rb] * rt[:, None]
    root[rows == 0] = src.root[0]
    root[rows == last] = src.root[-1]
    return root


def resample(params: SearchParams, src_frames, src_root, nff, nbf, dp, dh, N, goal_node, start, edges, m1):
    """Step 4: the spliced source frames resampled to ``m1`` output steps."""
    m1 = max(int(m1), 1)
    a, b, t, s_parts = resample_grid(params, len(src_frames), nff, nbf, m1)
    root = src_root[a] * (1 - t)[:, None] + src_root[b] * t[:, None]
    root[0] = src_root[0]
    root[-1] = src_root[-1]
    rates = resample_rates(dp, dh, N, s_parts)
    end = Config(int(goal_node), float(root[-1, 0]), float(root[-1, 1]), float(root[-1, 2]), start.frame + m1)
    # exact end: the last frame is the goal configuration by construction
    return SegmentResult(True, src_frames[a], src_frames[b], t.astype(np.float32), root, start.frame, end,
                         0.0, rates, 0, edges)
