"""Planning a whole scenario: characters one after another (Sung, Kovar and Gleicher 2005, section 3.1).

Characters are planned in an order that respects relative timing; each planned character
enters the space-time index and is a moving obstacle for the ones after it. A character's
track covers the whole scenario: its segments goal after goal, then idling in place (the
final node's self-loop clips with their drift removed) until the end.
"""
from __future__ import annotations

import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from ..motion.cylinders import enclosing_circles
from ..motion.graph import STATES
from .clearance import Clearance
from .goals import plan_goals
from .idle import still_nodes, track_cylinders
from .planner import CrowdPolicy, MotionCache, MotionLibrary, SearchParams
from .priorities import character_legs
from .scenario import Scenario, ScenarioError, planning_order
from .reservations import Reservations
from .tracks import Track

__all__ = ["CharacterResult", "CrowdResult", "PlanContext", "plan_scenario", "plan_one", "repair", "hold_starts",
           "start_node", "seat_hold", "hold_goal", "seated_radius", "crowd_order", "after_dependencies", "ORDERS", "REPAIR_BLOCKERS"]


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
    ladder: list = field(default_factory=list)    # runtime.crowd.goals.LadderStep per goal that needed one
    collides: bool = False    # not even standing at its start is clear (see plan_scenario)


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
    groups: int = 1           # interaction groups planned apart (CrowdPolicy.split_groups)
    cpu_seconds: float = 0.0  # CPU of the planning, worker processes included

    def by_name(self, name) -> CharacterResult:
        return next(c for c in self.characters if c.name == name)


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

    With ``policy.split_groups`` each interaction group (:func:`planning_groups`: characters
    whose routes come near each other) is planned that way on its own -- in ``policy.workers``
    forked processes at once -- and the groups are then merged; characters of different
    groups that meet after all (a detour) are planned again against everyone
    (:func:`mend_between_groups`). The plans do not depend on the number of workers.

    Args:
        sc: the scenario; its ``[synthesis]`` table overrides ``n_m``, ``k_m``, ``n_max``,
            ``approach_point`` (search) and ``start_still``, ``passes`` (policy).
        graph, env, roadmap: the motion graph, the environment and its roadmap (may be None).
        params, policy: defaults: the paper's search with the scenario's eps, the default policy.
        progress: called with the number of characters planned (of the first pass), as they are.
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
    static = Clearance(sdf, sdf.max_error) if sdf is not None else None
    t_all = time.perf_counter()
    cpu0 = time.process_time()
    passes = max(1, int(sc.synthesis.get("passes", policy.passes)))
    setup = PlanContext(sc, graph, env, roadmap, params, policy, lib, fps, n_total, static, None,
                        still_nodes(graph, params.eps, fps), None)
    order = crowd_order(sc, policy.order, env, roadmap, static=static, fps=fps, n_total=n_total, log=log)
    groups = planning_groups(sc, env, roadmap, order, static) if policy.split_groups and len(order) > 1 else [order]
    parts = _plan_groups(setup, groups, passes, policy.workers, progress, log)
    ctx = _context(setup, log)
    results: dict[int, CharacterResult] = {}
    k = 1
    worker_cpu = 0.0
    for res_g, k_g, cpu_g, hits_g, misses_g in parts:
        results.update(res_g)
        k = max(k, k_g)
        worker_cpu += cpu_g
        if ctx.cache is not None:
            ctx.cache.hits += hits_g
            ctx.cache.misses += misses_g
    for ci in order:
        ctx.insert(ci, results[ci].track)
    if len(groups) > 1:
        mend_between_groups(ctx, results, groups, order, passes)
    total = time.perf_counter() - t_all
    hits, misses = (ctx.cache.hits, ctx.cache.misses) if ctx.cache is not None else (0, 0)
    return CrowdResult(sc, fps, n_total, [results[i] for i in range(len(sc.characters))], order, total, k,
                       hits, misses, len(groups), time.process_time() - cpu0 + worker_cpu)


def _context(setup: PlanContext, log) -> PlanContext:
    """``setup`` (a context without index or cache) with an empty space-time index and motion
    cache of its own."""
    p = setup.params
    return replace(setup, index=Reservations(max(1.2, 2 * setup.lib.max_reach + 2 * (p.margin + p.seed_margin) + 0.05),
                                             setup.n_total, len(setup.sc.characters)),
                   log=log, cache=MotionCache() if setup.policy.reuse_motions else None, handed={})


EXACT_GROUPS_MAX = 200  # characters of a coarse group (priorities.coarse_groups) split into interaction groups
NARROW = 1.0           # m from obstacles where walking counts as narrow (planning_groups)
NARROW_SAMPLE = 0.25   # m between the route points counted


