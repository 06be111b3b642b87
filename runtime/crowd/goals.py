"""All goals of one character, with a ladder of honest alternatives when a goal cannot be met.

A character's goals are planned one after another from its start (Sung, Kovar and Gleicher
2005, section 3.1), each segment against everyone already planned (the space-time index) and
the environment. A segment is *clean* when its motion meets the goal exactly (position, heading,
pose, arrival window) within the per-frame adjustment tolerance eps and collides with nobody.
A motion that collides is never used. When no clean motion is found, the planner steps down a
ladder, each rung reported:

0. ``rerouted`` -- when the motion ran into characters planned before, a route in space and
   time around them (:mod:`runtime.crowd.planner.route`) gives the seeds new way points and,
   when it starts with a wait, a later departure.
1. ``later arrival`` -- arrive later inside the window (the part of it after its middle; an
   untimed last goal: after the character planned earlier that passes the goal has gone).
2. ``later departure`` -- stand at the start of the segment first, then go (the whole seconds
   after which a straight walk to the goal misses everyone planned, then fixed delays).
3. ``late`` -- arrive after the window (``delay_s``: how much after its end).
4. ``relaxed`` -- accept a per-frame adjustment up to ``RELAXED_EPS`` x eps (``eps_factor``: the
   largest rate over eps).
5. ``waiting`` -- give the goal (and the ones after it) up and stand where the character is,
   clear of everyone; if even that is not clear, stand at the start for the whole scenario.

Rungs 0-2 keep every constraint; 3-5 give one up and add a warning. The rungs of one segment
share a budget of search iterations (``CrowdPolicy.rung_budget``): once it is spent, the relaxed
rung still gets ``CrowdPolicy.relaxed_reserve`` iterations per eps scale (a relaxed adjustment
is better than a goal given up, and than the goals of others timed by it), then the goal is
given up (waiting), so a character that cannot be planned costs a bounded amount of work.
The ladder is a generator like the planner (:class:`SegmentLadder`), so the World runs it
time-sliced too. The result says, per goal, which rung was used (:class:`LadderStep`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..motion.cylinders import blend_cylinders
from .idle import hold_tail, idle_for, idle_track, track_cylinders
from .planner import Config, Goal, SegmentPlanner, Step, run_to_completion
from .planner.route import timed_route_steps
from .scenario import ScenarioError
from .tracks import Track, concat_tracks

__all__ = ["LadderStep", "GoalsPlan", "SegmentLadder", "with_prefix", "plan_goals", "ladder_summary", "LADDER_KINDS", "clear_after", "collides_early", "lane_clear_delay",
           "LATE_SHIFTS", "RELAXED_EPS", "LANE_RADIUS", "RungBudgetSpent"]

class RungBudgetSpent(Exception):
    """A segment's ladder spent ``CrowdPolicy.rung_budget`` search iterations on its rungs."""


LATE_SHIFTS = (3.0, 8.0, 15.0)   # s the window is moved later, in turn, for a late arrival
RELAXED_EPS = (2.0, 4.0)         # eps scales tried, in turn, for a relaxed adjustment
LANE_BATCH = 8                   # waits tested per query in lane_clear_delay
LANE_RADIUS = 0.5                # m: the bounding cylinder of a walk in lane_clear_delay's proxy


@dataclass
class LadderStep:
    """What a goal's plan gave up or changed (see the module docstring).

    Attributes:
        goal: the goal's index.
        kind: "rerouted", "later arrival", "later departure", "late", "relaxed" or "waiting".
        delay_s: seconds later than asked (departure delay, or arrival after the window).
        eps_factor: largest per-frame adjustment over eps ("relaxed").
        reason: why the rung was needed.
        blocked_by: {owner: samples} of the planned characters the goal's first motion ran into.
    """

    goal: int
    kind: str
    delay_s: float = 0.0
    eps_factor: float = 1.0
    reason: str = ""
    blocked_by: dict = field(default_factory=dict)

    @property
    def keeps_constraints(self) -> bool:
        return self.kind in ("rerouted", "later arrival", "later departure")

    def to_dict(self) -> dict:
        return {"goal": self.goal, "kind": self.kind, "delay_s": round(float(self.delay_s), 3),
                "eps_factor": round(float(self.eps_factor), 3), "reason": self.reason}


