"""runtime.World: loop, staged synthesis, commands, events, failure isolation (issue 5)."""
import math

import numpy as np
import pytest

from runtime.crowd.environment import Environment, Marker
from runtime.world import MAX_BUFFER, CharacterState, World


def _run(w, seconds):
    for _ in range(int(round(seconds * w.fps))):
        w.tick()


def _root_at(w, name, frame):
    c = w._chars[name]
    return w.buf_root[c.slot, frame % MAX_BUFFER]


@pytest.fixture
def env():
    return Environment(polygons=[np.array([[4.0, 4.0], [5.0, 4.0], [5.0, 5.0], [4.0, 5.0]])],
                       markers=[Marker("/World/Seats/s1", "seat", (-3.0, 5.0), math.pi),
                                Marker("/World/Boxes/b1", "box", (3.0, -4.0), 0.0)],
                       obstacle_paths=["/World/Obstacles/crate"])


def test_go_to_arrives_exactly_and_emits_event(default_graph):
    w = World(default_graph, seed=1)
    got = []
    w.on("arrived", got.append)
    w.spawn("a", (0.0, 0.0), 0.0)
    w.go_to("a", (1.0, 6.0), heading=math.radians(30))
    _run(w, 14)
    assert len(got) == 1 and got[0].character == "a"
    r = _root_at(w, "a", got[0].data["frame"])
    assert np.hypot(r[0] - 1.0, r[1] - 6.0) < 1e-6
    assert abs((r[2] - math.radians(30) + math.pi) % (2 * math.pi) - math.pi) < 1e-6
    assert w.state("a") is CharacterState.IDLE


def test_arrival_window_is_met(default_graph):
    w = World(default_graph, seed=2)
    got = []
    w.on("arrived", got.append)
    w.spawn("a", (0.0, 0.0), 0.0)
    w.go_to("a", (0.0, 5.0), arrive=(9.0, 9.5))
    _run(w, 12)
    assert len(got) == 1 and 9.0 - 1e-9 <= got[0].time <= 9.5 + 1e-9


def test_sit_and_pick_up_use_markers(default_graph, env):
    w = World(default_graph, world=env, seed=3)
    ev = []
    w.on("*", ev.append)
    w.spawn("s", (0.0, 0.0), 0.0)
    w.spawn("p", (2.0, 0.0), 0.0)
    w.sit("s", "/World/Seats/s1")
    w.pick_up("p", "/World/Boxes/b1")
    _run(w, 20)
    kinds = {(e.kind, e.character) for e in ev}
    assert ("sat", "s") in kinds and ("picked_up", "p") in kinds, [(e.kind, e.character, e.data) for e in ev]
    sat = next(e for e in ev if e.kind == "sat")
    assert np.allclose(sat.data["position"], (-3.0, 5.0), atol=1e-6)
    g = default_graph
    c = w._chars["s"]
    f = sat.data["frame"] % MAX_BUFFER
    pose = g.frame_rotations[w.buf_b[c.slot, f]]
    sit_nodes = g.nodes_with_label("sit")
    assert any(np.allclose(np.abs(np.sum(pose * g.node_rotations[n], -1)), 1, atol=1e-4) for n in sit_nodes)
    assert w._chars["p"].carrying == "/World/Boxes/b1"


def test_planning_is_time_sliced_and_characters_never_freeze(default_graph):
    w = World(default_graph, seed=4, budget_ms=0.0)   # at most one planner step per tick
    w.spawn("a", (0.0, 0.0), 0.0)
    w.go_to("a", (8.0, 8.0))
    planning_ticks = 0
    roots = []
    for _ in range(60):
        w.tick()
        planning_ticks += w.state("a") is CharacterState.PLANNING
        roots.append(w.root_states()[0].copy())
        assert w.tail[w._chars["a"].slot] - w.head[w._chars["a"].slot] >= 1   # buffered future
    assert planning_ticks >= 5                 # the work was spread over several ticks
    poses = [w.poses(alpha=1.0)]
    w.tick()
    poses.append(w.poses(alpha=1.0))
    assert not np.allclose(poses[0], poses[1])  # idle clips keep playing: no frozen pose


def test_a_failing_plan_never_stops_the_loop(default_graph, monkeypatch):
    import runtime.world as W

    def boom(self, *a, **k):
        raise RuntimeError("planner exploded")
        yield
    monkeypatch.setattr(W.SegmentPlanner, "run", boom)
    w = World(default_graph)
    warnings = []
    w.on("warning", warnings.append)
    w.on("warning", lambda e: 1 / 0)          # a broken listener is isolated too
    w.spawn("a", (0.0, 0.0))
    w.spawn("b", (3.0, 0.0))
    w.go_to("a", (5.0, 5.0))
    w.go_to("nobody", (1.0, 1.0))
    w.sit("b", "/World/Seats/none")           # no world: the command is refused, not raised
    _run(w, 2)
    msgs = " | ".join(e.data["message"] for e in warnings)
    assert "planner exploded" in msgs and "nobody" in msgs and "seat" in msgs
    assert w.state("a") is CharacterState.IDLE


def test_interpolated_poses(default_graph):
    w = World(default_graph)
    w.spawn("a", (0.0, 0.0))
    w.go_to("a", (0.0, 4.0))
    _run(w, 3)
    p1 = w.poses(alpha=1.0)
    w.tick()
    p0 = w.poses(alpha=0.0)
    p2 = w.poses(alpha=1.0)
    np.testing.assert_allclose(p0, p1, atol=1e-9)
    np.testing.assert_allclose(w.poses(alpha=0.5), 0.5 * (p0 + p2), atol=1e-9)


def test_same_seed_same_motion(default_graph):
    def run():
        w = World(default_graph, seed=7)
        for i in range(3):
            w.spawn(f"c{i}", (2.0 * i, 0.0))
            w.go_to(f"c{i}", (2.0 * i + 1, 5.0), heading=0.3)
        w.budget = 10.0   # deterministic regardless of machine speed
        _run(w, 8)
        return w.root_states()
    np.testing.assert_array_equal(run(), run())


def test_step_uses_an_accumulator(default_graph):
    w = World(default_graph)
    w.spawn("a", (0.0, 0.0))
    assert w.step(0.5 / 30) == 0
    assert w.step(0.6 / 30) == 1
    assert 0.0 < w.alpha < 1.0
    assert w.step(1.0) == 8                    # capped: a stall never snowballs


def test_embed_game_sample_runs_headless(default_graph, monkeypatch):
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "samples" / "embed_game.py"
    spec = importlib.util.spec_from_file_location("embed_game", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    # an unlimited planning budget makes the outcome independent of the machine's speed
    r = mod.run_headless(300, 6, budget_ms=1e6)
    assert r["ticks"] == 300 and r["characters"] == 6
    assert r["joints_shape"] == (6, default_graph.skeleton.num_joints, 3)
    assert sum(k == "arrived" for k, _ in r["events"]) >= 3   # they do cross the plaza