def planning_groups(sc: Scenario, env, roadmap, order: list, static=None) -> list[list[int]]:
    """The scenario's interaction groups (:func:`~.priorities.interaction_groups`: characters
    whose routes come near each other, or tied by ``after``), each in planning ``order``; a
    union of them larger than :data:`EXACT_GROUPS_MAX` (:func:`~.priorities.coarse_groups`)
    stays one group. The groups come in the order worker processes take them up: the most
    route points within :data:`NARROW` of an obstacle (``static``) first -- planning time
    goes to doors and passages -- then the largest; ties by their first character in
    ``order``. (The order changes how long the planning takes, not the plans.)"""
    from .priorities import coarse_groups, interaction_groups, route_legs
    rank = {ci: r for r, ci in enumerate(order)}
    legs = route_legs(sc, env, roadmap)
    groups = []
    for coarse in coarse_groups(sc, legs):
        # a large union (a grid of hundreds) stays whole: pairing its points costs more than
        # splitting it could gain
        groups += [coarse] if len(coarse) > EXACT_GROUPS_MAX else interaction_groups(sc, env, legs, coarse)
    groups = [sorted(g, key=rank.__getitem__) for g in groups]

    def narrow(g):
        if static is None or len(groups) == 1:
            return 0
        pts = []
        for ci in g:
            for _, way in legs[ci]:
                for a, b in zip(way[:-1], way[1:]):
                    m = max(1, int(np.ceil(np.hypot(*(b - a)) / NARROW_SAMPLE)))
                    pts.append(a + (np.arange(m) / m)[:, None] * (b - a))
        return int((static(np.concatenate(pts)) < NARROW).sum()) if pts else 0

    return sorted(groups, key=lambda g: (-narrow(g), -len(g), rank[g[0]]))


_GROUP_JOB = None       # (setup, groups, passes, with_log) for the forked workers of _plan_groups


def _plan_group(setup: PlanContext, group: list, passes: int, progress, log) -> tuple:
    """One interaction group planned on its own (its own index and motion cache): (results,
    passes run, CPU seconds, motions reused, searched)."""
    t = time.process_time()
    ctx = _context(setup, log)
    results, k = _plan_characters(ctx, group, passes, progress)
    hits, misses = (ctx.cache.hits, ctx.cache.misses) if ctx.cache is not None else (0, 0)
    return results, k, time.process_time() - t, hits, misses


def _group_in_worker(gi: int):
    setup, groups, passes, with_log = _GROUP_JOB
    lines: list = []
    out = _plan_group(setup, groups[gi], passes, None, lines.append if with_log else None)
    return out, lines


def _plan_groups(setup: PlanContext, groups: list, passes: int, workers, progress, log) -> list:
    """Every group planned on its own, in forked worker processes when ``workers`` (None:
    the cores) allows more than one and this process may have children: the plans are the
    same bytes either way."""
    n = min(len(groups), workers if workers is not None else (os.cpu_count() or 1))
    if n <= 1 or "fork" not in multiprocessing.get_all_start_methods() or multiprocessing.current_process().daemon:
        # (a daemonic process -- a batch worker, itself one per core -- may not have children)
        # (no worker CPU: it is this process's own)
        return [(r, k, 0.0, h, m) for r, k, _, h, m in (_plan_group(setup, g, passes, progress, log) for g in groups)]
    global _GROUP_JOB
    _GROUP_JOB = (setup, groups, passes, log is not None)
    try:
        with ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("fork")) as pool:
            futures = [pool.submit(_group_in_worker, gi) for gi in range(len(groups))]
            parts = []
            for gi, f in enumerate(futures):
                out, lines = f.result()
                parts.append(out)
                for line in lines:
                    log(line)
                if progress:
                    progress(len(groups[gi]))
    finally:
        _GROUP_JOB = None
    return parts


def _plan_characters(ctx: PlanContext, order: list, passes: int, progress) -> tuple[dict, int]:
    """Pass 1 over ``order``, then repair passes (see :func:`plan_scenario`): ({character:
    result}, passes run)."""
    policy = ctx.policy
    holds = hold_starts(ctx, order)
    held = HeldStarts(holds)
    if policy.reserve_goals:
        for ci in order:
            hold_goal(ctx, ci)
    results: dict[int, CharacterResult] = {}
    all_holds = dict(holds)

    def place(ci: int, attempt: int = 0) -> None:
        ctx.index.remove_owner(ci)          # its start hold (if any) gives way to its plan
        holds.pop(ci, None)
        held.release(ci)
        # holds on the character's own goals give way while it is planned (a swap of places):
        # the one holding there, planned later, leaves before it arrives
        freed = goal_holds(ctx, ci, held)
        for j in freed:
            ctx.index.release_hold(j)
        results[ci] = plan_one(ctx, results, ci, 0, attempt=attempt)
        ctx.insert(ci, results[ci].track)
        for j in freed:
            ctx.index.hold(j, *holds[j])

    def unplace(ci: int) -> None:
        ctx.index.remove_owner(ci)
        del results[ci]
        if ci in all_holds:
            holds[ci] = all_holds[ci]
            ctx.index.hold(ci, *holds[ci])
            held.hold_again(ci)

    def put_back(ci: int, result: CharacterResult) -> None:
        ctx.index.remove_owner(ci)
        holds.pop(ci, None)
        held.release(ci)
        results[ci] = result
        ctx.insert(ci, result.track)

    for ci in order:
        if ci in results:                   # planned early, for someone whose way it stood in
            continue
        place(ci)
        if policy.promote and results[ci].warnings:
            _promote(ctx, results, ci, all_holds, place, unplace, put_back, progress)
        if progress:
            progress(1)
    k = 1
    while k < passes:
        failed = [ci for ci in order if results[ci].warnings]
        if not failed:
            break
        if ctx.log:
            ctx.log(f"pass {k + 1}: repairing {len(failed)} character(s) without a clean plan")
        repair(ctx, results, failed, k)
        k += 1
    return results, k


MEND_ROUNDS = 3     # rounds of planning again the characters of different groups that meet


def between_groups(ctx: PlanContext, results: dict, group_of: dict, order: list) -> list:
    """The characters, in ``order``, whose tracks overlap a character of another group."""
    bad = set()
    for ci in order:
        hits = ctx.index.overlapping_owners(*ctx.cylinders(results[ci].track), margin=ctx.params.margin)
        for o in hits:
            if o != ci and group_of.get(o, -1) != group_of[ci]:
                bad |= {ci, int(o)}
    return [ci for ci in order if ci in bad]


