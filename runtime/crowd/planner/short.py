"""Short moves: a breadth-limited search over clip sequences, met by short endings.

For a goal a few metres away the greedy seeds of section 3.2 (Sung, Kovar and Gleicher 2005)
are a poor start: they head for the goal, overshoot, and the randomized search must then undo
a turn it cannot see (a goal behind the character, a heading to face on arrival). Here the
motion is built from both ends instead:

* *endings*: every sequence of at most ``ENDING_CLIPS`` clips of the travel state that ends in
  the goal node, as a rigid planar transform from its first node (distinct ones only);
* *beginnings*: sequences of clips from the start node, breadth first, up to ``SHORT_DEPTH``
  clips; at each depth the ``SHORT_BEAM`` whose best ending lands nearest the goal are kept.

Each beginning joined with each ending of its last node is a motion that ends in the goal
node; its splice cost (Eq. 1: position and orientation mismatch, and the window's, over the
duration) is arithmetic over the two transforms. The joined motions below eps are spliced and
tested exactly as the randomized search's (:meth:`.search.RandomizedSearch.accept`), the
shallowest depth first, so the motion found has few clips.

Limits: per depth, ``SHORT_BEAM`` x (out-degree) beginnings x (endings of a node, at most
``MAX_ENDINGS``) joins are costed (64 x 126 x 256, about two million, on the default library;
at most ``JOINS_PER_STEP`` per planner step);
the search runs when the goal is within ``SHORT_DISTANCE`` of the start.
"""
from __future__ import annotations

import numpy as np

from ...motion.planar import compose
from .types import Step

__all__ = ["short_move", "SHORT_DISTANCE", "SHORT_DEPTH", "SHORT_BEAM", "ENDING_CLIPS", "MAX_ENDINGS",
           "JOINS_PER_STEP"]

SHORT_DISTANCE = 3.5   # m: goals closer than this to the start are tried with the short search first
SHORT_DEPTH = 12       # clips in the beginning at most
SHORT_BEAM = 64        # beginnings kept per depth
ENDING_CLIPS = 3       # clips in an ending at most
MAX_ENDINGS = 256      # endings kept per node (the shortest of each distinct transform first)
JOINS_PER_STEP = 16384 # joins costed per planner step (about 2 ms)
REACH_SLACK = 1.5      # m: a beginning stays in the beam while its end is at most this much further
#                        from the goal than the start was


def _joined_costs(alpha, ends, dur, goal, window_rel, T, D):
    """Eq. 1 for every (beginning, ending) join: beginnings ending at ``ends`` (R, 3) after
    ``dur`` (R,) seconds, endings with transforms ``T`` (K, 3) and durations ``D`` (K,).
    Returns (cost (R, K), mismatch (R, K)). The orientation term uses the chord
    2 sin(|d theta| / 2) <= |d theta|, so both are lower bounds of the splice's (every join
    the exact cost accepts passes; the exact cost is taken again before a splice)."""
    a1, a2 = alpha
    c, s = np.cos(ends[:, 2])[:, None], np.sin(ends[:, 2])[:, None]
    tx, tz = T[None, :, 0], T[None, :, 1]
    dx = (ends[:, 0:1] - goal[0]) + c * tx + s * tz
    dz = (ends[:, 1:2] - goal[1]) - s * tx + c * tz
    rel = ends[:, 2] - goal[2]
    cr, sr = np.cos(rel)[:, None], np.sin(rel)[:, None]
    ct, st = np.cos(T[:, 2])[None], np.sin(T[:, 2])[None]
    chord = np.sqrt(np.maximum(0.0, 2.0 - 2.0 * (cr * ct - sr * st)))
    raw = np.sqrt(dx * dx + dz * dz) + a1 * chord
    n = dur[:, None] + D[None, :]
    cost = raw if window_rel is None else raw + a2 * np.maximum(0.0, np.maximum(window_rel[0] - n, n - window_rel[1]))
    return cost / np.maximum(n, 0.2), raw


