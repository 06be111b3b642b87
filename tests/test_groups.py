"""Interaction groups planned apart (runtime.crowd.scheduler: planning_groups, the workers,
mend_between_groups)."""
import numpy as np

from runtime.crowd import scheduler
from runtime.crowd.checker import check_crowd
from runtime.crowd.planner import CrowdPolicy
from runtime.crowd.scenario import parse_scenario
from runtime.crowd.scheduler import plan_scenario


def _char(name, start, goal, heading=0.0):
    return {"name": name, "start": {"position": list(start), "heading": heading, "pose": "stand"},
            "goal": [{"position": list(goal)}]}


def _scenario(chars, duration=20.0):
    return parse_scenario({"name": "groups", "duration": duration, "seed": 3, "character": chars})


def _bytes(res):
    return b"".join(a.tobytes() for c in res.characters
                    for a in (c.track.root, c.track.frames_a, c.track.frames_b, c.track.frames_t))


def test_groups_far_apart_plan_the_same_bytes_in_one_process_or_two(default_graph):
    """Two crossings 40 m apart are two groups; planned in forked workers or one after the
    other in this process, every track is the same, and the CPU counts the workers'."""
    sc = _scenario([_char("a", (0.0, 0.0), (6.0, 0.0), 1.57), _char("b", (3.0, -3.0), (3.0, 3.0)),
                    _char("c", (40.0, 0.0), (46.0, 0.0), 1.57), _char("d", (43.0, -3.0), (43.0, 3.0))])
    one = plan_scenario(sc, default_graph, policy=CrowdPolicy(workers=1))
    two = plan_scenario(sc, default_graph, policy=CrowdPolicy(workers=2))
    assert one.groups == two.groups == 2
    assert _bytes(one) == _bytes(two)
    assert two.cpu_seconds > 0.0
    together = plan_scenario(sc, default_graph, policy=CrowdPolicy(split_groups=False))
    assert together.groups == 1


def test_characters_of_groups_that_meet_are_planned_again_against_everyone(default_graph, monkeypatch):
    """Two characters swapping places head-on, forced into groups of their own, are planned
    blind to each other and meet; the merge plans them again against everyone, and the crowd
    has no overlapping pair."""
    sc = _scenario([_char("east", (0.0, 0.0), (8.0, 0.0), 1.57), _char("west", (8.0, 0.2), (0.0, 0.2), -1.57)])
    monkeypatch.setattr(scheduler, "planning_groups", lambda sc, env, roadmap, order, static=None: [[0], [1]])
    lines = []
    res = plan_scenario(sc, default_graph, policy=CrowdPolicy(workers=1), log=lines.append)
    assert res.groups == 2
    assert any(line.startswith("groups meet: planning east, west again") for line in lines)
    report = check_crowd(sc, {c.name: c.track for c in res.characters}, default_graph, None, res.fps)
    assert report.summary()["character_overlap_pairs"] == 0
