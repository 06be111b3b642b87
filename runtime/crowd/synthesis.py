"""Goal-directed motion synthesis (Sung, Kovar, Gleicher 2005 — paper 000, section 3).

One *segment* takes a character from a start configuration (node N_s, position p_s,
heading theta_s, time t_s) to a goal configuration (node N_e, p_e, theta_e) inside an
optional time window [t_a, t_b]:

1. Seeds (3.2): a greedy *forward* motion M_f from the start through the roadmap way points,
   and a greedy *backward* motion M_b (the same planner on the time-reversed graph) that ends
   exactly in the goal. Both stay inside the segment's travel state subgraph; entering or
   leaving another state (sit down, stand up, pick up, put down) uses the fewest-edge path,
   ties broken by the position/orientation error.
2. Search (3.3): the splice cost (Eq. 1)

       C(i, j) = (E_p + a1 E_theta + a2 E_t) / N(i, j)

   over every pair (prefix i of M_f, suffix j of M_b) that meets at the same node, minimised
   (Eq. 2). With the tolerance eps = (eps_p m/s, eps_theta deg/s, eps_t s/s) the units are
   a1 = eps_p / eps_theta, a2 = eps_p / eps_t, so "C' <= eps_p" is the paper's test
   (1 cm = 1 deg = 1/30 s with the default eps). While C' > eps, n_m perturbed pairs are made
   per iteration (one clip of one motion replaced by a clip between the same two nodes, drawn
   with probability inversely proportional to ``|dp - dp'| + a1 |dtheta - dtheta'| +
   a2 |dt - dt'|``), all costed at once as arrays; the k_m best are kept; after N_max
   iterations the best pair is used with a warning.
3. Splice (3.3, steps 1-4): displacement maps move the forward part by (k/N_f) lambda_1 dp
   and the backward part by -(1 - k/N_b) lambda_2 dp (and the same for heading), the parts
   are concatenated at the shared node, and the result is resampled in time to a duration
   inside the window (on the 30 Hz grid). A final collision test rejects the splice.

The planner is a generator (:meth:`SegmentPlanner.run`): every ``next()`` does a bounded
amount of work (one search iteration), so the runtime can time-slice it under a per-tick
budget.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from ..motion.graph import MotionGraph, STATES, TRANSITION
from . import search_kernels as _kernels
from .motion_cache import task_key

__all__ = ["SynthesisParams", "Config", "Goal", "SegmentResult", "MotionLibrary", "SegmentPlanner",
           "compose", "compose1", "compose_inverse", "wrap_angle"]

TWO_PI = 2.0 * np.pi


def wrap_angle(a):
    return (np.asarray(a) + np.pi) % TWO_PI - np.pi


def compose(c, d):
    """Planar rigid composition ``c o d`` of (..., 3) = (x, z, heading) arrays: d is expressed
    in c's frame (heading about +Y: Ry(h) (x, z) = (cos h x + sin h z, -sin h x + cos h z))."""
    h = c[..., 2]
    ch, sh = np.cos(h), np.sin(h)
    x = c[..., 0] + ch * d[..., 0] + sh * d[..., 1]
    out = np.empty(x.shape + (3,), dtype=np.result_type(x, h, d))
    out[..., 0] = x
    out[..., 1] = c[..., 1] - sh * d[..., 0] + ch * d[..., 1]
    out[..., 2] = h + d[..., 2]
    return out


def compose1(c, d):
    """:func:`compose` of one configuration and one displacement, each (3,), in scalar math
    (the same values: the planners chain thousands of single compositions per character, and
    a numpy call per one costs ~15 us)."""
    h = float(c[2])
    ch, sh = math.cos(h), math.sin(h)
    d0, d1 = float(d[0]), float(d[1])
    return np.array((c[0] + ch * d0 + sh * d1, c[1] - sh * d0 + ch * d1, h + d[2]))


def compose_inverse(c_end, d):
    """The configuration before an edge with displacement ``d`` that ends at ``c_end``."""
    h = c_end[..., 2] - d[..., 2]
    ch, sh = np.cos(h), np.sin(h)
    x = c_end[..., 0] - (ch * d[..., 0] + sh * d[..., 1])
    z = c_end[..., 1] - (-sh * d[..., 0] + ch * d[..., 1])
    return np.stack([x, z, h], axis=-1)


MAX_IDLE_EDGES = 400     # idle clips a seed may spend waiting (~15 min of the default library's)


@dataclass
class SynthesisParams:
    n_m: int = 200                 # perturbed pairs per iteration
    k_m: int = 30                  # pairs kept between iterations
    n_max: int = 1000              # iterations before giving up (warning, best pair used)
    retry_n_max: int = 300         # ... in the scheduler's further tries at a segment that failed (the
                                   # other start node, a later departure or arrival, repair passes):
                                   # 20 x 15 grid at 2.2 m, first 90 characters: retries that succeeded
                                   # took <= 228, first searches <= 546 (99% <= 373)
    eps: tuple = (0.02, 2.0, 1.0 / 15.0)   # per-frame adjustment tolerance: m/s, deg/s, s/s
    sample_step: int = 3           # frames between collision samples in seeds
    margin: float = 0.02           # extra clearance (m) in collision tests
    max_seed_edges: int = 80
    min_gain: float = 0.01         # metres (1 cm = 1 deg): smallest error decrease that counts
    min_gain_rate: float = 0.1     # metres per second of motion: smallest rate of decrease that counts
    approach_radius: float = 2.0   # metres from the goal where the seed starts to mind orientation
    facing_weight: float = 0.3     # metres per radian of facing away from the next way point (seeds)
    lookahead_width: int = 12      # second-level edges per node in the seeds' two-edge lookahead
    sweep: int = 100               # perturbations per iteration spent on every alternative of one clip
    sweep_pairs: int = 2000        # two-clip combinations scored per pair sweep (a random subset)
    splices_per_iteration: int = 3 # below-eps pairs spliced and collision-tested per iteration
    static_seed_margin: float = 0.0  # extra clearance (m) from obstacles in the seeds (0.08 broke rooms_box doors)
    seed_margin: float = 0.0       # extra clearance (m) from planned characters in the seeds
    reach_radius: float = 0.75     # a way point counts as reached within this distance (m)
    max_sidesteps: int = 6         # non-improving clear edges a seed may take per way point
    split_resample: bool = True    # resample the two spliced parts separately (junction on a frame)
    backward_idle: bool = False    # backward seeds may idle at the goal to spend surplus time (the World allows it)
    carrot: float = 1.5            # seeds aim this far (m) along the way-point path ahead of themselves
    carrot_final: float = 3.0      # ... until the path's end is this close (m): then at the end itself
    static_filter: float = 4.0     # pairs costing under this x eps are tested against static obstacles
                                   # before they may join the population (0: off) ...
    static_filter_slack: float = 0.1  # ... forgiving this much overlap (m)
    reseed_after: int = 20         # iterations after which a search whose splices collide makes new seeds
    retime_budget: int = 40        # colliding splices per search tried again at other durations
    retime_tries: int = 12         # durations tried per colliding splice (nearest first)
    retime_step: int = 3           # frames between those durations
    max_turns: int = 6             # edges a seed may take to turn towards its target when none gains on it
    approach_point: float = 0.0    # m in front of a seat that the way points pass first, and last when
                                   # leaving one (0: off; the plaza passes without it)
    stop_to_wait: bool = True      # a timed seed blocked at a walking hub stops on a node with idle clips to wait
    max_waits: int = 8             # idle clips a seed may insert to let a planned character pass
    depart_delays: tuple = (2.0, 4.0, 8.0)  # s an untimed goal's start is put off, in turn, when all its
                                   # motions collide (scheduler; from a node where one can stand still) ...
    depart_within: float = 60.0    # ... and the first collision comes within this many s of the start
                                   # (14 x 6 grid at 2.2 m, one pass, with depart_clear: 10 s left 12
                                   # characters with warnings, 60 s 5)
    depart_clear: bool = True      # ... the first delay tried instead: the whole seconds of waiting after
                                   # which a straight walk to the goal misses every planned character
                                   # (then 3 s more; the fixed delays when that is 0 s or never)
    start_still: bool | None = None  # characters start on a node of their pose where they can stand still
                                   # and wait (scheduler; the World always does). False: the pose's most
                                   # connected node, which for "stand" is a walking hub (see docs/status.md).
                                   # None: per character, still first when its first goal's window
                                   # opens more than ``wait_slack`` s after it could walk there
    wait_slack: float = 3.0        # s (see start_still)
    static_prefer: float = 0.12    # m of clearance from static obstacles a seed keeps when it can (edges
                                   # that keep it come first; the splice's displacement maps shift the
                                   # motion by a few cm, and seeds hugging a door post collided there)
    end_clearance: float = 0.65    # m from static obstacles a seed's edge must end (away from the goal),
                                   # so it can walk on (a walking cylinder is up to 0.63 m); 0: off
    reuse_motions: bool = True     # scheduler and World: a motion found for one character is tried first
                                   # for the next with the same task relative to its start (motion_cache)
    fps: float = 30.0

    @property
    def alpha(self):
        """(a1 per radian, a2 per second) in metres, so that the cost is in m/s."""
        ep, et, es = self.eps
        return ep / np.radians(et), ep / es