def mend_between_groups(ctx: PlanContext, results: dict, groups: list, order: list, passes: int) -> None:
    """Groups are planned apart, each blind to the others; their routes never come near each
    other, but a detour may. The characters of different groups that meet are planned again
    against everyone (in ``order``, their starts held until then, as in the first pass), then
    repaired once; for at most :data:`MEND_ROUNDS` rounds."""
    group_of = {ci: gi for gi, g in enumerate(groups) for ci in g}
    for rnd in range(MEND_ROUNDS):
        bad = between_groups(ctx, results, group_of, order)
        if not bad:
            return
        if ctx.log:
            names = ", ".join(ctx.sc.characters[ci].name for ci in bad)
            ctx.log(f"groups meet: planning {names} again against everyone")
        for ci in bad:
            ctx.index.remove_owner(ci)
        holds = hold_starts(ctx, bad)
        held = HeldStarts(holds)
        for ci in bad:
            ctx.index.remove_owner(ci)
            held.release(ci)
            freed = goal_holds(ctx, ci, held)
            for j in freed:
                ctx.index.release_hold(j)
            old = results[ci]
            results[ci] = _spent(plan_one(ctx, results, ci, passes + rnd), old)
            ctx.insert(ci, results[ci].track)
            for j in freed:
                ctx.index.hold(j, *holds[j])
        failed = [ci for ci in bad if results[ci].warnings]
        if failed:
            repair(ctx, results, failed, passes + rnd)


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
    index: Reservations
    still: np.ndarray
    log: object
    cache: MotionCache | None = None
    handed: dict = field(default_factory=dict)    # {character: those it took a failure over from}

    def cylinders(self, track):
        xz, rad = track_cylinders(self.graph, track)
        return np.arange(len(track)), xz, rad

    def insert(self, ci, track):
        self.index.insert(ci, *self.cylinders(track))


PROMOTE_BLOCKERS = 2    # characters not planned yet, standing in a failed one's way, planned before it
PROMOTE_REACH = 0.5     # m between a held start's disc and a failed character's route that count as in its way


def _promote(ctx: PlanContext, results: dict, ci: int, holds_of: dict, place, unplace, put_back,
             progress) -> None:
    """Character ``ci`` failed in the first pass, and characters not planned yet stood in its
    way (held starts among its blockers, or within :data:`PROMOTE_REACH` of its route): plan (at
    most :data:`PROMOTE_BLOCKERS` of) them now, so that they leave their starts in their own
    plans, then ``ci`` again. The new plans are kept if ``ci`` is better off and the promoted
    ones are clean, else everything is as before (the promoted characters wait for their turn).

    Args:
        holds_of: {owner: (xz, radius, until)} of every start held in the first pass.
        place, unplace, put_back: ``place(ci, attempt)`` plans a character into the index,
            ``unplace(ci)`` takes it out again (its start held), ``put_back(ci, result)`` puts a
            plan made before back.
        progress: as :func:`plan_scenario`'s.
    """
    first = results[ci]
    hits: dict = {}
    for step in first.ladder:
        for b, n in step.blocked_by.items():
            hits[b] = hits.get(b, 0) + n
    deps = after_dependencies(ctx.sc)

    def free(b):            # not planned yet, and its ``after`` goals timed by characters planned (not ``ci``)
        return (b != ci and b not in results and 0 <= b < len(ctx.sc.characters)
                and all(d in results and d != ci for d in deps[b]))
    waiting = [b for b, _ in sorted(hits.items(), key=lambda kv: -kv[1]) if free(b)][:PROMOTE_BLOCKERS]
    # a search the static filter stopped names nobody: add the held starts beside its route
    others = [o for o in holds_of if free(o) and o not in waiting]
    if len(waiting) < PROMOTE_BLOCKERS and others:
        xz = np.array([holds_of[o][0] for o in others], dtype=np.float64).reshape(-1, 2)
        r = np.array([holds_of[o][1] for o in others], dtype=np.float64)
        d, _ = _points_to_routes(xz, [_route(ctx.sc.characters[ci], ctx.env, ctx.roadmap)])
        gap = d[:, 0] - r
        near = np.flatnonzero(gap < PROMOTE_REACH)
        waiting += [others[k] for k in near[np.argsort(gap[near], kind="stable")]][:PROMOTE_BLOCKERS - len(waiting)]
    if not waiting:
        return
    if ctx.log:
        names = ", ".join(ctx.sc.characters[b].name for b in waiting)
        ctx.log(f"{ctx.sc.characters[ci].name}: planning {names} first, who stood in its way")
    unplace(ci)
    for b in waiting:
        place(b)
    place(ci, attempt=5)
    if _badness(results[ci]) < _badness(first) and not any(results[b].warnings for b in waiting):
        results[ci] = _spent(results[ci], first)
        if progress:
            progress(len(waiting))
        return
    spent = results[ci]
    unplace(ci)
    for b in waiting:
        spent = _spent(spent, results[b])
        unplace(b)
    put_back(ci, _spent(first, spent))


