"""Build a data-driven group graph from a recorded flock (Lai, Chenney and Fan 2005, section 4.3).

1. *Candidate configurations* every ``candidate_stride`` frames of the recording.
2. *Difference matrix* ``D[k, l] = E(c_k, c_l)`` (:mod:`runtime.flock.metric`, velocity weight
   0.5 s) over pairs at least ``min_gap_seconds`` apart: nearby frames are trivially alike, and
   a jump of only a few seconds back makes a loop that replays the same short clip forever (a
   straight "treadmill" that region walks cannot steer out of).
3. *Transitions* at its *local minima* (``D[k, l] <= D`` of all 8 neighbours), lowest first,
   ``transitions_per_minute`` of recording, never above ``max_rms`` (E <= max_rms^2). A minimum
   is taken greedily only if its frames keep every segment at least ``min_segment_seconds``
   long (or reuse existing cuts), and, per direction, only if a Hermite blend of at most that
   length keeps every agent's step within ``1 + step_tolerance`` times the recorder's largest
   per-step displacement (shortest such blend).
4. *Graph*: the chosen frames are nodes, the recording between consecutive nodes gives
   continuation edges, each transition direction an edge into the segment after its target;
   dead ends are trimmed by keeping the largest strongly connected component
   (``scipy.sparse.csgraph``), as Kovar et al. do. Segments are stored once, as float32.

Pruning (exact). ``E`` costs a few Hungarian solves per pair, so only pairs whose cheap lower
bound (``metric.lower_bound_matrix``: sorted radial/height/velocity profiles, never above ``E``)
is at most a threshold ``tau`` get the exact metric. Every pair with ``D <= tau`` has bound
``<= tau`` and is therefore evaluated, and any neighbour that could undercut it has
``D < tau`` too, so the local minima with ``D <= tau`` are exactly the brute-force ones. ``tau``
grows (doubling the evaluated set) until the greedy choice has its quota or ``tau`` reaches
the cap, so the chosen transitions are exactly those of the brute-force build
(``use_bound=False``); ``tests/test_flock_build.py`` checks this on small cases. How much the
bound saves depends on the data: a 20-agent flock keeps a fairly uniform density, so its radial
profiles vary little and the bound is weak (see ``bench/ddg.py`` for the measured fraction).
Exact evaluations are batched (and optionally spread over ``workers`` processes); each pair's
value does not depend on its batch, so every setting gives the same bytes.
"""
from __future__ import annotations

import bisect
import time
from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from runtime.flock.coords import invert_transform, yaw_rotate
from runtime.flock.ddg import DDG, hermite_weights
from runtime.flock.metric import bound_features, lower_bound_matrix, match_batch

__all__ = ["DDGBuildParams", "BuildStats", "Transition", "find_transitions", "build_ddg", "blend_offsets"]


@dataclass(frozen=True)
class DDGBuildParams:
    """Parameters of :func:`build_ddg` (frames, seconds, metres)."""

    candidate_stride: int = 15             # frames between candidate configurations (2 Hz at 30 fps)
    min_gap_seconds: float = 10.0          # a transition jumps at least this far in the recording
                                           # (no short loops that replay a few seconds forever)
    transitions_per_minute: float = 30.0   # local minima taken per minute of recording
    max_rms: float | None = None           # never join configurations further apart (sqrt E, metres);
                                           # None: 0.6 m in 2D, 0.9 m in 3D (3D groups recur less closely)
    velocity_weight: float = 0.5           # seconds; see runtime.flock.metric
    min_segment_seconds: float = 1.0       # shortest segment; also the longest blend
    blend_min_frames: int = 8
    step_tolerance: float = 0.1            # blended steps stay within (1 + tol) * recorder's max step
    use_bound: bool = True                 # False: brute force (every pair gets the exact metric)
    batch: int = 2048                      # pairs per vectorized metric batch
    workers: int = 1                       # processes for the exact metric (results do not depend on it)
    first_round_cells: int = 20000         # exact evaluations in the first pruning round

    def __post_init__(self):
        if self.candidate_stride < 1:
            raise ValueError("candidate_stride must be >= 1")
        if self.min_gap_seconds < self.min_segment_seconds:
            raise ValueError("min_gap_seconds must be at least min_segment_seconds")
        if (self.max_rms is not None and self.max_rms <= 0) or self.transitions_per_minute <= 0:
            raise ValueError("max_rms and transitions_per_minute must be positive")




