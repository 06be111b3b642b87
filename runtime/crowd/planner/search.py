"""The randomized search (Sung, Kovar and Gleicher 2005, section 3.3).

Starting from one seed pair (M_f, M_b), while no splice is within eps, every iteration makes
n_m perturbed pairs -- one clip of one motion replaced by a parallel clip between the same two
nodes, drawn with probability inversely proportional to how different it is -- costs them all
at once (Eq. 1-2, :mod:`.costs`), keeps the k_m best, and splices and collision-tests the best
new pairs below eps. On top of the paper's search:

* Sweeps on the best pair: odd iterations try every alternative of one random clip; even ones
  every combination of alternatives of two adjacent clips, keeping the combinations that bring
  that motion's free end closest to its target (gait-cycle clips differ a lot, so a good pair
  is rarely improved by one random swap).
* Pairs near acceptance whose unspliced parts cut into a static obstacle leave the population
  (``static_filter``), so the search does not converge on motions that cut a corner.
* A splice within eps that collides with a planned character is tried at the nearest other
  durations the window and eps_t allow (``retime_*``): the same motion a little slower or
  faster passes the others at other moments.
"""
from __future__ import annotations

import numpy as np

from ...motion.cylinders import blend_cylinders
from ...motion.planar import compose, compose1, compose_inverse, wrap_angle
from . import kernels
from .collision import Collider
from .costs import pair_costs, pairs_static_clear
from .library import MotionLibrary
from .params import SearchParams
from .splice import fits, resample_grid, resample_rates, resample_rows, resample_source, splice, splice_source
from .types import Config, SegmentResult, Step

__all__ = ["RandomizedSearch", "sweep_rows", "within_eps", "RETIME_NEAR"]

RETIME_NEAR = 6     # output frames either side of the first hit a retimed splice is tested on first


def within_eps(res: SegmentResult, eps) -> bool:
    """Whether a splice's per-frame adjustment is within the tolerance."""
    return within_eps_rates(res.rates, eps)


def within_eps_rates(rates, eps) -> bool:
    """Whether per-frame adjustment ``rates`` (m/s, deg/s, s/s) are within the tolerance."""
    return all(x <= e * (1 + 1e-9) for x, e in zip(rates, eps))


