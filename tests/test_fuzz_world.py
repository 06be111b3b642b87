"""World API fuzzing (hypothesis): random sequences of commands and steps, with arguments of
every kind (NaN, inf, huge numbers, wrong types and shapes, reversed windows, unknown names and
markers). The only exceptions are the documented ones (TypeError, ValueError, KeyError); a call
that raises changes nothing; ``step`` never raises; the World never holds NaN state."""
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import runtime.world.crowd as world_crowd
from runtime.crowd.environment import Environment, Marker
from runtime.world import World

DOCUMENTED = (TypeError, ValueError, KeyError)
ENV = Environment(markers=[Marker("/World/Seats/s01", "seat", (4.0, 0.0), 0.0),
                           Marker("/World/Boxes/b01", "box", (0.0, 4.0), 1.0)])


@pytest.fixture(scope="module")
def world_factory(default_graph):
    """Worlds on the default library, sharing one planner motion library (read-only tables of
    the graph, built in 0.1 s): 500 worlds would otherwise spend a minute building it."""
    real = world_crowd.MotionLibrary
    cache = {}

    def shared(graph, params):
        key = (id(graph), repr(params))
        if key not in cache:
            cache[key] = real(graph, params)
        return cache[key]
    world_crowd.MotionLibrary = shared
    yield lambda: World(default_graph, world=ENV, budget_ms=2.0, seed=0)
    world_crowd.MotionLibrary = real


floats = st.floats(allow_nan=True, allow_infinity=True)
junk = st.one_of(st.none(), st.booleans(), floats, st.integers(-10 ** 20, 10 ** 20), st.text(max_size=3),
                 st.lists(floats, max_size=3), st.tuples(floats, floats, floats), st.just({"x": 1.0}),
                 st.just(np.array([[1.0, 2.0]])), st.just(np.array(["a", "b"])), st.just(object()))
good_xz = st.tuples(st.floats(-12, 12), st.floats(-12, 12))
xz = st.one_of(good_xz, good_xz, good_xz, st.tuples(floats, floats), st.lists(st.floats(-5, 5), max_size=3),
               st.just(np.array([1.0, 2.0])), st.just((1e7, 0.0)), junk)
heading = st.one_of(st.none(), st.floats(-4, 4), st.floats(-4, 4), floats, junk)
window = st.one_of(st.none(), st.tuples(st.floats(0, 30), st.floats(0, 30)), st.tuples(floats, floats),
                   st.lists(st.floats(0, 10), max_size=3), junk)
valid_name = st.sampled_from(["a", "b", "c"])
name = st.one_of(valid_name, valid_name, valid_name, st.sampled_from(["", "x y", "1st", "nobody"]), junk)
pose = st.one_of(st.just("stand"), st.just("stand"), st.sampled_from(["sit", "carry", "walk", "dance", ""]), junk)
marker = st.one_of(st.sampled_from(["/World/Seats/s01", "/World/Boxes/b01"]),
                   st.sampled_from(["/World/Seats/s01", "/World/Boxes/b01", "/World/Seats/none", ""]), junk)
good_dt = st.floats(0.02, 0.27)
real_dt = st.one_of(good_dt, good_dt, good_dt, good_dt, st.just(1 / 30), floats, junk)

