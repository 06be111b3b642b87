"""Reuse of searched motions between characters with the same task (runtime.crowd.planner.motion_cache).

Whether a reused plan is right is the independent checker's call (goal, window, per-frame
adjustment, overlaps from the tracks); the planner's counters only say which path it took."""
import math

import numpy as np

from runtime.crowd.checker import check_crowd
from runtime.crowd.planner import Config, CrowdPolicy, Goal, SegmentResult
from runtime.crowd.planner.motion_cache import QUANTUM, MotionCache, task_key
from runtime.crowd.scenario import parse_scenario
from runtime.crowd.scheduler import plan_scenario
from runtime.crowd.tracks import Track


def _scenario(chars, duration=20.0):
    out = []
    for k, (sx, sz, h, gx, gz) in enumerate(chars):
        out.append({"name": f"c{k}", "start": {"position": [sx, sz], "heading": h, "pose": "stand"},
                    "goal": [{"position": [gx, gz]}]})
    return parse_scenario({"name": "reuse", "duration": duration, "seed": 0, "synthesis": {"start_still": True},
                           "character": out})


def _check(sc, res, graph, replace=None):
    rep = check_crowd(sc, {c.name: c.track for c in res.characters} | (replace or {}), graph)
    return rep.summary()


def test_task_key_is_the_task_in_the_starts_frame():
    a = task_key(Config(3, 0.0, 0.0, 0.0, 0), Goal(np.array([0.0, 10.0])), 30.0)
    # the same task turned by 90 deg about +Y (heading 0 = +Z, 90 = +X) and moved, later in time
    b = task_key(Config(3, 5.0, -2.0, math.pi / 2, 40), Goal(np.array([15.0, -2.0])), 30.0)
    assert a == b
    assert task_key(Config(3, 0.0, 0.0, 0.0, 0), Goal(np.array([0.0, 10.1])), 30.0) != a
    assert task_key(Config(4, 0.0, 0.0, 0.0, 0), Goal(np.array([0.0, 10.0])), 30.0) != a
    # windows count relative to the start
    w1 = task_key(Config(3, 0.0, 0.0, 0.0, 0), Goal(np.array([0.0, 10.0]), window=(8.0, 9.0)), 30.0)
    w2 = task_key(Config(3, 1.0, 0.0, 0.0, 60), Goal(np.array([1.0, 10.0]), window=(10.0, 11.0)), 30.0)
    w3 = task_key(Config(3, 1.0, 0.0, 0.0, 60), Goal(np.array([1.0, 10.0]), window=(8.0, 9.0)), 30.0)
    assert w1 == w2 != w3 and w1 != a