@dataclass
class Config:
    node: int
    x: float
    z: float
    heading: float     # radians
    frame: int         # absolute frame on the fps grid

    @property
    def xzh(self):
        return np.array([self.x, self.z, self.heading])


@dataclass
class Goal:
    position: np.ndarray                 # (2,)
    heading: float | None = None         # radians
    nodes: np.ndarray | None = None      # allowed end nodes (pose constraint), None = free
    window: tuple | None = None          # absolute seconds (t_a, t_b)
    label: str = ""


@dataclass
class SegmentResult:
    ok: bool
    frames_a: np.ndarray       # (m,) global library frame before each output frame
    frames_b: np.ndarray       # (m,) global library frame after
    frames_t: np.ndarray       # (m,) blend in [0, 1)
    root: np.ndarray           # (m, 3) x, z, heading (rad, continuous)
    start_frame: int           # absolute frame of output frame 0 (= the start config)
    end: Config
    cost: float
    rates: tuple               # achieved per-frame adjustment (m/s, deg/s, s/s)
    iterations: int
    edges: list                # library edges used, in order
    warning: str = ""
    collided: bool = False


class MotionLibrary:
    """Precomputed arrays over a :class:`MotionGraph` that the planner needs every query:
    forward and reversed adjacency, collision samples per edge, parallel-edge alternatives
    with their replacement probabilities."""

    def __init__(self, graph: MotionGraph, params: SynthesisParams | None = None):
        self.g = g = graph
        self.params = params or SynthesisParams()
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
        # alternatives: parallel edges weighted by 1 / distance (paper 000, section 3.3)
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
        self._lookahead = {}

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


