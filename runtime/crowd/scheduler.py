"""Planning a whole scenario: characters one after another (paper 000, section 3.1).

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
from .motion_cache import MotionCache
from .scenario import Scenario, ScenarioError, planning_order
from .spacetime import SpaceTimeIndex
from .synthesis import Config, Goal, MotionLibrary, SegmentPlanner, SynthesisParams, compose
from .tracks import Track, concat_tracks

__all__ = ["CharacterResult", "CrowdResult", "plan_scenario", "idle_track", "still_nodes", "run_to_completion"]


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


def run_to_completion(gen):
    try:
        while True:
            next(gen)
    except StopIteration as e:
        return e.value


def _idle_loop(g, node: int) -> int:
    """The node's self-loop clip with the least drift (the one idling repeats), or -1."""
    loops = np.flatnonzero((g.edge_src == node) & (g.edge_dst == node))
    if len(loops) == 0:
        return -1
    drift = np.hypot(g.edge_disp[loops, 0], g.edge_disp[loops, 1]) + 0.3 * np.abs(g.edge_disp[loops, 2])
    return int(loops[np.argmin(drift)])


def track_radius(graph, track: Track) -> np.ndarray:
    """Per frame of ``track``, its bounding cylinder's radius (the larger of the two library
    frames it blends)."""
    return np.maximum(graph.frame_radius[track.frames_a], graph.frame_radius[track.frames_b])


def idle_track(lib: MotionLibrary, cfg: Config, n_frames: int, turn: bool = False) -> Track:
    """``n_frames`` frames (including the start frame) of idling at ``cfg``: the node's
    self-loop clip with the least drift, repeated, each repeat bent back onto the start
    configuration; a held pose when the node has no self loop. ``turn``: each repeat is bent
    back onto the start position only and keeps the clip's turn, so the idling ends turned by
    the clips' own small turns -- what a wait before a motion needs: bent back onto the
    heading, a wait of 30 s leaves the raw clips integrated from its start a few degrees off
    the motion after it, which the checker's per-frame adjustment sees as the whole walk
    rotated (the 14 x 6 grid at 2.2 m: 10 characters over eps)."""
    g = lib.g
    e = _idle_loop(g, cfg.node)
    start = np.array([cfg.x, cfg.z, cfg.heading])
    last = g.edge_start[np.flatnonzero(g.edge_dst == cfg.node)[0] + 1] - 1 if np.any(g.edge_dst == cfg.node) else 0
    if e < 0 or n_frames <= 1:
        fa = np.full(n_frames, last, dtype=np.int64)
        return Track(fa, fa.copy(), np.zeros(n_frames, np.float32), np.repeat(start[None], n_frames, 0), cfg.frame)
    a, b = g.edge_start[e], g.edge_start[e + 1]
    L = b - a                                   # frames in the loop including both hub frames
    local = np.stack([g.frame_xz[a:b, 0], g.frame_xz[a:b, 1], g.frame_heading[a:b]], axis=1)
    ramp = np.linspace(0.0, 1.0, L)[:, None] * g.edge_disp[e][None, :]
    if turn:
        ramp[:, 2] = 0.0
    local = local - ramp                        # each repeat returns exactly to the start
    reps = int(np.ceil((n_frames - 1) / (L - 1)))
    idx = np.concatenate([[0]] + [np.arange(1, L)] * reps)[:n_frames]
    frames = a + idx
    if turn:
        rep = np.concatenate([[0], np.repeat(np.arange(reps), L - 1)])[:n_frames]
        starts = np.repeat(start[None], reps, 0)
        starts[:, 2] += np.arange(reps) * float(g.edge_disp[e, 2])
        root = compose(starts[rep], local[idx])
    else:
        root = compose(start[None], local[idx])
    return Track(frames, frames.copy(), np.zeros(n_frames, np.float32), root, cfg.frame)


def still_nodes(graph, eps, fps: float = 30.0) -> np.ndarray:
    """Per node: whether idling on it stands still -- its least-drifting self-loop clip (the
    one :func:`idle_track` repeats, its drift removed as a ramp) drifts within the per-frame
    adjustment tolerance ``eps`` (m/s, deg/s, ...). A walking hub's self loops are walk
    cycles: idling there would walk on the spot."""
    g = graph
    ep, eh = float(eps[0]), float(eps[1])
    still = np.zeros(g.num_nodes, dtype=bool)
    for n in range(g.num_nodes):
        e = _idle_loop(g, n)
        if e < 0:
            continue
        d = g.edge_disp[e]
        dur = (g.edge_frames[e] - 1) / fps
        still[n] = dur > 0 and np.hypot(d[0], d[1]) / dur <= ep and np.degrees(abs(d[2])) / dur <= eh
    return still


