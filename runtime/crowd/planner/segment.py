"""One segment of goal-directed synthesis (Sung, Kovar and Gleicher 2005, section 3).

A segment takes a character from a start configuration (node N_s, position p_s, heading
theta_s, time t_s) to a goal (node N_e, p_e, theta_e) inside an optional time window
[t_a, t_b]:

1. Seeds (section 3.2, :mod:`.seeds`): a greedy forward motion M_f from the start through the
   roadmap's way points and a greedy backward motion M_b that ends exactly in the goal. Both
   stay inside the segment's travel state; entering or leaving another state (sit down, stand
   up, pick up, put down) uses the fewest-edge path.
2. Search (section 3.3, :mod:`.search`, :mod:`.costs`): the splice cost Eq. 1 minimised over
   where the two motions meet (Eq. 2); with eps = (eps_p m/s, eps_theta deg/s, eps_t s/s) the
   units are a1 = eps_p / eps_theta, a2 = eps_p / eps_t, so "C' <= eps_p" is the paper's test
   (1 cm = 1 deg = 1/30 s with the default eps). Perturbed pairs are costed as arrays.
3. Splice (section 3.3, steps 1-4, :mod:`.splice`): displacement maps and time resampling
   make position, orientation, pose and arrival time exact; a final collision test
   (:mod:`.collision`) rejects the splice.

:meth:`SegmentPlanner.run` is a generator: every ``next()`` does a bounded amount of work and
the value it yields names the kind of the next step (:class:`~.types.Step`), so the runtime can
time-slice planning under a per-tick budget (section 5: "the search can be broken into
stages"). :func:`run_to_completion` runs it in one go.
"""
from __future__ import annotations

import numpy as np

from ...motion.graph import STATES
from ...motion.planar import compose, compose1
from . import kernels
from ..clearance import with_discs
from .bend import bend_around
from .collision import Collider
from .library import MotionLibrary
from .motion_cache import task_key
from .params import SearchParams
from .search import RandomizedSearch
from .seeds import GreedySeed
from .short import SHORT_DISTANCE, short_move
from .splice import splice
from .types import Config, Goal, SegmentResult, Step
from .waypoints import segment_waypoints

__all__ = ["SegmentPlanner", "run_to_completion", "DETOURS"]

DETOURS = (1.2, 2.2, 3.2)      # m beside a collision where new way points are tried, each side in turn
BEND_RADIUS = 0.5              # m: a walking character's disc (plus the margin) that way points bend round


def run_to_completion(gen):
    """Run a planner generator to its end and return its value."""
    try:
        while True:
            next(gen)
    except StopIteration as e:
        return e.value