def plan_one(ctx: PlanContext, results, ci: int, k: int, attempt: int = 0, give_up: bool = True) -> CharacterResult:
    """Character ``ci`` planned against the space-time index. Its random stream is seeded by
    the scenario seed, its index, the pass ``k`` and ``attempt``, so its plan depends on the
    order only through the characters already in the index.

    A character whose start pose has two kinds of node -- the pose's most connected node and
    one where it can stand still and wait (for "stand": a walking hub and a standing node) --
    is planned from the first (``start_still``: the second; unset: the second when the
    character has time to wait, :func:`time_to_wait`); if that plan has warnings, it is
    planned again from the other (without the ladder's rungs that give a constraint up), and
    the plan with fewer warnings is kept."""
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
        # the other start node is only worth it for a plan that keeps every constraint: its
        # ladder stops before the rungs that give one up (the first plan already has those)
        out = plan_goals(ctx, results, ci, node, rng, retry=bool(a or attempt), give_up=give_up and a == 0)
        iters += out.iterations
        if best is None or _badness(out) < _badness(best):
            best = out
        if not best.warnings:
            break
        if ctx.log and a == 0 and len(starts) > 1:
            ctx.log(f"{c.name}: planning again from the other {c.pose!r} start node")
    if ctx.log:
        for w in best.warnings:
            ctx.log(f"warning: {w}")
    return CharacterResult(c.name, best.track, best.arrivals, best.goals, best.warnings, time.perf_counter() - t0,
                           iters, best.arrivals[-1] / ctx.fps if best.arrivals else 0.0, best.ladder, best.collides)


def _badness(plan) -> tuple:
    """How far a character's plan is from clean, for choosing between plans: colliding worst,
    then goals given up (waiting), then warnings (late, relaxed)."""
    waiting = sum(s.kind == "waiting" for s in plan.ladder)
    return (bool(plan.collides), waiting, len(plan.warnings))


WALK_SPEED = 1.4    # m/s: a brisk walk, for telling whether a character has time to wait
HOLD_SPEED = 1.5    # m/s: the fastest straight walk for the earliest time a seated character leaves
HOLD_GET_UP = 2.0   # s: ... plus the time it takes to get up


def seat_hold(c, graph, fps: float, standing: bool = False) -> int:
    """Frames from 0 during which a character who starts seated (``start = { seat = ... }``)
    has no need to leave yet: getting up and walking straight to its first goal at a brisk
    pace (``HOLD_GET_UP``, ``HOLD_SPEED``) still arrives before the goal's window opens.
    Characters are planned one after another
    (Sung, Kovar and Gleicher 2005, section 3.1), and one planned later is invisible to those before it -- but a
    seated one cannot step aside: a neighbour sitting down next to it would turn across its
    place. So until it is planned its seat is held for those frames: earlier characters
    treat it as sitting there (0 when it does not start seated or its first goal has no
    window)."""
    if (c.start_marker is None and not standing) or not c.goals or c.goals[0].time is None \
            or c.goals[0].position is None:
        return 0
    d = float(np.hypot(*(np.asarray(c.goals[0].position, float) - np.asarray(c.position, float))))
    get_up = 0.0 if standing else HOLD_GET_UP
    return max(0, int((c.goals[0].time[0] - d / HOLD_SPEED - get_up) * fps))


def start_hold(ctx: PlanContext, c) -> tuple[int, np.ndarray, float]:
    """(frames from 0, disc centre (2,), radius) for which character ``c``'s start is held in
    the index until it is planned (``CrowdPolicy.reserve_starts``): characters planned before
    it then treat it as standing (or sitting) there. "none": only a seated start, while it has
    no need to leave (:func:`seat_hold`); "needed": any start, while it has no need to leave yet
    (a brisk straight walk still reaches its first goal before the window opens; 0 for an
    untimed first goal); "all": any start, for the whole scenario -- the revised prioritized
    planning of Čáp, Novák, Kleiner and Selecký (2015), which guarantees that standing at its
    start stays clear of everyone planned before it. The disc holds the idle (or seated)
    cylinders at the start's heading (:func:`held_disc`)."""
    mode = ctx.policy.reserve_starts
    seated = c.start_marker is not None
    xz, radius = held_disc(ctx.graph, ctx.still, "sit" if seated else "stand", c.position, c.heading)
    if mode == "all":
        return ctx.n_total, xz, radius
    if mode == "needed" or seated:
        return min(seat_hold(c, ctx.graph, ctx.fps, standing=not seated), ctx.n_total), xz, radius
    return 0, xz, radius


def hold_goal(ctx: PlanContext, ci: int) -> None:
    """Hold character ``ci``'s last goal (where it stands to the end) from the opening of that
    goal's window until it is planned (``CrowdPolicy.reserve_goals``): characters planned before
    it then keep off the place after it may arrive -- as Čáp, Novák, Kleiner and Selecký (2015)
    have every path avoid the other agents' endpoints. Untimed goals are not held."""
    c = ctx.sc.characters[ci]
    g = c.goals[-1] if c.goals else None
    if g is None or g.position is None or g.time is None:
        return
    f0 = int(np.floor(g.time[0] * ctx.fps))
    if f0 >= ctx.n_total:
        return
    xz, radius = held_disc(ctx.graph, ctx.still, "sit" if g.kind == "seat" else "stand", g.position, g.heading)
    ctx.index.hold(ci, xz, radius, ctx.n_total, start=f0, kind="goal")


def goal_holds(ctx: PlanContext, ci: int, holds) -> list:
    """The characters in ``holds`` ({owner: (xz, radius, until)}, or :class:`HeldStarts`) whose
    held start is where character ``ci`` must arrive: within the two bounding cylinders (and the
    margin) of one of its goal positions."""
    return (holds if isinstance(holds, HeldStarts) else HeldStarts(holds)).at_goals(ctx, ci)


