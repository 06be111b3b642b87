"""Hub poses for snap-together motion graphs (Gleicher, Shin, Kovar, Jepsen 2003).

1. Transition candidates: for every frame ``i`` the frames ``j`` where ``D(i, .)`` has a
   local minimum below the threshold (one per pass of the motion through ``i``'s pose),
   found chunk by chunk from :mod:`distance` so the full matrix never exists.
2. Greedy hub picking: the frame with the most candidate matches becomes a hub; its matches
   (thinned to be ``min_gap`` frames apart) are its *occurrences*; frames around every
   occurrence are taken out; repeat while a frame still has ``min_occurrences`` matches.

Frames may only match frames of a compatible locomotion state (a "carry" frame never
becomes an occurrence of a walking hub), see :mod:`labels`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .distance import FrameFeatures, distance_rows

__all__ = ["Candidates", "find_candidates", "candidate_block", "candidate_rows", "pick_hubs", "Hub", "still_loops"]


@dataclass
class Candidates:
    """Sparse row-wise local minima below the threshold (CSR layout)."""
    indptr: np.ndarray   # (N+1,)
    cols: np.ndarray     # (nnz,)
    dist: np.ndarray     # (nnz,)
    pairs_evaluated: int


@dataclass
class Hub:
    frame: int                 # global frame index of the hub's defining pose
    occurrences: np.ndarray    # global frame indices (sorted), includes ``frame``
    distances: np.ndarray      # D(frame, occurrence)


def candidate_block(f: FrameFeatures, s: int, e: int, threshold: float, state_cls: np.ndarray,
                    compatible: np.ndarray, row_ok: np.ndarray, col_ok: np.ndarray, band: int):
    """The row-wise local minima of rows ``s:e`` (see :func:`find_candidates`): ``(counts,
    cols, dist)``, matches per row and their columns and distances in row order. Blocks are
    independent, so they can be computed anywhere, in any order."""
    N = len(f.sq)
    D, _ = distance_rows(f, slice(s, e), with_angle=False)
    rows = np.arange(s, e)
    # forbid trivial neighbours and incompatible / invalid columns
    same_take = f.take[rows][:, None] == f.take[None, :]
    near = np.abs(rows[:, None] - np.arange(N)[None, :]) < band
    bad = (same_take & near) | ~col_ok[None, :] | ~compatible[state_cls[rows]][:, state_cls]
    D[bad] = np.inf
    # local minima along the row, inside one take (take borders count as +inf)
    left = np.concatenate([np.full((e - s, 1), np.inf), D[:, :-1]], axis=1)
    right = np.concatenate([D[:, 1:], np.full((e - s, 1), np.inf)], axis=1)
    border_l = np.concatenate([[True], f.take[1:] != f.take[:-1]])
    border_r = np.concatenate([f.take[1:] != f.take[:-1], [True]])
    left[:, border_l] = np.inf
    right[:, border_r] = np.inf
    is_min = (D <= left) & (D < right) & (D < threshold) & row_ok[rows][:, None]
    r, c = np.nonzero(is_min)
    return np.bincount(r, minlength=e - s), c.astype(np.int64), D[r, c]


def candidate_rows(n_frames: int, chunk_bytes: int = 256 << 20) -> list[tuple[int, int]]:
    """The row blocks ``(s, e)`` of :func:`find_candidates` (each block's distance rows take
    about ``chunk_bytes``)."""
    chunk = int(max(16, min(n_frames, chunk_bytes // max(1, 8 * 4 * n_frames))))
    return [(s, min(n_frames, s + chunk)) for s in range(0, n_frames, chunk)]


def find_candidates(f: FrameFeatures, threshold: float, state_cls: np.ndarray, compatible: np.ndarray,
                    row_ok: np.ndarray, col_ok: np.ndarray, band: int, chunk_bytes: int = 256 << 20,
                    progress=None, map_blocks=None) -> Candidates:
    """Row-wise local minima of D below ``threshold``.

    state_cls: (N,) state class of every frame; compatible: (S, S) bool, which classes may
    match (rows x cols);
    row_ok/col_ok: (N,) frames allowed as hubs / as occurrences;
    band: frames of the same take closer than this never match (trivial neighbours).
    map_blocks: ``map_blocks(candidate_block, blocks, f, threshold, ...)`` yields the results
    of ``candidate_block(f, s, e, threshold, ...)`` for every ``(s, e)`` of ``blocks``, in order
    (for example on the workers of a cluster); default: one after another in this process.
    The blocks are the same either way, so the result is too.
    """
    N = len(f.sq)
    blocks = candidate_rows(N, chunk_bytes)
    args = (threshold, state_cls, compatible, row_ok, col_ok, band)
    if map_blocks is None:
        results = (candidate_block(f, s, e, *args) for s, e in blocks)
    else:
        results = map_blocks(candidate_block, blocks, f, *args)
    indptr = np.zeros(N + 1, dtype=np.int64)
    cols_l, dist_l = [], []
    for (s, e), (counts, c, d) in zip(blocks, results):
        indptr[s + 1:e + 1] = counts
        cols_l.append(c)
        dist_l.append(d)
        if progress is not None:
            progress(e - s)
    indptr = np.cumsum(indptr)
    return Candidates(indptr, np.concatenate(cols_l) if cols_l else np.zeros(0, np.int64),
                      np.concatenate(dist_l) if dist_l else np.zeros(0), N * N)


def _thin(cols: np.ndarray, dist: np.ndarray, min_gap: int, take: np.ndarray):
    """Keep the best matches at least ``min_gap`` frames apart (non-maximum suppression)."""
    order = np.argsort(dist, kind="stable")
    kept = []
    for k in order:
        c = cols[k]
        if all(abs(c - q) >= min_gap or take[c] != take[q] for q in kept):
            kept.append(c)
    kept = np.array(sorted(kept), dtype=np.int64)
    return kept


def pick_hubs(f: FrameFeatures, cand: Candidates, min_gap: int, min_occurrences: int = 3,
              max_hubs: int = 40, hub_ok: np.ndarray | None = None) -> list[Hub]:
    """Greedy hub selection (see module docstring). Deterministic: ties go to the lowest frame."""
    N = len(f.sq)
    avail = np.ones(N, dtype=bool)
    hub_ok = np.ones(N, dtype=bool) if hub_ok is None else hub_ok
    row_of = np.repeat(np.arange(N), np.diff(cand.indptr))
    hubs: list[Hub] = []
    while len(hubs) < max_hubs:
        live = avail[cand.cols] & avail[row_of]
        counts = np.bincount(row_of[live], minlength=N)
        counts[~(avail & hub_ok)] = 0
        h = int(np.argmax(counts))
        if counts[h] + 1 < min_occurrences:
            break
        sl = slice(cand.indptr[h], cand.indptr[h + 1])
        m = live[sl]
        cols = np.concatenate([[h], cand.cols[sl][m]])
        dist = np.concatenate([[0.0], cand.dist[sl][m]])
        occ = _thin(cols, dist, min_gap, f.take)
        if len(occ) < min_occurrences:
            avail[h] = False
            continue
        d = distance_rows(f, slice(h, h + 1), occ)[0][0]
        hubs.append(Hub(h, occ, d))
        for o in occ:
            lo, hi = max(0, o - min_gap + 1), min(N, o + min_gap)
            same = f.take[lo:hi] == f.take[o]
            avail[lo:hi][same] = False
    return hubs


def still_loops(f: FrameFeatures, hubs: list[Hub], still_runs, root: np.ndarray, threshold: float,
                min_gap: int, fps: float, eps: tuple, stand_hub: np.ndarray) -> int:
    """Idle self-loops that stand still: in every run of standing frames (``still_runs``:
    global [start, end) frame ranges, one take each), the two frames ``min_gap`` or more apart
    that both match a standing hub (``stand_hub`` per hub) within ``threshold`` and between
    which the root drifts least -- if that drift is within ``eps`` (m/s, deg/s) -- become the
    hub's occurrences there, replacing any occurrence between or near them. The edge cut
    between them is then an idle clip a character can repeat to wait on the spot
    (``runtime.crowd.idle``). ``root`` (N, 3): per frame x, z, heading (rad) in its take's
    frame. Edits ``hubs`` in place; returns the number of loops made."""
    made = 0
    cand_hubs = [k for k, h in enumerate(hubs) if stand_hub[k]]
    if not cand_hubs:
        return 0
    hub_frames = np.array([hubs[k].frame for k in cand_hubs])
    for a, b in still_runs:
        idx = np.arange(a, b)
        idx = idx[f.valid[idx]]
        if len(idx) < 2 or idx[-1] - idx[0] < min_gap:
            continue
        D = distance_rows(f, hub_frames, idx, with_angle=False)[0]          # (H, n)
        i, j = np.triu_indices(len(idx), 1)
        keep = idx[j] - idx[i] >= min_gap
        i, j = i[keep], j[keep]
        dt = (idx[j] - idx[i]) / fps
        dp = np.hypot(*(root[idx[j], :2] - root[idx[i], :2]).T) / dt
        dh = np.degrees(np.abs(root[idx[j], 2] - root[idx[i], 2])) / dt
        rate = np.maximum(dp / eps[0], dh / eps[1])
        best = None
        for r, k in enumerate(cand_hubs):
            ok = (D[r, i] < threshold) & (D[r, j] < threshold)
            if ok.any():
                m = int(np.argmin(np.where(ok, rate, np.inf)))
                if best is None or rate[m] < best[0]:
                    best = (float(rate[m]), k, int(idx[i[m]]), int(idx[j[m]]), float(D[r, i[m]]), float(D[r, j[m]]))
        if best is None or best[0] > 1.0:
            continue
        _, k, fi, fj, di, dj = best
        take = f.take[fi]
        for h in hubs:                       # nothing between the two frames, nor too close to them
            near = (f.take[h.occurrences] == take) & (h.occurrences > fi - min_gap) & (h.occurrences < fj + min_gap)
            h.occurrences, h.distances = h.occurrences[~near], h.distances[~near]
        h = hubs[k]
        occ = np.concatenate([h.occurrences, [fi, fj]])
        dist = np.concatenate([h.distances, [di, dj]])
        order = np.argsort(occ, kind="stable")
        h.occurrences, h.distances = occ[order], dist[order]
        made += 1
    return made
