"""Goal-directed synthesis (paper 000) against the independent checker (issue 4).

The planner's own numbers are never asserted on: the checker recomputes arrivals, per-frame
adjustment and overlaps from the baked tracks."""
import copy
import dataclasses

import numpy as np
import pytest

from runtime.crowd.checker import adjustment_rates, check_crowd, overlapping_pairs
from runtime.crowd.scenario import parse_scenario, planning_order
from runtime.crowd.planner import (Config, CrowdPolicy, Goal, MotionLibrary, SearchParams, SegmentPlanner,
                                   run_to_completion)
from runtime.crowd.scheduler import plan_scenario
from runtime.motion.cylinders import blend_cylinders
from runtime.crowd.tracks import Track


def crossing_scenario(seed=0):
    """Three characters whose straight paths cross near the origin inside one time window."""
    chars = []
    for k, (sx, sz, gx, gz) in enumerate([(-6, 0, 6, 1), (0, -6, 1, 6), (-5, -5, 5, 5)]):
        chars.append({"name": f"c{k}", "start": {"position": [sx, sz], "heading": float(np.degrees(np.arctan2(gx - sx, gz - sz))),
                                                  "pose": "stand"},
                      "goal": [{"position": [gx, gz], "heading": 90.0 * k, "pose": "stand", "time": [13.0, 14.0]}]})
    return parse_scenario({"name": "cross", "duration": 16.0, "seed": seed, "character": chars})


@pytest.fixture(scope="module")
def crossing(default_graph):
    sc = crossing_scenario()
    return sc, plan_scenario(sc, default_graph)


def test_crossing_paths_pass_the_checker(crossing, default_graph):
    sc, res = crossing
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, default_graph)
    s = rep.summary()
    assert s["max_position_error_mm"] <= 1.0
    assert s["max_heading_error_deg"] <= 0.1
    assert s["goals_in_window"] == 3 and s["poses_ok"] == 3
    assert s["characters_within_eps"] == 3
    assert s["character_overlap_pairs"] == 0
    assert s["passed"]
    # the characters did pass close to each other: the test is not trivially collision-free
    XZ = np.stack([c.track.root[:, :2] for c in res.characters], axis=1)
    d = np.linalg.norm(XZ[:, :, None] - XZ[:, None, :], axis=-1)
    d[:, np.arange(3), np.arange(3)] = np.inf
    assert d.min() < 3.0


def test_same_seed_same_tracks(crossing, default_graph):
    sc, res = crossing
    again = plan_scenario(crossing_scenario(), default_graph)
    for a, b in zip(res.characters, again.characters):
        np.testing.assert_array_equal(a.track.root, b.track.root)
        np.testing.assert_array_equal(a.track.frames_a, b.track.frames_a)


def test_checker_catches_a_moved_goal_and_an_overlap(crossing, default_graph):
    sc, res = crossing
    tracks = {c.name: c.track for c in res.characters}
    bad = copy.deepcopy(sc)
    bad.characters[0].goals[0].position = bad.characters[0].goals[0].position + np.array([0.05, 0.0])
    assert check_crowd(bad, tracks, default_graph).summary()["max_position_error_mm"] > 40.0
    # put c1 on top of c0 for the whole scenario
    t0, t1 = tracks["c0"], tracks["c1"]
    tracks2 = dict(tracks)
    tracks2["c1"] = Track(t1.frames_a, t1.frames_b, t1.frames_t, t0.root.copy(), t1.start_frame)
    rep = check_crowd(sc, tracks2, default_graph)
    assert {"a": "c0", "b": "c1"} in [{k: r[k] for k in ("a", "b")} for r in rep.character_overlaps]
    assert not rep.summary()["passed"]


def test_checker_measures_an_added_drift(crossing, default_graph):
    sc, res = crossing
    tr = res.characters[0].track
    k1 = res.characters[0].arrivals[0]
    base = adjustment_rates(default_graph, tr, 0, k1, 30.0)
    # add a 5 cm/s sideways drift over the middle third: the checker must see at least that
    root = tr.root.copy()
    a, b = k1 // 3, 2 * k1 // 3
    drift = np.zeros(len(root))
    drift[a:b] = np.arange(b - a) * (0.05 / 30.0)
    drift[b:] = drift[b - 1]
    root[:, 0] += drift
    moved = adjustment_rates(default_graph, Track(tr.frames_a, tr.frames_b, tr.frames_t, root, tr.start_frame), 0, k1, 30.0)
    assert base[0] <= 0.02 * 1.001
    assert moved[0] >= 0.05 - base[0] - 1e-6


def test_splice_rates_equal_the_checkers(default_graph):
    """A segment with a window that forces time warping: the per-frame adjustment the planner
    promises is what the checker measures on the baked frames (no straddled junction)."""
    lib = MotionLibrary(default_graph, SearchParams())
    planner = SegmentPlanner(lib)
    node = int(default_graph.nodes_with_label("stand")[0])
    rng = np.random.default_rng(3)
    checked = 0
    for gx, gz, t in [(5.0, 3.0, (6.5, 6.6)), (-4.0, 6.0, (8.0, 8.1)), (7.0, -2.0, (5.0, 5.05))]:
        goal = Goal(np.array([gx, gz]), np.radians(40.0), default_graph.nodes_with_label("stand"), t)
        res = run_to_completion(planner.run(Config(node, 0.0, 0.0, 0.0, 0), goal, rng))
        tr = Track(res.frames_a, res.frames_b, res.frames_t, res.root, res.start_frame)
        got = adjustment_rates(default_graph, tr, 0, len(tr) - 1, 30.0)
        if res.ok:
            checked += 1
            np.testing.assert_allclose(got[:2], res.rates[:2], rtol=1e-3, atol=1e-4)
            assert abs(got[2] - res.rates[2]) < 1e-4
    assert checked >= 2


def test_overlapping_pairs_counts_frames():
    XZ = np.zeros((5, 3, 2))
    XZ[:, 1, 0] = [0.3, 0.5, 2.0, 2.0, 0.1]
    XZ[:, 2, 0] = 10.0
    R = np.full((5, 3), 0.2)
    assert overlapping_pairs(XZ, R) == {(0, 1): 2}      # 0.3 and 0.1 apart; 0.5 is not below 0.4


def test_planning_order_puts_dependencies_first():
    sc = parse_scenario({"name": "o", "duration": 10.0, "character": [
        {"name": "a", "start": {"position": [0, 0]}, "goal": [{"position": [1, 0]}]},
        {"name": "b", "start": {"position": [0, 3]}, "goal": [{"position": [1, 3]}]},
        {"name": "c", "start": {"position": [0, 6]},
         "goal": [{"position": [1, 6], "after": {"character": "b", "goal": 0, "within": [0.0, 2.0]}}]}]})
    assert planning_order(sc) == [0, 1, 2]
    sc.characters = sc.characters[::-1]            # c first in the file: b still before it
    assert planning_order(sc) == [1, 0, 2]


@pytest.mark.slow
def test_rooms_box_sample_passes_the_checker(default_graph):
    """Paper 000, Experiment 3: one character crosses five rooms (roadmap way points, doors,
    furniture) and picks up the box; the checker, not the planner, says it is exact and clear."""
    from pathlib import Path

    from authoring.commands.bake import load_sample
    sc, graph, env, roadmap = load_sample(Path(__file__).resolve().parents[1] / "samples" / "rooms_box",
                                          log=lambda *a: None, progress=False)
    res = plan_scenario(sc, graph, env, roadmap)
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, graph, env)
    assert rep.summary()["passed"], rep.summary()
    assert not rep.obstacle_overlaps
    # the route does cross the rooms: the motion runs far longer than the straight distance needs
    assert res.characters[0].arrivals[0] / 30.0 > 25.0


def _stand_in_the_way_scenario():
    """c0 (planned first) walks along z = 0 from x = -10 to x = 6; c1 arrives at the origin from
    the side, on c0's path, with no time window: it would get there before c0 passes."""
    chars = [{"name": "c0", "start": {"position": [-10.0, 0.0], "heading": 90.0, "pose": "stand"},
              "goal": [{"position": [6.0, 0.0]}]},
             {"name": "c1", "start": {"position": [0.0, -2.0], "heading": 0.0, "pose": "stand"},
              "goal": [{"position": [0.0, 0.0]}]}]
    return parse_scenario({"name": "in_the_way", "duration": 16.0, "seed": 0, "character": chars,
                           "synthesis": {"passes": 1}})


def test_standing_at_the_last_goal_is_clear_of_earlier_characters(default_graph, monkeypatch):
    """After its last goal a character stands there to the end; the planner's final test
    covers that too, so it arrives after the character planned before it has passed (the
    checker finds no overlap). Without the test of the held position it stands in the way."""
    import runtime.crowd.goals as goals_mod
    sc = _stand_in_the_way_scenario()
    res = plan_scenario(sc, default_graph)
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, default_graph)
    assert rep.summary()["character_overlap_pairs"] == 0, rep.character_overlaps
    assert rep.summary()["passed"]
    c0, c1 = res.characters
    passed_origin = int(np.argmin(np.abs(c0.track.root[:, 0])))
    assert c1.arrivals[0] > passed_origin          # it waited for c0
    monkeypatch.setattr(goals_mod, "hold_tail", lambda *a: None)
    blind = plan_scenario(_stand_in_the_way_scenario(), default_graph)
    rep = check_crowd(sc, {c.name: c.track for c in blind.characters}, default_graph)
    assert rep.summary()["character_overlap_pairs"] == 1