def _hold_tail(lib, graph, end: Config, n_total: int):
    """(frames, xz, radius) of idling at ``end`` from the frame after it to the scenario's end
    (what the scheduler appends after a character's last goal)."""
    n = n_total - end.frame
    if n <= 1:
        return None
    tr = idle_track(lib, end, n)
    frames = end.frame + np.arange(1, n)
    rad = track_radius(graph, tr)[1:]
    return frames, tr.root[1:, :2], rad


def _clear_after(planner, res, index):
    """When ``res``'s motion is clear but holding its end position is not (the final test
    returns one past its frames), the first frame after which the held position stays clear;
    else None."""
    if planner.final_collision(res, -1) != len(res.root):
        return None
    f2, xz2, r2 = planner.hold(res)
    bad = np.asarray(index.overlaps(f2, xz2, np.asarray(r2, float) + planner.p.margin), dtype=bool)
    if not bad.any():
        return None
    return int(f2[np.flatnonzero(bad)[-1]]) + int(round(0.5 * planner.p.fps))


def _start_node(graph, pose: str, where: str, still: np.ndarray | None = None) -> int:
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


def plan_scenario(sc: Scenario, graph, env=None, roadmap=None, params: SynthesisParams | None = None,
                  progress=None, log=None) -> CrowdResult:
    """Plan every character of ``sc`` (paper 000, section 3.1: one after another, earlier ones
    moving obstacles for later ones), then repair.

    Pass 1 plans all characters in :func:`planning_order`. Each later pass (``[synthesis]
    passes``, default 3, counts them all) repairs only the characters left with warnings:
    every planned character stays in the space-time index, so a repaired plan is tested
    against all the others, before and after it in the order. A failed character is planned
    again with a fresh random stream; if that still fails, the (at most ``REPAIR_BLOCKERS``)
    characters its plan runs into are taken out, it is planned without them, and they are
    planned again around it -- kept only if all of them come out clean, else everything goes
    back as it was. No character's plan is replaced by one with more warnings, so later
    passes only help. Characters whose arrivals time others' goals (``after``) are not
    re-planned."""
    params = params or SynthesisParams(eps=sc.epsilon)
    for k in ("n_m", "k_m", "n_max"):
        if k in sc.synthesis:
            setattr(params, k, int(sc.synthesis[k]))
    if "start_still" in sc.synthesis:
        params.start_still = bool(sc.synthesis["start_still"])
    if "approach_point" in sc.synthesis:
        params.approach_point = float(sc.synthesis["approach_point"])
    lib = MotionLibrary(graph, params)
    fps = params.fps
    n_total = int(round(sc.duration * fps)) + 1
    sdf = env.sdf(resolution=0.05, margin=2.0) if env is not None and (len(env.polygons) or len(env.circles)) else None
    # the sampled field may overestimate clearance by up to max_error: stay conservative
    static = (lambda xz: sdf.sample(xz) - sdf.max_error) if sdf is not None else None
    t_all = time.perf_counter()
    passes = max(1, int(sc.synthesis.get("passes", 3)))
    ctx = _Context(sc, graph, env, roadmap, params, lib, fps, n_total, static,
                   SpaceTimeIndex(cell=max(1.2, 2 * lib.max_radius + 2 * (params.margin + params.seed_margin) + 0.05)),
                   still_nodes(graph, params.eps, fps), log,
                   MotionCache() if params.reuse_motions else None)
    order = planning_order(sc)
    for ci in order:
        hold = _seat_hold(sc.characters[ci], graph, fps)
        if hold:
            ctx.index.insert(ci, np.arange(hold), np.repeat(sc.characters[ci].position[None], hold, 0),
                             _seated_radius(graph))
    results: dict[int, CharacterResult] = {}
    for ci in order:
        ctx.index.remove_owner(ci)          # its seat hold (if any) gives way to its plan
        results[ci] = _plan_one(ctx, results, ci, 0)
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
        _repair(ctx, results, failed, k)
        k += 1
    total = time.perf_counter() - t_all
    cache = ctx.cache
    return CrowdResult(sc, fps, n_total, [results[i] for i in range(len(sc.characters))], order, total, k,
                       cache.hits if cache else 0, cache.misses if cache else 0)


REPAIR_BLOCKERS = 3     # planned characters a failed one may displace in a repair


@dataclass
class _Context:
    sc: Scenario
    graph: object
    env: object
    roadmap: object
    params: SynthesisParams
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