command = st.one_of(
    st.tuples(st.just("spawn"), name, xz, heading, pose),
    st.tuples(st.just("spawn"), valid_name, good_xz, st.floats(-3, 3), st.just("stand")),
    st.tuples(st.just("remove"), name),
    st.tuples(st.just("go_to"), name, xz, heading, window, st.one_of(st.booleans(), junk)),
    st.tuples(st.just("go_to"), valid_name, good_xz, st.none(), st.none(), st.just(False)),
    st.tuples(st.just("go_to"), valid_name, good_xz, st.floats(-3, 3), st.tuples(st.floats(0, 8), st.floats(8, 20)),
              st.booleans()),
    st.tuples(st.just("sit"), name, marker),
    st.tuples(st.just("stand"), name),
    st.tuples(st.just("pick_up"), name, marker),
    st.tuples(st.just("put_down"), name, xz, heading),
    st.tuples(st.just("meet"), st.one_of(st.lists(name, max_size=3), junk), xz, st.one_of(st.floats(0, 30), junk)),
    st.tuples(st.just("step"), real_dt),
    st.tuples(st.just("step"), real_dt),
    st.tuples(st.just("poses"), st.one_of(st.none(), st.floats(0, 1), floats, junk)),
    st.tuples(st.just("position"), name),
    st.tuples(st.just("state"), name),
    st.tuples(st.just("budget"), st.one_of(st.floats(0, 0.01), floats, junk)),
)


def _snapshot(w):
    pb = w.playback
    return (list(w.names), sorted(w.crowd.chars), len(w.crowd.commands), w.frame, pb.active.copy(),
            pb.buf_root.copy(), pb.head.copy(), pb.tail.copy(), w.budget, len(w.events))


def _same(a, b):
    return all(np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y for x, y in zip(a, b))


def _call(w, cmd):
    kind, *a = cmd
    if kind == "spawn":
        return w.spawn(*a)
    if kind == "remove":
        return w.remove(*a)
    if kind == "go_to":
        return w.go_to(a[0], a[1], heading=a[2], arrive=a[3], queue=a[4])
    if kind in ("sit", "pick_up"):
        return getattr(w, kind)(*a)
    if kind == "stand":
        return w.stand(*a)
    if kind == "put_down":
        return w.put_down(a[0], a[1], heading=a[2])
    if kind == "meet":
        return w.meet(*a)
    if kind == "poses":
        return w.poses(alpha=a[0])
    if kind == "position":
        return w.position(*a)
    if kind == "state":
        return w.state(*a)
    if kind == "budget":
        w.budget = a[0]
        return None
    raise AssertionError(kind)


def _no_nan_state(w):
    pb = w.playback
    act = np.flatnonzero(pb.active)
    assert np.all(np.isfinite(pb.buf_root[act])), "NaN or inf in a character's buffered root"
    assert np.all(np.isfinite(w.root_states()))
    p = w.poses()
    assert p.shape[0] == len(w.names) and np.all(np.isfinite(p))
    assert math.isfinite(w.time) and math.isfinite(w.alpha) and math.isfinite(w.budget)


advance = st.one_of(st.tuples(st.just("step"), real_dt), st.tuples(st.just("run"), st.integers(1, 45)))


@settings(max_examples=500, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large,
                                 HealthCheck.function_scoped_fixture])
@given(cmds=st.lists(st.tuples(command, advance), min_size=1, max_size=10))
def test_random_command_sequences(world_factory, cmds):
    w = world_factory()
    w.spawn("a", (0.0, 0.0))
    w.spawn("b", (3.0, 1.0), heading=1.0)
    ticks = 0
    for cmd in (c for pair in cmds for c in pair):
        if cmd[0] == "run":                       # a stretch of frames at 30 Hz
            for _ in range(cmd[1]):
                ticks += w.step(1 / 30)
        elif cmd[0] == "step":
            n = w.step(cmd[1])                    # never raises
            assert isinstance(n, int) and 0 <= n <= 8
            ticks += n
            event("step ran" if n else "step ran no tick")
        else:
            before = _snapshot(w)
            try:
                out = _call(w, cmd)
            except DOCUMENTED as e:
                event(f"{cmd[0]}: {type(e).__name__}")
                assert str(e), "an error says what is wrong"
                assert _same(before, _snapshot(w)), f"{cmd[0]} raised {e!r} but changed the World"
            else:
                event(f"{cmd[0]}: ok")
                if cmd[0] == "poses":
                    assert np.all(np.isfinite(out))
        _no_nan_state(w)
    event(f"ticks {min(ticks, 100) // 25 * 25}+")
    event(f"plans done {min(w.stats['plans_done'], 3)}")