def test_compiled_splice_costs_equal_the_numpy_passes(default_graph):
    """The numba kernel (runtime.crowd.search_kernels) and the numpy passes of pair_costs
    (Eq. 1-2) give the same best cost and the same (i, j) for random motion pairs, with and
    without a time window."""
    from runtime.crowd.planner import kernels as search_kernels
    if not search_kernels.AVAILABLE:
        pytest.skip("numba is not installed: only the numpy path exists")
    from runtime.crowd.planner.costs import pair_costs
    g = default_graph
    lib = MotionLibrary(g)
    rng = np.random.default_rng(3)
    P, L = 120, 24
    F = -np.ones((P, L), np.int64)
    B = -np.ones((P, L), np.int64)
    nf, nb = rng.integers(1, 20, P), rng.integers(1, 20, P)
    start_node = int(g.edge_src[0])
    hub = int(rng.integers(g.num_nodes))
    for p in range(P):
        F[p, :nf[p]] = g.random_walk(start_node, nf[p], rng)
        B[p, L - nb[p]:] = g.random_walk(hub if p % 2 else int(rng.integers(g.num_nodes)), nb[p], rng)
    goal_node = int(g.edge_dst[B[0, -1]])
    start, goal = np.array([0.3, -0.2, 0.4]), np.array([5.0, 3.0, -1.0])
    for window in (None, (3.0, 6.0)):
        c1, i1, j1 = pair_costs(lib, lib.params, F, nf, B, nb, start, goal, start_node, goal_node, window, compiled=True)
        c0, i0, j0 = pair_costs(lib, lib.params, F, nf, B, nb, start, goal, start_node, goal_node, window, compiled=False)
        fin = np.isfinite(c0)
        assert fin.sum() > 20 and (~fin).sum() > 0          # both kinds of pairs occur
        np.testing.assert_array_equal(np.isfinite(c1), fin)
        np.testing.assert_allclose(c1[fin], c0[fin], rtol=1e-12, atol=0)
        np.testing.assert_array_equal(i1, i0)
        np.testing.assert_array_equal(j1, j0)


def test_compiled_perturbation_makes_the_numpy_pairs(default_graph):
    """The randomized search's perturbation (section 3.3: one clip of one motion replaced by a
    parallel alternative), compiled, makes the same pairs from the same random stream as the
    numpy path -- on kept pairs where only M_f, only M_b, both or neither have clips with
    alternatives -- and leaves the stream in the same state."""
    from runtime.crowd.planner import kernels as search_kernels
    from runtime.crowd.planner.search import RandomizedSearch
    if not search_kernels.AVAILABLE:
        pytest.skip("numba is not installed: only the numpy path exists")
    g = default_graph
    lib = MotionLibrary(g)
    rng = np.random.default_rng(7)
    K, Lf, Lb = 30, 20, 18
    Fp = -np.ones((K, Lf), np.int64)
    Bp = -np.ones((K, Lb), np.int64)
    nfp, nbp = rng.integers(0, 15, K), rng.integers(0, 15, K)
    no_alt = np.flatnonzero(~lib.has_alt)
    for p in range(K):
        Fp[p, :nfp[p]] = g.random_walk(int(g.edge_src[0]), nfp[p], rng) if nfp[p] else []
        Bp[p, Lb - nbp[p]:] = g.random_walk(int(rng.integers(g.num_nodes)), nbp[p], rng) if nbp[p] else []
        if p % 5 == 0 and len(no_alt):            # a motion with no alternative anywhere
            Fp[p, :nfp[p]] = no_alt[0]
    out = []
    for compiled in (True, False):
        search = RandomizedSearch(lib, lib.params, None, compiled, None, None, 0, [], [], None,
                                  np.random.default_rng(42), 0)
        out.append(search._perturbed(Fp, Bp, nfp, nbp, 400) + (search.rng.random(),))
    (F1, B1, nf1, nb1, r1), (F0, B0, nf0, nb0, r0) = out
    np.testing.assert_array_equal(F1, F0)
    np.testing.assert_array_equal(B1, B0)
    np.testing.assert_array_equal(nf1, nf0)
    np.testing.assert_array_equal(nb1, nb0)
    assert r1 == r0
    # some pairs differ from every kept pair: the perturbation did something
    kept = {(tuple(a), tuple(b)) for a, b in zip(Fp, Bp)}
    assert sum((tuple(a), tuple(b)) not in kept for a, b in zip(F1, B1)) > 200


def test_compiled_seed_lookahead_makes_the_numpy_seeds(default_graph):
    """The greedy seed planner (section 3.2) with its two-edge lookahead compiled (numba) walks
    the same edges as with the numpy passes: forward and time-reversed, to a point, to a point
    and heading (the final approach), along a bent way-point path, timed and untimed."""
    from runtime.crowd.planner import kernels as search_kernels
    from runtime.motion.graph import STATES
    if not search_kernels.AVAILABLE:
        pytest.skip("numba is not installed: only the numpy path exists")
    g = default_graph
    planner = SegmentPlanner(MotionLibrary(g))
    walking = STATES.index("walking")
    rng = np.random.default_rng(5)
    nodes = np.flatnonzero(g.node_state == walking)
    cases = 0
    for k in range(12):
        node = int(rng.choice(nodes))
        start = np.array([*rng.uniform(-2, 2, 2), rng.uniform(-np.pi, np.pi)])
        wps = np.concatenate([start[None, :2], rng.uniform(-8, 8, (1 + k % 3, 2))])
        heading = None if k % 2 else float(rng.uniform(-np.pi, np.pi))
        budget = None if k % 4 < 2 else 12.0
        seeds = []
        for compiled in (True, False):
            planner.compiled = compiled
            seeds.append(planner.greedy(node, start, 0, wps, heading, walking, None, bool(k % 3 == 1),
                                        time_budget=budget))
        assert seeds[0] == seeds[1]
        cases += len(seeds[0][0]) > 3
    assert cases >= 8          # the seeds walk somewhere


def test_compiled_clear_test_makes_the_numpy_seeds_among_characters_and_obstacles(default_graph):
    """The seeds' clear test of candidate clips, compiled (one gather of their collision
    samples, the index query stopping each clip at its first hit), walks the same seeds as the
    numpy gather and per-sample query, with planned characters and a static obstacle in the
    way -- which change the seeds (the test is not vacuous)."""
    from runtime.crowd.planner import kernels as search_kernels
    from runtime.crowd.spacetime import SpaceTimeIndex
    from runtime.motion.graph import STATES
    if not search_kernels.AVAILABLE:
        pytest.skip("numba is not installed: only the numpy path exists")
    g = default_graph
    lib = MotionLibrary(g)
    rng = np.random.default_rng(11)
    index = SpaceTimeIndex(cell=2 * lib.max_reach + 0.1)
    f = np.arange(0, 600)
    for o in range(6):                 # characters walking across the field, one per lane
        x0, z0 = rng.uniform(-1, 1), rng.uniform(1, 7)
        index.insert(o, f, np.stack([x0 - 4 + f * 0.03, np.full(len(f), z0)], axis=1), np.full(len(f), 0.35))
    for o in range(6, 9):              # and some standing in the way
        index.insert(o, f, np.broadcast_to([rng.uniform(-1.5, 1.5), 2.0 * (o - 5)], (len(f), 2)), np.full(len(f), 0.35))

    def static(xz):
        return np.hypot(xz[:, 0] - 0.5, xz[:, 1] - 4.0) - 0.6

    walking = STATES.index("walking")
    nodes = np.flatnonzero(g.node_state == walking)
    changed = 0
    for k in range(10):
        node = int(rng.choice(nodes))
        start = np.array([rng.uniform(-1, 1), 0.0, rng.uniform(-0.5, 0.5)])
        wps = np.array([start[:2], [rng.uniform(-2, 2), 8.0]])
        seeds = []
        for compiled, runs, coll in ((True, True, True), (False, False, True), (True, True, False)):
            planner = SegmentPlanner(lib, static=static, collide=index.overlaps if coll else None,
                                     collide_runs=index.any_overlap_runs if runs and coll else None)
            planner.compiled = compiled
            seeds.append(planner.greedy(node, start, 0, wps, None, walking, None, False))
        assert seeds[0] == seeds[1]
        changed += seeds[0] != seeds[2]
    assert changed >= 3


