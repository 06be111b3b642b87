"""Promotion in the first pass (``CrowdPolicy.promote``, ``scheduler._promote``): a character that
fails because someone not planned yet stands in its way has that someone planned first."""
import numpy as np

from authoring.roadmap import build_roadmap
from runtime.crowd.checker import check_crowd
from runtime.crowd.environment import Environment
from runtime.crowd.planner import CrowdPolicy
from runtime.crowd.scenario import parse_scenario
from runtime.crowd.scheduler import plan_scenario


def _char(name, start, goal):
    return {"name": name, "start": {"position": list(start), "heading": 90.0, "pose": "stand"},
            "goal": [{"position": list(goal)}]}


def _door(half_width: float = 0.8):
    """A long wall at x = 1 with a door of ``2 * half_width`` m round z = 0, and its roadmap."""
    w = half_width
    env = Environment(polygons=[np.array([[0.85, w], [1.15, w], [1.15, 30.0], [0.85, 30.0]]),
                                np.array([[0.85, -30.0], [1.15, -30.0], [1.15, -w], [0.85, -w]])])
    return env, build_roadmap(env, seed=0)


def test_a_start_in_a_doorway_is_planned_before_the_one_it_blocks(default_graph):
    """A long wall at x = 1 with a 1.6 m door; ``leaver`` starts in the door and walks out,
    ``walker`` (first in the file) must pass through it. Planned in the file's order the
    walker meets the leaver's held start and gives its goal up; with promotion the leaver is
    planned first and both arrive, clear of each other and of the wall."""
    env, roadmap = _door()
    sc = parse_scenario({"name": "door", "duration": 40.0, "seed": 0,
                         "character": [_char("walker", (-6.0, 0.0), (8.0, -3.0)),
                                       _char("leaver", (1.0, 0.0), (8.0, 3.0))]})
    plain = plan_scenario(sc, default_graph, env, roadmap, policy=CrowdPolicy(passes=1))
    assert plain.by_name("walker").warnings and not plain.by_name("leaver").warnings
    said = []
    res = plan_scenario(sc, default_graph, env, roadmap, policy=CrowdPolicy(passes=1, promote=True), log=said.append)
    assert any("walker: planning leaver first" in m for m in said)
    assert not res.by_name("walker").warnings and not res.by_name("leaver").warnings
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, default_graph, env, res.fps)
    assert rep.passed and not rep.character_overlaps and not rep.obstacle_overlaps


def test_a_promotion_that_does_not_help_is_undone(default_graph):
    """The leaver's goal is in the door too: planned first it still closes the way, so the
    walker's first plan is put back and the leaver is planned in its turn, as without promotion.
    Standing in the middle of the 1.6 m door, it leaves too little room on either side for a
    walker's cylinder."""
    env, roadmap = _door()
    sc = parse_scenario({"name": "door", "duration": 40.0, "seed": 0,
                         "character": [_char("walker", (-6.0, 0.0), (8.0, -3.0)),
                                       _char("stayer", (1.0, 0.0), (1.0, 0.0))]})
    plain = plan_scenario(sc, default_graph, env, roadmap, policy=CrowdPolicy(passes=1))
    said = []
    res = plan_scenario(sc, default_graph, env, roadmap, policy=CrowdPolicy(passes=1, promote=True), log=said.append)
    assert any("walker: planning stayer first" in m for m in said)
    a, b = plain.by_name("walker"), res.by_name("walker")
    assert a.warnings and b.warnings
    assert np.array_equal(a.track.root, b.track.root)
    assert res.order == plain.order
    assert bool(res.by_name("stayer").warnings) == bool(plain.by_name("stayer").warnings)
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, default_graph, env, res.fps)
    assert not rep.character_overlaps and not rep.obstacle_overlaps