@dataclass
class Transition:
    """One direction of a chosen local minimum: jump from recording frame ``src`` to ``dst``."""

    src: int
    dst: int
    cost: float
    yaw: float
    translation: np.ndarray
    perm: np.ndarray
    blend: int
    d0: np.ndarray
    d1: np.ndarray


@dataclass
class BuildStats:
    candidates: int = 0
    pairs: int = 0                   # cells of the difference matrix in the domain
    exact_evaluations: int = 0
    rounds: int = 0
    tau: float = 0.0
    local_minima: int = 0            # local minima at or below the final tau
    target_pairs: int = 0
    accepted_pairs: int = 0
    rejected_spacing: int = 0
    rejected_blend: int = 0
    directions: int = 0
    nodes: int = 0
    edges: int = 0
    transitions: int = 0
    nodes_trimmed: int = 0
    seconds_bound: float = 0.0
    seconds_exact: float = 0.0
    seconds_select: float = 0.0
    seconds_graph: float = 0.0
    seconds_total: float = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def skipped_fraction(self) -> float:
        return 1.0 - self.exact_evaluations / max(self.pairs, 1)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["skipped_fraction"] = self.skipped_fraction
        return d


def default_max_rms(dim: int, params: DDGBuildParams) -> float:
    if params.max_rms is not None:
        return float(params.max_rms)
    return 0.6 if dim == 2 else 0.9


class _NullBar:
    def update(self, n=1):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *a):
        return False


def _null_progress(desc, total):
    return _NullBar()


def blend_offsets(a_pos, a_vel, b_pos, b_vel, yaw, trans, perm, fps):
    """Hermite blend endpoints for a jump from configuration A into B (Lai, Chenney and Fan
    2005, section 4.3, "blended").

    ``(yaw, trans)`` is ``X_{A<-B}``, ``perm`` is ``M_{B<-A}``. Returns ``d0, d1`` (N, D) indexed by
    B's slots, in B's coordinates: the position gap and the per-frame velocity gap.
    """
    inv = np.argsort(perm)                      # inv[b] = slot of A that continues as b
    iyaw, itrans = invert_transform(yaw, trans)
    a_in_b = yaw_rotate(a_pos, iyaw) + itrans
    va_in_b = yaw_rotate(a_vel, iyaw)
    d0 = a_in_b[inv] - b_pos
    d1 = (va_in_b[inv] - b_vel) / fps
    return d0, d1


def _feasible_blend(rec_pos, g, d0, d1, k_min, k_max, limit):
    """Shortest blend length K in [k_min, k_max] whose steps all stay within ``limit``."""
    for K in range(k_min, k_max + 1):
        s = np.arange(K + 2)
        h00, h10 = hermite_weights(s, K)
        p = rec_pos[g:g + K + 2] + h00[:, None, None] * d0 + h10[:, None, None] * d1
        st = np.diff(p, axis=0)
        if np.sqrt((st * st).sum(-1)).max() <= limit:
            return K
    return None


def _lb_float32(lb64: np.ndarray) -> np.ndarray:
    """Round a lower bound down to float32 (so it stays a lower bound)."""
    lb = lb64.astype(np.float32)
    up = lb.astype(np.float64) > lb64
    lb[up] = np.nextafter(lb[up], np.float32(-np.inf))
    return lb


_WORKER: dict = {}


def _init_worker(CP, CV, w):
    _WORKER.update(CP=CP, CV=CV, w=w)


def _worker_batch(kl):
    k, l = kl
    CP, CV = _WORKER["CP"], _WORKER["CV"]
    return match_batch(CP[k], CV[k], CP[l], CV[l], _WORKER["w"])[0]


