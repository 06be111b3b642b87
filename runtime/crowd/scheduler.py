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

    def by_name(self, name) -> CharacterResult:
        return next(c for c in self.characters if c.name == name)


def run_to_completion(gen):
    try:
        while True:
            next(gen)
    except StopIteration as e:
        return e.value


def idle_track(lib: MotionLibrary, cfg: Config, n_frames: int) -> Track:
    """``n_frames`` frames (including the start frame) of idling at ``cfg``: the node's
    self-loop clip with the least drift, repeated, each repeat bent back onto the start
    configuration; a held pose when the node has no self loop."""
    g = lib.g
    loops = np.flatnonzero((g.edge_src == cfg.node) & (g.edge_dst == cfg.node))
    start = np.array([cfg.x, cfg.z, cfg.heading])
    last = g.edge_start[np.flatnonzero(g.edge_dst == cfg.node)[0] + 1] - 1 if np.any(g.edge_dst == cfg.node) else 0
    if len(loops) == 0 or n_frames <= 1:
        fa = np.full(n_frames, last, dtype=np.int64)
        return Track(fa, fa.copy(), np.zeros(n_frames, np.float32), np.repeat(start[None], n_frames, 0), cfg.frame)
    drift = np.hypot(g.edge_disp[loops, 0], g.edge_disp[loops, 1]) + 0.3 * np.abs(g.edge_disp[loops, 2])
    e = int(loops[np.argmin(drift)])
    a, b = g.edge_start[e], g.edge_start[e + 1]
    L = b - a                                   # frames in the loop including both hub frames
    local = np.stack([g.frame_xz[a:b, 0], g.frame_xz[a:b, 1], g.frame_heading[a:b]], axis=1)
    ramp = np.linspace(0.0, 1.0, L)[:, None] * g.edge_disp[e][None, :]
    local = local - ramp                        # each repeat returns exactly to the start
    reps = int(np.ceil((n_frames - 1) / (L - 1)))
    idx = np.concatenate([[0]] + [np.arange(1, L)] * reps)[:n_frames]
    frames = a + idx
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
        loops = np.flatnonzero((g.edge_src == n) & (g.edge_dst == n))
        if len(loops) == 0:
            continue
        drift = np.hypot(g.edge_disp[loops, 0], g.edge_disp[loops, 1]) + 0.3 * np.abs(g.edge_disp[loops, 2])
        e = int(loops[np.argmin(drift)])
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
    rad = np.maximum(graph.frame_radius[tr.frames_a[1:]], graph.frame_radius[tr.frames_b[1:]])
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
    params = params or SynthesisParams(eps=sc.epsilon)
    for k in ("n_m", "k_m", "n_max"):
        if k in sc.synthesis:
            setattr(params, k, int(sc.synthesis[k]))
    if "start_still" in sc.synthesis:
        params.start_still = bool(sc.synthesis["start_still"])
    lib = MotionLibrary(graph, params)
    fps = params.fps
    n_total = int(round(sc.duration * fps)) + 1
    sdf = env.sdf(resolution=0.05, margin=2.0) if env is not None and (len(env.polygons) or len(env.circles)) else None
    # the sampled field may overestimate clearance by up to max_error: stay conservative
    static = (lambda xz: sdf.sample(xz) - sdf.max_error) if sdf is not None else None
    t_all = time.perf_counter()
    passes = max(1, int(sc.synthesis.get("passes", 3)))
    best = None
    failed_first: list[int] = []
    for k in range(passes):
        order = planning_order(sc, first=failed_first)
        results = _plan_pass(sc, graph, env, roadmap, params, lib, fps, n_total, static, order,
                             progress if k == 0 else None, log, k)
        failed = [ci for ci in order if results[ci].warnings]
        if best is None or len(failed) < best[0]:
            best = (len(failed), order, results)
        if not failed:
            break
        if log:
            log(f"pass {k + 1}: {len(failed)} character(s) without a clean plan; planning them earlier")
        # the characters that failed are planned earlier next time (before those they ran into)
        failed_first = failed + [ci for ci in failed_first if ci not in set(failed)]
    _, order, results = best
    total = time.perf_counter() - t_all
    return CrowdResult(sc, fps, n_total, [results[i] for i in range(len(sc.characters))], order, total, k + 1)