class HeldStarts:
    """The held starts of a scenario as arrays, in the order of ``holds`` ({owner: (xz, radius,
    until)}), with the ones released since (their characters planned) masked out -- so asking
    who holds a character's goals costs one vectorized test, not a pass over a dict."""

    def __init__(self, holds: dict):
        self.owners = np.fromiter(holds.keys(), dtype=np.int64, count=len(holds))
        self.xz = np.array([h[0] for h in holds.values()], dtype=np.float64).reshape(-1, 2)
        self.radius = np.fromiter((h[1] for h in holds.values()), dtype=np.float64, count=len(holds))
        self.live = np.ones(len(holds), dtype=bool)
        self._row = {int(o): k for k, o in enumerate(self.owners)}

    def release(self, owner: int) -> None:
        k = self._row.get(int(owner))
        if k is not None:
            self.live[k] = False

    def hold_again(self, owner: int) -> None:
        """Undo :meth:`release` (the character was taken out of the index again)."""
        k = self._row.get(int(owner))
        if k is not None:
            self.live[k] = True

    def at_goals(self, ctx: PlanContext, ci: int) -> list:
        """The live holders whose disc is within the two bounding cylinders (and the margin) of
        one of character ``ci``'s goal positions."""
        goals = [g.position for g in ctx.sc.characters[ci].goals if g.position is not None]
        if not goals or not self.live.any():
            return []
        goals = np.asarray(goals, float)
        reach = ctx.lib.max_reach + ctx.params.margin
        xz, radius = self.xz[self.live], self.radius[self.live]
        d = np.hypot(xz[:, None, 0] - goals[None, :, 0], xz[:, None, 1] - goals[None, :, 1]).min(axis=1)
        return self.owners[self.live][d < reach + radius].tolist()


def standing_radius(graph, still) -> float:
    """The disc a character standing at its start holds: the largest reach (the circle about
    the root holding the bounding cylinder, whatever the heading) of the idle clips of the
    "stand" nodes where one can stand still."""
    loops = _idle_loops(graph, still)
    return float(graph.edge_reach[loops].max()) if len(loops) else float(graph.edge_reach.max())


def held_disc(graph, still, pose: str, position, heading) -> tuple[np.ndarray, float]:
    """The disc held for a character standing (``pose`` "stand") or seated ("sit") at
    ``position`` (x, z) facing ``heading`` (radians; None: any heading): the circle holding the
    bounding cylinders of every frame of the idle clips (seated: the sitting state's clips) as
    they play from there, or the disc about ``position`` of :func:`standing_radius` /
    :func:`seated_radius` (any heading) when that is smaller or no heading is given. Returns
    (centre (2,), radius)."""
    pos = np.asarray(position, dtype=np.float64)
    about = seated_radius(graph) if pose == "sit" else standing_radius(graph, still)
    if heading is None:
        return pos, about
    axis, radius = _held_cylinder(graph, still, pose)
    if radius >= about:
        return pos, about
    ch, sh = np.cos(heading), np.sin(heading)
    return pos + np.array([ch * axis[0] + sh * axis[1], -sh * axis[0] + ch * axis[1]]), radius


def _held_cylinder(graph, still, pose: str):
    """(axis (2,) from the start configuration, radius) holding the cylinders of every frame
    of the clips :func:`held_disc` holds, as placed from the clip's start (memoized per graph)."""
    key = (pose, None if still is None else np.flatnonzero(still).tobytes())
    memo = graph.__dict__.setdefault("_held_cylinder_memo", {})
    if key not in memo:
        if pose == "sit":
            edges = np.flatnonzero(graph.edge_state == STATES.index("sitting"))
        else:
            edges = _idle_loops(graph, still)
        if not len(edges):
            edges = np.arange(graph.num_edges)
        frames = np.concatenate([np.arange(graph.edge_start[e], graph.edge_start[e + 1]) for e in edges])
        cxz, r = graph.frame_cxz[frames], graph.frame_radius[frames].astype(np.float64)
        centre, _ = enclosing_circles(cxz)
        memo[key] = (centre, float(np.max(np.hypot(*(cxz - centre).T) + r)))
    return memo[key]


def _idle_loops(graph, still) -> np.ndarray:
    nodes = graph.nodes_with_label("stand")
    nodes = nodes[still[nodes]] if still is not None and still[nodes].any() else nodes
    return np.flatnonzero(np.isin(graph.edge_src, nodes) & (graph.edge_src == graph.edge_dst))


def seated_radius(graph) -> float:
    """The disc a seated character holds: the largest reach (about the root) of the sitting state's
    clips (a held seat's cylinder)."""
    sit = graph.edge_state == STATES.index("sitting")
    return float(graph.edge_reach[sit].max()) if sit.any() else float(graph.edge_reach.max())


def time_to_wait(c, policy: CrowdPolicy) -> bool:
    """Whether character ``c``'s first goal has a window that opens more than
    ``policy.wait_slack`` seconds after it could walk there in a straight line: it then waits
    at its start first (``start_still`` None), where it already stands, rather than walking
    off and stopping somewhere in the others' way."""
    if not c.goals or c.goals[0].time is None or c.goals[0].position is None:
        return False
    d = float(np.hypot(*(np.asarray(c.goals[0].position, float) - np.asarray(c.position, float))))
    return c.goals[0].time[0] - d / WALK_SPEED > policy.wait_slack


