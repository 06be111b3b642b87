"""The planning order chosen by the stand-in lattice plan (runtime.crowd.priorities)."""
import numpy as np

from authoring.roadmap import build_roadmap
from runtime.crowd.checker import check_crowd
from runtime.crowd.clearance import Clearance
from runtime.crowd.environment import Environment
from runtime.crowd.planner import CrowdPolicy
from runtime.crowd.priorities import coarse_groups, interaction_groups, lattice_failures, route_legs
from runtime.crowd.scenario import parse_scenario
from runtime.crowd.scheduler import crowd_order, plan_scenario

FPS = 30.0


def _char(name, start, goal, time=None, after=None):
    g = {"position": list(goal)}
    if time is not None:
        g["time"] = list(time)
    if after is not None:
        g["after"] = {"character": after, "goal": 0, "within": [0.0, 5.0]}
    return {"name": name, "start": {"position": list(start), "heading": 90.0, "pose": "stand"}, "goal": [g]}


def _door(half_width: float = 0.8):
    """A long wall at x = 1 with a door of ``2 * half_width`` m round z = 0, its roadmap and
    its clearance."""
    w = half_width
    env = Environment(polygons=[np.array([[0.85, w], [1.15, w], [1.15, 30.0], [0.85, 30.0]]),
                                np.array([[0.85, -30.0], [1.15, -30.0], [1.15, -w], [0.85, -w]])])
    sdf = env.sdf(resolution=0.05, margin=2.0)
    return env, build_roadmap(env, seed=0), Clearance(sdf, sdf.max_error)


def _door_scenario():
    """``stayer`` (first in the file) ends in the doorway and stays there; ``walker`` must pass
    through the door."""
    return parse_scenario({"name": "door", "duration": 40.0, "seed": 0,
                           "character": [_char("stayer", (-2.0, 2.5), (1.0, 0.0)),
                                         _char("walker", (-6.0, 0.0), (8.0, -3.0))]})


def test_a_goal_in_a_doorway_leaves_whoever_is_planned_after_it_without_a_route():
    env, roadmap, static = _door()
    sc = _door_scenario()
    legs = route_legs(sc, env, roadmap)
    n_total = int(sc.duration * FPS) + 1
    assert lattice_failures(sc, static, legs, [0, 1], FPS, n_total) == [1]
    assert lattice_failures(sc, static, legs, [1, 0], FPS, n_total) == []
    # alone, each has a route
    assert lattice_failures(sc, static, legs, [1], FPS, n_total) == []
    assert lattice_failures(sc, static, legs, [0], FPS, n_total) == []


def test_a_window_too_early_for_the_walk_has_no_route():
    env, roadmap, static = _door()
    n_total = int(40.0 * FPS) + 1
    sc = parse_scenario({"name": "early", "duration": 40.0, "seed": 0,
                         "character": [_char("quick", (-6.0, 0.0), (8.0, -3.0), time=(8.0, 9.0)),
                                       _char("easy", (-6.0, 0.0), (8.0, -3.0), time=(20.0, 22.0))]})
    legs = route_legs(sc, env, roadmap)
    assert lattice_failures(sc, static, legs, [0], FPS, n_total) == [0]
    assert lattice_failures(sc, static, legs, [1], FPS, n_total) == []


def test_groups_join_routes_in_sight_of_each_other_and_after_ties_but_not_through_a_wall():
    """``a`` and ``b`` walk beside each other 1.2 m apart (one group); ``c`` walks on the far
    side of the wall, 0.9 m from ``a``'s route through it, but never near the door (its own
    group); ``d`` is far from everyone but timed after ``c`` (joined to it)."""
    env, roadmap, _ = _door()
    sc = parse_scenario({"name": "groups", "duration": 40.0, "seed": 0,
                         "character": [_char("a", (0.4, 10.0), (0.4, 20.0)),
                                       _char("b", (-0.8, 10.0), (-0.8, 20.0)),
                                       _char("c", (1.6, 10.0), (1.6, 20.0), time=(15.0, 20.0)),
                                       _char("d", (20.0, -20.0), (25.0, -20.0), after="c")]})
    legs = route_legs(sc, env, roadmap)
    groups = interaction_groups(sc, env, legs)
    assert groups == [[0, 1], [2, 3]]
    # without pairing points, the wall does not part c from a: one coarse union of the three
    # beside each other, d with its tie; among the union's members, the same groups as above
    coarse = coarse_groups(sc, legs)
    assert coarse == [[0, 1, 2, 3]]
    assert interaction_groups(sc, env, legs, coarse[0]) == [[0, 1], [2, 3]]


def test_coarse_groups_hold_every_interaction_group_and_part_routes_far_apart():
    """Routes 3 m apart fall in neighbouring 2 m squares (one coarse union) though no two of
    their points are within 2 m (two interaction groups); routes 9 m away are apart either way."""
    sc = parse_scenario({"name": "coarse", "duration": 40.0, "seed": 0,
                         "character": [_char("a", (0.0, 0.0), (0.0, 12.0)),
                                       _char("b", (3.0, 0.0), (3.0, 12.0)),
                                       _char("c", (12.0, 0.0), (12.0, 12.0))]})
    legs = route_legs(sc, None, None)
    assert interaction_groups(sc, None, legs) == [[0], [1], [2]]
    assert coarse_groups(sc, legs) == [[0, 1], [2]]


def test_the_lattice_order_plans_the_one_ending_in_the_door_last(default_graph):
    env, roadmap, static = _door()
    sc = _door_scenario()
    assert crowd_order(sc, "file") == [0, 1]
    said = []
    order = crowd_order(sc, "lattice", env, roadmap, static=static, log=said.append)
    assert order == [1, 0]
    assert any("2 characters from stayer" in m and "0 without a stand-in route" in m for m in said)
    plain = plan_scenario(sc, default_graph, env, roadmap, policy=CrowdPolicy(passes=1))
    assert plain.by_name("walker").warnings
    res = plan_scenario(sc, default_graph, env, roadmap, policy=CrowdPolicy(passes=1, order="lattice"))
    assert res.order == [1, 0]
    assert not res.by_name("walker").warnings and not res.by_name("stayer").warnings
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, default_graph, env, res.fps)
    assert rep.passed and not rep.character_overlaps and not rep.obstacle_overlaps


def test_a_group_larger_than_the_limit_keeps_the_file_order(monkeypatch):
    """Over ``MAX_GROUP`` characters in one group the stand-in is not run: the file order."""
    from runtime.crowd import priorities
    env, roadmap, static = _door()
    sc = _door_scenario()
    monkeypatch.setattr(priorities, "MAX_GROUP", 1)
    said = []
    assert crowd_order(sc, "lattice", env, roadmap, static=static, log=said.append) == [0, 1]
    assert any("file (more than 1 in one group)" in m for m in said)