def _plan_pass(sc, graph, env, roadmap, params, lib, fps, n_total, static, order, progress, log, k=0):
    """One pass over the characters in ``order``; each has its own random stream (seeded by
    the scenario seed, its index and the pass number ``k``), so its plan depends on the order
    only through the characters planned before it, and a later pass searches afresh.

    A character whose start pose has two kinds of node -- the pose's most connected node and
    one where it can stand still and wait (for "stand": a walking hub and a standing node) --
    is planned from the first (``start_still``: the second); if that plan has warnings, it is
    planned again from the other, and the plan with fewer warnings is kept."""
    index = SpaceTimeIndex(cell=max(1.2, 2 * lib.max_radius + 2 * (params.margin + params.seed_margin) + 0.05))
    results: dict[int, CharacterResult] = {}
    still = still_nodes(graph, params.eps, fps)
    for ci in order:
        c = sc.characters[ci]
        t0 = time.perf_counter()
        where = f"{sc.path}: character {c.name!r} start"
        starts = list(dict.fromkeys([_start_node(graph, c.pose, where, still if params.start_still else None),
                                     _start_node(graph, c.pose, where, None if params.start_still else still)]))
        best = None
        iters = 0
        for attempt, node in enumerate(starts):
            rng = np.random.default_rng([int(sc.seed), int(ci), int(k)] + ([attempt] if attempt else []))
            out = _plan_character(sc, graph, env, roadmap, params, lib, fps, n_total, static, index, results,
                                  ci, node, rng)
            iters += out[4]
            if best is None or len(out[3]) < len(best[3]):
                best = out
            if not best[3]:
                break
            if log and attempt == 0 and len(starts) > 1:
                log(f"{c.name}: planning again from the other {c.pose!r} start node")
        track, arrivals, goals, warnings, _ = best
        if log:
            for w in warnings:
                log(f"warning: {w}")
        frames = np.arange(len(track))
        rad = np.maximum(graph.frame_radius[track.frames_a], graph.frame_radius[track.frames_b])
        index.insert(ci, frames, track.root[:, :2], rad)
        results[ci] = CharacterResult(c.name, track, arrivals, goals, warnings, time.perf_counter() - t0, iters,
                                      arrivals[-1] / fps if arrivals else 0.0)
        if progress:
            progress(1)
    return results


def _plan_character(sc, graph, env, roadmap, params, lib, fps, n_total, static, index, results, ci, node, rng):
    """All goals of character ``ci`` from start node ``node`` against the characters in
    ``index``: (track over the whole scenario, arrival frames, goals, warnings, iterations)."""
    c = sc.characters[ci]
    owner = ci
    planner = SegmentPlanner(lib, static=static,
                             collide=lambda f, xz, r: index.overlaps(f, xz, r),
                             roadmap=roadmap, env=env, params=params)
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
        res = run_to_completion(planner.run(cfg, goal, rng, owner, name=f"{c.name} goal {gi}"))
        iters += res.iterations
        if res.warning and planner.hold is not None and goal.window is None:
            # the motion is clear but standing at the goal afterwards is in the way of a
            # character planned earlier that passes there later: arrive after it has passed
            late = _clear_after(planner, res, index)
            if late is not None and late < n_total - 2 * fps:
                g2 = Goal(goal.position, goal.heading, goal.nodes, (late / fps, late / fps + 1.5), label=goal.label)
                res2 = run_to_completion(planner.run(cfg, g2, rng, owner, name=f"{c.name} goal {gi}"))
                iters += res2.iterations
                if not res2.warning:
                    res = res2
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