def short_move(search, travel: int, max_accept: int = 6):
    """Generator (yields :class:`~.types.Step`): the short-move search on ``search``'s start and
    goal (a :class:`~.search.RandomizedSearch`, used for its costs and its final tests).
    ``travel``: the travel state. Returns the accepted
    :class:`~.types.SegmentResult` or None; ``search.iterations`` counts the depths searched."""
    lib, p = search.lib, search.p
    g = lib.g
    eps_p = p.eps[0]
    start = search.start.xzh
    goal = search.goal_cfg
    yield Step.SEARCH
    ends_of = lib.endings(search.goal_node, travel, ENDING_CLIPS, MAX_ENDINGS)
    travel_edges = g.edge_state == travel
    d0 = float(np.hypot(*(goal[:2] - start[:2])))
    out_ptr = np.concatenate([[0], np.cumsum(np.bincount(g.edge_src[travel_edges], minlength=g.num_nodes))])
    order = np.flatnonzero(travel_edges)
    order = order[np.argsort(g.edge_src[order], kind="stable")]
    rows = np.zeros((1, 0), dtype=np.int64)
    ends = start[None].copy()
    dur = np.zeros(1)
    last = np.array([int(search.start.node)])
    B = -np.ones((1, 1), dtype=np.int64)
    for depth in range(1, SHORT_DEPTH + 1):
        search.iterations += 1
        yield Step.SEARCH
        cnt = out_ptr[last + 1] - out_ptr[last]
        if cnt.sum() == 0:
            return None
        parent = np.repeat(np.arange(len(rows)), cnt)
        first = np.repeat(out_ptr[last] - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt)
        e = order[first + np.arange(int(cnt.sum()))]
        F = np.concatenate([rows[parent], e[:, None]], axis=1)
        end = compose(ends[parent], lib.disp[e])
        T = dur[parent] + lib.dur[e]
        node = g.edge_dst[e]
        best_raw = np.full(len(F), np.inf)
        found = []                                   # per node: (costs, rows, endings) below eps
        for n in np.unique(node):
            if int(n) not in ends_of:
                continue
            E, Tn, Dn = ends_of[int(n)]
            rows_n = np.flatnonzero(node == n)
            step = max(1, JOINS_PER_STEP // len(Tn))
            for c0 in range(0, len(rows_n), step):
                yield Step.COSTS
                rr = rows_n[c0:c0 + step]
                cost, raw = _joined_costs(p.alpha, end[rr], T[rr], goal, search.window_rel, Tn, Dn)
                best_raw[rr] = raw.min(axis=1)
                r_ok, k_ok = np.nonzero(cost <= eps_p)
                if len(r_ok):
                    found.append((cost[r_ok, k_ok], rr[r_ok], E[k_ok]))
        if found:
            fc, fr, fe = (np.concatenate(x) for x in zip(*found))
            best = np.argsort(fc, kind="stable")[:max_accept]
        for r, ending in ([] if not found else zip(fr[best], fe[best])):
            full = np.concatenate([F[r], ending[ending >= 0]])
            Fr = full[None]
            c, i, j = search.costs(Fr, np.array([len(full)]), B, np.zeros(1, dtype=np.int64))
            if not c[0] <= eps_p:
                continue
            yield Step.SPLICE
            res = search.accept(c[0], Fr[0], i[0], B[0], j[0])
            if res is not None:
                return res
        # the beam: beginnings still within reach, whose best ending lands nearest the goal
        dist = np.hypot(end[:, 0] - goal[0], end[:, 1] - goal[1])
        idx = np.flatnonzero(dist <= d0 + REACH_SLACK)
        if not len(idx):
            return None
        q = np.stack([node[idx], np.rint(end[idx, 0] / 0.05), np.rint(end[idx, 1] / 0.05),
                      np.rint(end[idx, 2] / np.radians(5))], axis=1)
        rank = np.lexsort((dist[idx], best_raw[idx]))
        _, uniq = np.unique(q[rank], axis=0, return_index=True)
        keep = idx[rank[np.sort(uniq)][:SHORT_BEAM]]
        rows, ends, dur, last = F[keep], end[keep], T[keep], node[keep]
    return None