LADDER_KINDS = ("rerouted", "later arrival", "later departure", "late", "relaxed", "waiting")


def ladder_summary(characters) -> dict:
    """Per ladder kind, the characters whose plan used it (``characters``: objects with a
    ``ladder`` list of :class:`LadderStep`), the worst delay of late arrivals, the largest eps
    factor of relaxed ones, and the characters meeting every constraint ("clean")."""
    out = {k: 0 for k in LADDER_KINDS}
    late, relaxed, clean = 0.0, 1.0, 0
    for c in characters:
        kinds = {st.kind for st in c.ladder}
        for k in kinds:
            out[k] += 1
        late = max([late] + [st.delay_s for st in c.ladder if st.kind == "late"])
        relaxed = max([relaxed] + [st.eps_factor for st in c.ladder if st.kind == "relaxed"])
        clean += all(st.keeps_constraints for st in c.ladder)
    out.update(max_late_s=round(late, 3), max_eps_factor=round(relaxed, 3), clean=clean)
    return out


@dataclass
class GoalsPlan:
    """One character's plan over the whole scenario."""

    track: Track
    arrivals: list                  # clock frame of each goal reached
    goals: list                     # resolved Goals (absolute windows, allowed nodes)
    warnings: list
    iterations: int
    ladder: list = field(default_factory=list)   # LadderStep per goal that needed one
    collides: bool = False          # even standing at the start runs into someone (rare)


def clear_after(planner, res, index):
    """When ``res``'s motion is clear but holding its end position is not (the final test
    returns one past its frames), the first frame after which the held position stays clear;
    else None."""
    if planner.final_collision(res) != len(res.root):
        return None
    tail = planner.hold(res) if planner.hold is not None else None
    if tail is None:        # (it ends after the deadline: a later arrival would too)
        return None
    f2, xz2, r2 = tail
    bad = np.asarray(index.overlaps(f2, xz2, np.asarray(r2, float) + planner.p.margin), dtype=bool)
    if not bad.any():
        return None
    return int(f2[np.flatnonzero(bad)[-1]]) + int(round(0.5 * planner.p.fps))


def collides_early(planner, res, frames: float) -> bool:
    """Whether ``res``'s first collision with a character planned earlier comes within
    ``frames`` of its start (setting off later helps there; not with someone passing its goal
    later, or a jam halfway)."""
    hit = planner.final_collision(res)
    return hit is not None and hit < min(frames, len(res.root))


def _length(pts: np.ndarray) -> float:
    """The length (m) of the polyline ``pts`` (n >= 2, 2)."""
    return float(np.cumsum(np.hypot(*np.diff(pts, axis=0).T))[-1])