class SegmentPlanner:
    """Plans segments of one character; see the module docstring.

    Args:
        lib: the motion library.
        static, collide, collide_first, collide_runs: the obstacles (:mod:`.collision`).
        roadmap, env: the probabilistic roadmap and the environment (way points); may be None.
        params: the search parameters (default: the library's).

    Attributes:
        cache: a :class:`~.motion_cache.MotionCache` shared by the planners of one crowd, or
            None: motions found for other characters' same tasks, tried before a search.
        compiled: splice costs, seed lookahead and collision gathers by the numba kernels.
        waited: idle clips the last seed of :meth:`greedy` inserted for planned characters.
        standing: ``standing(frame) -> (xz (M, 2), radius (M,))``: characters who stand still
            from ``frame`` on (not planned yet; in the World, idle or queued), which the way
            points bend round; or None.
        still: ``still(frame) -> (xz (M, 2), radius (M,))``: everyone who stays put from
            ``frame`` to the end (the standing ones and planned characters who have stopped
            for good), obstacles of the search's static filter for a segment starting then; or None.
    """

    def __init__(self, lib: MotionLibrary, static=None, collide=None, roadmap=None, env=None,
                 params: SearchParams | None = None, collide_first=None, collide_runs=None):
        self.lib = lib
        self.g = lib.g
        self.p = params or lib.params
        self.collider = Collider(lib, self.p, static, collide, collide_first, collide_runs)
        self.roadmap = roadmap
        self.env = env
        self.compiled = kernels.ENABLED
        self.cache = None
        self.waited = 0
        self.standing = None
        self.still = None
        self._still_memo = (None, None)

    @property
    def hold(self):
        """``hold(res) -> (frames, xz, radius)`` or None: where the character stays after the
        segment, tested with it (:attr:`Collider.hold`)."""
        return self.collider.hold

    @hold.setter
    def hold(self, fn):
        self.collider.hold = fn

    @property
    def deadline(self):
        """The last frame a motion may end on, or None (:attr:`Collider.deadline`)."""
        return self.collider.deadline

    @deadline.setter
    def deadline(self, frame):
        self.collider.deadline = frame

    def final_collision(self, res: SegmentResult):
        """The final test of section 3.3 (:meth:`Collider.final_collision`)."""
        return self.collider.final_collision(res)

    def travel_state(self, start_node: int) -> int:
        """The state a segment travels in: carrying from a carrying node, else walking."""
        s0 = int(self.g.node_state[start_node])
        return STATES.index("carrying") if s0 == STATES.index("carrying") else STATES.index("walking")

    def waypoints(self, start: Config, goal: Goal) -> np.ndarray:
        """The segment's way points (:func:`.waypoints.segment_waypoints`), bent around the
        discs of :attr:`standing` (:func:`.bend.bend_around`)."""
        pts = segment_waypoints(self.lib, self.p, self.roadmap, self.env, start, goal)
        if self.standing is not None:
            xz, r = self.standing(start.frame)
            if len(xz):
                pts = bend_around(pts, xz, r, BEND_RADIUS + self.p.margin, self.env)
        return pts

    def _still_static(self, start: Config, goal: Goal):
        """The static clearance with the discs of :attr:`still` at the segment's start frame
        (those touching its start or goal left out: they are the final test's to judge), or
        None. The last one made is kept: the discs change only when someone is planned."""
        base = self.collider.static
        if self.still is None or base is None or getattr(base, "compiled_args", None) is None:
            return None
        xz, r = self.still(start.frame)
        if len(xz):
            near = self.lib.max_reach + self.p.margin
            keep = ((np.hypot(xz[:, 0] - start.x, xz[:, 1] - start.z) > r + near)
                    & (np.hypot(xz[:, 0] - goal.position[0], xz[:, 1] - goal.position[1]) > r + near))
            xz, r = xz[keep], r[keep]
        if not len(xz):
            return None
        key = np.concatenate([xz.ravel(), r]).round(3).tobytes()
        if self._still_memo[0] != key:
            # the filter reads a part's samples up to its clip's reach from where the clip starts
            pad = float(self.lib.samp_reach.max()) + 4 * base.offset + 0.5
            self._still_memo = (key, with_discs(base, xz, r, pad))
        return self._still_memo[1]

    def seed(self, start_node: int, start_cfg, frame0: int, waypoints, final_heading, travel: int, target_nodes,
             reverse: bool, time_budget: float | None = None, reserve: float = 0.0, schedule=None) -> GreedySeed:
        """A :class:`~.seeds.GreedySeed` with this planner's obstacles."""
        return GreedySeed(self.lib, self.p, self.collider, self.env, self.compiled, start_node, start_cfg, frame0,
                          waypoints, final_heading, travel, target_nodes, reverse, time_budget, reserve, schedule)

    def greedy(self, *args, **kwargs) -> tuple[list, int]:
        """A seed (:meth:`seed`'s arguments) run to completion: (edges, last node)."""
        s = self.seed(*args, **kwargs)
        out = run_to_completion(s.steps())
        self.waited = s.waits
        return out

    def run(self, start: Config, goal: Goal, rng: np.random.Generator, name: str = "", n_max: int | None = None,
            waypoints=None, schedule=None):
        """Generator: yields the kind of each next step (:class:`~.types.Step`); returns a
        :class:`~.types.SegmentResult`. ``n_max``: the iteration limit (default ``params.n_max``);
        ``waypoints``: (n, 2) way points to seed along instead of the roadmap's; ``schedule``:
        the timed route they come from (:class:`~.seeds.GreedySeed`), kept to by the first
        forward seed.

        Seeds are made from the roadmap's way points; the randomized search then runs on them.
        When the search keeps finding splices below eps that collide with characters already
        planned (section 3.3's final test), the seeds are made again through a detour way point
        beside the first collision, alternately left and right and further out (:data:`DETOURS`);
        the iterations of all attempts count against N_max. A search that stays far above eps
        (``params.hopeless_cost``; :attr:`.search.RandomizedSearch.hopeless`) ends the segment's
        search: its seeds cannot be adjusted into the goal, and the ladder tries what can.

        With a :attr:`cache`, motions found earlier for the same task (another character's,
        placed at this start) are tried first, each with the final collision test; the search
        runs only if none is clear, and its clean result is kept for the next.
        """
        g, lib, p = self.g, self.lib, self.p
        key = None
        if self.cache is not None:
            key = task_key(start, goal, p.fps)
            for k, res in self.cache.candidates(key, start, goal):
                if self.final_collision(res) is None:
                    self.cache.used(key, k)
                    return res
            self.cache.misses += 1
        n_max = p.n_max if n_max is None else int(n_max)
        travel = self.travel_state(start.node)
        base = self.waypoints(start, goal) if waypoints is None else np.asarray(waypoints, dtype=np.float64)
        self.collider.still_static = self._still_static(start, goal)
        yield Step.SEED_EDGE
        tgt = goal.nodes
        budget = None
        window_rel = None
        if goal.window is not None:
            budget = max(0.5, 0.5 * (goal.window[0] + goal.window[1]) - start.frame / p.fps)
            t0 = start.frame / p.fps
            window_rel = (goal.window[0] - t0, goal.window[1] - t0)
        eps_p = p.eps[0]
        reserve_f, reserve_b = self._reserves(start, goal, travel, budget)
        queue = [base]
        tried_detours = 0
        iterations = 0
        best_overall = None
        result = None
        goal_node = goal_cfg = None
        per_attempt = max(60, p.n_max // 6)     # reseeds at the same points whatever the limit
        short = (np.hypot(goal.position[0] - start.x, goal.position[1] - start.z) < SHORT_DISTANCE
                 and g.node_state[start.node] == travel)
        while result is None and iterations < n_max and queue:
            wps = queue.pop(0)
            timed = schedule if wps is base else None
            F0, f_end = yield from self.seed(start.node, start.xzh, start.frame, wps, goal.heading, travel, tgt,
                                             False, budget, reserve_f, timed).steps()
            if not F0:
                F0, f_end = self._nearest_out_edge(start, goal, travel)
            yield Step.SEED_EDGE
            if goal_node is None:
                goal_node, goal_cfg = self._goal_end(start, goal, F0, f_end, travel)
            # the backward seed runs back from the arrival: with a window, about its middle
            goal_frame = int(round(p.fps * 0.5 * (goal.window[0] + goal.window[1]))) if goal.window else start.frame
            B0r, _ = yield from self.seed(goal_node, goal_cfg, goal_frame, wps[::-1], start.heading, travel,
                                          np.array([start.node]) if g.node_state[start.node] == travel else None,
                                          True, budget, reserve_b).steps()
            B0 = B0r[::-1]
            yield Step.SEARCH
            if short:
                short = False
                quick = RandomizedSearch(lib, p, self.collider, self.compiled, start, goal_cfg, goal_node, F0, B0,
                                         window_rel, rng, 0)
                result = yield from short_move(quick, travel)
                iterations += quick.iterations
                if result is not None:
                    break
            search = RandomizedSearch(lib, p, self.collider, self.compiled, start, goal_cfg, goal_node, F0, B0,
                                      window_rel, rng, min(per_attempt, n_max - iterations))
            result = yield from search.steps()
            iterations += search.iterations
            best = search.best
            if best is not None and (best_overall is None or best[0] < best_overall[0]):
                best_overall = best
            if result is None and search.collision_at is not None and tried_detours < 2 * len(DETOURS):
                detour = self._detour(search.collision_at, tried_detours)
                if self.env is None or self.env.distance(detour[None])[0] > 0.5:
                    cxz = search.collision_at[0]
                    seg = int(np.argmin(np.hypot(*(base[:-1] - cxz).T))) if len(base) > 2 else 0
                    queue.append(np.concatenate([base[:seg + 1], detour[None], base[seg + 1:]]))
                tried_detours += 1
                if not queue:
                    queue.append(base)
            elif result is None and not queue and not search.hopeless:
                queue.append(base)
        if result is None:
            cost, Frow, nf, Brow, nb, i, j = best_overall
            res = splice(lib, p, start, goal_cfg, goal_node, Frow, i, Brow, j, window_rel, force=True)
            res.collided = self.final_collision(res) is not None
            res.ok = False
            res.cost = cost
            res.warning = (f"{name or 'character'}: no motion within eps after {iterations} iterations "
                           f"(best cost {cost / eps_p:.2f} x eps{', collides' if res.collided else ''}); using the best pair")
            result = res
        result.iterations = iterations
        if key is not None and result.ok and not result.warning:
            self.cache.store(key, start, result)
        return result

    def _reserves(self, start: Config, goal: Goal, travel: int, budget):
        """Seconds the seeds leave for a change of state at their far ends (the fewest-edge
        paths of section 3.2): the forward seed's into the goal pose, the backward seed's out
        of the start pose."""
        g, lib = self.g, self.lib
        travel_nodes = np.flatnonzero(g.node_state == travel)
        reserve_f = reserve_b = 0.0
        if budget is not None:
            if goal.nodes is not None:
                reserve_f = lib.change_time(travel_nodes, goal.nodes)
            reserve_b = lib.change_time([start.node], travel_nodes)
            reserve_f = reserve_f if np.isfinite(reserve_f) else 0.0
            reserve_b = reserve_b if np.isfinite(reserve_b) else 0.0
        return reserve_f, reserve_b

    def _nearest_out_edge(self, start: Config, goal: Goal, travel: int):
        """Already as close as the graph gets: the out-edge that ends nearest the goal, so the
        segment has a motion to adjust. Returns ([edge], its end node)."""
        g = self.g
        out = g.out_edges(start.node)
        out = out[g.edge_state[out] == travel] if np.any(g.edge_state[out] == travel) else out
        ends = compose(start.xzh[None], self.lib.disp[out])
        e0 = int(out[np.argmin(np.hypot(ends[:, 0] - goal.position[0], ends[:, 1] - goal.position[1]))])
        return [e0], int(g.edge_dst[e0])

    def _goal_end(self, start: Config, goal: Goal, F0, f_end: int, travel: int):
        """The goal's node and configuration: without a pose constraint the node the forward
        seed ends in; without a heading the heading the forward seed arrives with."""
        g = self.g
        if goal.nodes is None:
            end_nodes = (np.array([f_end]) if g.node_state[f_end] == travel
                         else np.flatnonzero(g.node_state == travel)[:1])
        else:
            end_nodes = np.asarray(goal.nodes)
        goal_node = int(f_end) if f_end in end_nodes else int(end_nodes[0])
        goal_h = goal.heading
        if goal_h is None:
            c = start.xzh
            for e in F0:
                c = compose1(c, self.lib.disp[e])
            goal_h = float(c[2])
        return goal_node, np.array([goal.position[0], goal.position[1], goal_h])

    @staticmethod
    def _detour(collision_at, k: int) -> np.ndarray:
        """The ``k``-th detour way point beside a collision: both sides, then further out."""
        side = 1.0 if k % 2 == 0 else -1.0
        off = DETOURS[k // 2]
        cxz, direction = collision_at
        perp = np.array([-direction[1], direction[0]])
        return cxz + side * off * perp