def find_transitions(positions, velocities, fps, params: DDGBuildParams, progress=None,
                     max_step: float | None = None):
    """Candidate frames, difference matrix (pruned or brute force), chosen transitions.

    Returns ``(transitions, info)``: ``transitions`` a list of :class:`Transition` (both
    directions of each accepted minimum, when feasible), ``info`` a dict with ``stats``
    (:class:`BuildStats`), ``frames`` (candidate frames), ``values`` (M, M) exact distances
    (NaN where not evaluated), ``lower_bound`` (M, M) float32 and ``chosen`` (accepted cells).
    """
    progress = progress or _null_progress
    t_start = time.perf_counter()
    X = np.asarray(positions, dtype=np.float64)
    Vv = np.asarray(velocities, dtype=np.float64)
    F, N, D = X.shape
    stats = BuildStats()
    seg_min = int(round(params.min_segment_seconds * fps))
    k_max = seg_min
    k_min = min(params.blend_min_frames, k_max)
    last = F - 2 - seg_min
    if last < 0:
        raise ValueError(f"recording of {F} frames is too short for {params.min_segment_seconds} s segments")
    frames = np.arange(0, last + 1, params.candidate_stride)
    M = len(frames)
    gap = int(np.ceil(params.min_gap_seconds * fps / params.candidate_stride))
    stats.candidates = M
    if max_step is None:
        st = np.diff(X, axis=0)
        max_step = float(np.sqrt((st * st).sum(-1)).max())
    limit = max_step * (1.0 + 0.98 * params.step_tolerance)
    cap = default_max_rms(D, params) ** 2
    w = params.velocity_weight
    minutes = (F - 1) / fps / 60.0
    n_target = max(1, int(round(params.transitions_per_minute * minutes)))
    stats.target_pairs = n_target
    CP, CV = X[frames], Vv[frames]

    # ---- cheap lower bound for every cell of the domain (l - k >= gap), row blocks
    t0 = time.perf_counter()
    feats = bound_features(CP, CV, w)
    lb = np.full((M, M), np.inf, dtype=np.float32)
    block = max(1, 2_000_000 // max(M, 1))
    for r0 in range(0, M, block):
        r1 = min(M, r0 + block)
        sub = lower_bound_matrix({"pos": [f[r0:r1] for f in feats["pos"]],
                                  "vel": [f[r0:r1] for f in feats["vel"]],
                                  "mean": None if feats["mean"] is None else feats["mean"][r0:r1]},
                                 feats, N)
        lb[r0:r1] = _lb_float32(sub)
    kk, ll = np.indices((M, M), sparse=True)
    domain = (ll - kk) >= gap
    lb[~domain] = np.inf
    stats.pairs = int(domain.sum())
    stats.seconds_bound = time.perf_counter() - t0

    values = np.full((M, M), np.nan)
    evaluated = np.zeros((M, M), dtype=bool)
    cache: dict = {}

    def evaluate(mask):
        ks, ls = np.nonzero(mask)
        if ks.size == 0:
            return
        t1 = time.perf_counter()
        chunks = [(ks[b0:b0 + params.batch], ls[b0:b0 + params.batch]) for b0 in range(0, ks.size, params.batch)]
        with progress("difference matrix", int(ks.size)) as bar:
            if params.workers > 1 and len(chunks) > 1:
                import multiprocessing as mp
                from concurrent.futures import ProcessPoolExecutor
                with ProcessPoolExecutor(params.workers, mp_context=mp.get_context("fork"),
                                         initializer=_init_worker, initargs=(CP, CV, w)) as ex:
                    for (k, l), d in zip(chunks, ex.map(_worker_batch, chunks)):
                        values[k, l] = d
                        bar.update(int(k.size))
            else:
                for k, l in chunks:
                    values[k, l] = match_batch(CP[k], CV[k], CP[l], CV[l], w)[0]
                    bar.update(int(k.size))
        evaluated[ks, ls] = True
        stats.exact_evaluations += int(ks.size)
        stats.seconds_exact += time.perf_counter() - t1

    def local_minima(tau):
        v = np.where(evaluated, values, np.inf)
        pad = np.pad(v, 1, constant_values=np.inf)
        nb = np.full((M, M), np.inf)
        for dk in (-1, 0, 1):
            for dl in (-1, 0, 1):
                if dk or dl:
                    nb = np.minimum(nb, pad[1 + dk:1 + dk + M, 1 + dl:1 + dl + M])
        cand = evaluated & (v <= tau) & (v <= nb)
        ks, ls = np.nonzero(cand)
        order = np.lexsort((ls, ks, v[ks, ls]))
        return ks[order], ls[order]

    def select(ks, ls):
        t1 = time.perf_counter()
        cuts: list[int] = []
        cutset: set[int] = set()
        chosen, trans = [], []
        rej_sp = rej_bl = 0

        def spaced(f):
            if f in cutset:
                return True
            i = bisect.bisect_left(cuts, f)
            if i > 0 and f - cuts[i - 1] < seg_min:
                return False
            if i < len(cuts) and cuts[i] - f < seg_min:
                return False
            return True

        for k, l in zip(ks.tolist(), ls.tolist()):
            if len(chosen) >= n_target:
                break
            fa, fb = int(frames[k]), int(frames[l])
            if not (spaced(fa) and spaced(fb)):
                rej_sp += 1
                continue
            if (k, l) not in cache:      # same numbers as the batch: pairs are independent
                _, p_, y_, t_, _ = match_batch(CP[k:k + 1], CV[k:k + 1], CP[l:l + 1], CV[l:l + 1], w)
                cache[(k, l)] = (p_[0], float(y_[0]), t_[0])
            perm, yaw, tr = cache[(k, l)]
            found = []
            # forward: arrive at fa (clip A), continue as the segment from fb (clip B)
            d0, d1 = blend_offsets(X[fa], Vv[fa], X[fb], Vv[fb], yaw, tr, perm, fps)
            K = _feasible_blend(X, fb, d0, d1, k_min, k_max, limit)
            if K is not None:
                found.append(Transition(fa, fb, float(values[k, l]), float(yaw), np.array(tr),
                                        np.array(perm), K, d0, d1))
            # backward: arrive at fb, continue from fa, with the inverse transform/correspondence
            iyaw, itr = invert_transform(yaw, tr)
            iperm = np.argsort(perm)
            d0, d1 = blend_offsets(X[fb], Vv[fb], X[fa], Vv[fa], iyaw, itr, iperm, fps)
            K = _feasible_blend(X, fa, d0, d1, k_min, k_max, limit)
            if K is not None:
                found.append(Transition(fb, fa, float(values[k, l]), float(iyaw), np.array(itr),
                                        iperm, K, d0, d1))
            if not found:
                rej_bl += 1
                continue
            chosen.append((k, l))
            trans.extend(found)
            for f in (fa, fb):
                if f not in cutset:
                    cutset.add(f)
                    bisect.insort(cuts, f)
        stats.seconds_select += time.perf_counter() - t1
        return chosen, trans, rej_sp, rej_bl

    if params.use_bound:
        dom_lb = np.sort(lb[domain & (lb <= cap)])
        count = max(params.first_round_cells, 20 * n_target)
        while True:
            stats.rounds += 1
            if count >= dom_lb.size:
                tau = cap
            else:
                tau = float(dom_lb[count - 1])
            evaluate(domain & (lb <= tau) & ~evaluated)
            ks, ls = local_minima(min(tau, cap))
            chosen, trans, rej_sp, rej_bl = select(ks, ls)
            if len(chosen) >= n_target or tau >= cap:
                break
            count *= 2
    else:
        stats.rounds = 1
        tau = cap
        evaluate(domain)
        ks, ls = local_minima(cap)
        chosen, trans, rej_sp, rej_bl = select(ks, ls)
    stats.tau = float(tau)
    stats.local_minima = int(ks.size)
    stats.accepted_pairs = len(chosen)
    stats.rejected_spacing = rej_sp
    stats.rejected_blend = rej_bl
    stats.directions = len(trans)
    stats.seconds_total = time.perf_counter() - t_start
    info = {"stats": stats, "frames": frames, "values": values, "lower_bound": lb, "chosen": chosen,
            "max_step": max_step}
    return trans, info


def build_graph(positions, fps, transitions: list, max_step: float, dim: int, meta=None):
    """Nodes, segments and edges from chosen transitions; dead ends trimmed (largest SCC)."""
    X = np.asarray(positions, dtype=np.float64)
    F, N, D = X.shape
    cuts = sorted({t.src for t in transitions} | {t.dst for t in transitions})
    if len(cuts) < 2:
        raise ValueError("no usable transitions: the graph would be empty (record longer or relax the limits)")
    node_of = {f: i for i, f in enumerate(cuts)}
    V = len(cuts)
    src, dst, seg, yaw, trn, perm, blend, d0, d1, cost = [], [], [], [], [], [], [], [], [], []
    ident = np.arange(N)
    zero = np.zeros((N, D))
    for i in range(V - 1):                      # continuations: segment i runs cuts[i] -> cuts[i+1]
        src.append(i); dst.append(i + 1); seg.append(i); yaw.append(0.0); trn.append(np.zeros(D))
        perm.append(ident); blend.append(0); d0.append(zero); d1.append(zero); cost.append(0.0)
    for t in transitions:
        j = node_of[t.dst]
        if j == V - 1:
            continue                            # nothing recorded after the last cut
        src.append(node_of[t.src]); dst.append(j + 1); seg.append(j); yaw.append(t.yaw)
        trn.append(t.translation); perm.append(t.perm); blend.append(t.blend)
        d0.append(t.d0); d1.append(t.d1); cost.append(t.cost)
    src, dst = np.array(src), np.array(dst)
    adj = csr_matrix((np.ones(len(src)), (src, dst)), shape=(V, V))
    n_comp, label = connected_components(adj, directed=True, connection="strong")
    big = int(np.argmax(np.bincount(label)))
    keep_node = label == big
    keep = keep_node[src] & keep_node[dst]
    if keep_node.sum() < 2 or not keep.any():
        raise ValueError("the transitions do not form a cycle: no strongly connected graph")
    new_node = np.cumsum(keep_node) - 1
    seg = np.array(seg)
    used = np.unique(seg[keep])
    new_seg = {int(s): i for i, s in enumerate(used)}
    seg_len = np.array([cuts[s + 1] - cuts[s] for s in used], dtype=np.int64)
    seg_start = np.zeros(len(used), dtype=np.int64)
    seg_start[1:] = np.cumsum(seg_len + 1)[:-1]
    frames = np.concatenate([X[cuts[s]:cuts[s + 1] + 1] for s in used]).astype(np.float32)
    idx = np.nonzero(keep)[0]
    g = DDG(
        dim=dim, fps=fps, max_step=max_step, frames=frames, seg_start=seg_start, seg_len=seg_len,
        seg_frame=np.array([cuts[s] for s in used]), node_frame=np.array(cuts)[keep_node],
        edge_src=new_node[src[idx]], edge_dst=new_node[dst[idx]],
        edge_seg=np.array([new_seg[int(seg[i])] for i in idx]),
        edge_yaw=np.array([yaw[i] for i in idx]), edge_trans=np.array([trn[i] for i in idx]).reshape(-1, D),
        edge_perm=np.array([perm[i] for i in idx]), edge_blend=np.array([blend[i] for i in idx]),
        edge_d0=np.array([d0[i] for i in idx]), edge_d1=np.array([d1[i] for i in idx]),
        edge_cost=np.array([cost[i] for i in idx]), meta=dict(meta or {}),
    )
    g.validate()
    return g, {"nodes_before_trim": V, "edges_before_trim": len(src)}


def build_ddg(recording, params: DDGBuildParams = DDGBuildParams(), progress=None):
    """Record -> DDG. ``recording`` is an :class:`authoring.boids.Recording` (or anything with
    ``positions``, ``velocities``, ``fps``, ``dim``, ``max_step``). Returns ``(ddg, stats)``."""
    t0 = time.perf_counter()
    max_step = float(recording.max_step)
    trans, info = find_transitions(recording.positions, recording.velocities, recording.fps, params,
                                   progress, max_step=max_step)
    stats: BuildStats = info["stats"]
    t1 = time.perf_counter()
    # only what determines the graph goes into the pack (no timings: same inputs, same bytes)
    meta = {"build_params": {k: v for k, v in asdict(params).items() if k not in ("workers", "batch")}}
    if hasattr(recording, "params_dict"):
        meta["recorder"] = recording.params_dict()
        meta["recorder_seed"] = int(recording.seed)
        meta["recorder_seconds"] = float(recording.virtual_seconds)
    ddg, ginfo = build_graph(recording.positions, recording.fps, trans, max_step, recording.dim, meta)
    stats.seconds_graph = time.perf_counter() - t1
    stats.nodes = ddg.n_nodes
    stats.edges = ddg.n_edges
    stats.transitions = ddg.n_transitions
    stats.nodes_trimmed = ginfo["nodes_before_trim"] - ddg.n_nodes
    stats.seconds_total = time.perf_counter() - t0
    ddg.meta["build_stats"] = {k: v for k, v in stats.to_dict().items()
                               if k != "extra" and not k.startswith("seconds")}
    return ddg, stats