def test_seeds_do_not_wait_for_a_wall(default_graph):
    """A seed blocked by planned characters waits on an idle clip for them to pass; blocked by a
    static obstacle in the same place it does not (waiting cannot move a wall)."""
    from runtime.motion.graph import STATES
    g = default_graph
    lib = MotionLibrary(g)
    loops = np.flatnonzero((g.edge_src == g.edge_dst) & (np.hypot(g.edge_disp[:, 0], g.edge_disp[:, 1]) < 0.1))
    node = int(np.bincount(g.edge_src[loops]).argmax())          # a standing node with idle clips

    def waits(static, collide):
        planner = SegmentPlanner(lib, static=static, collide=collide)
        planner.greedy(node, np.zeros(3), 0, np.array([[0.0, 0.0], [0.0, 6.0]]), None, STATES.index("walking"),
                       None, False, time_budget=None)
        return planner.waited

    band = lambda xz: (xz[:, 1] > 0.1) & (xz[:, 1] < 2.0) & (np.abs(xz[:, 0]) < 3.0)
    crowd = lambda f, xz, r: band(xz) & (np.asarray(f) < 60)               # passing ahead for 2 s
    wall = lambda xz: np.where(band(xz), -1.0, 10.0)                       # the same place, for good
    nobody = lambda f, xz, r: np.zeros(len(f), dtype=bool)
    assert waits(None, crowd) > 0
    assert waits(wall, nobody) == 0


def test_still_start_node_stands_still_and_the_hub_does_not_walk_on_the_spot(default_graph):
    """"stand" labels both a walking hub (the most connected node) and standing nodes; the
    still start node idles within eps on its idle clips; the hub has none (its self loops are
    walk cycles), so idling there holds its pose instead of walking on the spot."""
    from runtime.crowd.idle import idle_loop, idle_track, still_nodes
    from runtime.crowd.scheduler import start_node
    g = default_graph
    params = SearchParams()
    still = still_nodes(g, params.eps)
    hub = start_node(g, "stand", "x")
    stand = start_node(g, "stand", "x", still)
    assert hub != stand and still[stand] and not still[hub]
    assert np.any((g.edge_src == hub) & (g.edge_dst == hub)) and idle_loop(g, hub) < 0
    lib = MotionLibrary(g, params)
    for node in (stand, hub):
        tr = idle_track(lib, Config(node, 0.0, 0.0, 0.0, 0), 61)
        rates = adjustment_rates(g, tr, 0, len(tr) - 1, 30.0)   # the checker's per-frame adjustment
        assert rates[0] <= params.eps[0]
        moving = np.linalg.norm(np.diff(g.frame_xz[tr.frames_a], axis=0), axis=1) * 30.0
        same_edge = np.diff(np.searchsorted(g.edge_start, tr.frames_a, "right")) == 0
        assert not np.any(same_edge & (moving > 0.3))        # no frame of locomotion played in place
    assert len(np.unique(idle_track(lib, Config(hub, 0.0, 0.0, 0.0, 0), 61).frames_a)) == 1


def test_waiting_plays_idle_clips_or_holds_a_pose_on_every_node(default_graph):
    """Idling on any node plays only frames labelled idle, sit or carry_idle (never a walk, turn,
    start or stop with the root held; a node without such clips holds its pose), and standing
    and sitting characters have still nodes with idle clips from the generator."""
    from runtime.crowd.idle import IDLE_LABELS, idle_loop, idle_track, still_nodes
    g = default_graph
    lib = MotionLibrary(g)
    edge_of = lambda f: np.searchsorted(g.edge_start, f, "right") - 1
    for n in range(g.num_nodes):
        tr = idle_track(lib, Config(n, 0.0, 0.0, 0.0, 0), 90)
        moved = np.diff(tr.frames_a) != 0
        played = {lab for e in np.unique(edge_of(tr.frames_a[1:][moved])) for lab in g.edge_labels[e]}
        assert played <= IDLE_LABELS, (n, played)
    still = still_nodes(g, SearchParams().eps)
    for label in ("stand", "sit"):
        assert still[g.nodes_with_label(label)].any(), label
    assert not still[[n for n in range(g.num_nodes) if idle_loop(g, n) < 0]].any()


def test_a_failed_character_is_planned_again_from_the_other_start_node(default_graph, monkeypatch):
    """When the plan from the first start node has warnings, the scheduler plans the character
    again from the other kind of "stand" node and keeps the clean plan."""
    import runtime.crowd.scheduler as sched
    real = sched.plan_goals
    calls = []

    def fake(*args, **kw):
        node = args[3]           # (ctx, results, ci, node, rng)
        calls.append((node, kw.get("retry")))
        out = real(*args, **kw)
        return out if len(calls) > 1 else dataclasses.replace(out, warnings=["forced warning"])

    monkeypatch.setattr(sched, "plan_goals", fake)
    sc = parse_scenario({"name": "one", "duration": 8.0, "seed": 0, "synthesis": {"passes": 1},
                         "character": [{"name": "c0", "start": {"position": [0.0, 0.0], "heading": 0.0, "pose": "stand"},
                                        "goal": [{"position": [0.0, 4.0]}]}]})
    res = plan_scenario(sc, default_graph)
    assert len(calls) == 2 and calls[0][0] != calls[1][0]
    assert [r for _, r in calls] == [False, True]          # the second is a retry
    assert res.characters[0].warnings == []


def test_further_tries_at_a_failed_segment_get_retry_n_max_iterations(default_graph):
    """A segment that cannot meet eps (a tolerance no motion meets) searches n_max iterations
    from the first start node; the try from the other start node gets retry_n_max, and every
    repair pass retry_n_max per start node. The first try then steps down the ladder: the two
    relaxed-eps rungs (no window: no later or late arrival) get retry_n_max each; the other
    start node and the repairs try only what keeps every constraint."""
    ladder = 2 * 15
    for passes, want in ((1, 40 + ladder + 15), (2, 40 + ladder + 15 + 2 * 15)):
        sc = parse_scenario({"name": "one", "duration": 8.0, "seed": 0,
                             "synthesis": {"passes": passes, "epsilon": [1e-7, 1e-5, 1e-7]},
                             "character": [{"name": "c0", "start": {"position": [0.0, 0.0], "heading": 0.0,
                                                                    "pose": "stand"},
                                            "goal": [{"position": [0.0, 4.0]}]}]})
        prm = SearchParams(eps=sc.epsilon, n_max=40, hopeless_cost=0.0)      # every search runs its limit
        res = plan_scenario(sc, default_graph, params=prm, policy=CrowdPolicy(retry_n_max=15))
        assert res.characters[0].warnings
        assert res.characters[0].iterations == want


def test_a_search_far_above_eps_gives_up_early(default_graph):
    """A goal 9 m away with a window closing after 2 s: no motion gets near eps. The search
    stops after ``hopeless_after`` iterations and the segment is not searched again from the
    same seeds; with ``hopeless_cost`` 0 it spends all of n_max. A goal that can be met is
    still met."""
    lib = MotionLibrary(default_graph)
    node = int(default_graph.nodes_with_label("stand")[0])
    start = Config(node, 0.0, 0.0, 0.0, 0)
    far = Goal(np.array([0.0, 9.0]), 0.0, None, (1.5, 2.0))
    spent = {}
    for cost in (4.0, 0.0):
        prm = dataclasses.replace(lib.params, n_max=240, hopeless_after=20, hopeless_cost=cost)
        res = run_to_completion(SegmentPlanner(lib, params=prm).run(start, far, np.random.default_rng(3)))
        assert res.warning and not res.ok
        spent[cost] = res.iterations
    assert spent[4.0] == 20
    assert spent[0.0] == 240
    near = Goal(np.array([0.0, 5.0]), 0.0, None, (4.0, 7.0))
    prm = dataclasses.replace(lib.params, hopeless_after=20, hopeless_cost=4.0)
    res = run_to_completion(SegmentPlanner(lib, params=prm).run(start, near, np.random.default_rng(3)))
    assert res.ok and not res.warning


def test_the_relaxed_rung_keeps_a_reserve_when_the_rung_budget_is_spent(default_graph):
    """With no rung budget at all, a segment that cannot meet eps still tries the two relaxed
    eps scales with ``relaxed_reserve`` iterations each before it is given up; with no reserve
    it is given up at once. (The other start node's try gets retry_n_max.)"""
    sc = parse_scenario({"name": "one", "duration": 8.0, "seed": 0,
                         "synthesis": {"passes": 1, "epsilon": [1e-7, 1e-5, 1e-7]},
                         "character": [{"name": "c0", "start": {"position": [0.0, 0.0], "heading": 0.0, "pose": "stand"},
                                        "goal": [{"position": [0.0, 4.0]}]}]})
    spent = {}
    for reserve in (7, 0):
        prm = SearchParams(eps=sc.epsilon, n_max=40, hopeless_cost=0.0)
        res = plan_scenario(sc, default_graph, params=prm,
                            policy=CrowdPolicy(retry_n_max=15, rung_budget=0, relaxed_reserve=reserve))
        assert [s.kind for s in res.characters[0].ladder] == ["waiting"]
        spent[reserve] = res.characters[0].iterations
    assert spent == {7: 40 + 2 * 7 + 15, 0: 40 + 15}