ORDERS = ("file", "longest", "earliest", "shortest", "endpoints", "lattice")
ENDPOINT_REACH = 1.0    # m: a start or last goal this close to another's route is in its way ...
ENDPOINT_NARROW = 1.5   # m: ... where the route passes closer than this to a static obstacle (a door, a
#                         corridor: in the open a walker steps round someone standing)


def _routes(sc: Scenario, env, roadmap) -> list:
    """Per character, its route through all its goals (:func:`_route`)."""
    return [_route(c, env, roadmap) for c in sc.characters]


def _route(c, env, roadmap) -> np.ndarray:
    """Character ``c``'s route through all its goals: the roadmap's way points from the start
    to each goal in turn (straight lines without a roadmap), as one (n, 2) polyline."""
    return np.concatenate([np.asarray(c.position, float)[None]]
                          + [way[1:] for _, way in character_legs(c, env, roadmap)])


def _points_to_routes(points: np.ndarray, routes: list):
    """(P, R) the distance from each point to each polyline of ``routes``, and (P, R, 2) the
    nearest point of the polyline (vectorized over all their segments)."""
    segs = [(np.repeat(line, 2, axis=0)[1:-1].reshape(-1, 2, 2) if len(line) > 1 else line[None, [0, 0]])
            for line in routes]
    first = np.cumsum([0] + [len(sg) for sg in segs[:-1]])
    seg = np.concatenate(segs)
    a, ab = seg[:, 0], seg[:, 1] - seg[:, 0]
    rel = points[:, None, :] - a[None]
    t = np.clip(np.einsum("psk,sk->ps", rel, ab) / np.maximum(np.einsum("sk,sk->s", ab, ab), 1e-12), 0.0, 1.0)
    near = a[None] + t[..., None] * ab[None]
    d = np.hypot(*(points[:, None, :] - near).transpose(2, 0, 1))
    # per route (a run of columns): the distance, and its first segment at that distance
    dmin = np.minimum.reduceat(d, first, axis=1)
    at = d == np.repeat(dmin, np.diff(np.r_[first, len(seg)]), axis=1)
    arg = np.minimum.reduceat(np.where(at, np.arange(len(seg))[None], len(seg)), first, axis=1)
    return dmin, near[np.arange(len(points))[:, None], arg]


def endpoint_precedence(sc: Scenario, env=None, roadmap=None, reach: float = ENDPOINT_REACH,
                        narrow: float | None = ENDPOINT_NARROW) -> set:
    """Pairs (i, j): character i should be planned before j because an endpoint of one lies
    on the other's route (within ``reach`` m). A start waits, held, until its character is
    planned: one on j's route should leave first (i = its owner). A last goal is stood on to
    the end: one on i's route should be reached after i has passed (j = its owner). Prioritized
    planning always succeeds when no one's path needs to cross another's start or goal
    (well-formed infrastructures, Cap, Novak, Kleiner and Selecky 2015); where paths must, this
    order has the one in the way leave first, or arrive last. With ``env``, only where the
    route passes that endpoint closer than ``narrow`` m to a static obstacle (None: anywhere)."""
    n = len(sc.characters)
    if n < 2:
        return set()
    routes = _routes(sc, env, roadmap)
    starts = np.array([np.asarray(c.position, float) for c in sc.characters])
    lasts = [next((np.asarray(g.position, float) for g in reversed(c.goals) if g.position is not None), None)
             for c in sc.characters]
    has_last = np.array([x is not None for x in lasts])
    goals = np.array([x if x is not None else np.zeros(2) for x in lasts])

    def on_route(points):
        d, q = _points_to_routes(points, routes)
        on = d < reach
        if env is not None and narrow is not None and on.any():
            on[on] = env.distance(q[on]) < narrow
        return on
    near_s = on_route(starts)                        # [k, o]: k's start on o's route
    near_g = on_route(goals) & has_last[:, None]
    np.fill_diagonal(near_s, False)
    np.fill_diagonal(near_g, False)
    pairs = {(int(k), int(o)) for k, o in zip(*np.nonzero(near_s))}
    pairs |= {(int(o), int(k)) for k, o in zip(*np.nonzero(near_g))}
    return pairs


def crowd_order(sc: Scenario, how: str = "file", env=None, roadmap=None, static=None, fps: float = 30.0,
                n_total: int | None = None, log=None) -> list[int]:
    """The order characters are planned in (prioritized planning: each one avoids those before
    it). Always after the characters whose arrivals time its goals (``after``); among the
    others, by ``how``: "file" (the scenario's order), "longest" (the longest walk through all
    its goals first), "shortest", "earliest" (the earliest first arrival: its window's start,
    or a walk at ``WALK_SPEED`` for an untimed goal), or "endpoints" (file order, but a
    character whose start is on another's route before it, and one whose last goal is on
    another's route after it: :func:`endpoint_precedence`, routes on ``roadmap``; where these
    preferences form a cycle, the character with the fewest unmet ones goes first), or
    "lattice" (per interaction group, the order whose stand-in plan of discs on a space-time
    lattice leaves the fewest characters without a route: :mod:`runtime.crowd.priorities`;
    ``static`` is then the clearance the stand-in keeps from the obstacles, ``fps`` and
    ``n_total`` the clock, ``log`` hears the choice per group)."""
    import heapq
    if how == "file":
        return planning_order(sc)
    if how not in ORDERS:
        raise ScenarioError(f"{sc.path}: unknown planning order {how!r} (one of {', '.join(ORDERS)})")
    planning_order(sc)        # checks the 'after' references and cycles
    if how == "endpoints":
        return _soft_order(sc, endpoint_precedence(sc, env, roadmap))
    if how == "lattice":
        from .priorities import CANDIDATES, lattice_order
        n_total = n_total if n_total is not None else int(round(sc.duration * fps)) + 1
        candidates = {k: crowd_order(sc, k, env, roadmap) for k in CANDIDATES}
        return lattice_order(sc, env, roadmap, static, fps, n_total, candidates, after_dependencies(sc), log=log)
    n = len(sc.characters)

    def walk(c):
        pts = [np.asarray(c.position, float)] + [np.asarray(g.position, float) for g in c.goals
                                                  if g.position is not None]
        return float(sum(np.hypot(*(b - a)) for a, b in zip(pts[:-1], pts[1:])))

    def key(i):
        c = sc.characters[i]
        if how == "longest":
            return -walk(c)
        if how == "shortest":
            return walk(c)
        g = c.goals[0] if c.goals else None
        if g is not None and g.time is not None:
            return float(g.time[0])
        return walk(c) / WALK_SPEED

    deps = after_dependencies(sc)
    users = [[] for _ in range(n)]
    for i, d in enumerate(deps):
        for j in d:
            users[j].append(i)
    left = [len(d) for d in deps]
    heap = [(key(i), i) for i in range(n) if left[i] == 0]
    heapq.heapify(heap)
    order = []
    while heap:
        _, i = heapq.heappop(heap)
        order.append(i)
        for u in users[i]:
            left[u] -= 1
            if left[u] == 0:
                heapq.heappush(heap, (key(u), u))
    return order


