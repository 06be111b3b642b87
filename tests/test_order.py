"""Planning orders of the offline scheduler (runtime.crowd.scheduler.crowd_order)."""
import numpy as np
import pytest

from runtime.crowd.scenario import ScenarioError, parse_scenario
from runtime.crowd.scheduler import crowd_order, endpoint_precedence


def _char(name, start, goal, after=None):
    g = {"position": list(goal)}
    if after is not None:
        g["after"] = {"character": after, "goal": 0, "within": [0.0, 5.0]}
    return {"name": name, "start": {"position": list(start), "heading": 0.0, "pose": "stand"}, "goal": [g]}


def _scenario(chars):
    return parse_scenario({"name": "order", "duration": 30.0, "seed": 0, "character": chars})


def test_endpoints_on_a_route_give_the_precedence_that_keeps_the_way_open():
    """``walker`` crosses from x=0 to x=10 along z=0 (no roadmap: a straight route). ``leaver``
    starts 0.5 m beside that line: it should be planned before the walker (its held start is
    in the way until it leaves). ``stopper`` ends 0.6 m beside it: after the walker (standing
    there to the end would close the way). ``far`` is nowhere near anyone's route."""
    sc = _scenario([_char("walker", (0.0, 0.0), (10.0, 0.0)),
                    _char("leaver", (5.0, 0.5), (5.0, 8.0)),
                    _char("stopper", (8.0, -6.0), (7.0, -0.6)),
                    _char("far", (20.0, 20.0), (25.0, 20.0))])
    pairs = endpoint_precedence(sc)
    assert pairs == {(1, 0), (0, 2)}
    order = crowd_order(sc, "endpoints")
    assert order.index(1) < order.index(0) < order.index(2)
    assert sorted(order) == [0, 1, 2, 3]
    # 0.2 m of reach: nothing is near enough
    assert endpoint_precedence(sc, reach=0.2) == set()


def test_the_endpoint_order_keeps_after_constraints_and_breaks_cycles_by_fewest_unmet():
    """``b``'s goal is timed after ``a``'s arrival, so ``a`` comes first although ``b``'s start
    lies on ``a``'s route (a preference the other way). ``c`` and ``d`` each start on the
    other's route (a cycle): the one with fewer unmet preferences goes first, ties in file
    order."""
    sc = _scenario([_char("a", (0.0, 0.0), (10.0, 0.0)),
                    _char("b", (5.0, 0.3), (5.0, 9.0), after="a"),
                    _char("c", (0.0, 30.0), (10.0, 30.0)),
                    _char("d", (10.0, 30.3), (0.0, 30.3))])
    pairs = endpoint_precedence(sc)
    assert (1, 0) in pairs and (2, 3) in pairs and (3, 2) in pairs
    order = crowd_order(sc, "endpoints")
    assert order.index(0) < order.index(1)
    assert order.index(2) < order.index(3)


def test_an_unknown_order_is_a_clear_error():
    sc = _scenario([_char("a", (0.0, 0.0), (1.0, 0.0))])
    with pytest.raises(ScenarioError, match="unknown planning order 'random'"):
        crowd_order(sc, "random")
    assert crowd_order(sc, "endpoints") == [0]


def test_endpoint_routes_follow_the_roadmap_round_a_wall():
    """With an environment and its roadmap the routes go round obstacles: a start beside the
    straight line but behind a wall is not on the route, one beside the detour is."""
    from authoring.roadmap import build_roadmap
    from runtime.crowd.environment import Environment
    wall = np.array([[4.0, -3.0], [6.0, -3.0], [6.0, 3.0], [4.0, 3.0]])
    env = Environment(polygons=[wall])
    roadmap = build_roadmap(env, seed=0)
    sc = _scenario([_char("walker", (0.0, 0.0), (10.0, 0.0)),
                    _char("hidden", (7.0, 0.0), (7.0, 8.0))])
    straight = endpoint_precedence(sc)
    assert (1, 0) in straight        # a straight line would pass it
    routed = endpoint_precedence(sc, env, roadmap)
    way = roadmap.waypoints(env, np.array([0.0, 0.0]), np.array([10.0, 0.0]))
    assert np.abs(way[:, 1]).max() > 3.0           # the route goes round the wall
    assert (1, 0) not in routed


def test_only_endpoints_in_a_narrow_passage_count_when_the_environment_is_known():
    """In the open a walker steps round someone standing on its route; in a door it cannot.
    The same stopper 0.6 m beside the walker's line is in the way when a wall stands 1 m
    from the line there, and not when the nearest obstacle is far."""
    from runtime.crowd.environment import Environment
    sc = _scenario([_char("walker", (0.0, 0.0), (10.0, 0.0)),
                    _char("stopper", (7.0, -6.0), (7.0, -0.6))])
    far_wall = Environment(polygons=[np.array([[0.0, 20.0], [10.0, 20.0], [10.0, 21.0], [0.0, 21.0]])])
    near_wall = Environment(polygons=[np.array([[6.0, 1.0], [8.0, 1.0], [8.0, 2.0], [6.0, 2.0]])])
    assert endpoint_precedence(sc) == {(0, 1)}
    assert endpoint_precedence(sc, far_wall) == set()
    assert endpoint_precedence(sc, near_wall) == {(0, 1)}
    assert endpoint_precedence(sc, far_wall, narrow=None) == {(0, 1)}