def test_a_relaxed_search_that_lands_within_eps_gives_nothing_up(default_graph):
    """The relaxed rung reports what it gives up: a motion its wider search found that is
    within the scenario's eps after all is a clean plan (no ladder step), one over eps is
    "relaxed" with its factor."""
    from types import SimpleNamespace
    from runtime.crowd.goals import SegmentLadder
    planner = SegmentPlanner(MotionLibrary(default_graph))
    eps = planner.p.eps
    ladder = SegmentLadder(SimpleNamespace(policy=CrowdPolicy()), planner, "c0", np.random.default_rng(0), 10, 10)
    first = SimpleNamespace(warning="no motion within eps")
    for scale, expect in ((0.5, None), (1.5, 1.5)):
        res = SimpleNamespace(warning="", rates=tuple(scale * e for e in eps))

        def run(*args, _res=res, **kw):
            return _res
            yield
        ladder.run = run
        cfg = Config(0, 0.0, 0.0, 0.0, 0)
        goal = Goal(np.array([0.0, 4.0]), 0.0, None, None)
        idle, got, step = run_to_completion(ladder._relaxed(cfg, goal, 0, first))
        assert idle is None and got is res
        if expect is None:
            assert step is None
        else:
            assert step.kind == "relaxed" and step.eps_factor == pytest.approx(expect)


def test_a_motion_that_ends_after_the_scenario_is_never_accepted(default_graph):
    """The final test rejects a clear motion that ends after the planner's ``deadline`` (one
    past its frames, like a held end that is hit). A goal 9 m away with no window in a 4 s
    scenario has no motion that arrives in time: the goal is given up and the character waits,
    instead of a plan that reports an arrival after the scenario has ended."""
    from runtime.crowd.planner import SegmentResult
    g = default_graph
    m = 90
    root = np.zeros((m, 3))
    root[:, 1] = np.linspace(0.0, 3.0, m)
    fa = np.full(m, int(np.argmin(g.frame_radius)))
    res = SegmentResult(True, fa, fa, np.zeros(m), root, 100, Config(0, 0.0, 3.0, 0.0, 100 + m - 1), 0.0,
                        (0.0, 0.0, 0.0), 0, [])
    planner = SegmentPlanner(MotionLibrary(g))
    assert planner.final_collision(res) is None
    planner.deadline = 100 + m - 1
    assert planner.final_collision(res) is None
    planner.deadline = 100 + m - 2
    assert planner.final_collision(res) == m
    sc = parse_scenario({"name": "short", "duration": 4.0, "seed": 0, "synthesis": {"passes": 1},
                         "character": [{"name": "c0", "start": {"position": [0.0, 0.0], "heading": 0.0, "pose": "stand"},
                                        "goal": [{"position": [0.0, 9.0]}]}]})
    out = plan_scenario(sc, g, params=SearchParams(eps=sc.epsilon, n_max=40),
                        policy=CrowdPolicy(retry_n_max=15, rung_budget=60)).characters[0]
    assert [s.kind for s in out.ladder] == ["waiting"]
    assert not any("past the scenario" in w for w in out.warnings)
    assert len(out.track) == int(round(4.0 * 30)) + 1 and out.arrivals == []


def test_a_goal_held_in_someones_way_names_who_passes_there_later(default_graph):
    """When a segment's motion is clear but standing at its last goal afterwards is not (a
    character planned earlier walks through the goal later), the ladder's blockers are the ones
    who pass there -- so a repair knows whom to plan again -- and not an empty set."""
    import types
    from runtime.crowd.goals import SegmentLadder
    from runtime.crowd.idle import hold_tail
    from runtime.crowd.planner import SegmentResult
    from runtime.crowd.reservations import Reservations
    g = default_graph
    lib = MotionLibrary(g)
    n_total = 400
    index = Reservations(1.2, n_total)
    m, f0 = 90, 100
    root = np.zeros((m, 3))
    root[:, 1] = np.linspace(0.0, 3.0, m)
    fa = np.full(m, int(np.argmin(g.frame_radius)))
    node = int(g.nodes_with_label("stand")[0])
    res = SegmentResult(True, fa, fa, np.zeros(m), root, f0, Config(node, 0.0, 3.0, 0.0, f0 + m - 1), 0.0,
                        (0.0, 0.0, 0.0), 0, [])
    # owner 7 crosses x = -3..3 along z = 3, long after the arrival at frame 189; owner 8 is far off
    frames = np.arange(250, 280)
    index.insert(7, frames, np.stack([np.linspace(-3.0, 3.0, 30), np.full(30, 3.0)], axis=1), np.full(30, 0.3))
    index.insert(8, frames, np.tile([20.0, 20.0], (30, 1)), np.full(30, 0.3))
    planner = SegmentPlanner(lib, collide=lambda f, xz, r: index.overlaps(f, xz, r))
    ctx = types.SimpleNamespace(index=index, graph=g, params=SearchParams(), policy=CrowdPolicy())
    ladder = SegmentLadder(ctx, planner, "c", np.random.default_rng(0), 10, 10)
    assert planner.final_collision(res) is None and ladder.blockers(res) == {}
    planner.hold = lambda r: hold_tail(lib, g, r.end, n_total)
    assert planner.final_collision(res) == m                      # the hold is hit ...
    assert set(ladder.blockers(res)) == {7}                       # ... by owner 7


def test_change_time_is_the_quickest_state_change(default_graph):
    """MotionLibrary.change_time against a plain Bellman-Ford over the clips: the quickest
    motion from the walking nodes into a carrying pose (picking a box up), and back."""
    from runtime.motion.graph import STATES
    g = default_graph
    lib = MotionLibrary(g)
    walking = np.flatnonzero(g.node_state == STATES.index("walking"))
    carry = g.nodes_with_label("carry")

    def quickest(a, b):
        best = np.full(g.num_nodes, np.inf)
        best[a] = 0.0
        for _ in range(g.num_nodes):
            for e in range(g.num_edges):
                t = best[g.edge_src[e]] + g.edge_duration[e]
                if t < best[g.edge_dst[e]]:
                    best[g.edge_dst[e]] = t
        return best[b].min()

    for a, b in ((walking, carry), (carry, walking)):
        want = quickest(a, b)
        assert 0.5 < want < 10.0
        assert lib.change_time(a, b) == pytest.approx(want, abs=1e-6)
    assert lib.change_time(walking, walking[:1]) == 0.0


def test_a_seed_holding_a_box_turns_round(default_graph):
    """The library's carrying clips turn only while walking on (no turn on the spot): a seed
    carrying a box with its target behind it walks round in a loop to it instead of stopping
    where it stands (paper 000, section 3.2's greedy planner only takes improving edges)."""
    from runtime.motion.graph import STATES
    g = default_graph
    carrying = STATES.index("carrying")
    loops = np.flatnonzero((g.edge_src == g.edge_dst) & (g.edge_state == carrying)
                           & (np.hypot(g.edge_disp[:, 0], g.edge_disp[:, 1]) < 0.1))
    node = int(g.edge_src[loops[0]])
    turns_on_spot = (g.edge_src == node) & (g.edge_state == carrying) & (np.abs(g.edge_disp[:, 2]) > np.radians(30)) \
        & (np.hypot(g.edge_disp[:, 0], g.edge_disp[:, 1]) < 0.3)
    assert not turns_on_spot.any()            # the premise: no clip turns it round where it stands

    def end(max_turns):
        lib = MotionLibrary(g, SearchParams(max_turns=max_turns))
        planner = SegmentPlanner(lib)
        target = np.array([[0.0, 0.0], [0.5, -4.0]])                # behind the character (facing +Z)
        edges, _ = planner.greedy(node, np.zeros(3), 0, target, None, carrying, None, False, time_budget=None)
        c = np.zeros(3)
        from runtime.motion.planar import compose
        for e in edges:
            c = compose(c, lib.disp[e])
        return np.hypot(c[0] - 0.5, c[1] + 4.0)

    assert end(0) > 3.5                       # without turning it does not get going
    assert end(6) < 1.0


def test_splice_to_a_given_number_of_frames(default_graph):
    """splice(frames=m) resamples the same pair to m + 1 output frames ending exactly in the
    goal, and refuses a duration outside the window."""
    from runtime.crowd.planner.splice import splice
    lib = MotionLibrary(default_graph)
    planner = SegmentPlanner(lib)
    node = int(default_graph.nodes_with_label("stand")[0])
    goal = Goal(np.array([4.0, 3.0]), 0.5, None, (4.0, 8.0))
    res = run_to_completion(planner.run(Config(node, 0.0, 0.0, 0.0, 0), goal, np.random.default_rng(1)))
    assert res.ok
    F, B = np.array(res.edges), np.array([-1])
    goal_cfg = res.root[-1]
    m0 = len(res.root) - 1
    raw = int(sum(default_graph.edge_frames[e] - 1 for e in F))      # source frames of the pair
    for m in (m0 - 6, m0 + 6):
        r = splice(lib, lib.params, Config(node, 0.0, 0.0, 0.0, 0), goal_cfg, res.end.node, F, len(F), B, 1,
                   (4.0, 8.0), frames=m)
        assert len(r.root) == m + 1
        np.testing.assert_allclose(r.root[-1], goal_cfg, atol=1e-9)
        assert r.rates[2] == pytest.approx(abs(raw / m - 1.0), abs=1e-9)
    assert splice(lib, lib.params, Config(node, 0.0, 0.0, 0.0, 0), goal_cfg, res.end.node, F, len(F), B, 1,
                  (4.0, 8.0), frames=int(9.0 * 30)) is None