def _plan_one(ctx: _Context, results, ci: int, k: int, attempt: int = 0) -> CharacterResult:
    """Character ``ci`` planned against the space-time index. Its random stream is seeded by
    the scenario seed, its index, the pass ``k`` and ``attempt``, so its plan depends on the
    order only through the characters already in the index.

    A character whose start pose has two kinds of node -- the pose's most connected node and
    one where it can stand still and wait (for "stand": a walking hub and a standing node) --
    is planned from the first (``start_still``: the second; unset: the second when the
    character has time to wait, :func:`_time_to_wait`); if that plan has warnings, it is
    planned again from the other, and the plan with fewer warnings is kept."""
    sc, graph, params = ctx.sc, ctx.graph, ctx.params
    c = sc.characters[ci]
    t0 = time.perf_counter()
    where = f"{sc.path}: character {c.name!r} start"
    still_first = params.start_still if params.start_still is not None else _time_to_wait(c, params)
    starts = list(dict.fromkeys([_start_node(graph, c.pose, where, ctx.still if still_first else None),
                                 _start_node(graph, c.pose, where, None if still_first else ctx.still)]))
    best = None
    iters = 0
    for a, node in enumerate(starts):
        extra = [a] if a else []
        if k or attempt:
            extra = [a, attempt]
        rng = np.random.default_rng([int(sc.seed), int(ci), int(k)] + extra)
        out = _plan_character(sc, graph, ctx.env, ctx.roadmap, params, ctx.lib, ctx.fps, ctx.n_total, ctx.static,
                              ctx.index, results, ci, node, rng, ctx.still, retry=bool(a or attempt),
                              cache=ctx.cache)
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


def _seat_hold(c, graph, fps: float) -> int:
    """Frames from 0 during which a character who starts seated (``start = { seat = ... }``)
    has no need to leave yet: getting up and walking straight to its first goal at a brisk
    pace (``HOLD_GET_UP``, ``HOLD_SPEED``) still arrives before the goal's window opens.
    Characters are planned one after another
    (paper 000, section 3.1), and one planned later is invisible to those before it -- but a
    seated one cannot step aside: a neighbour sitting down next to it would turn across its
    place. So until it is planned its seat is held for those frames: earlier characters
    treat it as sitting there (0 when it does not start seated or its first goal has no
    window)."""
    if c.start_marker is None or not c.goals or c.goals[0].time is None or c.goals[0].position is None:
        return 0
    d = float(np.hypot(*(np.asarray(c.goals[0].position, float) - np.asarray(c.position, float))))
    return max(0, int((c.goals[0].time[0] - d / HOLD_SPEED - HOLD_GET_UP) * fps))


def _seated_radius(graph) -> float:
    """The bounding cylinder of a seated character: the largest radius of the sitting state's
    clips (a held seat's cylinder)."""
    sit = graph.edge_state == STATES.index("sitting")
    return float(graph.edge_radius[sit].max()) if sit.any() else float(graph.edge_radius.max())


def _time_to_wait(c, params) -> bool:
    """Whether character ``c``'s first goal has a window that opens more than
    ``params.wait_slack`` seconds after it could walk there in a straight line: it then waits
    at its start first (``start_still`` None), where it already stands, rather than walking
    off and stopping somewhere in the others' way."""
    if not c.goals or c.goals[0].time is None or c.goals[0].position is None:
        return False
    d = float(np.hypot(*(np.asarray(c.goals[0].position, float) - np.asarray(c.position, float))))
    return c.goals[0].time[0] - d / WALK_SPEED > params.wait_slack


def _timing(sc) -> set:
    """Indices of the characters whose arrivals time others' goals (``after``): they are
    planned once, in the first pass, and never re-planned."""
    return {sc.characters.index(sc.character(g.after["character"]))
            for c in sc.characters for g in c.goals if g.after is not None}


def _repair(ctx: _Context, results: dict, failed: list, k: int) -> None:
    """One repair pass over ``failed`` (see :func:`plan_scenario`); updates ``results`` and
    the index in place."""
    sc, index = ctx.sc, ctx.index
    timing = _timing(sc)

    def spent(r, *others):
        r.seconds += sum(o.seconds for o in others)
        r.iterations += sum(o.iterations for o in others)
        return r

    for ci in failed:
        if ci in timing:
            continue
        old = results[ci]
        index.remove_owner(ci)
        new = _plan_one(ctx, results, ci, k, attempt=1)
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
            first = _plan_one(ctx, results, ci, k, attempt=2)
            spare.append(first)
            again = {}
            if not first.warnings:
                ctx.insert(ci, first.track)
                for b in blockers:
                    rb = _plan_one(ctx, results, b, k, attempt=3)
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


