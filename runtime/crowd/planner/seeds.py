"""Greedy seed motions (Sung, Kovar and Gleicher 2005, section 3.2).

A forward seed walks the motion graph from the start through the roadmap's way points; a
backward seed is the same walk on the time-reversed graph from the goal. Each step takes, among
the collision-free edges of the travel state that reduce the error to the current target, the
one that brings the character closest to it (with a two-edge lookahead); at the last way point
the error also counts orientation, and the seed stops when the error stops decreasing.

On top of the paper's planner:

* On a path of several way points the target is a point ``carrot`` metres ahead of the
  character's projection onto the path, so seeds follow the roadmap's line through doors
  instead of cutting towards a way point beyond them; when no edge gains on it, it moves on.
* When improving edges exist but all collide, the seed waits on an idle clip for a planned
  character to pass (``max_waits``) or, short of the target, takes the clear edge that loses
  least (``max_sidesteps``), or turns towards the target (``max_turns``).
* Along a route in space and time (a ``schedule``, :mod:`.route`) the carrot is where the route
  is ``route_lead`` seconds after the seed's clock, and where the route waits for a planned
  character to pass the seed idles, so its motion keeps the route's timing, not only its
  turns (a time budget's pacing then applies only once the route has arrived).
* With a ``time_budget`` (seconds to the goal) the seed prefers the edge whose progress rate
  matches the rate the budget asks for, and idles on the node's self-loop clips while time is
  in surplus, so the seeds already come close to the window the search must meet. The budget
  counts the seed's own state-change prefix (standing up, say) and leaves ``reserve`` seconds
  for the change at the far end (sitting down, picking up).

The seed is a generator (:meth:`GreedySeed.steps`) yielding a :class:`~.types.Step` before each
bounded piece of work.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import shortest_path

from ...motion.graph import TRANSITION
from ...motion.planar import compose, compose1, wrap_angle
from ..clearance import Clearance
from . import kernels
from .collision import Collider
from .library import MotionLibrary
from .params import SearchParams
from .types import Step

__all__ = ["GreedySeed", "fewest_edges_to", "MAX_IDLE_EDGES"]

MAX_IDLE_EDGES = 400     # idle clips a seed may spend waiting (~15 min of the default library's)


def fewest_edges_to(graph, targets: np.ndarray, allowed: np.ndarray, reverse: bool) -> np.ndarray:
    """Fewest edges from every node to any of ``targets`` (edges masked by ``allowed``;
    ``reverse``: on the time-reversed graph)."""
    N = graph.num_nodes
    s, d = (graph.edge_src, graph.edge_dst) if not reverse else (graph.edge_dst, graph.edge_src)
    m = allowed
    # distance to targets = shortest path in the reversed graph from a super source
    A = csr_matrix((np.ones(m.sum()), (d[m], s[m])), shape=(N, N))
    dist = shortest_path(A, unweighted=True, indices=np.asarray(targets), directed=True)
    return np.min(np.atleast_2d(dist), axis=0)


class GreedySeed:
    """One greedy seed motion; see the module docstring.

    Args:
        lib, params, collider: the motion library, the search parameters, the collision tests.
        env: the environment (line-of-sight tests of the carrot), or None.
        compiled: the lookahead and collision gathers by the numba kernels.
        start_node, start_cfg, frame0: where and when the seed starts (for a backward seed: the
            goal's node, configuration and arrival frame).
        waypoints: (n, 2) way points in walking order of this seed.
        final_heading: radians to arrive facing at the last way point, or None.
        travel: the state (walking, carrying) the seed travels in.
        target_nodes: nodes the seed must end on, or None.
        reverse: plan on the time-reversed graph (a backward seed).
        time_budget: seconds to the goal, or None (untimed).
        reserve: seconds left for the change of state at the far end.
        schedule: a route in space and time to keep to, or None: ((k, 2) positions, (k,) clock
            frames) (:func:`.route.timed_route_steps`); a forward seed then aims at where the
            route is ``params.route_lead`` s after its own clock, and idles where the route waits.

    Attributes (after :meth:`steps` finished):
        edges: the edges in walking order of the seed (reversed for a backward seed).
        node: the node it ends on.
        waits: idle clips inserted for planned characters.
    """

    def __init__(self, lib: MotionLibrary, params: SearchParams, collider: Collider, env, compiled: bool,
                 start_node: int, start_cfg: np.ndarray, frame0: int, waypoints: np.ndarray, final_heading,
                 travel: int, target_nodes, reverse: bool, time_budget: float | None = None, reserve: float = 0.0,
                 schedule=None):
        self.lib, self.g, self.p = lib, lib.g, params
        self.collider, self.env, self.compiled = collider, env, compiled
        g = self.g
        self.src, self.dst = (g.edge_src, g.edge_dst) if not reverse else (g.edge_dst, g.edge_src)
        self.disp = lib.disp if not reverse else lib.disp_rev
        self.in_travel = g.edge_state == travel
        self.travel, self.reverse = travel, reverse
        self.node = int(start_node)
        self.cfg = np.asarray(start_cfg, dtype=np.float64)
        self.start_cfg = start_cfg
        self.frame = int(frame0)
        self.edges: list[int] = []
        self.elapsed = 0.0       # seconds of motion so far (+ the reserve, once past the prefix)
        self.idled = 0           # idle clips spent waiting (not counted against max_seed_edges)
        self.waits = self.sidesteps = self.turns = 0
        self.waypoints = waypoints
        self.final_heading = final_heading
        self.target_nodes = None if target_nodes is None else np.asarray(target_nodes)
        self.time_budget, self.reserve = time_budget, reserve
        self.a1 = params.alpha[0]
        self.t_sign = -1 if reverse else 1
        self.face_off = np.pi if reverse else 0.0   # played backwards, a clip travels against its facing
        # planned characters count where the seed's frames mean something: forward, or
        # backward from a time window
        self.timed = (not reverse) or time_budget is not None
        # the way-point polyline and the carrot on it
        self.seg_len = np.hypot(*np.diff(waypoints, axis=0).T) if len(waypoints) > 1 else np.zeros(0)
        self.cum = np.concatenate([[0.0], np.cumsum(self.seg_len)])
        self.total = float(self.cum[-1])
        self.s_proj = 0.0
        self.ahead = params.carrot
        self.tp = waypoints[-1]
        self.schedule = None if (schedule is None or reverse) else \
            (np.asarray(schedule[0], dtype=np.float64), np.asarray(schedule[1], dtype=np.float64))
        self.lead = params.route_lead * params.fps
        self.goal_xz = np.asarray(waypoints[-1], dtype=np.float64)
        self.home_xz = np.asarray(start_cfg[:2], dtype=np.float64)
        # nodes where a seed can stand and wait: a self-loop clip of the travel state that
        # stays on the spot
        src, dst, disp = self.src, self.dst, self.disp
        still_loop = self.in_travel & (src == dst) & (np.hypot(disp[:, 0], disp[:, 1]) < 0.1)
        self.idle_node = np.zeros(g.num_nodes, dtype=bool)
        self.idle_node[src[still_loop]] = True
        it = self.in_travel
        self.turn_rate = float(np.max(np.abs(disp[it, 2]) / lib.dur[it])) if it.any() else 1.0

    # -- bookkeeping -----------------------------------------------------------------------------
    def advance(self, e) -> None:
        """Take edge ``e``."""
        self.edges.append(int(e))
        self.cfg = compose1(self.cfg, self.disp[e])
        self.node = int(self.dst[e])
        self.frame += self.t_sign * int(self.lib.nframes[e] - 1)
        self.elapsed += float(self.lib.dur[e])

    def self_loops(self, out: np.ndarray) -> np.ndarray:
        """The clips of ``out`` that return to the current node on the spot."""
        return out[(self.dst[out] == self.node) & (np.hypot(self.disp[out, 0], self.disp[out, 1]) < 0.1)]

    def most_still(self, loops: np.ndarray) -> int:
        return int(loops[np.argmin(np.hypot(self.disp[loops, 0], self.disp[loops, 1]))])

    # -- errors and the carrot -------------------------------------------------------------------
    def err(self, cfgs, final):
        """Position error to the target, plus how far the character faces away from it (so
        turning on the spot counts as progress); near the goal (within the approach radius)
        the goal orientation counts instead (1 cm = 1 deg)."""
        tp = self.tp
        dx = tp[0] - cfgs[..., 0]
        dz = tp[1] - cfgs[..., 1]
        e = np.hypot(dx, dz)
        bearing = np.arctan2(dx, dz)
        facing = self.p.facing_weight * np.abs(wrap_angle(cfgs[..., 2] + self.face_off - bearing)) * np.minimum(e, 1.0)
        if final and self.final_heading is not None:
            near = e < self.p.approach_radius
            return e + np.where(near, self.a1 * np.abs(wrap_angle(cfgs[..., 2] - self.final_heading)),
                                self.a1 * np.pi + facing)
        return e + facing

    def path_point(self, ss):
        seg_len, cum, waypoints = self.seg_len, self.cum, self.waypoints
        j = np.clip(np.searchsorted(cum, ss, side="right") - 1, 0, len(seg_len) - 1)
        u = (ss - cum[j]) / np.maximum(seg_len[j], 1e-12)
        return waypoints[j] + u[:, None] * (waypoints[j + 1] - waypoints[j])

    def place_carrot(self) -> bool:
        """Set the target: the point ``ahead`` metres along the way-point polyline beyond the
        character's projection onto it (the projection only moves forward, and only within 3 m
        of the last one, so a path that doubles back is not short-cut). Returns whether the
        target is the last way point."""
        waypoints, cfg = self.waypoints, self.cfg
        if self.schedule is not None:
            return self._scheduled_carrot()
        if len(waypoints) <= 2:         # a straight path: aim at its end, as the paper does
            self.tp = waypoints[-1]
            return True
        a = waypoints[:-1]
        ab = waypoints[1:] - a
        t = np.clip(((cfg[:2] - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12), 0.0, 1.0)
        d = np.hypot(*(a + t[:, None] * ab - cfg[None, :2]).T)
        s_all = self.cum[:-1] + t * self.seg_len
        d = np.where((s_all >= self.s_proj - 1e-9) & (self.cum[:-1] <= self.s_proj + 3.0), d, np.inf)
        k = int(np.argmin(d))
        if np.isfinite(d[k]):
            self.s_proj = max(self.s_proj, float(s_all[k]))
        sc = min(self.s_proj + self.ahead, self.total)
        if sc >= self.total - 1e-9 or self.total - self.s_proj < self.p.carrot_final:
            self.tp = waypoints[-1]
            return True
        if self.env is not None:
            # the target must be in sight: a carrot moved round a corner (a row's end, a door
            # post) would pull the seed into the obstacle's far side
            ss = np.linspace(self.s_proj, sc, 8)
            seen = self.in_sight(cfg[:2], self.path_point(ss), 0.55)
            if seen[0]:
                k = int(np.argmin(seen)) - 1 if not seen.all() else len(ss) - 1
                sc = float(ss[k])
        self.tp = self.path_point(np.array([sc]))[0]
        return False

    def in_sight(self, a, points, radius: float) -> np.ndarray:
        """(n,) bool: the straight moves from ``a`` to ``points`` keep ``radius`` from every
        obstacle (:meth:`~runtime.crowd.environment.Environment.segment_clear`). A move no longer
        than the static clearance at ``a`` less ``radius`` stays inside the free disc round
        ``a`` and is clear without the exact test (the clearance never overestimates)."""
        static = self.collider.static
        if not isinstance(static, Clearance):
            return self.env.segment_clear(a[None], points, radius)
        seen = np.hypot(points[:, 0] - a[0], points[:, 1] - a[1]) + radius <= float(static(a[None])[0])
        if not seen.all():
            rest = ~seen
            seen[rest] = self.env.segment_clear(a[None], points[rest], radius)
        return seen

    def _scheduled_carrot(self) -> bool:
        """The target on a timed route: where the route is ``lead`` frames after the seed's
        clock (the route's end once it has arrived). Returns whether it is the end."""
        sxz, sf = self.schedule
        t = self.frame + self.lead
        if t >= sf[-1] or len(sf) < 2:
            self.tp = self.waypoints[-1]
            return True
        i = int(np.searchsorted(sf, t, side="right")) - 1
        u = (t - sf[i]) / max(sf[i + 1] - sf[i], 1e-9)
        self.tp = sxz[i] + u * (sxz[i + 1] - sxz[i])
        return False

    def _keep_to_schedule(self, out) -> bool:
        """On a timed route, nothing gains on a target close by: the route waits here (for a
        planned character to pass). Idle on the node's most stationary self-loop clip, or stop
        on a clip to a node where one can stand, if that is clear. Returns whether it idled."""
        if self.schedule is None or self.idled >= MAX_IDLE_EDGES:
            return False
        if np.hypot(self.cfg[0] - self.tp[0], self.cfg[1] - self.tp[1]) > self.p.reach_radius:
            return False
        w = self.wait_clip(out, stop=True)
        if len(w) and self.clear_here(w, True)[0]:
            self.advance(int(w[0]))
            self.idled += 1
            return True
        return False

    # -- collision tests -------------------------------------------------------------------------
    def clear_both(self, es, moving):
        """(collision-free, and also ``static_prefer`` clear of static obstacles) per edge of
        ``es`` from the current configuration and frame."""
        es = np.asarray(es, dtype=np.int64)
        if not self.reverse:
            return self.collider.clear_edges(es, self.cfg, np.full(len(es), self.frame), moving, self.compiled)
        # a backward seed's clip ends where the seed is: it is placed from where it starts
        starts = compose(self.cfg[None], self.disp[es])
        return self.collider.clear_edges(es, starts, self.frame - (self.lib.nframes[es] - 1),
                                         moving and self.p.backward_moving, self.compiled)

    def clear_here(self, es, moving):
        """Which edges from the current configuration and frame are collision-free."""
        return self.clear_both(es, moving)[0]

    def roomy(self, es):
        """Edges whose end leaves room to walk on: ``end_clearance`` from the static obstacles
        (a seed that stops closer, at a corner, cannot leave it), except near the segment's
        ends, where the goal or the start itself may be close to an obstacle (a seat or a box
        by a wall)."""
        static, room = self.collider.static, self.p.end_clearance
        if static is None or not room:
            return np.ones(len(es), dtype=bool)
        ends = compose(self.cfg[None], self.disp[es])[:, :2]
        near = np.hypot(ends[:, 0] - self.goal_xz[0], ends[:, 1] - self.goal_xz[1]) < self.p.approach_radius
        near |= np.hypot(ends[:, 0] - self.home_xz[0], ends[:, 1] - self.home_xz[1]) < self.p.reach_radius
        return near | (static(ends) >= room)

    def stop_clip(self, out):
        """The shortest clear clip among ``out`` to a node where one can stand and wait (at
        most one, as an array)."""
        disp = self.disp
        stops = out[self.idle_node[self.dst[out]] & (np.hypot(disp[out, 0], disp[out, 1]) < 1.0)]
        w = stops[np.argsort(np.hypot(disp[stops, 0], disp[stops, 1]), kind="stable")][:6]
        return w[self.clear_here(w, self.timed)][:1] if len(w) else w

    def wait_clip(self, out, stop: bool):
        """The clip to wait on (at most one, as an array): the node's most stationary self-loop;
        without one and with ``stop``, :meth:`stop_clip`."""
        loops = self.self_loops(out)
        if len(loops):
            return np.array([self.most_still(loops)])
        return self.stop_clip(out) if stop else loops

    def first_ok(self, cand):
        """The first of ``cand`` that is clear and leaves room to walk on -- the first that
        also keeps ``static_prefer`` from static obstacles if any does -- or None."""
        cand = np.asarray(cand, dtype=np.int64)
        ok, roomier = self.clear_both(cand, self.timed)
        room_ok = self.roomy(cand)
        ok &= room_ok
        roomier &= room_ok
        if roomier.any():
            return int(cand[np.argmax(roomier)])
        return int(cand[np.argmax(ok)]) if ok.any() else None

    # -- the walk ---------------------------------------------------------------------------------
    def steps(self):
        """Generator: yields a :class:`~.types.Step` before each bounded piece of work; returns
        (edges in walking order, last node)."""
        g, p = self.g, self.p
        if g.node_state[self.node] != self.travel:
            yield from self._leave_state()
        self.elapsed += float(self.reserve)
        best = None
        table = self.lib.lookahead(self.reverse, self.travel)
        tgt = self.target_nodes
        while len(self.edges) - self.idled < p.max_seed_edges:
            final = self.place_carrot()
            out, comb, dur2, disp_out, dur_out = table[self.node]
            if len(out) == 0:
                break
            e, span, end_xz, ends, cur = self._lookahead(out, comb, dur2, disp_out, dur_out, final)
            if self.time_budget is not None and (final or self.schedule is None):
                order = self._paced_order(out, e, span, end_xz, final)
                if order is None:          # idled a clip on the spot: time in surplus
                    continue
            else:
                order = np.argsort(e, kind="stable")
            # "the error stops decreasing": an edge must gain at least min_gain (1 cm / 1 deg)
            # and min_gain_rate per second of motion, or seeds creep on for tiny gains
            order = order[e[order] < cur - np.maximum(p.min_gain, p.min_gain_rate * span[order])]
            pick = None
            if len(order):
                pick = self.first_ok(out[order[:12]])
                if pick is None and self._wait_for_others(out, out[order[:12]]):
                    yield Step.SEED_EDGE
                    continue
            if pick is None and not final and self._keep_to_schedule(out):
                yield Step.SEED_EDGE
                continue
            if pick is None:
                alt = self._sidestep_or_turn(out, order, e, ends, comb)
                if alt is not None:
                    self.advance(alt)
                    yield Step.SEED_EDGE
                    continue
                if not final:
                    # nothing gains on this target: aim further along the path
                    self.ahead += p.carrot
                    self.lead += p.fps
                    self.sidesteps = 0
                    yield Step.SEED_EDGE
                    continue
                if self._stop_when_blocked_early(out, order):
                    yield Step.SEED_EDGE
                    continue
                break
            self.advance(pick)
            self.ahead = p.carrot
            self.lead = p.route_lead * p.fps
            yield Step.SEED_EDGE
            if tgt is not None and self.node in tgt:
                best = (list(self.edges), self.node, self.cfg.copy())
        if tgt is not None:
            if best is not None:
                return best[0], best[1]
            yield from self._path_to_target_nodes()
        return self.edges, self.node

    def _leave_state(self):
        """The prefix: leave the start state for the travel state by the fewest edges. With
        time to spare, first wait where the character stands (a still start node's idle clips):
        the time left over after the prefix would otherwise be idled wherever the prefix ended,
        a step away -- in a doorway, say."""
        g, lib, src, dst, disp = self.g, self.lib, self.src, self.dst, self.disp
        node = self.node
        tnodes = np.flatnonzero(g.node_state == self.travel)
        if not self.reverse and self.time_budget is not None:
            loops = np.flatnonzero((src == node) & (dst == node) & (np.hypot(disp[:, 0], disp[:, 1]) < 0.1))
            if len(loops):
                loop = int(loops[np.argmin(np.hypot(disp[loops, 0], disp[loops, 1]))])
                wps = self.waypoints
                path_len = float(np.hypot(*np.diff(wps, axis=0).T).sum()) if len(wps) > 1 else 0.0
                need = lib.change_time([node], tnodes) + self.reserve + path_len / 1.1
                need = need if np.isfinite(need) else self.time_budget
                while self.time_budget - self.elapsed - need > lib.dur[loop] + 0.5 and self.idled < MAX_IDLE_EDGES:
                    self.advance(loop)
                    self.idled += 1
                yield Step.SEED_PATH
        dist = fewest_edges_to(g, tnodes, np.ones(g.num_edges, bool), self.reverse)
        yield Step.SEED_PATH
        target = self.waypoints[min(1, len(self.waypoints) - 1)]
        yield from self._fewest_path(dist, target, np.ones(g.num_edges, bool))

    def _lookahead(self, out, comb, dur2, disp_out, dur_out, final):
        """The best error reachable with one more edge after each candidate of ``out``:
        (error, duration of the one or two edges, where they end (xz), where each candidate
        ends, the current error)."""
        p, cfg = self.p, self.cfg
        if self.compiled:
            return kernels.lookahead_errors(cfg, disp_out, comb, dur_out, dur2, self.tp, final, self.final_heading,
                                            p.facing_weight, self.face_off, p.approach_radius, self.a1)
        ends = compose(cfg[None], disp_out)
        ends2 = compose(cfg[None, None], comb)
        e2 = np.nan_to_num(self.err(ends2, final), nan=np.inf)
        k2 = np.argmin(e2, axis=1)
        rows = np.arange(len(out))
        best2 = e2[rows, k2]
        e1 = self.err(ends, final)
        use2 = best2 < e1
        e = np.where(use2, best2, e1)
        span = dur_out + np.where(use2, dur2[rows, k2], 0.0)
        end_xz = np.where(use2[:, None], ends2[rows, k2, :2], ends[:, :2])
        cur = float(self.err(cfg, final))
        return e, span, end_xz, ends, cur

    def _paced_order(self, out, e, span, end_xz, final):
        """With a time budget: the candidates ordered by how well their progress rate matches
        the rate the budget asks for; or None after idling one clip on the spot because time
        is in surplus. Surplus time is spent at the start of the segment, where the character
        already stands: a forward seed idles first; a backward seed (which runs back from the
        goal) never idles, or the motion would stand at the goal early, in the way of
        characters passing before the window opens."""
        cfg, tp, p, lib = self.cfg, self.tp, self.p, self.lib
        remaining = float(np.hypot(cfg[0] - tp[0], cfg[1] - tp[1])) + \
            (0.0 if final else self.total - min(self.s_proj + self.ahead, self.total))
        # facing away from the target, turning round takes time too (walking on while turning,
        # for a state without turns on the spot): half the state's top turn rate
        facing_off = float(np.abs(wrap_angle(cfg[2] + self.face_off - np.arctan2(tp[0] - cfg[0], tp[1] - cfg[1]))))
        remaining += 1.1 * facing_off / max(0.5 * self.turn_rate, 1e-3) if facing_off > np.pi / 4 else 0.0
        left = self.time_budget - self.elapsed
        loops = self.self_loops(out)
        if (not self.reverse or p.backward_idle) and len(loops) and left - remaining / 1.1 > lib.dur[loops].min() + 0.5 \
                and self.idled < MAX_IDLE_EDGES:
            self.advance(self.most_still(loops))
            self.idled += 1
            return None
        want = remaining / max(left, 0.3)
        pos_now = float(np.hypot(cfg[0] - tp[0], cfg[1] - tp[1]))
        pos_new = np.hypot(end_xz[:, 0] - tp[0], end_xz[:, 1] - tp[1])
        rate = (pos_now - pos_new) / span
        # slow down by walking slower, not by wandering sideways: penalise the part of the
        # travelled distance that is not progress
        travelled = np.hypot(end_xz[:, 0] - cfg[0], end_xz[:, 1] - cfg[1])
        waste = np.maximum(travelled - (pos_now - pos_new), 0.0) / span
        return np.argsort(np.abs(rate - want) + 0.5 * waste + 0.1 * (e - e.min()), kind="stable")

    def _wait_for_others(self, out, cand) -> bool:
        """Every improving edge runs into someone already planned (at least one is clear of the
        static obstacles: waiting cannot move a wall): wait for them to pass on the node's most
        stationary self-loop clip, if that is clear. A walking hub has no such clip: with time
        to spare (a window), stop first, on the shortest clear clip to a node where one can
        stand and wait (without a window, stopping for someone walking the same way rarely
        splices clear, see docs/decisions.md). Returns whether it waited."""
        p = self.p
        if not (self.waits < p.max_waits and self.collider.collide is not None and self.timed
                and self.clear_here(cand, False).any()):
            return False
        w = self.wait_clip(out, stop=p.stop_to_wait and self.time_budget is not None)
        if len(w) and self.clear_here(w, self.timed)[0]:
            self.waits += 1
            self.advance(int(w[0]))
            return True
        return False

    def _sidestep_or_turn(self, out, order, e, ends, comb):
        """A clear edge that does not gain on the target, or None. Blocked short of the target
        (an obstacle or a planned character in the way): the clear edge that loses least,
        rather than skipping the way point (``max_sidesteps``). Facing away from the target with
        nothing that gains on it (a character holding a box has no clip that turns on the spot:
        it turns while walking on): the clear edge that turns it furthest towards the target
        (``max_turns``)."""
        cfg, tp, p, disp = self.cfg, self.tp, self.p, self.disp
        far = float(np.hypot(cfg[0] - tp[0], cfg[1] - tp[1])) > p.reach_radius
        alt = None
        if far and len(order) and self.sidesteps < p.max_sidesteps:
            moves = np.hypot(ends[:, 0] - cfg[0], ends[:, 1] - cfg[1]) > 0.3
            cand = out[np.argsort(np.where(moves, e, np.inf), kind="stable")[:24]]
            cand = cand[np.hypot(*(compose(cfg[None], disp[cand])[:, :2] - cfg[None, :2]).T) > 0.3]
            alt = self.first_ok(cand)
            self.sidesteps += alt is not None
        elif far and not len(order) and self.turns < p.max_turns:
            face_off = self.face_off

            def ang(c):
                return np.abs(wrap_angle(c[..., 2] + face_off - np.arctan2(tp[0] - c[..., 0], tp[1] - c[..., 1])))

            a_now = float(ang(cfg))
            if a_now > np.pi / 3:
                # with the lookahead: the best angle one more edge can reach
                a2 = np.nan_to_num(ang(compose(cfg[None, None], comb)), nan=np.inf)
                k2t = np.argmin(a2, axis=1)
                a_new = np.minimum(ang(ends), a2[np.arange(len(out)), k2t])
                score = a_new + 0.3 * np.hypot(ends[:, 0] - tp[0], ends[:, 1] - tp[1])
                turning = np.flatnonzero(a_new < a_now - 0.1)
                alt = self.first_ok(out[turning[np.argsort(score[turning], kind="stable")][:24]])
                self.turns += alt is not None
        return alt

    def _stop_when_blocked_early(self, out, order) -> bool:
        """Blocked right at the start by someone planned earlier (the one ahead in a crowd that
        sets off together) with no wait and no sidestep: rather than end the seed a step from
        the start, stop and wait, untimed as well. Returns whether it stopped."""
        p = self.p
        if len(order) and len(self.edges) - self.idled < 3 and self.waits < p.max_waits and p.stop_to_wait \
                and self.collider.collide is not None and self.timed and self.clear_here(out[order[:12]], False).any():
            w = self.stop_clip(out)
            if len(w):
                self.waits += 1
                self.advance(int(w[0]))
                return True
        return False

    def _path_to_target_nodes(self):
        """Fallback: the fewest-edge path to a required end node (ties by the error)."""
        g, tgt = self.g, self.target_nodes
        allowed = self.in_travel | (g.edge_state == TRANSITION) | np.isin(self.dst, tgt)
        dist = fewest_edges_to(g, tgt, allowed, self.reverse)
        if not np.isfinite(dist[self.node]):
            allowed = np.ones(g.num_edges, bool)
            dist = fewest_edges_to(g, tgt, allowed, self.reverse)
        yield from self._fewest_path(dist, self.waypoints[-1], allowed,
                                     clear=lambda es: self.clear_here(es, not self.reverse))

    def _fewest_path(self, dist, target_xz, allowed, clear=None):
        """Generator: fewest edges to the nodes ``dist`` measures, ties broken by the distance to
        ``target_xz``; with ``clear`` (edges -> bool array), collision-free edges are preferred."""
        src, dst, disp = self.src, self.dst, self.disp
        guard = 0
        while np.isfinite(dist[self.node]) and dist[self.node] > 0 and guard < 64:
            guard += 1
            n = self.node
            out = np.flatnonzero((src == n) & allowed & (dist[dst] == dist[n] - 1))
            if len(out) == 0:
                break
            ends = compose(self.cfg[None], disp[out])
            e = np.hypot(ends[:, 0] - target_xz[0], ends[:, 1] - target_xz[1])
            order = out[np.argsort(e, kind="stable")]
            pick = order[0]
            if clear is not None:
                ok = clear(order[:8])
                if ok.any():
                    pick = order[:8][np.argmax(ok)]
            self.advance(pick)
            yield Step.SEED_PATH