def test_resampled_rows_are_the_rows_of_the_whole_resample(default_graph):
    """The retimes' partial resample gives, at any output frames, the very numbers of the whole
    resample at those frames, first and last frames included."""
    from runtime.crowd.planner.splice import resample_grid, resample_rows, resample_source, splice_source
    lib = MotionLibrary(default_graph)
    planner = SegmentPlanner(lib)
    node = int(default_graph.nodes_with_label("stand")[0])
    goal = Goal(np.array([4.0, 3.0]), 0.5, None, (4.0, 8.0))
    start = Config(node, 0.0, 0.0, 0.0, 0)
    res = run_to_completion(planner.run(start, goal, np.random.default_rng(1)))
    F, B = np.array(res.edges), np.array([-1])
    src = splice_source(lib, start, res.root[-1], F, len(F) - 2, np.array(res.edges[-2:]), 0)
    for m in (len(res.root) - 7, len(res.root) + 5):
        whole = resample_source(lib.params, src, res.end.node, start, m)
        a, b, t, _ = resample_grid(lib.params, len(src.frames), src.nff, src.nbf, m)
        rows = np.array([0, 1, m // 2, m - 1, m])
        assert np.array_equal(resample_rows(src, a, b, t, rows), whole.root[rows])
        assert np.array_equal(src.frames[a[rows]], whole.frames_a[rows])


def test_hits_runs_is_first_hit_per_run(default_graph):
    """Collider.hits_runs answers, for many runs of samples at once, what first_hit answers for
    each run: static obstacles and planned characters both count."""
    from runtime.crowd.planner.collision import Collider
    lib = MotionLibrary(default_graph)
    wall_x = 1.0

    def static(xz):
        return wall_x - xz[:, 0]

    def collide(f, xz, r):
        return (np.hypot(xz[:, 0] + 2.0, xz[:, 1]) < r + 0.3) & (np.asarray(f) >= 10)

    col = Collider(lib, lib.params, static=static, collide=collide)
    rng = np.random.default_rng(4)
    counts = np.array([5, 0, 7, 3, 6, 4])
    n = counts.sum()
    xz = np.column_stack([rng.uniform(-3.0, 1.5, n), rng.uniform(-0.5, 0.5, n)])
    frames = rng.integers(0, 20, n)
    rad = np.full(n, 0.3)
    starts = np.cumsum(counts) - counts
    want = [col.first_hit(frames[s:s + c], xz[s:s + c], rad[s:s + c]) >= 0 if c else False
            for s, c in zip(starts, counts)]
    got = col.hits_runs(frames, xz, rad, counts)
    assert got.tolist() == want
    assert any(want) and not all(want)

def _repair_setup(monkeypatch, plans, lead=False, starts=None, seen=None):
    """Three planned characters (a, b at rest apart; c failed, standing on a) and a fake
    planner returning ``plans[(character, attempt)]``. ``lead``: a failed instead, standing
    at 0, and c's goal is timed by a's arrival ('after'), c standing at 9. ``starts``: {name:
    x} of scenario starts (default 0). ``seen``: a dict the fake planner fills with {(character,
    attempt): the owners in the index at x = 0, 0.5, .., 9.5 at frame 0} when it is called."""
    import types
    import runtime.crowd.scheduler as sched
    from runtime.crowd.reservations import Reservations
    goal = {"position": [1.0, 0.0]}
    after = {"position": [1.0, 0.0], "after": {"character": "a", "goal": 0, "within": [0.0, 2.0]}}
    starts = starts or {}
    sc = parse_scenario({"name": "three", "duration": 1.0, "seed": 0, "character": [
        {"name": n, "start": {"position": [starts.get(n, 0.0), 0.0], "heading": 0.0, "pose": "stand"},
         "goal": [after if lead and n == "c" else goal]} for n in ("a", "b", "c")]})
    graph = types.SimpleNamespace(frame_radius=np.full(4, 0.4), nodes_with_label=lambda label: np.array([0]),
                                  edge_src=np.array([0]), edge_dst=np.array([0]), edge_radius=np.array([0.3]),
                                  edge_reach=np.array([0.3]), edge_start=np.array([0, 4]), num_edges=1,
                                  edge_state=np.array([0]), frame_cxz=np.zeros((4, 2)))
    lib = types.SimpleNamespace(max_radius=0.4, max_reach=0.4)

    def result(name, x, warnings=()):
        n = 31
        tr = Track(np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n, np.float32),
                   np.tile([x, 0.0, 0.0], (n, 1)), 0)
        return sched.CharacterResult(name, tr, [30], [], list(warnings), 1.0, 10)

    ctx = sched.PlanContext(sc, graph, None, None, SearchParams(), CrowdPolicy(), lib, 30.0, 31, None,
                            Reservations(1.2, 31), None, None)
    results = {0: result("a", 0.0), 1: result("b", 5.0), 2: result("c", 0.2, ["c collides"])}
    if lead:
        results = {0: result("a", 0.0, ["a waits"]), 1: result("b", 5.0),
                   2: result("c", 9.0, ["c: its 'after' constraint is dropped"])}
    for ci, r in results.items():
        ctx.insert(ci, r.track)
    made = {key: result(*spec) for key, spec in plans.items()}

    def plan_one(ctx, results, ci, k, attempt=0, give_up=True):
        if seen is not None:
            seen[(ci, attempt)] = {x / 2: set(ctx.index.overlapping_owners(np.array([0]), np.array([[x / 2, 0.0]]),
                                                                           np.array([0.05]))) for x in range(20)}
        return made[(ci, attempt)]
    monkeypatch.setattr(sched, "plan_one", plan_one)
    return sched, ctx, results, made


def test_repair_displaces_a_blocker_and_keeps_it_only_if_all_come_out_clean(monkeypatch):
    """A repair pass: c fails again where it is (on a); planned without a it is clean, and a
    planned again around it is clean: both new plans are kept, and their time is counted."""
    sched, ctx, results, made = _repair_setup(monkeypatch, {
        (2, 1): ("c", 0.1, ["still on a"]), (2, 2): ("c", 0.0), (0, 3): ("a", 2.5)})
    old_a = results[0]
    sched.repair(ctx, results, [2], 1)
    assert results[2] is made[(2, 2)] and results[0] is made[(0, 3)] and results[1].track.root[0, 0] == 5.0
    assert results[2].seconds == 3.0 and results[0].seconds == old_a.seconds + 1.0
    # the index holds exactly the kept plans: a moved to x = 2.5, c at 0
    probe = lambda x: ctx.index.overlapping_owners(np.array([0]), np.array([[x, 0.0]]), np.array([0.1]))
    assert set(probe(0.0)) == {2} and set(probe(2.5)) == {0} and set(probe(5.0)) == {1}


def test_repair_puts_everything_back_when_a_blocker_fails(monkeypatch):
    """Same, but a cannot be planned clean around c, and would be worse off than c was (two
    warnings against one), so it cannot take the failure over either: a's and c's old plans stay,
    in the index too."""
    sched, ctx, results, made = _repair_setup(monkeypatch, {
        (2, 1): ("c", 0.1, ["still on a"]), (2, 2): ("c", 0.0), (0, 3): ("a", 2.5, ["a fails", "a is late"])})
    assert ctx.policy.hand_over
    old = dict(results)
    sched.repair(ctx, results, [2], 1)
    assert results[0] is old[0] and results[1] is old[1]
    assert results[2].warnings and results[2].track.root[0, 0] in (0.2, 0.1)
    assert results[2].seconds == 4.0          # its old plan and three tries (one of them a's)
    probe = lambda x: ctx.index.overlapping_owners(np.array([0]), np.array([[x, 0.0]]), np.array([0.05]))
    assert 0 in probe(0.0) and not probe(2.5) and set(probe(5.0)) == {1}


def test_a_blocker_may_take_the_failure_over_once_and_then_not_displace_who_gave_it(monkeypatch):
    """With ``hand_over``, the same repair keeps c's clean plan and a's failing one (no worse than
    c's was): a takes the failure over. Repaired in the next pass, a fails in place again (on c)
    but may not displace c, who handed it the failure: c's plan stays."""
    sched, ctx, results, made = _repair_setup(monkeypatch, {
        (2, 1): ("c", 0.1, ["still on a"]), (2, 2): ("c", 0.0), (0, 3): ("a", 2.5, ["a fails"]),
        (0, 1): ("a", 0.0, ["a on c"])})
    ctx.policy.hand_over = True
    sched.repair(ctx, results, [2], 1)
    assert results[2] is made[(2, 2)] and results[0] is made[(0, 3)]
    assert ctx.handed == {0: {2}}
    probe = lambda x: ctx.index.overlapping_owners(np.array([0]), np.array([[x, 0.0]]), np.array([0.05]))
    assert set(probe(0.0)) == {2} and set(probe(2.5)) == {0}
    sched.repair(ctx, results, [0], 2)        # (0, 2) is not a plan of the fake: c is not taken out
    assert results[2] is made[(2, 2)] and results[0].warnings
    assert set(probe(0.0)) == {2} and 0 in probe(2.5)


def test_a_failed_lead_is_repaired_with_the_characters_it_times(monkeypatch):
    """a failed and c's goal is timed by a's arrival: the repair takes c out, plans a again
    (clean, at 2.5), then c after it (clean, at 8): both kept, in the index too, and c is not
    repaired a second time."""
    sched, ctx, results, made = _repair_setup(monkeypatch, {(0, 1): ("a", 2.5), (2, 4): ("c", 8.0)}, lead=True)
    sched.repair(ctx, results, [0, 2], 1)
    assert results[0] is made[(0, 1)] and results[2] is made[(2, 4)]
    assert results[0].seconds == 2.0 and results[2].seconds == 2.0
    probe = lambda x: set(ctx.index.overlapping_owners(np.array([0]), np.array([[x, 0.0]]), np.array([0.1])))
    assert probe(2.5) == {0} and probe(8.0) == {2} and probe(5.0) == {1} and not probe(0.0) and not probe(9.0)


def test_a_lead_repair_is_undone_when_its_group_is_no_better(monkeypatch):
    """Same, but c comes out with two warnings after a's new plan: the group is no better, so
    a's and c's old plans stay (their time counted), in the index too."""
    sched, ctx, results, made = _repair_setup(
        monkeypatch, {(0, 1): ("a", 2.5), (2, 4): ("c", 8.0, ["c late", "c relaxed"])}, lead=True)
    old = dict(results)
    sched.repair(ctx, results, [0], 1)
    assert results[0].track is old[0].track and results[0].warnings == ["a waits"]
    assert results[2].track is old[2].track and results[1] is old[1]
    assert results[0].seconds == 2.0 and results[2].seconds == 2.0
    probe = lambda x: set(ctx.index.overlapping_owners(np.array([0]), np.array([[x, 0.0]]), np.array([0.1])))
    assert probe(0.0) == {0} and probe(9.0) == {2} and not probe(2.5) and not probe(8.0)


def test_characters_taken_out_for_a_repair_hold_their_starts_until_planned_again(monkeypatch):
    """a (the lead, failed) is planned again without c, whose goal it times; c starts at 7. While a
    is planned, c's start is held (as in the first pass), so a's new plan keeps off it; when c is
    planned again its own hold has given way, and once the repair is done no hold is left."""
    seen = {}
    sched, ctx, results, made = _repair_setup(monkeypatch, {(0, 1): ("a", 2.5), (2, 4): ("c", 8.0)}, lead=True,
                                              starts={"c": 7.0}, seen=seen)
    sched.repair(ctx, results, [0], 1)
    assert results[0] is made[(0, 1)] and results[2] is made[(2, 4)]
    assert seen[(0, 1)][7] == {2} and seen[(0, 1)][9] == set()      # c held at its start, its old plan out
    assert seen[(2, 4)][7] == set() and seen[(2, 4)][2.5] == {0}     # c planned: its hold gone, a's new plan in
    probe = lambda x: set(ctx.index.overlapping_owners(np.array([0]), np.array([[x, 0.0]]), np.array([0.1])))
    assert probe(7.0) == set() and probe(8.0) == {2} and probe(2.5) == {0}


def test_blockers_taken_out_for_a_repair_hold_their_starts_while_the_failed_one_is_planned(monkeypatch):
    """c fails on a; planned without a, a's start (4) is held, and given way when a is planned again."""
    seen = {}
    sched, ctx, results, made = _repair_setup(monkeypatch, {
        (2, 1): ("c", 0.1, ["still on a"]), (2, 2): ("c", 0.0), (0, 3): ("a", 2.5)}, starts={"a": 4.0}, seen=seen)
    sched.repair(ctx, results, [2], 1)
    assert results[2] is made[(2, 2)] and results[0] is made[(0, 3)]
    assert seen[(2, 2)][4] == {0} and seen[(2, 2)][0] == set()       # a's start held, its old plan out
    assert seen[(0, 3)][4] == set() and seen[(0, 3)][0] == {2}       # c's new plan in
    probe = lambda x: set(ctx.index.overlapping_owners(np.array([0]), np.array([[x, 0.0]]), np.array([0.1])))
    assert probe(4.0) == set() and probe(2.5) == {0}


def test_a_seat_is_approached_from_in_front(default_graph):
    """With ``approach_point``, the way points to a seat pass a point that far in front of it,
    so a character coming from the side walks in front of the seat before it sits (not across
    the neighbouring seats)."""
    g = default_graph
    node = int(g.nodes_with_label("stand")[0])
    sit = g.nodes_with_label("sit")
    seat, facing = np.array([0.0, 0.0]), 0.0          # sits facing +Z: "in front" is +Z
    start = Config(node, 6.0, 0.5, np.radians(-90.0), 0)   # comes in from the side (+X)

    def closest(ap, nodes):
        lib = MotionLibrary(g, SearchParams(approach_point=ap))
        res = run_to_completion(SegmentPlanner(lib).run(start, Goal(seat, facing, nodes, None), np.random.default_rng(0)))
        assert res.ok
        return np.hypot(res.root[:, 0] - 0.0, res.root[:, 1] - 1.2).min()

    near, far = closest(1.2, sit), closest(0.0, sit)      # measured: 0.25 m and 0.74 m
    assert near < 0.35 and far > near + 0.3


def test_pairs_static_clear_agrees_with_a_frame_by_frame_test(default_graph):
    """The search's static pre-test of motion pairs (M_f[:i] placed at the start, M_b[j:] at the
    goal, tested at the library's collision samples) against an independent test of every
    frame of the same clips: it never flags a pair that is clear, and misses few."""
    from runtime.crowd.planner.costs import pairs_static_clear
    from runtime.motion.planar import compose
    g = default_graph
    wall_x = 2.5
    static = lambda xz: wall_x - np.asarray(xz)[:, 0]          # a wall filling x > 2.5
    planner = SegmentPlanner(MotionLibrary(g), static=static)
    rng = np.random.default_rng(5)
    P, L = 150, 16
    F = -np.ones((P, L), np.int64)
    B = -np.ones((P, L), np.int64)
    start_node = int(g.edge_src[0])
    nf, nb = rng.integers(1, 14, P), rng.integers(1, 14, P)
    for p in range(P):
        F[p, :nf[p]] = g.random_walk(start_node, nf[p], rng)
        B[p, L - nb[p]:] = g.random_walk(int(rng.integers(g.num_nodes)), nb[p], rng)
    i = np.array([rng.integers(0, n + 1) for n in nf])
    j = np.array([rng.integers(L - n, L + 1) for n in nb])
    start, goal = np.array([0.0, 0.0, 0.3]), np.array([0.5, 6.0, 2.0])
    got = pairs_static_clear(planner.lib, static, planner.p.margin, F, B, i, j, start, goal)

    def frames_clear(c, edges):
        for e in edges:
            a, b = g.edge_start[e], g.edge_start[e + 1]
            local = np.stack([g.frame_cxz[a:b, 0], g.frame_cxz[a:b, 1], g.frame_heading[a:b]], axis=1)
            w = compose(c[None], local)
            if np.any(static(w[:, :2]) < g.frame_radius[a:b] + planner.p.margin):
                return False
            c = compose(c, planner.lib.disp[e])
        return True

    want = np.zeros(P, dtype=bool)
    for p in range(P):
        bpart = [int(e) for e in B[p, j[p]:] if e >= 0]
        c = goal.copy()                        # M_b[j:] runs into the goal: place it backwards
        for e in reversed(bpart):
            d = planner.lib.disp[e]
            h = c[2] - d[2]
            c = np.array([c[0] - (np.cos(h) * d[0] + np.sin(h) * d[1]),
                          c[1] - (-np.sin(h) * d[0] + np.cos(h) * d[1]), h])
        want[p] = frames_clear(start.copy(), [int(e) for e in F[p, :i[p]]]) and frames_clear(c, bpart)
    assert want.sum() > 10 and (~want).sum() > 10          # both kinds of pairs occur
    assert (got & ~want).sum() <= 0.05 * P                 # misses few (between samples)
    assert not np.any(~got & want)                          # never flags a clear pair


def test_a_character_with_time_to_wait_starts_on_a_still_node(default_graph, monkeypatch):
    """With ``start_still`` unset, a "stand" character whose first window opens long after it
    could walk there is planned first from a node where it can stand and wait; one without
    a window (or with a tight one) first from the walking hub. Setting the key overrides."""
    import runtime.crowd.scheduler as sched
    from runtime.crowd.idle import still_nodes
    from runtime.crowd.scheduler import start_node
    g = default_graph
    still = still_nodes(g, SearchParams().eps)
    hub, stand = start_node(g, "stand", "x"), start_node(g, "stand", "x", still)
    first = {}
    real = sched.plan_goals

    def spy(ctx, results, ci, node, *args, **kw):
        first.setdefault(ctx.sc.characters[ci].name, node)
        return real(ctx, results, ci, node, *args, **kw)

    monkeypatch.setattr(sched, "plan_goals", spy)

    def scenario(**syn):
        chars = [{"name": name, "start": {"position": [3.0 * k, 0.0], "heading": 0.0, "pose": "stand"},
                  "goal": [{"position": [3.0 * k, 4.0], **({"time": t} if t else {})}]}
                 for k, (name, t) in enumerate([("waits", [12.0, 13.0]), ("free", None), ("tight", [3.2, 4.0])])]
        return parse_scenario({"name": "w", "duration": 15.0, "seed": 0, "synthesis": {"passes": 1, **syn},
                               "character": chars})

    # (one worker: the spy sees the groups planned in this process)
    plan_scenario(scenario(), g, policy=CrowdPolicy(workers=1))
    assert first == {"waits": stand, "free": hub, "tight": hub}
    first.clear()
    plan_scenario(scenario(start_still=False), g, policy=CrowdPolicy(workers=1))
    assert first == {"waits": hub, "free": hub, "tight": hub}


def test_a_seated_character_leaves_through_the_point_in_front_of_its_seat(default_graph):
    """With ``approach_point``, the way points from a seat pass the point that far in front of
    it (down the aisle) before they turn along the row; standing starts and a zero
    ``approach_point`` keep the straight line."""
    g = default_graph
    sit = int(g.nodes_with_label("sit")[0])
    stand = g.nodes_with_label("stand")
    goal = Goal(np.array([6.0, 0.3]), None, stand, None)          # further along the row
    seated = Config(sit, 1.0, 0.0, np.radians(-90.0), 0)          # faces -X: "in front" is -X

    def wps(ap, start):
        return SegmentPlanner(MotionLibrary(g, SearchParams(approach_point=ap))).waypoints(start, goal)

    np.testing.assert_allclose(wps(2.0, seated), [[1.0, 0.0], [-1.0, 0.0], [6.0, 0.3]], atol=1e-12)
    np.testing.assert_allclose(wps(0.0, seated), [[1.0, 0.0], [6.0, 0.3]])
    standing = Config(int(stand[0]), 1.0, 0.0, np.radians(-90.0), 0)
    np.testing.assert_allclose(wps(2.0, standing), [[1.0, 0.0], [6.0, 0.3]])
    # and a goal within twice the distance of that point: straight there
    near = Goal(np.array([-1.0, 3.0]), None, stand, None)
    lib = MotionLibrary(g, SearchParams(approach_point=2.0))
    np.testing.assert_allclose(SegmentPlanner(lib).waypoints(seated, near), [[1.0, 0.0], [-1.0, 3.0]])


def test_a_seated_character_holds_its_seat_until_it_is_planned(default_graph):
    """A character who starts seated and leaves late is planned after one who walks past its
    seat: until it is planned, its seat is held (for the frames before it could leave), so
    the walker goes round it and the seated character's plan comes out clean."""
    from runtime.crowd.environment import Environment, Marker
    from runtime.crowd.scheduler import seat_hold, seated_radius
    g = default_graph
    env = Environment(markers=[Marker("/World/Seats/s", "seat", [0.0, 0.0], np.radians(90.0))])
    data = {"name": "hold", "duration": 16.0, "seed": 0, "synthesis": {"passes": 1},
            "character": [
                {"name": "walker", "start": {"position": [-4.0, 0.2], "heading": 90.0, "pose": "stand"},
                 "goal": [{"position": [4.0, 0.2]}]},
                {"name": "sitter", "start": {"seat": "/World/Seats/s"},
                 "goal": [{"position": [3.0, 3.0], "time": [13.0, 14.0]}]}]}
    sc = parse_scenario(data, env=env, node_labels=set(g.node_labels_all()))
    hold = seat_hold(sc.character("sitter"), g, 30.0)
    assert hold == int((13.0 - np.hypot(3.0, 3.0) / 1.5 - 2.0) * 30.0)
    assert seat_hold(sc.character("walker"), g, 30.0) == 0
    res = plan_scenario(sc, g, env)
    walker = res.characters[0].track.root
    gap = np.hypot(walker[:hold, 0], walker[:hold, 1]) - seated_radius(g)
    assert gap.min() > 0.2                     # round the held seat (straight on: through it)
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, g, env)
    assert rep.summary()["character_overlap_pairs"] == 0 and not res.characters[1].warnings