class RandomizedSearch:
    """The search on one seed pair; :meth:`steps` is the generator.

    Args:
        lib, params, collider: the motion library, the search parameters, the collision tests.
        compiled: splice costs by the numba kernel.
        start: the segment's start configuration.
        goal_cfg: (3,) the goal's x, z, heading; goal_node: its node.
        F0, B0: the seeds (edges in walking order).
        window_rel: the arrival window relative to the start (s), or None.
        rng: the random stream.
        max_iter: iterations at most.

    Attributes (after :meth:`steps` finished):
        iterations: spent.
        best: (cost, F row, nf, B row, nb, i, j) of the cheapest pair seen.
        collision_at: (xz, direction) of the first collision of a splice within eps, or None.
        hopeless: the search stopped early because its best pair stayed far above eps
            (``hopeless_cost`` x eps after ``hopeless_after`` iterations): these seeds cannot
            be adjusted into the goal, and searching them longer does not help.
    """

    def __init__(self, lib: MotionLibrary, params: SearchParams, collider: Collider, compiled: bool, start: Config,
                 goal_cfg: np.ndarray, goal_node: int, F0, B0, window_rel, rng, max_iter: int):
        self.lib, self.p, self.collider, self.compiled = lib, params, collider, compiled
        self.start, self.goal_cfg, self.goal_node = start, goal_cfg, goal_node
        self.window_rel, self.rng, self.max_iter = window_rel, rng, max_iter
        self.F0, self.B0 = F0, B0
        self.rejected: set = set()
        self.collision_at = None
        self.iterations = 0
        self.best = None
        self.hopeless = False
        self.retimes = params.retime_budget     # colliding splices that may be tried at other durations
        self.static_memo: dict = {}             # parts of pairs already tested against static obstacles

    def costs(self, F, nf, B, nb):
        return pair_costs(self.lib, self.p, F, nf, B, nb, self.start.xzh, self.goal_cfg, int(self.start.node),
                          self.goal_node, self.window_rel, compiled=self.compiled)

    def splice(self, Frow, i, Brow, j, **kw):
        return splice(self.lib, self.p, self.start, self.goal_cfg, self.goal_node, Frow, i, Brow, j,
                      self.window_rel, **kw)

    def accept(self, cost, Frow, i, Brow, j):
        """Splice the pair (M_f[:i], M_b[j:]) and run the final tests: the spliced motion if it
        is within eps and collision-free (perhaps at another duration), else None."""
        steps = self.accept_steps(cost, Frow, i, Brow, j)
        while True:
            try:
                next(steps)
            except StopIteration as stop:
                return stop.value

    def accept_steps(self, cost, Frow, i, Brow, j):
        """Generator: :meth:`accept` time-sliced -- it yields :attr:`Step.SPLICE` before each
        other duration it tries (:meth:`_retimed`) and returns the motion or None."""
        key = (tuple(Frow[:i]), tuple(Brow[j:][Brow[j:] >= 0]))
        if key in self.rejected:
            return None
        self.rejected.add(key)
        res = self.splice(Frow, i, Brow, j)
        if res is None or not within_eps(res, self.p.eps):
            return None
        hit = self.collider.final_collision(res)
        if (hit is not None and self.collider.collide is not None and self.retimes > 0
                and self._timing_may_help(res, hit)):
            self.retimes -= 1
            r2 = yield from self._retimed(res, Frow, i, Brow, j, hit)
            if r2 is not None:
                r2.cost = float(cost)
                return r2
        if hit is not None:
            if self.collision_at is None and hit < len(res.root):
                k = hit
                a, b = max(k - 3, 0), min(k + 3, len(res.root) - 1)
                d = res.root[b, :2] - res.root[a, :2]
                n = np.hypot(*d)
                d = d / n if n > 1e-6 else np.array([np.sin(res.root[k, 2]), np.cos(res.root[k, 2])])
                self.collision_at = (res.root[k, :2].copy(), d)
            return None
        res.cost = float(cost)
        return res

    def _timing_may_help(self, res: SegmentResult, hit: int) -> bool:
        """Whether the same motion at another duration might pass where ``res`` failed the
        final test at output frame ``hit``: not when it ends in the way (past the deadline, or
        standing at the goal afterwards) nor when the first hit is a static obstacle, which the
        same path in space meets at any duration."""
        if hit >= len(res.root):
            return False
        static = self.collider.static
        if static is None:
            return True
        g = self.lib.g
        xz, rad = blend_cylinders(g, res.frames_a[hit:hit + 1], res.frames_b[hit:hit + 1], res.root[hit:hit + 1])
        return bool(static(xz)[0] >= rad[0] + self.p.margin)

    def _retimed(self, res, Frow, i, Brow, j, hit: int):
        """Generator: the same splice at the nearest other durations (time resampling within
        eps_t and the window): returns the first that is within eps and collision-free, or
        None; yields :attr:`Step.SPLICE` before the splice and before each final test.

        ``res`` first hit someone at output frame ``hit``; few retimes clear that, so every
        duration is first tested -- all at once, without resampling the rest of the motion --
        on the frames about the same point of its path (:data:`RETIME_NEAR` either side), and
        only a motion clear there is resampled whole for the final test: the same verdicts,
        for a fraction of the work."""
        p = self.p
        m0 = len(res.root) - 1
        raw = int(sum(self.lib.nframes[e] - 1 for e in res.edges))      # source frame steps
        lo_m = int(np.ceil(raw / (1 + p.eps[2]))) + 1
        hi_m = int(np.floor(raw / max(1 - p.eps[2], 1e-3))) - 1
        cands = [m for k in range(1, 64) for m in (m0 + p.retime_step * k, m0 - p.retime_step * k)
                 if lo_m <= m <= hi_m][:p.retime_tries]
        if not cands:
            return None
        yield Step.SPLICE
        src = splice_source(self.lib, self.start, self.goal_cfg, Frow, i, Brow, j)
        # every duration inside the window and eps, tested at once about the same point of
        # its path; then the whole final test of each clear there, in order
        scale = 1.0 / max(m0, 1)
        kept, rows_of = [], []
        for m in cands:
            if not fits(p, self.window_rel, m):
                continue
            a, b, t, s_parts = resample_grid(p, len(src.frames), src.nff, src.nbf, m)
            if not within_eps_rates(resample_rates(src.dp, src.dh, src.N, s_parts), p.eps):
                continue
            at = int(round(hit * m * scale))
            kept.append(m)
            rows_of.append((a, b, t, np.arange(max(at - RETIME_NEAR, 0), min(at + RETIME_NEAR + 1, m + 1))))
        if not kept:
            return None
        counts = np.array([len(r[3]) for r in rows_of], dtype=np.int64)
        root = np.concatenate([resample_rows(src, a, b, t, rows) for a, b, t, rows in rows_of])
        fa = np.concatenate([src.frames[a[rows]] for a, _, _, rows in rows_of])
        fb = np.concatenate([src.frames[b[rows]] for _, b, _, rows in rows_of])
        frames = self.start.frame + np.concatenate([rows for *_, rows in rows_of])
        xz, rad = blend_cylinders(self.lib.g, fa, fb, root)
        near = self.collider.hits_runs(frames, xz, rad + p.margin, counts)
        for m in np.asarray(kept)[~near]:
            yield Step.SPLICE
            r2 = resample_source(p, src, self.goal_node, self.start, int(m))
            if self.collider.final_collision(r2) is None:
                return r2
        return None

    def _perturbed(self, Fp, Bp, nfp, nbp, P):
        """n_m pairs, each a random kept pair with one clip replaced by a parallel alternative."""
        lib, rng = self.lib, self.rng
        Lf, Lb = Fp.shape[1], Bp.shape[1]
        parent = rng.integers(0, len(Fp), size=P)
        if self.compiled:
            # the same draws, in the same order, as the numpy path below
            r_use = rng.random(P)
            r_f = rng.random((P, Lf))
            r_b = rng.random((P, Lb))
            return kernels.perturb(lib, Fp, Bp, nfp, nbp, parent, r_use, r_f, r_b, rng.random(P))
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
        return Fn, Bn, nfn, nbn

    def steps(self):
        """Generator: yields a :class:`~.types.Step` before each bounded piece of work; returns
        the accepted :class:`~.types.SegmentResult` or None (see the attributes)."""
        p, F0, B0 = self.p, self.F0, self.B0
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
        costp, ip, jp = self.costs(Fp, nfp, Bp, nbp)
        self.best = (float(costp[0]), Fp[0].copy(), nfp[0], Bp[0].copy(), nbp[0], int(ip[0]), int(jp[0]))
        if np.isfinite(costp[0]) and costp[0] <= eps_p:
            res = yield from self.accept_steps(costp[0], Fp[0], ip[0], Bp[0], jp[0])
            if res is not None:
                self.collision_at = None
                return res
        P = p.n_m
        while self.iterations < self.max_iter:
            self.iterations += 1
            Fn, Bn, nfn, nbn = self._perturbed(Fp, Bp, nfp, nbp, P)
            sw = min(p.sweep, P)
            if sw:
                rows_new = sweep_rows(self.lib, p, Fp[0], nfp[0], Bp[0], nbp[0], self.start.xzh, self.goal_cfg,
                                      self.rng, sw, pair=self.iterations % 2 == 0)
                if rows_new is not None:
                    Fs, Bs = rows_new
                    k = len(Fs)
                    Fn[P - k:], Bn[P - k:], nfn[P - k:], nbn[P - k:] = Fs, Bs, nfp[0], nbp[0]
                yield Step.COSTS
            cn, inn, jn = self.costs(Fn, nfn, Bn, nbn)
            if p.static_filter and self.collider.static is not None:
                # pairs near acceptance whose parts hit a static obstacle leave the population
                near = np.flatnonzero(cn <= p.static_filter * eps_p)
                if len(near):
                    static = self.collider.static if self.collider.still_static is None else self.collider.still_static
                    okn = pairs_static_clear(self.lib, static, p.margin, Fn[near], Bn[near], inn[near],
                                             jn[near], self.start.xzh, self.goal_cfg, slack=p.static_filter_slack,
                                             memo=self.static_memo)
                    cn[near[~okn]] = np.inf
            allc = np.concatenate([costp, cn])
            Fa, Ba = np.concatenate([Fp, Fn]), np.concatenate([Bp, Bn])
            nfa, nba = np.concatenate([nfp, nfn]), np.concatenate([nbp, nbn])
            ia, ja = np.concatenate([ip, inn]), np.concatenate([jp, jn])
            order = np.argsort(allc, kind="stable")
            if allc[order[0]] < self.best[0]:
                r = order[0]
                self.best = (float(allc[r]), Fa[r].copy(), nfa[r], Ba[r].copy(), nba[r], int(ia[r]), int(ja[r]))
            # splice and test the best new pairs below eps (a pair the final test rejects stays
            # in the population, see docs/decisions.md)
            K0 = len(costp)
            # the new pairs in ``order`` are in their own stable order (the keys of one sort)
            for r in order[order >= K0][:p.splices_per_iteration]:
                if not (allc[r] <= eps_p):
                    break
                yield Step.SPLICE
                res = yield from self.accept_steps(allc[r], Fa[r], ia[r], Ba[r], ja[r])
                if res is not None:
                    self.collision_at = None
                    return res
            # keep the k_m best of old and new
            keep = order[:p.k_m]
            Fp, Bp, nfp, nbp, ip, jp = Fa[keep], Ba[keep], nfa[keep], nba[keep], ia[keep], ja[keep]
            costp = allc[keep]
            if self.collision_at is not None and self.iterations >= p.reseed_after and costp[0] <= eps_p:
                # below eps but colliding for a while: better seeds are needed
                break
            if (p.hopeless_cost and self.iterations >= p.hopeless_after and self.collision_at is None
                    and self.best[0] > p.hopeless_cost * eps_p):
                self.hopeless = True
                break
            yield Step.SEARCH
        return None


def sweep_rows(lib: MotionLibrary, params: SearchParams, Frow, nf, Brow, nb, start_cfg, goal_cfg, rng, k: int,
               pair: bool):
    """Candidate rows from exhaustive replacement at one (``pair`` False) or two adjacent clip
    positions of one motion of the best pair. Returns (F rows, B rows) or None."""
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
    if pair:
        where = set(pos.tolist())
        if c0 + 1 in where:
            cols.append(c0 + 1)
        elif c0 - 1 in where:
            cols.insert(0, c0 - 1)
    options = [np.concatenate([[row[c]], lib.alt_idx[lib.alt_ptr[row[c]]:lib.alt_ptr[row[c] + 1]]]) for c in cols]
    grid = np.stack(np.meshgrid(*options, indexing="ij"), axis=-1).reshape(-1, len(cols))
    if len(cols) == 2 and len(grid) > k:
        if len(grid) > params.sweep_pairs:
            keep = rng.choice(len(grid) - 1, size=params.sweep_pairs - 1, replace=False) + 1
            grid = np.concatenate([grid[:1], grid[np.sort(keep)]])
        # score every combination by where the motion's free end lands: the clips before
        # and after the two positions are one fixed transform each
        a1 = params.alpha[0]
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