def _collides_early(planner, res, frames: float) -> bool:
    """Whether ``res``'s first collision with a character planned earlier comes within
    ``frames`` of its start (setting off later helps there; not with someone passing its goal
    later, or a jam halfway)."""
    hit = planner.final_collision(res, -1)
    return hit is not None and hit < min(frames, len(res.root))


LANE_RADIUS = 0.5    # m: the bounding cylinder of a walk in _lane_clear_delay's straight proxy


def _lane_clear_delay(index, cfg, goal, fps, n_total, radius, speed: float = 1.3, step: float = 1.0):
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


def _idle_for(lib, graph, cfg: Config, seconds: float, fps: float) -> Track:
    """About ``seconds`` of idling at ``cfg`` (:func:`idle_track`) in whole repeats of its
    loop clip, so that the last frame is back on ``cfg``'s node and position (turned by the
    clip's own turns, see ``turn``); its clock starts at ``cfg.frame``."""
    e = _idle_loop(graph, cfg.node)             # the clip idle_track repeats
    step = int(graph.edge_start[e + 1] - graph.edge_start[e]) - 1
    n = 1 + max(1, int(round(seconds * fps / step))) * step
    tr = idle_track(lib, cfg, n, turn=True)
    tr.start_frame = cfg.frame
    return tr


def _plan_character(sc, graph, env, roadmap, params, lib, fps, n_total, static, index, results, ci, node, rng,
                    still=None, retry: bool = False, cache=None):
    """All goals of character ``ci`` from start node ``node`` against the characters in
    ``index``: (track over the whole scenario, arrival frames, goals, warnings, iterations).
    Each segment's search gets ``params.n_max`` iterations (``retry``: this is a further try
    at the character -- the other start node, a repair pass -- and gets ``retry_n_max``); the
    further tries below (a later arrival, a later departure) get ``retry_n_max``."""
    n_retry = min(params.retry_n_max, params.n_max)
    c = sc.characters[ci]
    owner = ci
    planner = SegmentPlanner(lib, static=static,
                             collide=lambda f, xz, r: index.overlaps(f, xz, r),
                             collide_first=lambda f, xz, r: index.first_overlap(f, xz, r),
                             collide_runs=lambda f, xz, r, cnt: index.any_overlap_runs(f, xz, r, cnt),
                             roadmap=roadmap, env=env, params=params)
    planner.cache = cache
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
        planner.hold = (lambda r: _hold_tail(lib, graph, r.end, n_total)) if gi == len(c.goals) - 1 else None
        res = run_to_completion(planner.run(cfg, goal, rng, owner, name=f"{c.name} goal {gi}",
                                            n_max=n_retry if retry else None))
        iters += res.iterations
        if res.warning and planner.hold is not None and goal.window is None:
            # the motion is clear but standing at the goal afterwards is in the way of a
            # character planned earlier that passes there later: arrive after it has passed
            late = _clear_after(planner, res, index)
            if late is not None and late < n_total - 2 * fps:
                g2 = Goal(goal.position, goal.heading, goal.nodes, (late / fps, late / fps + 1.5), label=goal.label)
                res2 = run_to_completion(planner.run(cfg, g2, rng, owner, name=f"{c.name} goal {gi}", n_max=n_retry))
                iters += res2.iterations
                if not res2.warning:
                    res = res2
        if res.warning and res.collided and goal.window is None and still is not None and still[cfg.node] \
                and _collides_early(planner, res, params.depart_within * fps):
            # an untimed goal whose motions all run into characters planned earlier (a crowd
            # setting off together): stand a while first, then go -- the ones ahead are then
            # further on (the 20 x 15 grid at 2.2 m, first 90 characters: 8 -> 1 with warnings)
            delays = params.depart_delays
            dc = _lane_clear_delay(index, cfg, goal, fps, n_total, LANE_RADIUS + params.margin) \
                if params.depart_clear else None
            if dc:          # (0: the straight walk is clear now, the fixed delays are tried)
                delays = (dc, dc + 3.0)
            for d in delays:
                idle = _idle_for(lib, graph, cfg, d, fps)
                frames = cfg.frame + np.arange(len(idle))
                rad = track_radius(graph, idle) + params.margin
                if np.asarray(index.overlaps(frames, idle.root[:, :2], rad), dtype=bool).any():
                    break           # someone passes where it stands: waiting longer will not help
                later = Config(cfg.node, *(float(v) for v in idle.root[-1]), int(frames[-1]))
                res2 = run_to_completion(planner.run(later, goal, rng, owner, name=f"{c.name} goal {gi}",
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