def _along(pts: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(len(s), 2): the points ``s`` metres along the polyline ``pts`` (n >= 2, 2)."""
    seg = np.hypot(*np.diff(pts, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    j = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    u = (s - cum[j]) / np.maximum(seg[j], 1e-12)
    return pts[j] + u[:, None] * (pts[j + 1] - pts[j])


def lane_clear_delay(index, cfg, goal, fps, n_total, radius, speed: float = 1.3, step: float = 1.0, route=None):
    """Whole ``step`` seconds to stand at ``cfg`` before a walk at ``speed`` to the goal (a
    proxy of the motion, a cylinder of ``radius``) misses every planned character in
    ``index``; None when no such wait leaves 2 s of the scenario (``n_total`` frames) after the
    walk. The walk follows ``route`` ((n, 2) way points from the start to the goal: through
    the doors the motion will take), else a straight line. A crowd setting off together
    clears a lane in front of a character in this time."""
    a = np.array([cfg.x, cfg.z])
    b = np.asarray(goal.position, float)
    if route is None or len(route) < 2:
        n = int(np.hypot(*(b - a)) / speed * fps) + 1
        xz = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    else:
        pts = np.asarray(route, float)
        length = _length(pts)
        n = int(length / speed * fps) + 1
        xz = _along(pts, np.linspace(0.0, length, n))
    delays = []
    d = 0.0
    while cfg.frame + (d + 2.0) * fps + n < n_total:
        delays.append(d)
        d += step
    # LANE_BATCH waits per query (one walk sample each per frame of the walk)
    for k in range(0, len(delays), LANE_BATCH):
        ds = delays[k:k + LANE_BATCH]
        f0 = cfg.frame + np.rint(np.multiply(ds, fps)).astype(np.int64)
        frames = (f0[:, None] + np.arange(n)[None]).ravel()
        hit = index.any_overlap_runs(frames, np.tile(xz, (len(ds), 1)), np.full(len(frames), radius),
                                     np.full(len(ds), n))
        if not hit.all():
            return ds[int(np.argmin(hit))]
    return None


WALK_CHECK_SPEED = 1.2    # m/s of the straight proxy walk that decides whether a route is busy


def _route_blocked(index, route_xz, frame0: int, fps: float, radius: float) -> bool:
    """Whether a walk along ``route_xz`` at ``WALK_CHECK_SPEED`` from ``frame0`` (a disc of
    ``radius``, sampled every 3 frames) runs into a planned character."""
    length = _length(route_xz)
    n = int(length / WALK_CHECK_SPEED * fps) + 1
    f = np.arange(0, n, 3)
    xz = _along(route_xz, np.minimum(f / fps * WALK_CHECK_SPEED, length))
    return index.first_overlap(frame0 + f, xz, np.full(len(f), radius)) >= 0


def _clear_track(ctx, track: Track) -> bool:
    """Whether ``track`` (on the clock from its ``start_frame``) collides with nobody in the
    index and no obstacle."""
    frames = track.start_frame + np.arange(len(track))
    xz, rad = track_cylinders(ctx.graph, track)
    rad = rad + ctx.params.margin
    if ctx.static is not None and np.any(ctx.static(xz) < rad):
        return False
    return not np.asarray(ctx.index.overlaps(frames, xz, rad), dtype=bool).any()


class SegmentLadder:
    """Plans one goal from ``cfg`` with the ladder (rungs 1-4); see the module docstring.

    Args:
        ctx: what the plan is made against: ``index`` (the space-time queries ``overlaps``,
            ``first_overlap``, ``any_overlap_runs``, ``overlapping_owners``, ``at_frame``),
            ``static``, ``still``, ``graph``, ``lib``, ``params``, ``policy``, ``fps``,
            ``n_total`` (the last frame + 1 a plan may use) -- a scheduler's
            :class:`~runtime.crowd.scheduler.PlanContext` or the World's
            :class:`~runtime.world.occupancy.PlanningView`.
        planner: the character's :class:`SegmentPlanner` (its ``hold`` is the last goal's).
        name: for messages. rng: the random stream.
        n_first, n_retry: search iterations of the first try and of each rung.
        give_up: use the rungs that give a constraint up (late, relaxed); without them the
            ladder only tries what keeps every constraint.
    """

    def __init__(self, ctx, planner: SegmentPlanner, name: str, rng, n_first, n_retry, give_up: bool = True):
        self.ctx, self.planner, self.name, self.rng = ctx, planner, name, rng
        self.give_up = give_up
        self.n_first, self.n_retry = n_first, n_retry
        self.iterations = 0
        self.last_blockers: dict = {}
        budget = getattr(ctx.policy, "rung_budget", None)
        self.rung_left = None if budget is None else int(budget)   # search iterations left for the rungs
        self.out_of_budget = False

    def run(self, cfg: Config, goal: Goal, n_max=None, planner=None, waypoints=None, rung: bool = True,
            schedule=None):
        """Generator: one segment search (time-sliced like the planner's own steps). A rung's
        search (``rung``) is cut to the iterations left of ``policy.rung_budget``; with none
        left it raises :class:`RungBudgetSpent`."""
        n = self.n_retry if n_max is None else n_max
        if rung and self.rung_left is not None:
            if self.rung_left <= 0:
                self.out_of_budget = True
                raise RungBudgetSpent(self.name)
            n = min(n, self.rung_left)
        res = yield from (planner or self.planner).run(cfg, goal, self.rng, name=self.name, n_max=n,
                                                        waypoints=waypoints, schedule=schedule)
        self.iterations += res.iterations
        if rung and self.rung_left is not None:
            self.rung_left -= max(int(res.iterations), 1)
        return res

    def plan(self, cfg: Config, goal: Goal, gi: int):
        """Generator (yields planner step kinds); returns (idle prefix Track or None,
        SegmentResult, LadderStep or None) -- the result is clean or within the rung reported,
        and collision-free -- or None when every rung failed."""
        try:
            return (yield from self._plan(cfg, goal, gi))
        except RungBudgetSpent:
            return None

    def _plan(self, cfg: Config, goal: Goal, gi: int):
        ctx = self.ctx
        if ctx.policy.space_time_seeds:
            out = yield from self._rerouted(cfg, goal, None, n_max=self.n_first, only_if_blocked=True, rung=False)
            if out is not None:
                idle, res, d = out
                step = None if idle is None else LadderStep(gi, "later departure", delay_s=d,
                                                            reason="the way is busy")
                return idle, res, step
        res = yield from self.run(cfg, goal, n_max=self.n_first, rung=False)
        if not res.warning:
            return None, res, None
        first = res
        self.last_blockers = self.blockers(first) if first.collided else {}
        try:
            out = yield from self._ladder(cfg, goal, gi, first)
        except RungBudgetSpent:
            # better a relaxed adjustment than a goal given up (and the goals timed by it)
            reserve = getattr(self.ctx.policy, "relaxed_reserve", 0)
            if not (self.give_up and reserve):
                raise
            out = yield from self._relaxed(cfg, goal, gi, first, n_max=reserve, rung=False)
        if out is not None and out[2] is not None:
            out[2].blocked_by = self.last_blockers
        return out

    def blockers(self, res) -> dict:
        """{owner: samples} of the planned characters ``res``'s motion runs into; when it runs
        into nobody, the ones that pass where it then stands (the planner's ``hold``: a
        character planned earlier walks through the last goal after the arrival)."""
        ctx = self.ctx
        xz, rad = blend_cylinders(ctx.graph, res.frames_a, res.frames_b, res.root)
        out = ctx.index.overlapping_owners(res.start_frame + np.arange(len(res.root)), xz, rad + ctx.params.margin)
        if not out and self.planner.hold is not None:
            tail = self.planner.hold(res)
            if tail is not None and len(tail[0]):
                f2, xz2, r2 = tail
                out = ctx.index.overlapping_owners(np.asarray(f2), np.asarray(xz2, dtype=np.float64),
                                                   np.asarray(r2, dtype=np.float64) + ctx.params.margin)
        return out

    def _ladder(self, cfg: Config, goal: Goal, gi: int, first):
        """Rungs 1-4 after ``first`` failed."""
        ctx, planner = self.ctx, self.planner
        res = first
        if first.collided:
            out = yield from self._rerouted(cfg, goal, first)
            if out is not None:
                idle, res2, d = out
                return idle, res2, LadderStep(gi, "later departure" if d > 0 else "rerouted", delay_s=d,
                                              reason=first.warning)
        # 1. a later arrival inside the window
        if planner.hold is not None and goal.window is None:
            # the motion is clear but standing at the goal afterwards is in the way of a
            # character planned earlier that passes there later: arrive after it has passed
            late = clear_after(planner, res, ctx.index)
            if late is not None and late < ctx.n_total - 2 * ctx.fps:
                g2 = Goal(goal.position, goal.heading, goal.nodes, (late / ctx.fps, late / ctx.fps + 1.5),
                          label=goal.label)
                res2 = yield from self.run(cfg, g2)
                if not res2.warning:
                    return None, res2, LadderStep(gi, "later arrival", reason="someone passes the goal later")
        elif goal.window is not None and goal.window[1] - goal.window[0] >= 0.4:
            mid = 0.5 * (goal.window[0] + goal.window[1])
            res2 = yield from self.run(cfg, Goal(goal.position, goal.heading, goal.nodes, (mid, goal.window[1]), goal.label))
            if not res2.warning:
                return None, res2, LadderStep(gi, "later arrival", reason=first.warning)
        # 2. a later departure
        out = yield from self._later_departure(cfg, goal, first)
        if out is not None:
            idle, res2, d = out
            return idle, res2, LadderStep(gi, "later departure", delay_s=d, reason=first.warning)
        if not self.give_up:
            return None
        # 3. late
        if goal.window is not None:
            for s in LATE_SHIFTS:
                w = (goal.window[0] + s, goal.window[1] + s)
                if w[1] * ctx.fps >= ctx.n_total - 1:
                    break
                res2 = yield from self.run(cfg, Goal(goal.position, goal.heading, goal.nodes, w, goal.label))
                if not res2.warning:
                    delay = max(0.0, res2.end.frame / ctx.fps - goal.window[1])
                    return None, res2, LadderStep(gi, "late", delay_s=delay, reason=first.warning)
        return (yield from self._relaxed(cfg, goal, gi, first))

    def _relaxed(self, cfg: Config, goal: Goal, gi: int, first, n_max=None, rung: bool = True):
        """Rung 4: the segment planned with eps scaled by :data:`RELAXED_EPS` in turn."""
        planner = self.planner
        for scale in RELAXED_EPS:
            p2 = replace(planner.p, eps=tuple(e * scale for e in planner.p.eps))
            relaxed = SegmentPlanner(planner.lib, static=planner.collider.static, collide=planner.collider.collide,
                                     roadmap=planner.roadmap, env=planner.env, params=p2,
                                     collide_first=planner.collider.collide_first,
                                     collide_runs=planner.collider.collide_runs)
            relaxed.hold = planner.hold
            relaxed.deadline = planner.deadline
            res2 = yield from self.run(cfg, goal, planner=relaxed, n_max=n_max, rung=rung)
            if not res2.warning:
                factor = max(r / e for r, e in zip(res2.rates, planner.p.eps))
                if factor <= 1.0 + 1e-9:
                    # the wider search found a motion within eps after all: nothing is given up
                    return None, res2, None
                return None, res2, LadderStep(gi, "relaxed", eps_factor=factor, reason=first.warning)
        return None

    def _rerouted(self, cfg: Config, goal: Goal, first, n_max=None, only_if_blocked: bool = False,
                  rung: bool = True):
        """The segment planned along a route in space and time around the characters planned
        before (:func:`~runtime.crowd.planner.route.timed_route_steps`), leaving when the route does:
        (idle Track or None, SegmentResult, delay in s) or None. ``only_if_blocked``: None when
        a walk along the static route at ``WALK_CHECK_SPEED`` already misses everyone."""
        ctx = self.ctx
        index = ctx.index
        base = self.planner.waypoints(cfg, goal)
        radius = LANE_RADIUS + ctx.params.margin
        if only_if_blocked and not _route_blocked(index, base, cfg.frame, ctx.fps, radius):
            return None
        gx = np.asarray(goal.position, float)

        def stays_clear(frame):
            f = np.arange(frame, ctx.n_total, 5)
            return len(f) == 0 or index.first_overlap(f, np.broadcast_to(gx, (len(f), 2)),
                                                      np.full(len(f), radius)) < 0
        hold = stays_clear if self.planner.hold is not None else None
        yield Step.WAYPOINTS
        route = yield from timed_route_steps(base, cfg.frame, index.at_frame, ctx.static, radius, ctx.n_total - 1,
                                             hold)
        if route is None:
            return None
        pts, _, delay, trail = route
        idle, start = None, cfg
        if delay >= ctx.fps and ctx.still is not None and ctx.still[cfg.node]:
            idle = idle_for(ctx.lib, ctx.graph, cfg, delay / ctx.fps, ctx.fps)
            if not _clear_track(ctx, idle):
                idle = None
            else:
                start = Config(cfg.node, *(float(v) for v in idle.root[-1]), int(cfg.frame + len(idle) - 1))
                pts = np.concatenate([np.array([[start.x, start.z]]), pts[1:]])
        res = yield from self.run(start, goal, waypoints=pts, n_max=n_max, rung=rung,
                                  schedule=trail if self.ctx.policy.route_schedule else None)
        if res.warning:
            return None
        return idle, res, 0.0 if idle is None else (len(idle) - 1) / ctx.fps

    def _later_departure(self, cfg: Config, goal: Goal, first):
        """Stand at ``cfg`` for a while, then go: (idle Track, SegmentResult, seconds) or None.
        Only from a node where one can stand still, and only when the first motion ran into
        someone early (a crowd setting off together; not a jam far on, nor a wall)."""
        ctx, policy = self.ctx, self.ctx.policy
        if not (first.collided and ctx.still is not None and ctx.still[cfg.node]
                and collides_early(self.planner, first, policy.depart_within * ctx.fps)):
            return None
        delays = policy.depart_delays
        dc = lane_clear_delay(ctx.index, cfg, goal, ctx.fps, ctx.n_total, LANE_RADIUS + ctx.params.margin,
                              route=self.planner.waypoints(cfg, goal) if policy.depart_route else None) \
            if policy.depart_clear else None
        if dc:          # (0: the straight walk is clear now, the fixed delays are tried)
            delays = (dc, dc + 3.0)
        for d in delays:
            idle = idle_for(ctx.lib, ctx.graph, cfg, d, ctx.fps)
            if goal.window is not None and (cfg.frame + len(idle)) / ctx.fps > goal.window[1] - 1.0:
                break
            if not _clear_track(ctx, idle):
                break           # someone passes where it stands: waiting longer will not help
            later = Config(cfg.node, *(float(v) for v in idle.root[-1]), int(cfg.frame + len(idle) - 1))
            res2 = yield from self.run(later, goal)
            if not res2.warning:
                return idle, res2, d
        return None


def with_prefix(idle: Track | None, res):
    """``res`` with the idle track ``idle`` (a wait before it) in front, as one result."""
    if idle is None:
        return res
    tr = concat_tracks([idle, Track(res.frames_a, res.frames_b, res.frames_t, res.root, res.start_frame)])
    return replace(res, frames_a=tr.frames_a, frames_b=tr.frames_b, frames_t=tr.frames_t, root=tr.root,
                   start_frame=idle.start_frame)


def _resolve_goal(ctx, results, ci, gi, gs, arrivals, warnings):
    """The :class:`Goal` of scenario goal ``gs`` (window including its ``after`` constraint;
    when the other character gave that goal up, the constraint is dropped with a warning)."""
    sc, fps = ctx.sc, ctx.fps
    c = sc.characters[ci]
    window = gs.time
    if gs.after is not None:
        other = sc.character(gs.after["character"])
        oi = sc.characters.index(other)
        reached = results[oi].arrivals if oi != ci else arrivals
        k = gs.after["goal"]
        if k >= len(reached):
            warnings.append(f"{c.name} goal {gi}: its 'after' constraint is dropped: {other.name} gave goal {k} up")
            return Goal(np.asarray(gs.position, float), gs.heading, _pose_nodes(ctx, c, gi, gs), window,
                        label=gs.pose or "")
        t_other = reached[k] / fps
        w = (t_other + gs.after["within"][0], t_other + gs.after["within"][1])
        window = w if window is None else (max(w[0], window[0]), min(w[1], window[1]))
        if window[1] < window[0]:
            raise ScenarioError(f"{sc.path}: character {c.name!r} goal {gi}: its time window and "
                                f"'after' window do not overlap")
    return Goal(np.asarray(gs.position, float), gs.heading, _pose_nodes(ctx, c, gi, gs), window, label=gs.pose or "")


def _pose_nodes(ctx, c, gi, gs):
    nodes = ctx.graph.nodes_with_label(gs.pose) if gs.pose else None
    if nodes is not None and len(nodes) == 0:
        raise ScenarioError(f"{ctx.sc.path}: character {c.name!r} goal {gi}: pose {gs.pose!r} not in the library")
    return nodes


def plan_goals(ctx, results: dict, ci: int, node: int, rng, retry: bool = False, give_up: bool = True) -> GoalsPlan:
    """All goals of character ``ci`` from start node ``node`` against the characters in the
    index (``ctx``: a :class:`~runtime.crowd.scheduler.PlanContext`).

    Each segment's first search gets ``params.n_max`` iterations (``retry``: this is a further
    try at the character -- the other start node, a repair pass -- and gets
    ``policy.retry_n_max``); every rung of the ladder gets ``policy.retry_n_max``. ``give_up``:
    the ladder may give a constraint up (see :class:`SegmentLadder`)."""
    sc, graph, params, policy, lib = ctx.sc, ctx.graph, ctx.params, ctx.policy, ctx.lib
    fps, n_total, index = ctx.fps, ctx.n_total, ctx.index
    n_retry = min(policy.retry_n_max, params.n_max)
    c = sc.characters[ci]
    planner = SegmentPlanner(lib, static=ctx.static,
                             collide=lambda f, xz, r: index.overlaps(f, xz, r),
                             collide_first=lambda f, xz, r: index.first_overlap(f, xz, r),
                             collide_runs=lambda f, xz, r, cnt: index.any_overlap_runs(f, xz, r, cnt),
                             roadmap=ctx.roadmap, env=ctx.env, params=params)
    planner.cache = ctx.cache
    planner.deadline = n_total - 1        # a motion that ends after the scenario never arrives
    if ctx.policy.bend_waypoints and hasattr(index, "standing"):
        planner.standing = lambda f: index.standing(f, ignore_owner=ci)
    if ctx.policy.still_static and hasattr(index, "still"):
        planner.still = lambda f: index.still(f, ignore_owner=ci)
    start = Config(node, float(c.position[0]), float(c.position[1]), float(c.heading), 0)
    cfg = start
    parts, arrivals, goals, warnings, ladder = [], [], [], [], []
    iters = 0
    waiting = False
    for gi, gs in enumerate(c.goals):
        goal = _resolve_goal(ctx, results, ci, gi, gs, arrivals, warnings)
        goals.append(goal)
        # after its last goal a character stands there to the end: that must be clear too
        planner.hold = (lambda r: hold_tail(lib, graph, r.end, n_total)) if gi == len(c.goals) - 1 else None
        seg = SegmentLadder(ctx, planner, f"{c.name} goal {gi}", rng, n_retry if retry else params.n_max, n_retry,
                            give_up)
        out = run_to_completion(seg.plan(cfg, goal, gi))
        iters += seg.iterations
        if out is None:
            reason = (f"{c.name} goal {gi}: no collision-free motion within the ladder's search budget"
                      if seg.out_of_budget else f"{c.name} goal {gi}: no collision-free motion, even late or with eps relaxed")
            ladder.append(LadderStep(gi, "waiting", reason=reason, blocked_by=seg.last_blockers))
            warnings.append(f"{reason}; it waits in place (goal {gi}"
                            + (f" and {len(c.goals) - gi - 1} later" if gi < len(c.goals) - 1 else "") + " given up)")
            waiting = True
            break
        idle, res, step = out
        if step is not None:
            ladder.append(step)
            if not step.keeps_constraints:
                detail = {"late": f"arrives {step.delay_s:.2f} s after its window",
                          "relaxed": f"adjustment {step.eps_factor:.2f} x eps"}[step.kind]
                warnings.append(f"{c.name} goal {gi}: {step.kind}: {detail} ({step.reason})")
        if idle is not None:
            parts.append(idle)
        parts.append(Track(res.frames_a, res.frames_b, res.frames_t, res.root, res.start_frame))
        cfg = res.end
        arrivals.append(cfg.frame)
    collides = False
    if waiting and not _stays_clear(ctx, cfg, n_total):
        # standing where it got to is in someone's way: stand at the start for the whole scenario
        parts, arrivals, cfg = [], [], start
        ladder[-1].reason += "; standing there was not clear either, so it stays at its start"
        collides = not _stays_clear(ctx, start, n_total)
    track = concat_tracks(parts) if parts else idle_track(lib, cfg, n_total)
    if len(track) > n_total:
        warnings.append(f"{c.name}: motion runs {len(track) / fps:.1f} s, past the scenario's {sc.duration} s")
        n_total_c = len(track)
    else:
        n_total_c = n_total
    if len(track) < n_total_c:
        track = concat_tracks([track, idle_track(lib, cfg, n_total_c - len(track) + 1)])
    if collides:
        warnings.append(f"{c.name}: standing at its start runs into characters planned earlier")
    return GoalsPlan(track.slice(0, n_total), arrivals, goals, warnings, iters, ladder, collides)


def _stays_clear(ctx, cfg: Config, n_total: int) -> bool:
    """Whether idling at ``cfg`` from its frame to the scenario's end is clear of everyone."""
    n = n_total - cfg.frame
    if n <= 1:
        return True
    return _clear_track(ctx, idle_track(ctx.lib, cfg, n))