def test_a_held_goal_is_kept_clear_from_its_window_by_characters_planned_before(default_graph):
    """With ``reserve_goals``, a character planned first walks round the place where one planned
    after it will stand from its window's opening (straight on, it walks through it then); the
    second arrives there clean."""
    from runtime.crowd.planner import CrowdPolicy
    from runtime.crowd.scheduler import standing_radius
    from runtime.crowd.idle import still_nodes
    g = default_graph
    data = {"name": "goal-hold", "duration": 16.0, "seed": 0, "synthesis": {"passes": 1},
            "character": [
                {"name": "walker", "start": {"position": [-6.0, 0.0], "heading": 90.0, "pose": "stand"},
                 "goal": [{"position": [6.0, 0.0]}]},
                {"name": "stander", "start": {"position": [0.0, 5.0], "heading": 180.0, "pose": "stand"},
                 "goal": [{"position": [0.0, 0.0], "time": [3.0, 4.0]}]}]}
    sc = parse_scenario(data, node_labels=set(g.node_labels_all()))
    radius = standing_radius(g, still_nodes(g, sc.epsilon, 30.0))
    gaps = {}
    for held in (False, True):
        res = plan_scenario(sc, g, policy=CrowdPolicy(reserve_goals=held))
        walker = res.characters[0].track.root
        gaps[held] = (np.hypot(walker[90:, 0], walker[90:, 1]) - radius).min()
        if held:
            rep = check_crowd(sc, {c.name: c.track for c in res.characters}, g)
            assert rep.summary()["character_overlap_pairs"] == 0 and not res.characters[1].warnings
    assert gaps[False] < 0.0 < gaps[True]      # through the held place, and round it