# ------------------------------------------------------------------------------------------
class SegmentPlanner:
    """Plans one segment; see the module docstring. ``collide(frames, xz, radius) -> bool
    array`` tests samples against moving obstacles (the space-time index), ``static(xz) ->
    distance`` against the environment (a signed distance field); both may be None."""

    def __init__(self, lib: MotionLibrary, static=None, collide=None, roadmap=None, env=None,
                 params: SynthesisParams | None = None, collide_first=None, collide_runs=None):
        self.lib = lib
        self.g = lib.g
        self.static = static
        self.collide = collide
        # collide_first(frames, xz, radius) -> index of the first sample that collides, or -1
        # (the final tests need no more: the index stops at it); from ``collide`` if not given
        if collide_first is None and collide is not None:
            def collide_first(f, xz, r):
                hit = np.flatnonzero(np.asarray(collide(f, xz, r), dtype=bool))
                return int(hit[0]) if len(hit) else -1
        self.collide_first = collide_first
        # collide_runs(frames, xz, radius, counts) -> per run of ``counts`` consecutive samples,
        # whether any collides (the seeds' test of many candidate clips); from ``collide`` if
        # not given
        if collide_runs is None and collide is not None:
            def collide_runs(f, xz, r, cnt):
                return np.logical_or.reduceat(np.asarray(collide(f, xz, r), dtype=bool), np.cumsum(cnt) - cnt)
        self.collide_runs = collide_runs
        self.roadmap = roadmap
        self.env = env
        self.p = params or lib.params
        # hold(res) -> (frames, xz, radius) or None: where the character stays after the
        # segment (its idle tail after a last goal), tested with the segment in the final test
        self.hold = None
        self.waited = 0             # waits of the last seed (greedy_steps)
        self.compiled = _kernels.AVAILABLE      # splice costs and seed lookahead by the numba kernels
        # motions found for other characters' same tasks, tried before a search (a
        # motion_cache.MotionCache shared by the planners of one scenario; None: off)
        self.cache = None

    # -- helpers -------------------------------------------------------------------------------
    def travel_state(self, start_node: int, goal: Goal) -> int:
        s0 = int(self.g.node_state[start_node])
        sitting = STATES.index("sitting")
        carrying = STATES.index("carrying")
        walking = STATES.index("walking")
        if s0 == sitting:
            return walking
        if s0 == carrying:
            return carrying
        return walking

    def _clear(self, edges: np.ndarray, cfg: np.ndarray, frames0: np.ndarray, moving: bool):
        """(collision-free, and also ``static_prefer`` further from static obstacles) per
        candidate clip ``edges`` placed at the configuration ``cfg``, clip k starting at frame
        ``frames0[k]`` (vectorized over candidates; one compiled gather of their collision
        samples with numba, and the moving test stops each clip at its first hit)."""
        lib = self.lib
        n = len(edges)
        ok = np.ones(n, dtype=bool)
        if n == 0 or (self.static is None and (self.collide is None or not moving)):
            return ok, ok.copy()
        if self.compiled:
            xz, rad, frames, cnt = _kernels.edge_samples(lib, edges, cfg, frames0, self.p.margin)
        else:
            cnt = lib.samp_ptr[edges + 1] - lib.samp_ptr[edges]
            which = np.repeat(np.arange(n), cnt)
            sidx = lib.samp_ptr[edges][which] + (np.arange(int(cnt.sum())) - (np.cumsum(cnt) - cnt)[which])
            gf = lib.samp_frame[sidx]
            local = np.stack([self.g.frame_xz[gf, 0], self.g.frame_xz[gf, 1], self.g.frame_heading[gf]], axis=1)
            xz = compose(np.asarray(cfg, dtype=np.float64)[None], local)[:, :2]
            rad = self.g.frame_radius[gf].astype(np.float64) + self.p.margin
            frames = frames0[which] + lib.samp_off[sidx]
        starts = np.cumsum(cnt) - cnt
        roomier = ok.copy()
        if self.static is not None:
            # samples are every few frames: keep the distance a character covers between two
            # samples from obstacles too, or a seed that grazes one fails the per-frame test
            d = self.static(xz)
            ok &= ~np.logical_or.reduceat(d < rad + self.p.static_seed_margin, starts)
            roomier &= ~np.logical_or.reduceat(d < rad + self.p.static_seed_margin + self.p.static_prefer, starts)
        if moving and self.collide is not None:
            # seeds keep a wider berth from moving characters: the splice later shifts the
            # motion in space (displacement maps) and in time (resampling)
            ok &= ~self.collide_runs(frames, xz, rad + self.p.seed_margin, cnt)
        return ok, ok & roomier

    def _bfs_dist(self, targets: np.ndarray, allowed: np.ndarray, reverse: bool) -> np.ndarray:
        """Fewest edges from every node to any of ``targets`` (edges masked by ``allowed``)."""
        g = self.g
        N = g.num_nodes
        s, d = (g.edge_src, g.edge_dst) if not reverse else (g.edge_dst, g.edge_src)
        m = allowed
        # distance to targets = shortest path in the reversed graph from a super source
        A = csr_matrix((np.ones(m.sum()), (d[m], s[m])), shape=(N, N))
        dist = shortest_path(A, unweighted=True, indices=np.asarray(targets), directed=True)
        return np.min(np.atleast_2d(dist), axis=0)

    def greedy(self, *args, **kwargs) -> tuple[list, int]:
        """:meth:`greedy_steps` run to completion."""
        gen = self.greedy_steps(*args, **kwargs)
        try:
            while True:
                next(gen)
        except StopIteration as stop:
            return stop.value

    def greedy_steps(self, start_node: int, start_cfg: np.ndarray, frame0: int, waypoints: np.ndarray,
                     final_heading, travel: int, target_nodes, reverse: bool, rng,
                     time_budget: float | None = None, reserve: float = 0.0):
        """Generator (yields after every edge it adds) of a greedy seed motion (paper 000, section 3.2). ``reverse`` plans M_b on the
        time-reversed graph (edges walked from their end to their start). Returns
        (edges in the walking order, last node).

        Each step takes, among the collision-free edges of the travel state that reduce the
        error to the current target, the one that brings the character closest to it (with a
        two-edge lookahead); at the last way point the error also counts orientation and the
        planner stops when it stops decreasing. On a path of several way points the target is
        a point ``carrot`` metres ahead of the character's projection onto the path (so seeds
        follow the roadmap's line through doors instead of cutting towards a way point beyond
        them); when no edge gains on it, the target moves further along. When improving edges
        exist but all collide, the seed waits on an idle clip for a planned character to pass
        (``max_waits``) or, short of the target, takes the clear edge that loses least
        (``max_sidesteps``) instead of giving the target up.
        The paper's planner ignores time. With a ``time_budget`` (seconds to the goal) this
        one prefers, among the improving edges, the one whose progress rate matches the rate
        the budget asks for, and idles on the node's self-loop clips while time is in
        surplus, so that the seeds are already close to the time window the search must meet.
        The budget counts the seed's own state-change prefix (standing up, say) and leaves
        ``reserve`` seconds for the change at the far end (sitting down, picking up), which the
        seed makes after the greedy part or the other seed contributes.
        """
        g, lib = self.g, self.lib
        src, dst = (g.edge_src, g.edge_dst) if not reverse else (g.edge_dst, g.edge_src)
        disp = lib.disp if not reverse else lib.disp_rev
        in_travel = g.edge_state == travel
        node = int(start_node)
        cfg = np.asarray(start_cfg, dtype=np.float64)
        frame = int(frame0)
        edges: list[int] = []
        a1 = self.p.alpha[0]
        t_sign = -1 if reverse else 1

        elapsed = 0.0           # seconds of motion so far (+ the reserve, once past the prefix)

        def advance(e):
            nonlocal node, cfg, frame, elapsed
            edges.append(int(e))
            cfg = compose1(cfg, disp[e])
            node = int(dst[e])
            frame += t_sign * int(lib.nframes[e] - 1)
            elapsed += float(lib.dur[e])

        idled = 0               # idle clips spent waiting (not counted against max_seed_edges)
        # prefix: leave the start state for the travel state by the fewest edges
        if g.node_state[node] != travel:
            tnodes = np.flatnonzero(g.node_state == travel)
            if not reverse and time_budget is not None:
                # with time to spare, wait where the character stands (a still start node's
                # idle clips) before it leaves its state: the time left over after the
                # prefix would otherwise be idled wherever the prefix ended, a step away --
                # in a doorway, say
                loops = np.flatnonzero((src == node) & (dst == node) & (np.hypot(disp[:, 0], disp[:, 1]) < 0.1))
                if len(loops):
                    loop = int(loops[np.argmin(np.hypot(disp[loops, 0], disp[loops, 1]))])
                    path_len = float(np.hypot(*np.diff(waypoints, axis=0).T).sum()) if len(waypoints) > 1 else 0.0
                    need = lib.change_time([node], tnodes) + reserve + path_len / 1.1
                    need = need if np.isfinite(need) else time_budget
                    while time_budget - elapsed - need > lib.dur[loop] + 0.5 and idled < MAX_IDLE_EDGES:
                        advance(loop)
                        idled += 1
                    yield
            dist = self._bfs_dist(tnodes, np.ones(g.num_edges, bool), reverse)
            yield
            yield from self._fewest_path(node, dist, advance, lambda: node, lambda: cfg,
                                         waypoints[min(1, len(waypoints) - 1)], src, dst, disp, np.ones(g.num_edges, bool))
        wi = 1 if len(waypoints) > 1 else 0
        best = None
        tgt = None if target_nodes is None else np.asarray(target_nodes)

        approach = self.p.approach_radius

        face_w = self.p.facing_weight
        face_off = np.pi if reverse else 0.0   # played backwards, a clip travels against its facing

        def err(cfgs, final):
            # position error, plus how far the character faces away from the way point (so
            # turning on the spot counts as progress); near the goal (within the approach
            # radius) the goal orientation counts instead (1 cm = 1 deg)
            dx = tp[0] - cfgs[..., 0]
            dz = tp[1] - cfgs[..., 1]
            e = np.hypot(dx, dz)
            bearing = np.arctan2(dx, dz)
            facing = face_w * np.abs(wrap_angle(cfgs[..., 2] + face_off - bearing)) * np.minimum(e, 1.0)
            if final and final_heading is not None:
                near = e < approach
                return e + np.where(near, a1 * np.abs(wrap_angle(cfgs[..., 2] - final_heading)), a1 * np.pi + facing)
            return e + facing

        seg_len = np.hypot(*np.diff(waypoints, axis=0).T) if len(waypoints) > 1 else np.zeros(0)
        cum = np.concatenate([[0.0], np.cumsum(seg_len)])
        total = float(cum[-1])
        s_proj = 0.0
        ahead = self.p.carrot
        tp = waypoints[-1]

        def place_carrot():
            """The target: the point ``ahead`` metres along the way-point polyline beyond the
            character's projection onto it (the projection only moves forward, and only
            within 3 m of the last one, so a path that doubles back is not short-cut). Returns
            whether the target is the last way point."""
            nonlocal s_proj, tp, wi
            if len(waypoints) <= 2:         # a straight path: aim at its end, as the paper does
                tp, wi = waypoints[-1], len(waypoints) - 1
                return True
            a = waypoints[:-1]
            ab = waypoints[1:] - a
            t = np.clip(((cfg[:2] - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12), 0.0, 1.0)
            d = np.hypot(*(a + t[:, None] * ab - cfg[None, :2]).T)
            s_all = cum[:-1] + t * seg_len
            d = np.where((s_all >= s_proj - 1e-9) & (cum[:-1] <= s_proj + 3.0), d, np.inf)
            k = int(np.argmin(d))
            if np.isfinite(d[k]):
                s_proj = max(s_proj, float(s_all[k]))
            sc = min(s_proj + ahead, total)
            if sc >= total - 1e-9 or total - s_proj < self.p.carrot_final:
                tp, wi = waypoints[-1], len(waypoints) - 1
                return True
            if self.env is not None:
                # the target must be in sight: a carrot moved round a corner (a row's end, a
                # door post) would pull the seed into the obstacle's far side
                ss = np.linspace(s_proj, sc, 8)
                seen = self.env.segment_clear(cfg[None, :2], path_point(ss), 0.55)
                if seen[0]:
                    k = int(np.argmin(seen)) - 1 if not seen.all() else len(ss) - 1
                    sc = float(ss[k])
            tp = path_point(np.array([sc]))[0]
            wi = int(np.clip(np.searchsorted(cum, sc, side="right") - 1, 0, len(seg_len) - 1)) + 1
            return False

        def path_point(ss):
            j = np.clip(np.searchsorted(cum, ss, side="right") - 1, 0, len(seg_len) - 1)
            u = (ss - cum[j]) / np.maximum(seg_len[j], 1e-12)
            return waypoints[j] + u[:, None] * (waypoints[j + 1] - waypoints[j])

        elapsed += float(reserve)
        waits = 0
        sidesteps = 0
        turns = 0
        # planned characters count where the seed's frames mean something: forward, or backward
        # from a time window
        timed = (not reverse) or time_budget is not None

        def clear_here(es, moving):
            """Which edges from the current configuration and frame are collision-free."""
            return clear_both(es, moving)[0]

        def clear_both(es, moving):
            """(collision-free, and also ``static_prefer`` clear of static obstacles)."""
            es = np.asarray(es, dtype=np.int64)
            return self._clear(es, cfg,
                                np.full(len(es), frame) if not reverse else frame - (lib.nframes[es] - 1),
                                moving=moving)
        goal_xz = np.asarray(waypoints[-1], dtype=np.float64)
        home_xz = np.asarray(start_cfg[:2], dtype=np.float64)
        room = self.p.end_clearance

        def roomy(es):
            """Edges whose end leaves room to walk on: ``end_clearance`` from the static
            obstacles (a seed that stops closer, at a corner, cannot leave it), except near the
            segment's ends, where the goal or the start itself may be close to an obstacle (a
            seat or a box by a wall)."""
            if self.static is None or not room:
                return np.ones(len(es), dtype=bool)
            ends = compose(cfg[None], disp[es])[:, :2]
            near = np.hypot(ends[:, 0] - goal_xz[0], ends[:, 1] - goal_xz[1]) < self.p.approach_radius
            near |= np.hypot(ends[:, 0] - home_xz[0], ends[:, 1] - home_xz[1]) < self.p.reach_radius
            return near | (self.static(ends) >= room)

        def stop_clip(out):
            """The shortest clear clip among ``out`` to a node where one can stand and wait (at
            most one, as an array)."""
            stops = out[idle_node[dst[out]] & (np.hypot(disp[out, 0], disp[out, 1]) < 1.0)]
            w = stops[np.argsort(np.hypot(disp[stops, 0], disp[stops, 1]), kind="stable")][:6]
            return w[clear_here(w, timed)][:1] if len(w) else w

        def first_ok(cand):
            """The first of ``cand`` that is clear and leaves room to walk on -- the first
            that also keeps ``static_prefer`` from static obstacles if any does -- or None."""
            cand = np.asarray(cand, dtype=np.int64)
            ok, roomier = clear_both(cand, timed)
            room_ok = roomy(cand)
            ok &= room_ok
            roomier &= room_ok
            if roomier.any():
                return int(cand[np.argmax(roomier)])
            return int(cand[np.argmax(ok)]) if ok.any() else None

        table = lib.lookahead(reverse, travel)
        # nodes where a seed can stand and wait: a self-loop clip of the travel state that
        # stays on the spot
        still_loop = in_travel & (src == dst) & (np.hypot(disp[:, 0], disp[:, 1]) < 0.1)
        idle_node = np.zeros(g.num_nodes, dtype=bool)
        idle_node[src[still_loop]] = True
        turn_rate = float(np.max(np.abs(disp[in_travel, 2]) / lib.dur[in_travel])) if in_travel.any() else 1.0
        while len(edges) - idled < self.p.max_seed_edges:
            final = place_carrot()
            out, comb, dur2, disp_out, dur_out = table[node]
            if len(out) == 0:
                break
            # lookahead: the best error reachable with one more edge after each candidate
            if self.compiled:
                e, span, end_xz, ends, cur = _kernels.lookahead_errors(
                    cfg, disp_out, comb, dur_out, dur2, tp, final, final_heading, face_w, face_off, approach, a1)
            else:
                ends = compose(cfg[None], disp_out)
                ends2 = compose(cfg[None, None], comb)
                e2 = np.nan_to_num(err(ends2, final), nan=np.inf)
                k2 = np.argmin(e2, axis=1)
                rows = np.arange(len(out))
                best2 = e2[rows, k2]
                e1 = err(ends, final)
                use2 = best2 < e1
                e = np.where(use2, best2, e1)
                span = dur_out + np.where(use2, dur2[rows, k2], 0.0)
                end_xz = np.where(use2[:, None], ends2[rows, k2, :2], ends[:, :2])
                cur = float(err(cfg, final))
            if time_budget is not None:
                remaining = float(np.hypot(cfg[0] - tp[0], cfg[1] - tp[1])) + (0.0 if final else total - min(s_proj + ahead, total))
                # facing away from the target, turning round takes time too (walking on while
                # turning, for a state without turns on the spot): half the state's top turn rate
                facing_off = float(np.abs(wrap_angle(cfg[2] + face_off - np.arctan2(tp[0] - cfg[0], tp[1] - cfg[1]))))
                remaining += 1.1 * facing_off / max(0.5 * turn_rate, 1e-3) if facing_off > np.pi / 4 else 0.0
                left = time_budget - elapsed
                loops = out[(dst[out] == node) & (np.hypot(disp[out, 0], disp[out, 1]) < 0.1)]
                # surplus time is spent idling at the start of the segment, where the character
                # already stands: a forward seed idles first; a backward seed (which runs back
                # from the goal) never idles, or the motion would stand at the goal early, in
                # the way of characters passing before the window opens
                if (not reverse or self.p.backward_idle) and len(loops) and left - remaining / 1.1 > lib.dur[loops].min() + 0.5 \
                        and idled < MAX_IDLE_EDGES:
                    advance(loops[np.argmin(np.hypot(disp[loops, 0], disp[loops, 1]))])
                    idled += 1
                    continue
                want = remaining / max(left, 0.3)
                pos_now = float(np.hypot(cfg[0] - tp[0], cfg[1] - tp[1]))
                pos_new = np.hypot(end_xz[:, 0] - tp[0], end_xz[:, 1] - tp[1])
                rate = (pos_now - pos_new) / span
                # slow down by walking slower, not by wandering sideways: penalise the part of
                # the travelled distance that is not progress
                travelled = np.hypot(end_xz[:, 0] - cfg[0], end_xz[:, 1] - cfg[1])
                waste = np.maximum(travelled - (pos_now - pos_new), 0.0) / span
                order = np.argsort(np.abs(rate - want) + 0.5 * waste + 0.1 * (e - e.min()), kind="stable")
            else:
                order = np.argsort(e, kind="stable")
            # "the error stops decreasing": an edge must gain at least min_gain (1 cm / 1 deg)
            # and min_gain_rate per second of motion, or seeds creep on for tiny gains
            order = order[e[order] < cur - np.maximum(self.p.min_gain, self.p.min_gain_rate * span[order])]
            pick = None
            if len(order):
                cand = out[order[:12]]
                pick = first_ok(cand)
                if pick is None and waits < self.p.max_waits and self.collide is not None and timed and \
                        clear_here(cand, False).any():
                    # every improving edge runs into someone already planned (at least one is
                    # clear of the static obstacles: waiting cannot move a wall): wait for them
                    # to pass on the node's most stationary self-loop clip, if that is clear
                    loops = out[(dst[out] == node) & (np.hypot(disp[out, 0], disp[out, 1]) < 0.1)]
                    if len(loops):
                        w = loops[np.argmin(np.hypot(disp[loops, 0], disp[loops, 1]))][None]
                    elif self.p.stop_to_wait and time_budget is not None:
                        # a walking hub has no such clip: with time to spare (a window), stop
                        # first, on the shortest clear clip to a node where one can stand and
                        # wait (without a window, stopping for someone walking the same way
                        # made grid300 4.5x slower: the seeds' stops rarely splice clear)
                        w = stop_clip(out)
                    else:
                        w = loops
                    if len(w) and clear_here(w, timed)[0]:
                        waits += 1
                        advance(int(w[0]))
                        yield
                        continue
            if pick is None:
                far = float(np.hypot(cfg[0] - tp[0], cfg[1] - tp[1])) > self.p.reach_radius
                alt = None          # a clear edge that does not gain: a sidestep or a turn
                if far and len(order) and sidesteps < self.p.max_sidesteps:
                    # blocked short of the way point (an obstacle or a planned character in the
                    # way): take the clear edge that loses least, rather than skip the way point
                    moves = np.hypot(ends[:, 0] - cfg[0], ends[:, 1] - cfg[1]) > 0.3
                    cand = out[np.argsort(np.where(moves, e, np.inf), kind="stable")[:24]]
                    cand = cand[np.hypot(*(compose(cfg[None], disp[cand])[:, :2] - cfg[None, :2]).T) > 0.3]
                    alt = first_ok(cand)
                    sidesteps += alt is not None
                elif far and not len(order) and turns < self.p.max_turns:
                    # facing away from the target with nothing that gains on it (a character
                    # holding a box has no clip that turns on the spot: it turns while walking
                    # on): take the clear edge that turns it furthest towards the target
                    ang = lambda c: np.abs(wrap_angle(c[..., 2] + face_off - np.arctan2(tp[0] - c[..., 0], tp[1] - c[..., 1])))
                    a_now = float(ang(cfg))
                    if a_now > np.pi / 3:
                        # with the lookahead: the best angle one more edge can reach
                        a2 = np.nan_to_num(ang(compose(cfg[None, None], comb)), nan=np.inf)
                        k2t = np.argmin(a2, axis=1)
                        a_new = np.minimum(ang(ends), a2[np.arange(len(out)), k2t])
                        score = a_new + 0.3 * np.hypot(ends[:, 0] - tp[0], ends[:, 1] - tp[1])
                        turning = np.flatnonzero(a_new < a_now - 0.1)
                        alt = first_ok(out[turning[np.argsort(score[turning], kind="stable")][:24]])
                        turns += alt is not None
                if alt is not None:
                    advance(alt)
                    yield
                    continue
                if not final:
                    # nothing gains on this target: aim further along the path
                    ahead += self.p.carrot
                    sidesteps = 0
                    yield           # each target move is a bounded step (time slicing)
                    continue
                if len(order) and len(edges) - idled < 3 and waits < self.p.max_waits and self.p.stop_to_wait \
                        and self.collide is not None and timed and clear_here(out[order[:12]], False).any():
                    # blocked right at the start by someone planned earlier (the one ahead in a
                    # crowd that sets off together) with no wait and no sidestep: rather than
                    # end the seed a step from the start, stop and wait, untimed as well (the
                    # quick 10 x 6 grid at 2.2 m: 29 overlapping pairs without this, 0 with it)
                    w = stop_clip(out)
                    if len(w):
                        waits += 1
                        advance(int(w[0]))
                        yield
                        continue
                break
            advance(pick)
            ahead = self.p.carrot
            yield
            if tgt is not None and node in tgt:
                best = (list(edges), node, cfg.copy())
        if tgt is not None:
            if best is not None:
                return best[0], best[1]
            # fallback: fewest-edge path to the required node (ties by the error)
            allowed = in_travel | (g.edge_state == TRANSITION) | np.isin(dst, tgt)
            dist = self._bfs_dist(tgt, allowed, reverse)
            if not np.isfinite(dist[node]):
                allowed = np.ones(g.num_edges, bool)
                dist = self._bfs_dist(tgt, allowed, reverse)
            yield from self._fewest_path(node, dist, advance, lambda: node, lambda: cfg, waypoints[-1], src, dst,
                                         disp, allowed, clear=lambda es: clear_here(es, not reverse))
        self.waited = waits         # idle clips inserted for planned characters (diagnostics)
        return edges, node

    def _fewest_path(self, node, dist, advance, get_node, get_cfg, target_xz, src, dst, disp, allowed, clear=None):
        """Generator (yields after every edge): fewest edges to the nodes ``dist`` measures,
        ties broken by the distance to ``target_xz``; with ``clear`` (edges -> bool array),
        collision-free edges are preferred."""
        guard = 0
        while np.isfinite(dist[get_node()]) and dist[get_node()] > 0 and guard < 64:
            guard += 1
            n = get_node()
            out = np.flatnonzero((src == n) & allowed & (dist[dst] == dist[n] - 1))
            if len(out) == 0:
                break
            ends = compose(get_cfg()[None], disp[out])
            e = np.hypot(ends[:, 0] - target_xz[0], ends[:, 1] - target_xz[1])
            order = out[np.argsort(e, kind="stable")]
            pick = order[0]
            if clear is not None:
                ok = clear(order[:8])
                if ok.any():
                    pick = order[:8][np.argmax(ok)]
            advance(pick)
            yield

    def _forward_configs(self, F: np.ndarray, start: np.ndarray):
        """(x, z, heading), each (P, Lf + 1): configurations at the nodes of left-aligned
        forward motions F (padded -1) placed at ``start``."""
        P = len(F)
        fv = F >= 0
        dF = np.where(fv[..., None], self.lib.disp[np.where(fv, F, 0)], 0.0)
        h = start[2] + np.concatenate([np.zeros((P, 1)), np.cumsum(dF[..., 2], axis=1)], axis=1)
        c, s = np.cos(h[:, :-1]), np.sin(h[:, :-1])
        x = start[0] + np.concatenate([np.zeros((P, 1)), np.cumsum(c * dF[..., 0] + s * dF[..., 1], axis=1)], axis=1)
        z = start[1] + np.concatenate([np.zeros((P, 1)), np.cumsum(-s * dF[..., 0] + c * dF[..., 1], axis=1)], axis=1)
        return x, z, h

    def _backward_configs(self, B: np.ndarray, goal: np.ndarray):
        """(x, z, heading), each (P, Lb + 1): configurations at the node positions of
        right-aligned motions B (walking order, padded -1) that end at ``goal`` (position Lb)."""
        P = len(B)
        bv = B >= 0
        dB = np.where(bv[..., None], self.lib.disp[np.where(bv, B, 0)], 0.0)
        h = goal[2] - np.concatenate([np.cumsum(dB[:, ::-1, 2], axis=1)[:, ::-1], np.zeros((P, 1))], axis=1)
        c, s = np.cos(h[:, :-1]), np.sin(h[:, :-1])
        x = goal[0] - np.concatenate([np.cumsum((c * dB[..., 0] + s * dB[..., 1])[:, ::-1], axis=1)[:, ::-1],
                                      np.zeros((P, 1))], axis=1)
        z = goal[1] - np.concatenate([np.cumsum((-s * dB[..., 0] + c * dB[..., 1])[:, ::-1], axis=1)[:, ::-1],
                                      np.zeros((P, 1))], axis=1)
        return x, z, h

    # -- cost (Eq. 1, 2), vectorized over pairs ---------------------------------------------------
    def pair_costs(self, F: np.ndarray, nf: np.ndarray, B: np.ndarray, nb: np.ndarray,
                   start: np.ndarray, goal: np.ndarray, window_rel):
        """Splice costs of many (M_f, M_b) pairs.

        F: (P, Lf) forward edges left-aligned, padded -1, lengths nf; B: (P, Lb) backward edges
        right-aligned (walking order), lengths nb. Returns (cost (P,), i (P,), j (P,)) where
        the best splice joins M_f[:i] with M_b[j:] (columns of B). With numba the compiled
        kernel of :mod:`runtime.crowd.search_kernels` computes it (same formula; set
        ``self.compiled = False`` for the numpy passes below)."""
        lib = self.lib
        g = self.g
        if self.compiled:
            return _kernels.pair_costs(F, nf, B, nb, lib.disp, lib.dur, g.edge_src, g.edge_dst, start, goal,
                                       self._start_node, self._goal_node, *self.p.alpha, window_rel)
        P, Lf = F.shape
        Lb = B.shape[1]
        a1, a2 = self.p.alpha
        fv = F >= 0
        bv = B >= 0
        Fe = np.where(fv, F, 0)
        Be = np.where(bv, B, 0)
        # forward configurations at nodes 0..Lf; backward ones at node positions 0..Lb
        # (position Lb = goal), right-aligned
        xF, zF, hF = self._forward_configs(F, start)
        xB, zB, hB = self._backward_configs(B, goal)
        tF = np.concatenate([np.zeros((P, 1)), np.cumsum(np.where(fv, lib.dur[Fe], 0.0), axis=1)], axis=1)
        nodeF = np.concatenate([np.full((P, 1), -2), np.where(fv, g.edge_dst[Fe], -3)], axis=1)
        nodeF[:, 0] = self._start_node
        tB = np.concatenate([np.cumsum(np.where(bv, lib.dur[Be], 0.0)[:, ::-1], axis=1)[:, ::-1], np.zeros((P, 1))], axis=1)
        nodeB = np.concatenate([np.where(bv, g.edge_src[Be], -4), self._goal_node_col(P)], axis=1)
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

    def pairs_static_clear(self, F, B, i, j, start, goal, slack: float = 0.0) -> np.ndarray:
        """Per pair: whether its two unspliced parts -- M_f[:i] placed at the start and
        M_b[j:] placed at the goal -- clear the static obstacles at the library's collision
        samples (bounding cylinder + ``margin``). A pair that fails cannot pass the final
        test once spliced (the displacement maps move it a few cm at most), so the search
        drops it before splicing, instead of converging on motions that cut a corner.
        F, B as in :meth:`pair_costs` (rows of the pairs to test). ``slack``: metres of
        overlap forgiven (the displacement maps may still move a grazing part clear)."""
        lib, g = self.lib, self.g
        P = len(F)
        if self.static is None or P == 0:
            return np.ones(P, dtype=bool)
        Lf, Lb = F.shape[1], B.shape[1]
        fv, bv = F >= 0, B >= 0
        # the configuration each edge starts from
        xF, zF, hF = (a[:, :-1] for a in self._forward_configs(F, start))
        xB, zB, hB = (a[:, :-1] for a in self._backward_configs(B, goal))
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
        local = np.stack([g.frame_xz[gf, 0], g.frame_xz[gf, 1], g.frame_heading[gf]], axis=1)
        world = compose(base[which], local)
        bad = self.static(world[:, :2]) < g.frame_radius[gf].astype(np.float64) + self.p.margin - slack
        return np.bincount(row[which], weights=bad, minlength=P) == 0

    def _goal_node_col(self, P):
        return np.full((P, 1), self._goal_node)

    def waypoints(self, start: Config, goal: Goal) -> np.ndarray:
        """The segment's way points (n, 2): the roadmap's path from the start to the goal (a
        straight line without one), passing ``approach_point`` metres in front of a seat
        before sitting down on it and after getting up from it."""
        g = self.g
        gxz = np.asarray(goal.position, float)
        via = None
        if self.p.approach_point > 0 and goal.heading is not None and goal.nodes is not None \
                and np.all(g.node_state[goal.nodes] == STATES.index("sitting")):
            # one sits down from in front of the seat: the way points pass a point that far in
            # front first, so the seeds come in square rather than across the neighbours'
            # places
            via = gxz + self.p.approach_point * np.array([np.sin(goal.heading), np.cos(goal.heading)])
            if self.env is not None and self.env.distance(via[None])[0] < 0.5 * self.p.approach_point:
                via = None
            if via is not None and np.hypot(*(via - [start.x, start.z])) < 2 * self.p.approach_point:
                via = None
        dep = None
        if self.p.approach_point > 0 and g.node_state[start.node] == STATES.index("sitting"):
            # and one gets up to in front of the seat: the way points leave through the same
            # point, so a character walks off down the middle of the aisle, not along the
            # seated row's knees
            dep = np.array([start.x, start.z]) + self.p.approach_point * np.array([np.sin(start.heading), np.cos(start.heading)])
            if (self.env is not None and self.env.distance(dep[None])[0] < 0.5 * self.p.approach_point) \
                    or np.hypot(*(dep - gxz)) < 2 * self.p.approach_point:
                dep = None
        origin = np.array([start.x, start.z])
        a, b = (origin if dep is None else dep), (gxz if via is None else via)
        path = self.roadmap.waypoints(self.env, a, b) if self.roadmap is not None and self.env is not None \
            else np.array([a, b], dtype=np.float64)
        return np.concatenate([origin[None]] * (dep is not None) + [path] + [gxz[None]] * (via is not None))

    # -- the whole segment ------------------------------------------------------------------------------
    def run(self, start: Config, goal: Goal, rng: np.random.Generator, owner: int = -1, name: str = "",
            n_max: int | None = None):
        """Generator: yields after each bounded step; returns a :class:`SegmentResult`.
        ``n_max``: the iteration limit (default ``params.n_max``).

        Seeds are made from the roadmap's way points; the randomized search then runs on them.
        When the search keeps finding splices below eps that collide with characters already
        planned (section 3.3's final test), the seeds are made again through a detour way
        point beside the first collision, alternately left and right and further out; the
        iterations of all attempts count against N_max.

        With a :attr:`cache`, motions found earlier for the same task (another character's,
        placed at this start) are tried first, each with the final collision test; the search
        runs only if none is clear, and its clean result is kept for the next.
        """
        g, lib, p = self.g, self.lib, self.p
        key = None
        if self.cache is not None:
            # a motion found for the same task from another start, placed here (motion_cache)
            key = task_key(start, goal, p.fps)
            for k, res in self.cache.candidates(key, start, goal):
                if self.final_collision(res, owner) is None:
                    self.cache.used(key, k)
                    return res
            self.cache.misses += 1
        n_max = p.n_max if n_max is None else int(n_max)
        travel = self.travel_state(start.node, goal)
        base = self.waypoints(start, goal)
        yield
        tgt = goal.nodes
        budget = None
        window_rel = None
        if goal.window is not None:
            budget = max(0.5, 0.5 * (goal.window[0] + goal.window[1]) - start.frame / p.fps)
            t0 = start.frame / p.fps
            window_rel = (goal.window[0] - t0, goal.window[1] - t0)
        eps_p = p.eps[0]
        self._start_node = int(start.node)
        # time the seeds leave for a change of state at their far ends (section 3.2's
        # fewest-edge paths): the forward seed's into the goal pose, the backward seed's out
        # of the start pose
        travel_nodes = np.flatnonzero(g.node_state == travel)
        reserve_f = reserve_b = 0.0
        if budget is not None:
            if tgt is not None:
                reserve_f = lib.change_time(travel_nodes, tgt)
            reserve_b = lib.change_time([start.node], travel_nodes)
            reserve_f = reserve_f if np.isfinite(reserve_f) else 0.0
            reserve_b = reserve_b if np.isfinite(reserve_b) else 0.0
        queue = [base]
        tried_detours = 0
        iterations = 0
        best_overall = None
        result = None
        goal_node = goal_cfg = None
        per_attempt = max(60, p.n_max // 6)     # reseeds at the same points whatever the limit
        while result is None and iterations < n_max and queue:
            wps = queue.pop(0)
            F0, f_end = yield from self.greedy_steps(start.node, start.xzh, start.frame, wps, goal.heading, travel,
                                                     tgt, False, rng, time_budget=budget, reserve=reserve_f)
            if not F0:
                # already as close as the graph gets: take the out-edge that ends nearest the goal,
                # so that the segment has a motion to adjust
                out = g.out_edges(start.node)
                out = out[g.edge_state[out] == travel] if np.any(g.edge_state[out] == travel) else out
                ends = compose(start.xzh[None], lib.disp[out])
                e0 = int(out[np.argmin(np.hypot(ends[:, 0] - goal.position[0], ends[:, 1] - goal.position[1]))])
                F0, f_end = [e0], int(g.edge_dst[e0])
            yield
            if goal_node is None:
                if tgt is None:
                    # no pose constraint: end in the node the forward seed ends in
                    end_nodes = (np.array([f_end]) if g.node_state[f_end] == travel
                                 else np.flatnonzero(g.node_state == travel)[:1])
                else:
                    end_nodes = np.asarray(tgt)
                goal_node = int(f_end) if f_end in end_nodes else int(end_nodes[0])
                goal_h = goal.heading
                if goal_h is None:
                    # free orientation: the heading the forward seed arrives with
                    c = start.xzh
                    for e in F0:
                        c = compose1(c, lib.disp[e])
                    goal_h = float(c[2])
                goal_cfg = np.array([goal.position[0], goal.position[1], goal_h])
                self._goal_node = goal_node
            # the backward seed runs back from the arrival: with a window, about its middle
            goal_frame = int(round(p.fps * 0.5 * (goal.window[0] + goal.window[1]))) if goal.window else start.frame
            B0r, _ = yield from self.greedy_steps(goal_node, goal_cfg, goal_frame, wps[::-1], start.heading, travel,
                                                  np.array([start.node]) if g.node_state[start.node] == travel else None,
                                                  True, rng, time_budget=budget, reserve=reserve_b)
            B0 = B0r[::-1]
            yield
            out = yield from self._search(start, goal_cfg, goal_node, F0, B0, window_rel, travel, owner, rng,
                                          min(per_attempt, n_max - iterations))
            res, its, best, collision_at = out
            iterations += its
            if best is not None and (best_overall is None or best[0] < best_overall[0]):
                best_overall = best
            result = res
            if result is None and collision_at is not None and tried_detours < 6:
                # make a way point beside the first collision; try both sides, then further out
                k = tried_detours
                side = 1.0 if k % 2 == 0 else -1.0
                off = (1.2, 2.2, 3.2)[k // 2]
                cxz, direction = collision_at
                perp = np.array([-direction[1], direction[0]])
                detour = cxz + side * off * perp
                if self.env is None or self.env.distance(detour[None])[0] > 0.5:
                    seg = int(np.argmin(np.hypot(*(base[:-1] - cxz).T))) if len(base) > 2 else 0
                    queue.append(np.concatenate([base[:seg + 1], detour[None], base[seg + 1:]]))
                tried_detours += 1
                if not queue:
                    queue.append(base)
            elif result is None and not queue:
                queue.append(base)
        if result is None:
            cost, Frow, nf, Brow, nb, i, j = best_overall
            res = self.splice(start, goal_cfg, goal_node, Frow, i, Brow, j, window_rel, travel, force=True)
            res.collided = self.final_collision(res, owner) is not None
            res.ok = False
            res.cost = cost
            res.warning = (f"{name or 'character'}: no motion within eps after {iterations} iterations "
                           f"(best cost {cost / eps_p:.2f} x eps{', collides' if res.collided else ''}); using the best pair")
            result = res
        result.iterations = iterations
        if key is not None and result.ok and not result.warning:
            self.cache.store(key, start, result)
        return result

    def _search(self, start, goal_cfg, goal_node, F0, B0, window_rel, travel, owner, rng, max_iter):
        """The randomized search of section 3.3 on one seed pair (generator; returns
        (result or None, iterations, best (cost, F, nf, B, nb, i, j), collision info))."""
        lib, p = self.lib, self.p
        eps_p = p.eps[0]
        Lf = max(len(F0), 1) + 8
        Lb = max(len(B0), 1) + 8
        Fp = -np.ones((1, Lf), dtype=np.int64)
        Bp = -np.ones((1, Lb), dtype=np.int64)
        Fp[0, :len(F0)] = F0
        if len(B0):
            Bp[0, Lb - len(B0):] = B0
        nfp = np.array([len(F0)])
        nbp = np.array([len(B0)])
        costp, ip, jp = self.pair_costs(Fp, nfp, Bp, nbp, start.xzh, goal_cfg, window_rel)
        best = (float(costp[0]), Fp[0].copy(), nfp[0], Bp[0].copy(), nbp[0], int(ip[0]), int(jp[0]))
        rejected = set()
        collision_at = None
        iterations = 0
        retimes = [p.retime_budget]      # colliding splices that may be tried at other durations

        def within_eps(r):
            return all(x <= e * (1 + 1e-9) for x, e in zip(r.rates, p.eps))

        def try_accept(cost, Frow, i, Brow, j):
            nonlocal collision_at
            key = (tuple(Frow[:i]), tuple(Brow[j:][Brow[j:] >= 0]))
            if key in rejected:
                return None
            rejected.add(key)
            res = self.splice(start, goal_cfg, goal_node, Frow, i, Brow, j, window_rel, travel)
            if res is None:
                return None
            if not within_eps(res):
                return None
            hit = self.final_collision(res, owner)
            if hit is not None and self.collide is not None and retimes[0] > 0:
                # the same motion a little slower or faster (time resampling within eps_t and
                # the window) passes the others at other moments: try the nearest durations
                retimes[0] -= 1
                m0 = len(res.root) - 1
                raw = int(sum(lib.nframes[e] - 1 for e in res.edges))      # source frame steps
                lo_m = int(np.ceil(raw / (1 + p.eps[2]))) + 1
                hi_m = int(np.floor(raw / max(1 - p.eps[2], 1e-3))) - 1
                cands = [m for k in range(1, 64) for m in (m0 + p.retime_step * k, m0 - p.retime_step * k)
                         if lo_m <= m <= hi_m][:p.retime_tries]
                rs = [r for r in self.splice(start, goal_cfg, goal_node, Frow, i, Brow, j, window_rel, travel,
                                             frames=cands) if r is not None and within_eps(r)] if cands else []
                for r2 in rs:
                    if self.final_collision(r2, owner) is None:
                        r2.cost = float(cost)
                        return r2
            if hit is not None:
                if collision_at is None and hit < len(res.root):
                    k = hit
                    a, b = max(k - 3, 0), min(k + 3, len(res.root) - 1)
                    d = res.root[b, :2] - res.root[a, :2]
                    n = np.hypot(*d)
                    d = d / n if n > 1e-6 else np.array([np.sin(res.root[k, 2]), np.cos(res.root[k, 2])])
                    collision_at = (res.root[k, :2].copy(), d)
                return None
            res.cost = float(cost)
            return res

        if np.isfinite(costp[0]) and costp[0] <= eps_p:
            res = try_accept(costp[0], Fp[0], ip[0], Bp[0], jp[0])
            if res is not None:
                return res, 0, best, None
        P = p.n_m
        while iterations < max_iter:
            iterations += 1
            K = len(costp)
            parent = rng.integers(0, K, size=P)
            Fn = Fp[parent].copy()
            Bn = Bp[parent].copy()
            nfn = nfp[parent].copy()
            nbn = nbp[parent].copy()
            # which motion to perturb, and a clip of it that has a parallel alternative
            fa = (Fn >= 0) & lib.has_alt[np.maximum(Fn, 0)]
            ba = (Bn >= 0) & lib.has_alt[np.maximum(Bn, 0)]
            use_f = rng.random(P) < 0.5
            use_f = np.where(fa.any(1) & ~ba.any(1), True, np.where(ba.any(1) & ~fa.any(1), False, use_f))
            col_f = np.argmax(rng.random((P, Lf)) * np.where(use_f[:, None], fa, False), axis=1)
            col_b = np.argmax(rng.random((P, Lb)) * np.where(~use_f[:, None], ba, False), axis=1)
            u = rng.random(P)
            rowf = np.flatnonzero(use_f & fa.any(1))
            if len(rowf):
                Fn[rowf, col_f[rowf]] = lib.sample_alternatives(Fn[rowf, col_f[rowf]], u[rowf])
            rowb = np.flatnonzero(~use_f & ba.any(1))
            if len(rowb):
                Bn[rowb, col_b[rowb]] = lib.sample_alternatives(Bn[rowb, col_b[rowb]], u[rowb])
            # sweeps on the best pair (still clip replacement between the same nodes): odd
            # iterations try every alternative of one random clip; even ones try every
            # combination of alternatives of two adjacent clips and keep the combinations that
            # bring that motion's free end closest to its target (gait-cycle clips differ a
            # lot, so a good pair is rarely improved by one random swap)
            sw = min(p.sweep, P)
            if sw:
                rows_new = self._sweep(Fp[0], nfp[0], Bp[0], nbp[0], start.xzh, goal_cfg, rng, sw,
                                       pair=iterations % 2 == 0)
                if rows_new is not None:
                    Fs, Bs = rows_new
                    k = len(Fs)
                    Fn[P - k:], Bn[P - k:], nfn[P - k:], nbn[P - k:] = Fs, Bs, nfp[0], nbp[0]
                yield       # the sweep and the costing are separate steps (time slicing)
            cn, inn, jn = self.pair_costs(Fn, nfn, Bn, nbn, start.xzh, goal_cfg, window_rel)
            if p.static_filter and self.static is not None:
                # pairs near acceptance whose parts hit a static obstacle leave the population
                near = np.flatnonzero(cn <= p.static_filter * eps_p)
                if len(near):
                    okn = self.pairs_static_clear(Fn[near], Bn[near], inn[near], jn[near], start.xzh, goal_cfg,
                                                  slack=p.static_filter_slack)
                    cn[near[~okn]] = np.inf
            allc = np.concatenate([costp, cn])
            Fa, Ba = np.concatenate([Fp, Fn]), np.concatenate([Bp, Bn])
            nfa, nba = np.concatenate([nfp, nfn]), np.concatenate([nbp, nbn])
            ia, ja = np.concatenate([ip, inn]), np.concatenate([jp, jn])
            order = np.argsort(allc, kind="stable")
            if allc[order[0]] < best[0]:
                r = order[0]
                best = (float(allc[r]), Fa[r].copy(), nfa[r], Ba[r].copy(), nba[r], int(ia[r]), int(ja[r]))
            # splice and test the best new pairs below eps (a pair the final test rejects stays
            # in the population: dropping it, and splicing the best untried old pairs as well,
            # was measured 1.5-2x slower on grid300 and no better on theater40)
            K0 = len(costp)
            for r in K0 + np.argsort(cn, kind="stable")[:p.splices_per_iteration]:
                if not (allc[r] <= eps_p):
                    break
                yield   # each splice + collision test is its own step (time slicing)
                res = try_accept(allc[r], Fa[r], ia[r], Ba[r], ja[r])
                if res is not None:
                    return res, iterations, best, None
            # keep the k_m best of old and new
            keep = np.argsort(allc, kind="stable")[:p.k_m]
            Fp, Bp, nfp, nbp, ip, jp = Fa[keep], Ba[keep], nfa[keep], nba[keep], ia[keep], ja[keep]
            costp = allc[keep]
            if collision_at is not None and iterations >= p.reseed_after and costp[0] <= eps_p:
                # below eps but colliding for a while: better seeds are needed
                break
            yield
        return None, iterations, best, collision_at

    # -- splice (steps 1-4) -------------------------------------------------------------------------------
    def splice(self, start: Config, goal_cfg, goal_node, Frow, i, Brow, j, window_rel, travel, force=False,
               frames: int | None = None):
        """Steps 1-4 of section 3.3 for the pair (M_f[:i], M_b[j:]). The result lasts the
        duration nearest the raw one inside the window, or ``frames`` output frames (None if
        outside the window); ``frames`` a sequence: a list of results, one per duration."""
        g, lib, p = self.g, self.lib, self.p
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
            return self._resample(src_frames, src_root, len(ff), len(bf), dp, dh, N, goal_node, start, edges, m1)
        out = []
        for m in np.atleast_1d(frames):
            m = int(m)
            inside = window_rel is None or (window_rel[0] - 1e-9 <= m / fps <= window_rel[1] + 1e-9)
            out.append(self._resample(src_frames, src_root, len(ff), len(bf), dp, dh, N, goal_node, start, edges, m)
                       if inside and m >= 1 else None)
        return out if np.ndim(frames) else out[0]

    def _resample(self, src_frames, src_root, nff, nbf, dp, dh, N, goal_node, start, edges, m1):
        """Step 4: the spliced source frames resampled to ``m1`` output steps."""
        p = self.p
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

    def _sweep(self, Frow, nf, Brow, nb, start_cfg, goal_cfg, rng, k, pair):
        """Candidate rows from exhaustive replacement at one or two adjacent clip positions of
        one motion of the best pair (see :meth:`_search`). Returns (F rows, B rows) or None."""
        lib = self.lib
        Lb = len(Brow)
        fpos = np.flatnonzero((Frow >= 0) & lib.has_alt[np.maximum(Frow, 0)])
        bpos = np.flatnonzero((Brow >= 0) & lib.has_alt[np.maximum(Brow, 0)])
        if len(fpos) + len(bpos) == 0:
            return None
        on_f = rng.random() < len(fpos) / (len(fpos) + len(bpos))
        row = Frow if on_f else Brow
        pos = fpos if on_f else bpos
        c0 = int(pos[rng.integers(0, len(pos))])
        cols = [c0]
        if pair and (c0 + 1) in set(pos.tolist()):
            cols.append(c0 + 1)
        elif pair and (c0 - 1) in set(pos.tolist()):
            cols.insert(0, c0 - 1)
        options = [np.concatenate([[row[c]], lib.alt_idx[lib.alt_ptr[row[c]]:lib.alt_ptr[row[c] + 1]]]) for c in cols]
        grid = np.stack(np.meshgrid(*options, indexing="ij"), axis=-1).reshape(-1, len(cols))
        if len(cols) == 2 and len(grid) > k:
            if len(grid) > self.p.sweep_pairs:
                keep = rng.choice(len(grid) - 1, size=self.p.sweep_pairs - 1, replace=False) + 1
                grid = np.concatenate([grid[:1], grid[np.sort(keep)]])
            # score every combination by where the motion's free end lands: the clips before
            # and after the two positions are one fixed transform each
            a1 = self.p.alpha[0]
            if on_f:
                edges = [int(e) for e in row[:nf]]
                pre = start_cfg.copy()
                for e in edges[:cols[0]]:
                    pre = compose1(pre, lib.disp[e])
                suf = np.zeros(3)
                for e in edges[cols[1] + 1:]:
                    suf = compose1(suf, lib.disp[e])
                mid = compose(compose(compose(pre[None], lib.disp[grid[:, 0]]), lib.disp[grid[:, 1]]), suf[None])
                tgt = goal_cfg
            else:
                edges = [int(e) for e in row[Lb - nb:]]
                c_first = cols[0] - (Lb - nb)
                post = goal_cfg.copy()
                for e in edges[c_first + 2:][::-1]:
                    post = compose_inverse(post, lib.disp[e])
                pre_d = np.zeros(3)
                for e in edges[:c_first]:
                    pre_d = compose1(pre_d, lib.disp[e])
                mid = compose_inverse(compose_inverse(compose_inverse(np.broadcast_to(post, (len(grid), 3)),
                                                                      lib.disp[grid[:, 1]]), lib.disp[grid[:, 0]]),
                                      pre_d[None])
                tgt = start_cfg
            err = np.hypot(mid[:, 0] - tgt[0], mid[:, 1] - tgt[1]) + a1 * np.abs(wrap_angle(mid[:, 2] - tgt[2]))
            grid = grid[np.argsort(err, kind="stable")[:k]]
        else:
            grid = grid[1:k + 1] if len(grid) > 1 else grid
        n = len(grid)
        Fs = np.repeat(Frow[None], n, 0)
        Bs = np.repeat(Brow[None], n, 0)
        tgt_rows = Fs if on_f else Bs
        for q, c in enumerate(cols):
            tgt_rows[:, c] = grid[:, q]
        return Fs, Bs

    def _first_hit(self, frames, xz, rad) -> int:
        """Index of the first sample whose cylinder (``rad`` includes the margin) hits an
        obstacle or a planned character, or -1."""
        first = len(xz)
        rad = np.broadcast_to(rad, (first,))
        if self.static is not None:
            hit = np.flatnonzero(self.static(xz) < rad)
            first = int(hit[0]) if len(hit) else first
        if self.collide_first is not None and first:
            k = self.collide_first(frames[:first], xz[:first], rad[:first])
            first = k if k >= 0 else first
        return first if first < len(xz) else -1

    def final_collision(self, res: SegmentResult, owner: int):
        """First output frame whose bounding cylinder hits an obstacle or a planned character,
        or None (the final test of section 3.3); ``len(res.root)`` when the motion is clear but
        standing at its end afterwards (:attr:`hold`) would be in someone's way."""
        g, p = self.g, self.p
        rad = np.maximum(g.frame_radius[res.frames_a], g.frame_radius[res.frames_b]).astype(np.float64) + p.margin
        hit = self._first_hit(res.start_frame + np.arange(len(res.root)), res.root[:, :2], rad)
        if hit >= 0:
            return hit
        if self.hold is not None:
            tail = self.hold(res)
            if tail is not None and len(tail[0]):
                f2, xz2, r2 = tail
                r2 = np.asarray(r2, dtype=np.float64) + p.margin
                if self._first_hit(np.asarray(f2), np.asarray(xz2, dtype=np.float64), r2) >= 0:
                    return len(res.root)
        return None
