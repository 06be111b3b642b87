"""Planning a whole scenario: characters one after another (Sung, Kovar and Gleicher 2005, section 3.1).

Characters are planned in an order that respects relative timing; each planned character
enters the space-time index and is a moving obstacle for the ones after it. A character's
track covers the whole scenario: its segments goal after goal, then idling in place (the
final node's self-loop clips with their drift removed) until the end.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..motion.graph import STATES
from .idle import hold_tail, idle_for, idle_track, still_nodes, track_radius
from .planner import (Config, CrowdPolicy, Goal, MotionCache, MotionLibrary, SearchParams, SegmentPlanner,
                      run_to_completion)
from .scenario import Scenario, ScenarioError, planning_order
from .spacetime import SpaceTimeIndex
from .tracks import Track, concat_tracks

__all__ = ["CharacterResult", "CrowdResult", "PlanContext", "plan_scenario", "plan_one", "plan_goals", "repair",
           "start_node", "seat_hold", "seated_radius", "collides_early", "lane_clear_delay", "clear_after",
           "REPAIR_BLOCKERS"]


@dataclass
class CharacterResult:
    name: str
    track: Track
    arrivals: list            # clock frame of each goal's arrival
    goals: list               # resolved Goal objects (absolute windows, allowed nodes)
    warnings: list = field(default_factory=list)
    seconds: float = 0.0      # synthesis time
    iterations: int = 0
    motion_seconds: float = 0.0


@dataclass
class CrowdResult:
    scenario: Scenario
    fps: float
    num_frames: int
    characters: list
    order: list
    total_seconds: float = 0.0
    passes: int = 1           # planning passes run (failed characters first in each new one)
    reused: int = 0           # segments whose motion was another character's, reused (motion_cache)
    searched: int = 0         # segments that searched (no stored motion for the task was clear)

    def by_name(self, name) -> CharacterResult:
        return next(c for c in self.characters if c.name == name)


def clear_after(planner, res, index):
    """When ``res``'s motion is clear but holding its end position is not (the final test
    returns one past its frames), the first frame after which the held position stays clear;
    else None."""
    if planner.final_collision(res) != len(res.root):
        return None
    f2, xz2, r2 = planner.hold(res)
    bad = np.asarray(index.overlaps(f2, xz2, np.asarray(r2, float) + planner.p.margin), dtype=bool)
    if not bad.any():
        return None
    return int(f2[np.flatnonzero(bad)[-1]]) + int(round(0.5 * planner.p.fps))


def start_node(graph, pose: str, where: str, still: np.ndarray | None = None) -> int:
    nodes = graph.nodes_with_label(pose)
    if len(nodes) == 0:
        raise ScenarioError(f"{where}: pose {pose!r} is not a node label of the library")
    if still is not None and still[nodes].any():
        # where one can stand still: a character waits there until it is time to go (a
        # walking hub also labelled "stand" could not wait)
        nodes = nodes[still[nodes]]
    # the most connected node with that label
    deg = np.bincount(graph.edge_src, minlength=graph.num_nodes)[nodes]
    return int(nodes[np.argmax(deg)])


def plan_scenario(sc: Scenario, graph, env=None, roadmap=None, params: SearchParams | None = None,
                  policy: CrowdPolicy | None = None, progress=None, log=None) -> CrowdResult:
    """Plan every character of ``sc`` (Sung, Kovar and Gleicher 2005, section 3.1: one after
    another, earlier ones moving obstacles for later ones), then repair.

    Pass 1 plans all characters in :func:`planning_order`. Each later pass (``[synthesis]
    passes``, default ``policy.passes``, counts them all) repairs only the characters left
    with warnings (:func:`repair`): every planned character stays in the space-time index, so
    a repaired plan is tested against all the others, before and after it in the order.

    Args:
        sc: the scenario; its ``[synthesis]`` table overrides ``n_m``, ``k_m``, ``n_max``,
            ``approach_point`` (search) and ``start_still``, ``passes`` (policy).
        graph, env, roadmap: the motion graph, the environment and its roadmap (may be None).
        params, policy: defaults: the paper's search with the scenario's eps, the default policy.
        progress: called with 1 after each character of the first pass.
        log: called with messages (repairs, warnings).
    """
    params = params or SearchParams(eps=sc.epsilon)
    policy = policy or CrowdPolicy()
    for k in ("n_m", "k_m", "n_max"):
        if k in sc.synthesis:
            setattr(params, k, int(sc.synthesis[k]))
    if "start_still" in sc.synthesis:
        policy.start_still = bool(sc.synthesis["start_still"])
    if "approach_point" in sc.synthesis:
        params.approach_point = float(sc.synthesis["approach_point"])
    lib = MotionLibrary(graph, params)
    fps = params.fps
    n_total = int(round(sc.duration * fps)) + 1
    sdf = env.sdf(resolution=0.05, margin=2.0) if env is not None and (len(env.polygons) or len(env.circles)) else None
    # the sampled field may overestimate clearance by up to max_error: stay conservative
    static = (lambda xz: sdf.sample(xz) - sdf.max_error) if sdf is not None else None
    t_all = time.perf_counter()
    passes = max(1, int(sc.synthesis.get("passes", policy.passes)))
    ctx = PlanContext(sc, graph, env, roadmap, params, policy, lib, fps, n_total, static,
                      SpaceTimeIndex(cell=max(1.2, 2 * lib.max_radius + 2 * (params.margin + params.seed_margin) + 0.05)),
                      still_nodes(graph, params.eps, fps), log,
                      MotionCache() if policy.reuse_motions else None)
    order = planning_order(sc)
    for ci in order:
        hold = seat_hold(sc.characters[ci], graph, fps)
        if hold:
            ctx.index.insert(ci, np.arange(hold), np.repeat(sc.characters[ci].position[None], hold, 0),
                             seated_radius(graph))
    results: dict[int, CharacterResult] = {}
    for ci in order:
        ctx.index.remove_owner(ci)          # its seat hold (if any) gives way to its plan
        results[ci] = plan_one(ctx, results, ci, 0)
        ctx.insert(ci, results[ci].track)
        if progress:
            progress(1)
    k = 1
    while k < passes:
        failed = [ci for ci in order if results[ci].warnings]
        if not failed:
            break
        if log:
            log(f"pass {k + 1}: repairing {len(failed)} character(s) without a clean plan")
        repair(ctx, results, failed, k)
        k += 1
    total = time.perf_counter() - t_all
    cache = ctx.cache
    return CrowdResult(sc, fps, n_total, [results[i] for i in range(len(sc.characters))], order, total, k,
                       cache.hits if cache else 0, cache.misses if cache else 0)


REPAIR_BLOCKERS = 3     # planned characters a failed one may displace in a repair


@dataclass
class PlanContext:
    """What planning one scenario shares: the scenario, the motion graph and its
    :class:`MotionLibrary`, the obstacles (``static``: the environment's signed distance, the
    space-time ``index`` of planned characters), the still nodes, the motion cache."""

    sc: Scenario
    graph: object
    env: object
    roadmap: object
    params: SearchParams
    policy: CrowdPolicy
    lib: MotionLibrary
    fps: float
    n_total: int
    static: object
    index: SpaceTimeIndex
    still: np.ndarray
    log: object
    cache: MotionCache | None = None

    def cylinders(self, track):
        rad = track_radius(self.graph, track)
        return np.arange(len(track)), track.root[:, :2], rad

    def insert(self, ci, track):
        self.index.insert(ci, *self.cylinders(track))


def plan_one(ctx: PlanContext, results, ci: int, k: int, attempt: int = 0) -> CharacterResult:
    """Character ``ci`` planned against the space-time index. Its random stream is seeded by
    the scenario seed, its index, the pass ``k`` and ``attempt``, so its plan depends on the
    order only through the characters already in the index.

    A character whose start pose has two kinds of node -- the pose's most connected node and
    one where it can stand still and wait (for "stand": a walking hub and a standing node) --
    is planned from the first (``start_still``: the second; unset: the second when the
    character has time to wait, :func:`time_to_wait`); if that plan has warnings, it is
    planned again from the other, and the plan with fewer warnings is kept."""
    sc, graph, policy = ctx.sc, ctx.graph, ctx.policy
    c = sc.characters[ci]
    t0 = time.perf_counter()
    where = f"{sc.path}: character {c.name!r} start"
    still_first = policy.start_still if policy.start_still is not None else time_to_wait(c, policy)
    starts = list(dict.fromkeys([start_node(graph, c.pose, where, ctx.still if still_first else None),
                                 start_node(graph, c.pose, where, None if still_first else ctx.still)]))
    best = None
    iters = 0
    for a, node in enumerate(starts):
        extra = [a] if a else []
        if k or attempt:
            extra = [a, attempt]
        rng = np.random.default_rng([int(sc.seed), int(ci), int(k)] + extra)
        out = plan_goals(ctx, results, ci, node, rng, retry=bool(a or attempt))
        iters += out[4]
        if best is None or len(out[3]) < len(best[3]):
            best = out
        if not best[3]:
            break
        if ctx.log and a == 0 and len(starts) > 1:
            ctx.log(f"{c.name}: planning again from the other {c.pose!r} start node")
    track, arrivals, goals, warnings, _ = best
    if ctx.log:
        for w in warnings:
            ctx.log(f"warning: {w}")
    return CharacterResult(c.name, track, arrivals, goals, warnings, time.perf_counter() - t0, iters,
                           arrivals[-1] / ctx.fps if arrivals else 0.0)


WALK_SPEED = 1.4    # m/s: a brisk walk, for telling whether a character has time to wait
HOLD_SPEED = 1.5    # m/s: the fastest straight walk for the earliest time a seated character leaves
HOLD_GET_UP = 2.0   # s: ... plus the time it takes to get up


def seat_hold(c, graph, fps: float) -> int:
    """Frames from 0 during which a character who starts seated (``start = { seat = ... }``)
    has no need to leave yet: getting up and walking straight to its first goal at a brisk
    pace (``HOLD_GET_UP``, ``HOLD_SPEED``) still arrives before the goal's window opens.
    Characters are planned one after another
    (Sung, Kovar and Gleicher 2005, section 3.1), and one planned later is invisible to those before it -- but a
    seated one cannot step aside: a neighbour sitting down next to it would turn across its
    place. So until it is planned its seat is held for those frames: earlier characters
    treat it as sitting there (0 when it does not start seated or its first goal has no
    window)."""
    if c.start_marker is None or not c.goals or c.goals[0].time is None or c.goals[0].position is None:
        return 0
    d = float(np.hypot(*(np.asarray(c.goals[0].position, float) - np.asarray(c.position, float))))
    return max(0, int((c.goals[0].time[0] - d / HOLD_SPEED - HOLD_GET_UP) * fps))


def seated_radius(graph) -> float:
    """The bounding cylinder of a seated character: the largest radius of the sitting state's
    clips (a held seat's cylinder)."""
    sit = graph.edge_state == STATES.index("sitting")
    return float(graph.edge_radius[sit].max()) if sit.any() else float(graph.edge_radius.max())


def time_to_wait(c, policy: CrowdPolicy) -> bool:
    """Whether character ``c``'s first goal has a window that opens more than
    ``policy.wait_slack`` seconds after it could walk there in a straight line: it then waits
    at its start first (``start_still`` None), where it already stands, rather than walking
    off and stopping somewhere in the others' way."""
    if not c.goals or c.goals[0].time is None or c.goals[0].position is None:
        return False
    d = float(np.hypot(*(np.asarray(c.goals[0].position, float) - np.asarray(c.position, float))))
    return c.goals[0].time[0] - d / WALK_SPEED > policy.wait_slack


def timing_characters(sc) -> set:
    """Indices of the characters whose arrivals time others' goals (``after``): they are
    planned once, in the first pass, and never re-planned."""
    return {sc.characters.index(sc.character(g.after["character"]))
            for c in sc.characters for g in c.goals if g.after is not None}


def repair(ctx: PlanContext, results: dict, failed: list, k: int) -> None:
    """One repair pass over ``failed`` (see :func:`plan_scenario`); updates ``results`` and
    the index in place."""
    sc, index = ctx.sc, ctx.index
    timing = timing_characters(sc)

    def spent(r, *others):
        r.seconds += sum(o.seconds for o in others)
        r.iterations += sum(o.iterations for o in others)
        return r

    for ci in failed:
        if ci in timing:
            continue
        old = results[ci]
        index.remove_owner(ci)
        new = plan_one(ctx, results, ci, k, attempt=1)
        if not new.warnings:
            results[ci] = spent(new, old)
            ctx.insert(ci, new.track)
            continue
        hits = index.overlapping_owners(*ctx.cylinders(new.track), margin=ctx.params.margin)
        blockers = [b for b, _ in sorted(hits.items(), key=lambda kv: -kv[1])
                    if b != ci and b not in timing][:REPAIR_BLOCKERS]
        tried = [new]          # plans made with every other character in place
        spare = []             # ... and without the blockers (void once they are back)
        if blockers:
            if ctx.log:
                names = ", ".join(sc.characters[b].name for b in blockers)
                ctx.log(f"{sc.characters[ci].name}: planning it without {names}, then them around it")
            for b in blockers:
                index.remove_owner(b)
            first = plan_one(ctx, results, ci, k, attempt=2)
            spare.append(first)
            again = {}
            if not first.warnings:
                ctx.insert(ci, first.track)
                for b in blockers:
                    rb = plan_one(ctx, results, b, k, attempt=3)
                    if rb.warnings:
                        spare.append(rb)
                        break
                    again[b] = rb
                    ctx.insert(b, rb.track)
                if len(again) == len(blockers):
                    for b, rb in again.items():
                        results[b] = spent(rb, results[b])
                    results[ci] = spent(first, old, new)
                    continue
                spare += list(again.values())
                index.remove_owner(ci)
                for b in again:
                    index.remove_owner(b)
            for b in blockers:              # as it was
                ctx.insert(b, results[b].track)
        cand = min(tried, key=lambda r: len(r.warnings))
        keep = cand if len(cand.warnings) < len(old.warnings) else old
        results[ci] = spent(keep, *[r for r in [old] + tried + spare if r is not keep])
        ctx.insert(ci, keep.track)


def collides_early(planner, res, frames: float) -> bool:
    """Whether ``res``'s first collision with a character planned earlier comes within
    ``frames`` of its start (setting off later helps there; not with someone passing its goal
    later, or a jam halfway)."""
    hit = planner.final_collision(res)
    return hit is not None and hit < min(frames, len(res.root))


LANE_RADIUS = 0.5    # m: the bounding cylinder of a walk in lane_clear_delay's straight proxy


def lane_clear_delay(index, cfg, goal, fps, n_total, radius, speed: float = 1.3, step: float = 1.0):
    """Whole ``step`` seconds to stand at ``cfg`` before a straight walk at ``speed`` to the
    goal (a proxy of the motion, a cylinder of ``radius``) misses every planned character in
    ``index``; None when no such wait leaves 2 s of the scenario (``n_total`` frames) after the
    walk. A crowd setting off together clears a lane in front of a character in this time --
    the wait sized to it, where fixed delays of a few seconds were too short behind the
    dense grids' front columns."""
    a = np.array([cfg.x, cfg.z])
    b = np.asarray(goal.position, float)
    n = int(np.hypot(*(b - a)) / speed * fps) + 1
    xz = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    d = 0.0
    while cfg.frame + (d + 2.0) * fps + n < n_total:
        f0 = cfg.frame + int(round(d * fps))
        if index.first_overlap(f0 + np.arange(n), xz, radius) < 0:
            return d
        d += step
    return None


def plan_goals(ctx: PlanContext, results: dict, ci: int, node: int, rng, retry: bool = False):
    """All goals of character ``ci`` from start node ``node`` against the characters in the
    index: (track over the whole scenario, arrival frames, goals, warnings, iterations).

    Each segment's search gets ``params.n_max`` iterations (``retry``: this is a further try at
    the character -- the other start node, a repair pass -- and gets ``policy.retry_n_max``); the
    further tries below (a later arrival, a later departure) get ``policy.retry_n_max``."""
    sc, graph, params, policy, lib = ctx.sc, ctx.graph, ctx.params, ctx.policy, ctx.lib
    fps, n_total, index, still = ctx.fps, ctx.n_total, ctx.index, ctx.still
    n_retry = min(policy.retry_n_max, params.n_max)
    c = sc.characters[ci]
    planner = SegmentPlanner(lib, static=ctx.static,
                             collide=lambda f, xz, r: index.overlaps(f, xz, r),
                             collide_first=lambda f, xz, r: index.first_overlap(f, xz, r),
                             collide_runs=lambda f, xz, r, cnt: index.any_overlap_runs(f, xz, r, cnt),
                             roadmap=ctx.roadmap, env=ctx.env, params=params)
    planner.cache = ctx.cache
    cfg = Config(node, float(c.position[0]), float(c.position[1]), float(c.heading), 0)
    parts = []
    arrivals, goals, warnings = [], [], []
    iters = 0
    for gi, gs in enumerate(c.goals):
        window = gs.time
        if gs.after is not None:
            other = sc.character(gs.after["character"])
            oi = sc.characters.index(other)
            t_other = (results[oi].arrivals[gs.after["goal"]] / fps) if oi != ci else arrivals[gs.after["goal"]] / fps
            w = (t_other + gs.after["within"][0], t_other + gs.after["within"][1])
            window = w if window is None else (max(w[0], window[0]), min(w[1], window[1]))
            if window[1] < window[0]:
                raise ScenarioError(f"{sc.path}: character {c.name!r} goal {gi}: its time window and "
                                    f"'after' window do not overlap")
        nodes = graph.nodes_with_label(gs.pose) if gs.pose else None
        if nodes is not None and len(nodes) == 0:
            raise ScenarioError(f"{sc.path}: character {c.name!r} goal {gi}: pose {gs.pose!r} not in the library")
        goal = Goal(np.asarray(gs.position, float), gs.heading, nodes, window, label=gs.pose or "")
        goals.append(goal)
        # after its last goal a character stands there to the end: that must be clear too
        planner.hold = (lambda r: hold_tail(lib, graph, r.end, n_total)) if gi == len(c.goals) - 1 else None
        res = run_to_completion(planner.run(cfg, goal, rng, name=f"{c.name} goal {gi}",
                                            n_max=n_retry if retry else None))
        iters += res.iterations
        if res.warning and planner.hold is not None and goal.window is None:
            # the motion is clear but standing at the goal afterwards is in the way of a
            # character planned earlier that passes there later: arrive after it has passed
            late = clear_after(planner, res, index)
            if late is not None and late < n_total - 2 * fps:
                g2 = Goal(goal.position, goal.heading, goal.nodes, (late / fps, late / fps + 1.5), label=goal.label)
                res2 = run_to_completion(planner.run(cfg, g2, rng, name=f"{c.name} goal {gi}", n_max=n_retry))
                iters += res2.iterations
                if not res2.warning:
                    res = res2
        if res.warning and res.collided and goal.window is None and still is not None and still[cfg.node] \
                and collides_early(planner, res, policy.depart_within * fps):
            # an untimed goal whose motions all run into characters planned earlier (a crowd
            # setting off together): stand a while first, then go -- the ones ahead are then
            # further on
            delays = policy.depart_delays
            dc = lane_clear_delay(index, cfg, goal, fps, n_total, LANE_RADIUS + params.margin) \
                if policy.depart_clear else None
            if dc:          # (0: the straight walk is clear now, the fixed delays are tried)
                delays = (dc, dc + 3.0)
            for d in delays:
                idle = idle_for(lib, graph, cfg, d, fps)
                frames = cfg.frame + np.arange(len(idle))
                rad = track_radius(graph, idle) + params.margin
                if np.asarray(index.overlaps(frames, idle.root[:, :2], rad), dtype=bool).any():
                    break           # someone passes where it stands: waiting longer will not help
                later = Config(cfg.node, *(float(v) for v in idle.root[-1]), int(frames[-1]))
                res2 = run_to_completion(planner.run(later, goal, rng, name=f"{c.name} goal {gi}",
                                                     n_max=n_retry))
                iters += res2.iterations
                if not res2.warning:
                    parts.append(idle)
                    res = res2
                    break
        if res.warning:
            warnings.append(res.warning)
        parts.append(Track(res.frames_a, res.frames_b, res.frames_t, res.root, res.start_frame))
        cfg = res.end
        arrivals.append(cfg.frame)
    track = concat_tracks(parts) if parts else idle_track(lib, cfg, n_total)
    if len(track) > n_total:
        warnings.append(f"{c.name}: motion runs {len(track) / fps:.1f} s, past the scenario's {sc.duration} s")
        n_total_c = len(track)
    else:
        n_total_c = n_total
    if len(track) < n_total_c:
        track = concat_tracks([track, idle_track(lib, cfg, n_total_c - len(track) + 1)])
    return track.slice(0, n_total), arrivals, goals, warnings, iters