def test_the_final_test_finds_the_first_collision_and_collides_early_uses_it(default_graph):
    """final_collision returns the first output frame whose cylinder hits a planned character
    (the compiled index stops at it), one past the motion when only the held end position is
    hit, else None; collides_early compares that frame with the limit."""
    from runtime.crowd.goals import collides_early
    from runtime.crowd.spacetime import SpaceTimeIndex
    from runtime.crowd.planner import SegmentResult
    g = default_graph
    m = 90
    root = np.zeros((m, 3))
    root[:, 1] = np.linspace(0.0, 3.0, m)            # walks 3 m along +z from frame 100
    fa = np.full(m, int(np.argmin(g.frame_radius)))
    res = SegmentResult(True, fa, fa, np.zeros(m), root, 100, Config(0, 0.0, 3.0, 0.0, 100 + m - 1), 0.0,
                        (0.0, 0.0, 0.0), 0, [])
    idx = SpaceTimeIndex(cell=1.6)
    planner = SegmentPlanner(MotionLibrary(g), collide=lambda f, xz, r: idx.overlaps(f, xz, r),
                             collide_first=lambda f, xz, r: idx.first_overlap(f, xz, r))
    assert planner.final_collision(res) is None and not collides_early(planner, res, 60)
    idx.insert(7, np.arange(100, 400), np.tile([[0.0, 3.0]], (300, 1)), 0.3)   # stands at the end
    planner.hold = lambda r: (np.arange(r.start_frame + m, r.start_frame + m + 30), np.tile(r.root[-1:, :2], (30, 1)),
                              np.full(30, 0.3))
    first = planner.final_collision(res)
    cxz, r = blend_cylinders(g, fa, fa, root)
    d = np.hypot(cxz[:, 0], cxz[:, 1] - 3.0)
    rad = r + planner.p.margin + 0.3
    assert first == int(np.flatnonzero(d < rad)[0]) > 40          # the first frame within reach of it
    assert collides_early(planner, res, first + 1) and not collides_early(planner, res, first)
    # the same through the fallback (first sample of the boolean collide) and the numpy walk
    plain = SegmentPlanner(MotionLibrary(g), collide=lambda f, xz, r: idx.overlaps(f, xz, r))
    assert plain.final_collision(res) == first
    idx.remove_owner(7)
    idx.insert(8, np.arange(100 + m, 400), np.tile([[0.0, 3.0]], (300 - m, 1)), 0.3)   # comes after it arrives
    assert planner.final_collision(res) == m                    # only the held position is hit
    assert not collides_early(planner, res, 10 * m)


