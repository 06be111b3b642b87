"""The World API checks its arguments and is transactional: the cases a careless caller hits
(tests/test_fuzz_world.py tries random sequences of them)."""
import math

import numpy as np
import pytest

from runtime.world import World


@pytest.fixture
def w(default_graph):
    return World(default_graph)


@pytest.mark.parametrize("position,heading,error", [
    ((float("nan"), 0.0), 0.0, ValueError), ((0.0, float("inf")), 0.0, ValueError),
    ((0.0, 0.0), float("nan"), ValueError),
    ((0.0, 0.0), float("-inf"), ValueError), (5.0, 0.0, TypeError), ((1.0, 2.0, 3.0), 0.0, ValueError),
    ("here", 0.0, TypeError), ((0.0, 0.0), "north", TypeError), ((2e6, 0.0), 0.0, ValueError), (None, 0.0, TypeError),
])
def test_a_spawn_that_raises_registers_nothing(w, position, heading, error):
    with pytest.raises(error):
        w.spawn("x", position, heading)
    assert w.names == [] and "x" not in w.crowd.chars and not w.playback.active.any()
    w.spawn("x", (0.0, 0.0))                      # the name is free: no ghost
    assert w.names == ["x"]


def test_a_spawn_failing_midway_is_rolled_back(w, monkeypatch):
    w.spawn("a", (0.0, 0.0))
    before = w.playback.active.copy()

    def broken(*a, **k):
        raise MemoryError("no room")
    monkeypatch.setattr(w.crowd, "append_idle", broken)
    with pytest.raises(MemoryError):
        w.spawn("b", (2.0, 0.0))
    assert w.names == ["a"] and "b" not in w.crowd.chars
    np.testing.assert_array_equal(w.playback.active, before)


def test_bad_names_and_poses(w):
    with pytest.raises(TypeError, match="name must be a string"):
        w.spawn(5, (0.0, 0.0))
    with pytest.raises(ValueError, match="must not be empty"):
        w.spawn("", (0.0, 0.0))
    with pytest.raises(ValueError, match="pose 'dance' is not a node label"):
        w.spawn("a", (0.0, 0.0), pose="dance")
    w.spawn("a", (0.0, 0.0))
    with pytest.raises(ValueError, match="already exists"):
        w.spawn("a", (1.0, 0.0))
    with pytest.raises(KeyError, match="no character named 'nobody'"):
        w.remove("nobody")
    with pytest.raises(KeyError, match="nobody"):
        w.position("nobody")
    assert w.names == ["a"]


def test_commands_check_their_arguments_and_queue_nothing_when_they_raise(w):
    w.spawn("a", (0.0, 0.0))
    w.spawn("b", (3.0, 0.0))
    bad = [
        (lambda: w.go_to("a", (float("nan"), 1.0)), ValueError, "position must be finite"),
        (lambda: w.go_to("a", (1.0, 1.0), heading=float("inf")), ValueError, "heading must be finite"),
        (lambda: w.go_to("a", (1.0, 1.0), arrive=(9.0, 8.0)), ValueError, "reversed"),
        (lambda: w.go_to("a", (1.0, 1.0), arrive=(float("nan"), 8.0)), ValueError, "finite"),
        (lambda: w.go_to("a", (1.0, 1.0), arrive=(-1.0, 8.0)), ValueError, "from 0"),
        (lambda: w.go_to("a", (1.0, 1.0), arrive=5.0), TypeError, "arrive must be"),
        (lambda: w.go_to("a", (1.0, 1.0), queue="yes"), TypeError, "queue"),
        (lambda: w.put_down("a", [1.0]), ValueError, "two numbers"),
        (lambda: w.sit("a", None), TypeError, "seat"),
        (lambda: w.pick_up("a", ""), ValueError, "box"),
        (lambda: w.meet([], (0.0, 0.0), 5.0), ValueError, "at least one"),
        (lambda: w.meet("ab", (0.0, 0.0), 5.0), TypeError, "list"),
        (lambda: w.meet(["a", "a"], (0.0, 0.0), 5.0), ValueError, "distinct"),
        (lambda: w.meet(["a", "b"], (0.0, 0.0), float("nan")), ValueError, "time_s"),
        (lambda: w.meet(["a", "b", "c"], (1e6 - 0.1, 0.0), 5.0), ValueError, "from the origin"),  # the 2nd point
    ]
    for call, error, words in bad:
        with pytest.raises(error, match=words):
            call()
        assert len(w.crowd.commands) == 0
    w.meet(["a", "b"], (1.0, 4.0), 9.0)
    assert len(w.crowd.commands) == 2


def test_poses_never_nan_and_step_never_raises(w):
    w.spawn("a", (0.0, 0.0))
    assert w.step(1 / 30) == 1
    with pytest.raises(ValueError, match="alpha must be finite"):
        w.poses(alpha=float("nan"))
    np.testing.assert_array_equal(w.poses(alpha=7.0), w.poses(alpha=1.0))
    np.testing.assert_array_equal(w.poses(alpha=-3.0), w.poses(alpha=0.0))
    warnings = []
    w.on("warning", warnings.append)
    frame = w.frame
    for dt in (float("nan"), float("inf"), -1.0, "fast", None, [1.0]):
        assert w.step(dt) == 0
    assert w.frame == frame and len(warnings) == 6
    assert all("step: real_dt" in e.data["message"] for e in warnings)
    assert np.all(np.isfinite(w.poses())) and math.isfinite(w.alpha)
    w.go_to("a", (2.0, 0.0))
    for _ in range(10):
        w.step(1 / 30)
    assert np.all(np.isfinite(w.poses()))


def test_world_settings_are_checked(default_graph):
    for kw, error in (({"dt": 0.0}, ValueError), ({"dt": float("inf")}, ValueError), ({"budget_ms": -1.0}, ValueError),
                      ({"budget_ms": float("nan")}, ValueError), ({"seed": -1}, ValueError), ({"seed": 1.5}, TypeError),
                      ({"capacity": 0}, ValueError)):
        with pytest.raises(error):
            World(default_graph, **kw)
    w = World(default_graph)
    with pytest.raises(ValueError):
        w.budget = float("nan")
    w.budget = 0.002
    assert w.budget == 0.002


def test_add_flocks_checks_its_starts(w):
    for pos, error in (([[0.0, float("nan"), 0.0]], ValueError), ([[0.0, 0.0]], ValueError), ("here", TypeError),
                       ([], ValueError)):
        with pytest.raises(error):
            w.add_flocks("never-loaded.cwpack", pos)
    with pytest.raises(ValueError, match="headings"):
        w.add_flocks("never-loaded.cwpack", [[0.0, 0.0, 0.0]], headings=[0.0, 1.0])
    assert w.flocks == []          # nothing was started (the pack was never even opened)
