"""Precomputed arrays over a motion graph that every segment query needs (Sung, Kovar and
Gleicher 2005, section 3): forward and time-reversed edge displacements, collision samples per
edge, parallel-edge alternatives with their replacement probabilities (section 3.3), the seeds'
two-edge lookahead tables (section 3.2) and the quickest change of state between node sets."""
from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from ...motion.graph import MotionGraph
from ...motion.planar import compose, wrap_angle
from .params import SearchParams

__all__ = ["MotionLibrary"]


class MotionLibrary:
    """Precomputed arrays over a :class:`MotionGraph` that the planner needs every query:
    forward and reversed adjacency, collision samples per edge, parallel-edge alternatives
    with their replacement probabilities."""

    def __init__(self, graph: MotionGraph, params: SearchParams | None = None):
        self.g = g = graph
        self.params = params or SearchParams()
        E, N = g.num_edges, g.num_nodes
        self.disp = g.edge_disp.copy()
        self.disp_rev = np.stack([
            -(np.cos(-self.disp[:, 2]) * self.disp[:, 0] + np.sin(-self.disp[:, 2]) * self.disp[:, 1]),
            -(-np.sin(-self.disp[:, 2]) * self.disp[:, 0] + np.cos(-self.disp[:, 2]) * self.disp[:, 1]),
            -self.disp[:, 2]], axis=1)
        self.dur = g.edge_duration.copy()
        self.nframes = g.edge_frames.copy()
        # collision samples: every ``step`` frames and the last, as CSR over edges
        step = self.params.sample_step
        ptr = [0]
        idx = []
        for e in range(E):
            a, b = g.edge_start[e], g.edge_start[e + 1]
            s = np.arange(a, b, step)
            if s[-1] != b - 1:
                s = np.append(s, b - 1)
            idx.append(s)
            ptr.append(ptr[-1] + len(s))
        self.samp_ptr = np.array(ptr)
        self.samp_frame = np.concatenate(idx)
        self.samp_edge = np.repeat(np.arange(E), np.diff(self.samp_ptr))
        self.samp_off = self.samp_frame - g.edge_start[self.samp_edge]
        # per clip: how far its collision samples reach from its start, cylinder included (a clip
        # that starts farther than that from every obstacle clears them all)
        reach = (np.hypot(g.frame_cxz[self.samp_frame, 0], g.frame_cxz[self.samp_frame, 1])
                 + g.frame_radius[self.samp_frame].astype(np.float64))
        self.samp_reach = np.zeros(E)
        np.maximum.at(self.samp_reach, self.samp_edge, reach)
        # alternatives: parallel edges weighted by 1 / distance (Sung, Kovar and Gleicher 2005, section 3.3)
        a1, a2 = self.params.alpha
        aptr, aidx, acum = [0], [], []
        for e in range(E):
            par = g.parallel_edges(e)
            par = par[par != e]
            if len(par):
                d = (np.hypot(*(self.disp[par, :2] - self.disp[e, :2]).T)
                     + a1 * np.abs(self.disp[par, 2] - self.disp[e, 2]) + a2 * np.abs(self.dur[par] - self.dur[e]))
                w = 1.0 / (d + 1e-3)
                c = np.cumsum(w) / w.sum()
                c[-1] = 1.0
                aidx.append(par)
                acum.append(c + e)        # offset by the group id for one global searchsorted
            aptr.append(aptr[-1] + len(par))
        self.alt_ptr = np.array(aptr)
        self.alt_idx = np.concatenate(aidx) if aidx else np.zeros(0, np.int64)
        self.alt_cum = np.concatenate(acum) if acum else np.zeros(0)
        self.has_alt = np.diff(self.alt_ptr) > 0
        # adjacency for fewest-edge paths
        self.adj = csr_matrix((np.ones(E), (g.edge_src, g.edge_dst)), shape=(N, N))
        self.max_radius = float(g.frame_radius.max()) if len(g.frame_radius) else 0.5
        self.max_reach = float(g.frame_reach.max()) if len(g.frame_reach) else 0.5    # about the root
        self._lookahead = {}
        self._endings = {}

    def lookahead(self, reverse: bool, travel: int):
        """Per node: its out-edges inside the travel state and, for each, every two-edge
        continuation as one composed displacement, padded to a dense table
        ``(out (d1,), comb (d1, d2, 3) NaN-padded, dur2 (d1, d2) inf-padded, disp[out], dur[out])``.
        Built once per (direction, state) and cached: the greedy seed planner's lookahead is
        then two vectorized compositions per step (one compiled loop with numba)."""
        key = (bool(reverse), int(travel))
        if key in self._lookahead:
            return self._lookahead[key]
        g = self.g
        src, dst = (g.edge_src, g.edge_dst) if not reverse else (g.edge_dst, g.edge_src)
        disp = self.disp if not reverse else self.disp_rev
        m = np.flatnonzero(g.edge_state == travel)
        o = m[np.argsort(src[m], kind="stable")]
        optr = np.searchsorted(src[o], np.arange(g.num_nodes + 1))
        # the second level only needs representative continuations: at most ``width`` edges
        # per node, evenly spread over the range of heading change (then distance)
        width = self.params.lookahead_width
        reps = []
        for n in range(g.num_nodes):
            e2 = o[optr[n]:optr[n + 1]]
            if len(e2) > width:
                srt = e2[np.lexsort((np.hypot(disp[e2, 0], disp[e2, 1]), disp[e2, 2]))]
                e2 = srt[np.unique(np.round(np.linspace(0, len(srt) - 1, width)).astype(int))]
            reps.append(e2)
        table = []
        for n in range(g.num_nodes):
            out = o[optr[n]:optr[n + 1]]
            d2 = int(max((len(reps[dst[e]]) for e in out), default=0))
            comb = np.full((len(out), max(d2, 1), 3), np.nan)
            dur2 = np.full((len(out), max(d2, 1)), np.inf)
            for k, e in enumerate(out):
                e2 = reps[dst[e]]
                if len(e2):
                    comb[k, :len(e2)] = compose(disp[e][None], disp[e2])
                    dur2[k, :len(e2)] = self.dur[e2]
            table.append((out, comb, dur2, np.ascontiguousarray(disp[out]), np.ascontiguousarray(self.dur[out])))
        self._lookahead[key] = table
        return table

    def endings(self, goal_node: int, travel: int, clips: int = 2, limit: int = 256) -> dict:
        """Clip sequences of the ``travel`` state that end in ``goal_node``, per first node (the
        short-move search's endings, :mod:`.short`; computed once per goal node).

        Returns {node: (edges (K, clips) padded -1 at the end, transform (K, 3), duration (K,))}
        with the empty ending at ``goal_node`` itself; distinct transforms only (5 cm, 5 deg:
        of two sequences from the same node with the same transform only the one with fewer
        clips is kept, and only it is extended), at most ``limit`` per node."""
        key = (int(goal_node), int(travel), int(clips), int(limit))
        if key in self._endings:
            return self._endings[key]
        g = self.g
        tr_edges = np.flatnonzero(g.edge_state == travel)
        by_dst = tr_edges[np.argsort(g.edge_dst[tr_edges], kind="stable")]
        ptr = np.searchsorted(g.edge_dst[by_dst], np.arange(g.num_nodes + 1))
        seq = -np.ones((1, clips), dtype=np.int64)           # level 0: the empty ending
        first = np.array([int(goal_node)])
        tr = np.zeros((1, 3))
        dur = np.zeros(1)
        levels = [(seq, first, tr, dur)]
        seen = np.zeros(0, dtype=np.int64)

        def distinct(first, tr):
            nonlocal seen
            # one int64 per (first node, x, z, heading) cell: 5 cm and 5 deg cells
            q = (((first.astype(np.int64) * 65536 + (np.rint(tr[:, 0] / 0.05).astype(np.int64) + 32768)) * 65536
                  + (np.rint(tr[:, 1] / 0.05).astype(np.int64) + 32768)) * 128
                 + np.rint(wrap_angle(tr[:, 2]) / np.radians(5)).astype(np.int64) + 64)
            _, idx = np.unique(q, return_index=True)
            idx = np.sort(idx)
            idx = idx[~np.isin(q[idx], seen)]
            seen = np.concatenate([seen, q[idx]])
            return idx

        distinct(first, tr)
        for _ in range(clips):
            cnt = ptr[first + 1] - ptr[first]
            if cnt.sum() == 0:
                break
            parent = np.repeat(np.arange(len(first)), cnt)
            off = np.repeat(ptr[first] - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt)
            e = by_dst[off + np.arange(int(cnt.sum()))]
            seq = np.concatenate([e[:, None], seq[parent, :clips - 1]], axis=1)
            tr = compose(self.disp[e], tr[parent])
            dur = self.dur[e] + dur[parent]
            first = g.edge_src[e]
            k = distinct(first, tr)
            seq, first, tr, dur = seq[k], first[k], tr[k], dur[k]
            levels.append((seq, first, tr, dur))
        S, N, T, D = (np.concatenate(x) for x in zip(*levels))
        out = {}
        for n in np.unique(N):
            m = np.flatnonzero(N == n)[:limit]
            out[int(n)] = (S[m], T[m], D[m])
        self._endings[key] = out
        return out

    def change_time(self, from_nodes, to_nodes) -> float:
        """Seconds of the quickest motion from any of ``from_nodes`` to any of ``to_nodes``
        (0 when they share a node; inf when unreachable): what a change of state costs, e.g.
        sitting down or picking up a box from the walking subgraph."""
        a = np.unique(np.asarray(from_nodes, dtype=np.int64))
        b = np.unique(np.asarray(to_nodes, dtype=np.int64))
        key = ("change", a.tobytes(), b.tobytes())
        if key not in self._lookahead:
            g = self.g
            w = np.full((g.num_nodes, g.num_nodes), np.inf)
            np.minimum.at(w, (g.edge_src, g.edge_dst), self.dur)     # the quickest of parallel clips
            w[~np.isfinite(w)] = 0.0                                    # dense input: 0 = no edge
            d = shortest_path(w, method="D", directed=True, indices=a)
            self._lookahead[key] = float(np.min(np.atleast_2d(d)[:, b])) if len(a) and len(b) else 0.0
        return self._lookahead[key]

    def sample_alternatives(self, edges: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Replacement clips for ``edges`` (all must have alternatives), u ~ U[0, 1)."""
        k = np.searchsorted(self.alt_cum, edges + u, side="right")
        k = np.clip(k, self.alt_ptr[edges], self.alt_ptr[edges + 1] - 1)
        return self.alt_idx[k]

    def state_edges(self, state: int) -> np.ndarray:
        return self.g.edge_state == state