def test_a_stored_motion_placed_elsewhere_keeps_its_shape_and_meets_the_goal_exactly():
    rng = np.random.default_rng(1)
    m = 50
    steps = np.cumsum(rng.normal(0, 0.05, (m, 3)), axis=0)
    steps -= steps[0]
    steps[:, :2] += np.linspace(0, 1, m)[:, None] * (np.array([3.0, 4.0]) - steps[-1, :2])   # ends on the key's grid
    s0 = Config(2, 0.0, 0.0, 0.0, 10)
    root = steps + np.array([s0.x, s0.z, s0.heading])
    end = Config(7, *root[-1], s0.frame + m - 1)
    res = SegmentResult(True, np.arange(m), np.arange(m) + 1, np.zeros(m, np.float32), root, s0.frame, end,
                        0.01, (0.01, 1.0, 0.0), 12, [4, 5])
    goal0 = Goal(root[-1, :2].copy(), float(root[-1, 2]))
    cache = MotionCache()
    key = task_key(s0, goal0, 30.0)
    cache.store(key, s0, res)
    # the same task from a start turned by 1.4 rad and moved far away; the goal off the exact
    # image by 0.3 x QUANTUM in x and z, which the key rounds away
    s1 = Config(2, -40.0, 75.0, 1.4, 0)
    d = root[-1, :2] - root[0, :2]
    c, s = math.cos(1.4), math.sin(1.4)
    image = np.array([s1.x + c * d[0] + s * d[1], s1.z - s * d[0] + c * d[1]])
    goal1 = Goal(image + 0.3 * QUANTUM, float(root[-1, 2]) + 1.4)
    assert task_key(s1, goal1, 30.0) == key
    (k, placed), = list(cache.candidates(key, s1, goal1))
    assert k == 0 and placed.start_frame == 0 and placed.end.frame == m - 1 and placed.end.node == 7
    np.testing.assert_allclose(placed.root[0], [s1.x, s1.z, s1.heading], atol=1e-9)
    np.testing.assert_allclose(placed.root[-1, :2], goal1.position, atol=1e-12)
    assert abs(placed.root[-1, 2] - goal1.heading) < 1e-12
    # rigid: the distances between frames are the stored motion's (to the rounding's correction)
    dd0 = np.linalg.norm(np.diff(root[:, :2], axis=0), axis=1)
    dd1 = np.linalg.norm(np.diff(placed.root[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(dd1, dd0, atol=2 * QUANTUM / (m - 1))
    np.testing.assert_allclose(np.diff(placed.root[:, 2]), np.diff(root[:, 2]), atol=1e-12)
    np.testing.assert_array_equal(placed.frames_a, res.frames_a)
    # a later store goes first; more than per_task drops the oldest
    small = MotionCache(per_task=2)
    for _ in range(3):
        small.store(key, s0, res)
    assert len(small) == 2


def test_side_by_side_characters_reuse_one_motion(default_graph):
    # 4 m apart, each walk is an interaction group of its own, and groups planned apart keep
    # their own caches: planned as one group, the three share one
    sc = _scenario([(0.0, 0.0, 90.0, 10.0, 0.0), (0.0, 4.0, 90.0, 10.0, 4.0), (0.0, -4.0, 90.0, 10.0, -4.0)])
    apart = plan_scenario(sc, default_graph)
    assert (apart.groups, apart.reused) == (3, 0)
    res = plan_scenario(sc, default_graph, policy=CrowdPolicy(split_groups=False))
    assert (res.reused, res.searched) == (2, 1)
    s = _check(sc, res, default_graph)
    assert s["passed"], s
    # the three walks are one motion, moved: same clips, same shape
    a, b = res.characters[0].track, res.characters[1].track
    np.testing.assert_array_equal(a.frames_a, b.frames_a)
    np.testing.assert_allclose(b.root[:, 1] - a.root[:, 1], 4.0, atol=1e-9)
    res_off = plan_scenario(sc, default_graph, policy=CrowdPolicy(reuse_motions=False))
    assert (res_off.reused, res_off.searched) == (0, 0)
    assert _check(sc, res_off, default_graph)["passed"]


def test_a_reused_motion_that_would_collide_is_searched_instead(default_graph):
    # the same task (10 m straight ahead) head-on along one line: the first character's motion,
    # turned round, walks into it, so the second must search for its own
    sc = _scenario([(0.0, 0.0, 90.0, 10.0, 0.0), (10.0, 0.3, -90.0, 0.0, 0.3)])
    res = plan_scenario(sc, default_graph)
    assert (res.reused, res.searched) == (0, 2)
    s = _check(sc, res, default_graph)
    assert s["passed"] and s["character_overlap_pairs"] == 0, s
    # ... and the stored motion, placed for the second, does collide (the test is not vacuous)
    first = res.characters[0].track
    root = np.stack([10.0 - first.root[:, 0], 0.3 - first.root[:, 1], first.root[:, 2] + np.pi], axis=1)
    turned = Track(first.frames_a, first.frames_b, first.frames_t, root, first.start_frame)
    s2 = _check(sc, res, default_graph, {"c1": turned})
    assert s2["character_overlap_pairs"] == 1