def after_dependencies(sc: Scenario) -> list[set]:
    """Per character, the other characters whose arrivals time its goals (``after``)."""
    idx = {c.name: i for i, c in enumerate(sc.characters)}
    deps = [set() for _ in sc.characters]
    for i, c in enumerate(sc.characters):
        for g in c.goals:
            if g.after is not None and idx[g.after["character"]] != i:
                deps[i].add(idx[g.after["character"]])
    return deps


def _soft_order(sc: Scenario, soft: set) -> list[int]:
    """A topological order of the ``after`` dependencies (hard) that meets as many of the
    ``soft`` pairs (i before j) as a greedy pass does: at each step, of the characters whose
    hard dependencies are planned, the one with the fewest soft predecessors not yet planned
    (ties: file order)."""
    n = len(sc.characters)
    hard = after_dependencies(sc)
    pred = [set() for _ in range(n)]
    for a, b in soft:
        pred[b].add(a)
    done, order = set(), []
    while len(order) < n:
        ready = [i for i in range(n) if i not in done and hard[i] <= done]
        i = min(ready, key=lambda k: (len(pred[k] - done), k))
        order.append(i)
        done.add(i)
    return order


def timing_characters(sc) -> set:
    """Indices of the characters whose arrivals time others' goals (``after``)."""
    return {sc.characters.index(sc.character(g.after["character"]))
            for c in sc.characters for g in c.goals if g.after is not None}


def dependents(sc) -> dict:
    """{index: the indices of the characters whose goals its arrivals time ('after'), directly
    or through others, in planning order}."""
    idx = {c.name: i for i, c in enumerate(sc.characters)}
    direct = {}
    for i, c in enumerate(sc.characters):
        for g in c.goals:
            if g.after is not None and idx[g.after["character"]] != i:
                direct.setdefault(idx[g.after["character"]], set()).add(i)
    rank = {ci: r for r, ci in enumerate(planning_order(sc))}
    out = {}
    for lead in direct:
        seen, todo = set(), [lead]
        while todo:
            for d in direct.get(todo.pop(), ()):
                if d not in seen:
                    seen.add(d)
                    todo.append(d)
        out[lead] = sorted(seen, key=rank.get)
    return out


def repair(ctx: PlanContext, results: dict, failed: list, k: int) -> None:
    """One repair pass over ``failed`` (see :func:`plan_scenario`); updates ``results`` and
    the index in place.

    A failed character is planned again in place; if that fails, without the (at most
    :data:`REPAIR_BLOCKERS`) planned characters it ran into, which are then planned again
    around it -- kept only if all of them come out clean, else they are put back. With
    ``CrowdPolicy.hand_over``, one of them may come out failing instead, no worse off than the
    repaired character was: the failure is handed over, and the next pass repairs it (a
    character takes a failure over once, and never displaces the one that handed it over, so
    the two cannot trade it back and forth). The count of failing characters is the same, but
    the failure moves to a character whose blockers may give way where the first one's could
    not. A failed character whose arrivals time others' goals (``after``, :func:`dependents`) is
    repaired with those others taken out, and they are planned again after its new plan: the group's
    new plans are kept only if the group as a whole is better off (:func:`_badness`, summed),
    else everything is put back as it was."""
    deps_of = dependents(ctx.sc)
    timing = timing_characters(ctx.sc)
    for ci in failed:
        if not results[ci].warnings:        # mended with its group earlier in this pass
            continue
        deps = deps_of.get(ci, [])
        if not deps:
            _repair_alone(ctx, results, ci, k, timing)
            continue
        before = {o: results[o] for o in [ci, *deps]}
        for d in deps:
            ctx.index.remove_owner(d)
        held = hold_starts(ctx, deps)
        changed = _repair_alone(ctx, results, ci, k, timing | set(deps), held)
        if not changed:
            for d in deps:
                ctx.index.remove_owner(d)
                ctx.insert(d, results[d].track)
            continue
        for d in deps:
            ctx.index.remove_owner(d)       # its start hold gives way to its plan
            results[d] = plan_one(ctx, results, d, k, attempt=4)
            ctx.insert(d, results[d].track)
        if _group_badness(results[o] for o in before) < _group_badness(before.values()):
            for d in deps:
                _spent(results[d], before[d])
            continue
        # the group is no better: everything as it was (the time spent stays counted)
        olds = {**changed, **{d: before[d] for d in deps}}
        for o in olds:
            ctx.index.remove_owner(o)
        for o, r in olds.items():
            now = results[o]
            extra = (0.0, 0) if o not in deps else (r.seconds, r.iterations)
            results[o] = replace(r, seconds=now.seconds + extra[0], iterations=now.iterations + extra[1])
            ctx.insert(o, r.track)


