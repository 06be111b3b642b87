"""The splice (Sung, Kovar and Gleicher 2005, section 3.3, steps 1-4): a forward prefix and a
backward suffix that meet at a motion-graph node are joined, and displacement maps spread the
position and orientation mismatch over both parts so the start and the goal hold exactly; the
result is resampled in time to a duration inside the goal's window, on the fixed frame grid."""
from __future__ import annotations

import numpy as np

from ...motion.planar import TWO_PI, compose, compose1, compose_inverse, wrap_angle
from .library import MotionLibrary
from .params import SearchParams
from .types import Config, SegmentResult

__all__ = ["splice", "resample"]


def splice(lib: MotionLibrary, params: SearchParams, start: Config, goal_cfg, goal_node, Frow, i, Brow, j,
           window_rel, force: bool = False, frames=None):
    """Steps 1-4 of section 3.3 for the pair (M_f[:i], M_b[j:]). The result lasts the
    duration nearest the raw one inside the window, or ``frames`` output frames (None if
    outside the window); ``frames`` a sequence: a list of results, one per duration."""
    g, p = lib.g, params
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
    src_frames = np.concatenate(parts_f)
    src_root = np.concatenate(parts_r)
    n_src = len(src_frames)
    # step 4: resample to a duration inside the window, on the frame grid
    fps = p.fps
    D = (n_src - 1) / fps
    if window_rel is not None:
        lo, hi = window_rel
        target = min(max(D, lo), hi)
        m1 = int(round(target * fps))
        if m1 / fps < lo - 1e-9:
            m1 += 1
        if m1 / fps > hi + 1e-9:
            m1 -= 1
        if not (lo - 1e-9 <= m1 / fps <= hi + 1e-9) and not force and frames is None:
            return None
    else:
        m1 = n_src - 1
    if frames is None:
        return resample(params, src_frames, src_root, len(ff), len(bf), dp, dh, N, goal_node, start, edges, m1)
    out = []
    for m in np.atleast_1d(frames):
        m = int(m)
        inside = window_rel is None or (window_rel[0] - 1e-9 <= m / fps <= window_rel[1] + 1e-9)
        out.append(resample(params, src_frames, src_root, len(ff), len(bf), dp, dh, N, goal_node, start, edges, m)
                   if inside and m >= 1 else None)
    return out if np.ndim(frames) else out[0]

def resample(params: SearchParams, src_frames, src_root, nff, nbf, dp, dh, N, goal_node, start, edges, m1):
    """Step 4: the spliced source frames resampled to ``m1`` output steps."""
    p = params
    n_src = len(src_frames)
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
    root = src_root[a] * (1 - t)[:, None] + src_root[b] * t[:, None]
    root[0] = src_root[0]
    root[-1] = src_root[-1]
    s = max(s_parts)
    rates = (float(np.hypot(*dp) * s / N), float(np.degrees(abs(dh)) * s / N),
             float(max(abs(x - 1.0) for x in s_parts)))
    end = Config(int(goal_node), float(root[-1, 0]), float(root[-1, 1]), float(root[-1, 2]), start.frame + m1)
    # exact end: the last frame is the goal configuration by construction
    return SegmentResult(True, src_frames[a], src_frames[b], t.astype(np.float32), root, start.frame, end,
                         0.0, rates, 0, edges)