def test_an_untimed_goal_whose_motions_collide_sets_off_later(default_graph, monkeypatch):
    """When every motion to an untimed goal runs into characters planned earlier, the scheduler
    puts the start off (``depart_delays``): the character stands at its start, on its still
    node, then goes -- the plan keeps the idling (back on the start configuration, within eps)
    and has no warning. Here the planner is made to fail every motion that starts at frame 0
    (as if it ran into someone right at the start)."""
    import runtime.crowd.goals as sched
    import runtime.crowd.planner.segment as synth
    real = synth.SegmentPlanner.run
    starts = []

    def run(self, start, goal, rng, name="", **kw):
        starts.append(start.frame)
        res = yield from real(self, start, goal, rng, name, **kw)
        if start.frame == 0:
            res.warning, res.collided = "forced collision", True
        return res

    monkeypatch.setattr(synth.SegmentPlanner, "run", run)
    monkeypatch.setattr(sched, "collides_early", lambda planner, res, frames: res.start_frame == 0)
    sc = parse_scenario({"name": "one", "duration": 12.0, "seed": 0, "synthesis": {"passes": 1},
                         "character": [{"name": "c0", "start": {"position": [0.0, 0.0], "heading": 0.0, "pose": "stand"},
                                        "goal": [{"position": [0.0, 4.0]}]}]})
    res = plan_scenario(sc, default_graph)
    c = res.characters[0]
    assert c.warnings == []
    later = [f for f in starts if f > 0]
    assert later and 1.5 * 30 <= later[0] <= 2.5 * 30          # the first delay, 2 s, in whole idle loops
    root = c.track.root
    assert np.abs(root[: later[0] + 1] - root[0]).max() < 0.05     # standing at the start till then
    assert np.abs(root[later[0], :2] - root[0, :2]).max() < 1e-9   # ... and back on its position
    assert np.hypot(*(root[c.arrivals[0], :2] - [0.0, 4.0])) < 1e-3
    rep = check_crowd(sc, {c.name: c.track}, default_graph)
    assert rep.summary()["passed"], rep.summary()
    # with a lane that clears after 5 s (lane_clear_delay), that is the wait tried first
    starts.clear()
    monkeypatch.setattr(sched, "lane_clear_delay", lambda *a, **k: 5.0)
    c = plan_scenario(sc, default_graph).characters[0]
    assert c.warnings == []
    later = [f for f in starts if f > 0]
    assert later and 4.5 * 30 <= later[0] <= 5.5 * 30
    # with no delays the forced collision stays a warning
    starts.clear()
    monkeypatch.setattr(sched, "lane_clear_delay", lambda *a, **k: None)
    monkeypatch.setattr(CrowdPolicy, "__init__", _with(CrowdPolicy.__init__, depart_delays=()))
    res = plan_scenario(sc, default_graph)
    assert res.characters[0].warnings and all(f == 0 for f in starts)


def test_a_wait_before_a_motion_keeps_its_idle_clips_turns(default_graph):
    """The wait before a put-off departure (``idle_for``) is bent back onto the start
    position only: its heading follows the idle clips' own turns exactly (the checker's raw
    increments, integrated), so the motion after it is not rotated off the raw clips the
    checker integrates from the segment's start. (Bent back onto the start heading too, 30 s
    of the "stand" idle clip turning 0.34 deg/s would leave a walk 10 degrees off: ~0.2 m/s of
    adjustment at 1.3 m/s.) Its position stays on the start and it ends there."""
    from runtime.crowd.checker import raw_increments
    from runtime.crowd.idle import idle_for, idle_loop, still_nodes
    g = default_graph
    lib = MotionLibrary(g)
    still = np.flatnonzero(still_nodes(g, (0.02, 2.0, 1 / 15)))
    node = max(still, key=lambda n: abs(g.edge_disp[idle_loop(g, n), 2]))   # the one that turns most
    assert abs(g.edge_disp[idle_loop(g, node), 2]) > 1e-3
    cfg = Config(int(node), 1.0, 2.0, 0.5, 60)
    tr = idle_for(lib, g, cfg, 30.0, 30.0)
    assert tr.start_frame == 60 and len(tr) > 29 * 30
    inc, _ = raw_increments(g, tr)
    np.testing.assert_allclose(tr.root[0, 2] + np.concatenate([[0.0], np.cumsum(inc[:, 2])]), tr.root[:, 2], atol=1e-6)
    assert abs(tr.root[-1, 2] - 0.5) > 0.01                               # it did turn
    assert np.abs(tr.root[:, :2] - [1.0, 2.0]).max() < 0.05
    np.testing.assert_allclose(tr.root[-1, :2], [1.0, 2.0], atol=1e-9)


def test_lane_clear_delay_is_the_first_whole_second_a_straight_walk_is_clear():
    """``lane_clear_delay``: the wait before a straight walk at 1.3 m/s from the start to the
    goal misses every planned character -- here one standing on the line until frame 400 --
    found by brute force over whole seconds."""
    from runtime.crowd.goals import lane_clear_delay
    from runtime.crowd.spacetime import SpaceTimeIndex
    index = SpaceTimeIndex(cell=1.6)
    f = np.arange(400)
    index.insert(0, f, np.broadcast_to([0.2, 5.0], (400, 2)), np.full(400, 0.4))
    cfg = Config(0, 0.0, 0.0, 0.0, 30)
    goal = Goal(np.array([0.0, 10.0]))
    d = lane_clear_delay(index, cfg, goal, 30.0, 1800, 0.5)
    n = int(10.0 / 1.3 * 30) + 1
    path = np.linspace(0.0, 10.0, n)
    want = next(k for k in range(60)
                if not any(30 + 30 * k + i < 400 and np.hypot(0.2, path[i] - 5.0) < 0.9 for i in range(n)))
    assert d == float(want) and 5 <= want <= 10
    assert lane_clear_delay(index, cfg, goal, 30.0, 400, 0.5) is None     # no time left to wait that long


def test_lane_clear_delay_walks_the_route_when_given_one():
    """With way points the proxy walk follows them (through the door the motion takes): a
    character standing on the route but 3 m off the straight line delays the walk along the
    route and not the straight one."""
    from runtime.crowd.goals import lane_clear_delay
    from runtime.crowd.spacetime import SpaceTimeIndex
    index = SpaceTimeIndex(cell=1.6)
    f = np.arange(400)
    index.insert(0, f, np.broadcast_to([3.0, 5.0], (400, 2)), np.full(400, 0.4))
    cfg = Config(0, 0.0, 0.0, 0.0, 30)
    goal = Goal(np.array([0.0, 10.0]))
    route = np.array([[0.0, 0.0], [3.0, 5.0], [0.0, 10.0]])
    assert lane_clear_delay(index, cfg, goal, 30.0, 1800, 0.5) == 0.0
    d = lane_clear_delay(index, cfg, goal, 30.0, 1800, 0.5, route=route)
    half = np.hypot(3.0, 5.0)
    n = int(2 * half / 1.3 * 30) + 1
    s = np.linspace(0.0, 2 * half, n)
    along = np.where(s[:, None] <= half, s[:, None] / half * [3.0, 5.0],
                     [3.0, 5.0] + (s[:, None] - half) / half * np.array([-3.0, 5.0]))
    want = next(k for k in range(60) if not any(30 + 30 * k + i < 400 and np.hypot(*(along[i] - [3.0, 5.0])) < 0.9
                                                 for i in range(n)))
    assert d == float(want) and want >= 5


def _with(init, **overrides):
    def patched(self, *a, **k):
        init(self, *a, **k)
        for key, v in overrides.items():
            setattr(self, key, v)
    return patched


def test_compiled_static_filter_and_sdf_agree_with_numpy(default_graph, random_pairs):
    """The compiled static filter (reading the clearance grid directly, stopping at a pair's
    first bad sample) and the compiled SDF lookup give the numpy paths' answers."""
    from runtime.crowd import clearance
    from runtime.crowd.clearance import Clearance
    from runtime.crowd.environment import Environment
    from runtime.crowd.planner import kernels
    from runtime.crowd.planner.costs import pairs_static_clear
    if not (kernels.AVAILABLE and clearance.AVAILABLE):
        pytest.skip("numba is not installed: only the numpy paths exist")
    g = default_graph
    env = Environment([[[1.0, 1.0], [3.0, 1.0], [3.0, 4.0], [1.0, 4.0]]], [[-2.0, 3.0, 0.8]])
    sdf = env.sdf(resolution=0.05, margin=2.0)
    static = Clearance(sdf, sdf.max_error)
    lib = MotionLibrary(g)
    rng = np.random.default_rng(7)
    pts = rng.uniform(-12, 12, (5000, 2))
    clearance.ENABLED = False
    try:
        slow = sdf.sample(pts)
    finally:
        clearance.ENABLED = True
    np.testing.assert_allclose(sdf.sample(pts), slow, atol=1e-12)
    P = 300
    F, B, i, j = random_pairs(rng, P, 14)
    start, goal = np.array([-1.0, -1.0, 0.4]), np.array([0.5, 6.0, 2.0])
    fast = pairs_static_clear(lib, static, 0.02, F, B, i, j, start, goal, slack=0.1)
    plain = pairs_static_clear(lib, lambda xz: static(xz), 0.02, F, B, i, j, start, goal, slack=0.1)
    assert 0 < fast.sum() < P              # some pairs hit the obstacles, some do not
    # some first clips start farther from every obstacle than their samples reach, so the
    # compiled filter may pass them without reading the samples: the answers still equal the
    # sample-by-sample ones
    far = sdf.sample(start[None, :2])[0] >= lib.samp_reach[F[:, 0]] + (0.02 - 0.1) + 3 * sdf.max_error
    assert far.any()
    assert np.array_equal(fast, plain)
    memo = {}                              # a search's memo of parts tested: same answers, second time from it
    half = pairs_static_clear(lib, static, 0.02, F[:150], B[:150], i[:150], j[:150], start, goal, slack=0.1, memo=memo)
    again = pairs_static_clear(lib, static, 0.02, F, B, i, j, start, goal, slack=0.1, memo=memo)
    assert np.array_equal(half, plain[:150]) and np.array_equal(again, plain)
    assert len(memo["f"]) > 0