def _group_badness(plans) -> tuple:
    return tuple(int(v) for v in np.sum([_badness(r) for r in plans], axis=0))


def _spent(r, *others):
    r.seconds += sum(o.seconds for o in others)
    r.iterations += sum(o.iterations for o in others)
    return r


def hold_starts(ctx: PlanContext, owners) -> dict:
    """Hold the starts of ``owners`` (:func:`start_hold`) until they are planned: in the first
    pass every character's, in a repair those taken out of the index to be planned again after
    another, so that the one planned before them keeps off where they stand. Returns {owner:
    (xz, radius, until)} of the holds made."""
    holds = {}
    for o in owners:
        c = ctx.sc.characters[o]
        until, xz, radius = start_hold(ctx, c)
        if until:
            holds[o] = (xz, radius, until)
            ctx.index.hold(o, *holds[o])
    return holds


def _plan_among_held(ctx: PlanContext, results: dict, ci: int, k: int, attempt: int, held: dict) -> CharacterResult:
    """``plan_one`` (keeping every constraint) while the starts in ``held`` are held, but for
    the ones where ``ci`` must arrive (a swap of places: as in the first pass, they give way)."""
    freed = goal_holds(ctx, ci, held) if held else []
    for j in freed:
        ctx.index.release_hold(j)
    try:
        return plan_one(ctx, results, ci, k, attempt=attempt, give_up=False)
    finally:
        for j in freed:
            ctx.index.hold(j, *held[j])


def _repair_alone(ctx: PlanContext, results: dict, ci: int, k: int, keep: set, held: dict | None = None) -> dict:
    """Character ``ci`` repaired against everyone in the index (see :func:`repair`); the
    blockers it may displace are never in ``keep`` (the characters whose arrivals time others,
    and those being planned again with ``ci``). ``held``: the held starts of characters taken
    out to be planned after it (:func:`hold_starts`). Blockers taken out have their starts held
    the same way while ``ci`` is planned without them. Returns {owner: its result before} of
    the characters whose plans it replaced."""
    sc, index = ctx.sc, ctx.index
    held = held or {}
    old = results[ci]
    index.remove_owner(ci)
    new = _plan_among_held(ctx, results, ci, k, 1, held)
    if not new.warnings:
        results[ci] = _spent(new, old)
        ctx.insert(ci, new.track)
        return {ci: old}
    hits = {}
    for step in new.ladder:
        for b, n in step.blocked_by.items():
            hits[b] = hits.get(b, 0) + n
    hits.update(index.overlapping_owners(*ctx.cylinders(new.track), margin=ctx.params.margin))
    handed_by = ctx.handed.get(ci, set())
    blockers = [b for b, _ in sorted(hits.items(), key=lambda kv: -kv[1])
                if b != ci and b not in keep and b not in handed_by][:REPAIR_BLOCKERS]
    tried = [new]          # plans made with every other character in place
    spare = []             # ... and without the blockers (void once they are back)
    if blockers:
        if ctx.log:
            names = ", ".join(sc.characters[b].name for b in blockers)
            ctx.log(f"{sc.characters[ci].name}: planning it without {names}, then them around it")
        for b in blockers:
            index.remove_owner(b)
        held_b = hold_starts(ctx, blockers)
        first = _plan_among_held(ctx, results, ci, k, 2, {**held, **held_b})
        spare.append(first)
        again = {}
        taker = None            # the blocker that takes the failure over (CrowdPolicy.hand_over)
        if not first.warnings:
            ctx.insert(ci, first.track)
            for b in blockers:
                index.remove_owner(b)       # its start hold gives way to its plan
                rb = plan_one(ctx, results, b, k, attempt=3, give_up=False)
                if rb.warnings and not (taker is None and ctx.policy.hand_over and b not in ctx.handed
                                        and _badness(rb) <= _badness(old)):
                    spare.append(rb)
                    break
                taker = b if rb.warnings else taker
                again[b] = rb
                ctx.insert(b, rb.track)
            if len(again) == len(blockers):
                changed = {b: results[b] for b in again}
                for b, rb in again.items():
                    results[b] = _spent(rb, results[b])
                results[ci] = _spent(first, old, new)
                if taker is not None:
                    ctx.handed[taker] = {ci}
                    if ctx.log:
                        ctx.log(f"{sc.characters[taker].name} takes {sc.characters[ci].name}'s failure over")
                return {ci: old, **changed}
            spare += list(again.values())
            index.remove_owner(ci)
            for b in again:
                index.remove_owner(b)
        for b in blockers:              # as it was
            index.remove_owner(b)
            ctx.insert(b, results[b].track)
    cand = min(tried, key=_badness)
    keep_plan = cand if _badness(cand) < _badness(old) else old
    results[ci] = _spent(keep_plan, *[r for r in [old] + tried + spare if r is not keep_plan])
    ctx.insert(ci, keep_plan.track)
    return {} if keep_plan is old else {ci: old}
