"""Short moves: a 0.5-3 m go_to in open space always arrives exactly (the short-move search,
runtime.crowd.planner.short), whatever the turn it needs."""
import math

import numpy as np
import pytest

from runtime.crowd.planner import Config, Goal, MotionLibrary, SegmentPlanner, run_to_completion
from runtime.motion.planar import compose, wrap_angle
from runtime.world import World
from runtime.world.crowd import online_params


def _stand_node(graph):
    from runtime.crowd.idle import still_nodes
    still = still_nodes(graph, online_params(graph.fps).eps, graph.fps)
    stand = graph.nodes_with_label("stand")
    stand = stand[still[stand]]
    deg = np.bincount(graph.edge_src, minlength=graph.num_nodes)[stand]
    return int(stand[np.argmax(deg)]), stand


def test_endings_are_the_composed_clips_ending_in_the_goal_node(default_graph):
    lib = MotionLibrary(default_graph, online_params(default_graph.fps))
    goal_node, _ = _stand_node(default_graph)
    ends = lib.endings(goal_node, 0)
    assert lib.endings(goal_node, 0) is ends                     # computed once
    g = default_graph
    assert np.array_equal(ends[goal_node][0][0], [-1, -1])        # the empty ending first
    for node, (E, T, D) in ends.items():
        assert len(E) == len(T) == len(D) <= 256
        for row, tr, dur in zip(E[:20], T[:20], D[:20]):
            edges = row[row >= 0]
            if len(edges):
                assert g.edge_src[edges[0]] == node and g.edge_dst[edges[-1]] == goal_node
                assert np.all(g.edge_src[edges[1:]] == g.edge_dst[edges[:-1]])
                assert np.all(g.edge_state[edges] == 0)
            c = np.zeros((1, 3))
            for e in edges:
                c = compose(c, lib.disp[e][None])
            np.testing.assert_allclose(c[0], tr, atol=1e-12)
            assert math.isclose(dur, float(lib.dur[edges].sum()), abs_tol=1e-12)


def test_segment_planner_meets_short_goals_within_eps(default_graph):
    """Seeded sweep: distance, direction, start heading and goal heading at random."""
    p = online_params(default_graph.fps)
    lib = MotionLibrary(default_graph, p)
    node, stand = _stand_node(default_graph)
    rng = np.random.default_rng(7)
    for trial in range(40):
        d, a, h0 = rng.uniform(0.5, 3.0), rng.uniform(-math.pi, math.pi), rng.uniform(-math.pi, math.pi)
        head = None if trial % 2 else float(rng.uniform(-math.pi, math.pi))
        goal = np.array([d * math.sin(a), d * math.cos(a)])
        res = run_to_completion(SegmentPlanner(lib, params=p).run(Config(node, 0.0, 0.0, h0, 0),
                                                                   Goal(goal, head, stand, None),
                                                                   np.random.default_rng(trial)))
        assert not res.warning, (trial, d, a, h0, head, res.warning)
        assert all(r <= e * (1 + 1e-9) for r, e in zip(res.rates, p.eps))
        assert np.hypot(*(res.root[-1, :2] - goal)) < 1e-6
        if head is not None:
            assert abs(wrap_angle(res.root[-1, 2] - head)) < 1e-6
        assert res.end.node in stand


@pytest.mark.parametrize("seed", [0, 1])
def test_world_go_to_short_moves_always_arrive(default_graph, seed):
    rng = np.random.default_rng(100 + seed)
    for trial in range(20):
        d, a, h0 = rng.uniform(0.5, 3.0), rng.uniform(-math.pi, math.pi), rng.uniform(-math.pi, math.pi)
        head = None if trial % 3 == 0 else float(rng.uniform(-math.pi, math.pi))
        w = World(default_graph, seed=trial)
        got, warnings = [], []
        w.on("arrived", got.append)
        w.on("warning", warnings.append)
        w.spawn("a", (0.0, 0.0), h0)
        goal = (d * math.sin(a), d * math.cos(a))
        w.go_to("a", goal, heading=head)
        for _ in range(30 * 30):
            w.tick()
            if got:
                break
        assert got and not warnings, (trial, d, a, h0, head, [e.data for e in warnings])
        r = w.playback.root_at(w.slot("a"), got[0].data["frame"])
        assert math.hypot(r[0] - goal[0], r[1] - goal[1]) < 1e-6
        if head is not None:
            assert abs(wrap_angle(r[2] - head)) < 1e-6

