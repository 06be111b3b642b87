"""A splice within eps that fails the final test is tried at other durations only where timing can
matter (``RandomizedSearch._timing_may_help``): a character met on the way, not a wall, and not a
motion that ends in the way."""
import numpy as np

from runtime.crowd.clearance import Clearance
from runtime.crowd.environment import Environment
from runtime.crowd.planner import Config, MotionLibrary, SegmentPlanner
from runtime.crowd.planner.search import RandomizedSearch
from runtime.crowd.planner.types import SegmentResult


def _line(z, n=60):
    root = np.zeros((n, 3))
    root[:, 0] = np.linspace(-1.0, 5.0, n)
    root[:, 1] = z
    f = np.zeros(n, np.int64)
    end = Config(0, float(root[-1, 0]), float(root[-1, 1]), 0.0, n - 1)
    return SegmentResult(True, f, f, np.zeros(n, np.float32), root, 0, end, 0.0, (0.0, 0.0, 0.0), 0, [0])


def test_only_a_character_met_on_the_way_is_worth_other_durations(default_graph):
    env = Environment([[[1.0, 1.0], [3.0, 1.0], [3.0, 4.0], [1.0, 4.0]]], [])
    sdf = env.sdf(resolution=0.05, margin=2.0)
    met = {"at": -1}                       # the sample a planned character is met at (-1: nobody)

    def first(f, xz, r):
        return met["at"] if met["at"] < len(xz) else -1
    lib = MotionLibrary(default_graph)
    planner = SegmentPlanner(lib, static=Clearance(sdf, sdf.max_error), collide=lambda f, xz, r: np.zeros(len(f), bool),
                             collide_first=first)
    search = RandomizedSearch(lib, lib.params, planner.collider, False, Config(0, -1.0, 2.5, 0.0, 0),
                              np.array([5.0, 2.5, 0.0]), 0, [], [], None, np.random.default_rng(0), 1)
    through_wall = _line(2.5)              # crosses the box x 1..3, z 1..4
    hit = planner.final_collision(through_wall)
    assert hit is not None and 0 < hit < len(through_wall.root)
    assert not search._timing_may_help(through_wall, hit)
    beside = _line(6.0)                    # clear of the wall ...
    assert planner.final_collision(beside) is None
    met["at"] = 20                         # ... but someone planned is met there
    hit = planner.final_collision(beside)
    assert hit == 20
    assert search._timing_may_help(beside, hit)
    # ending in the way (past the deadline, or standing at the goal afterwards)
    assert not search._timing_may_help(beside, len(beside.root))


def test_a_window_of_frames_hit_is_a_final_test_hit(default_graph):
    """``Collider.hits_between`` tests part of what the final test does: a hit in the window is a
    hit of the whole motion, and a window before the first hit is clear."""
    env = Environment([[[1.0, 1.0], [3.0, 1.0], [3.0, 4.0], [1.0, 4.0]]], [])
    sdf = env.sdf(resolution=0.05, margin=2.0)
    planner = SegmentPlanner(MotionLibrary(default_graph), static=Clearance(sdf, sdf.max_error))
    line = _line(2.5)                      # into the box x 1..3 about a third of the way
    hit = planner.final_collision(line)
    assert hit is not None and 5 < hit < len(line.root) - 5
    col = planner.collider
    assert col.hits_between(line, hit - 2, hit + 3)
    assert col.hits_between(line, hit, hit + 1)
    assert not col.hits_between(line, 0, hit)
    assert not col.hits_between(line, hit + 100, hit + 110)   # beyond the motion: nothing to test
    assert planner.final_collision(_line(6.0)) is None and not col.hits_between(_line(6.0), 0, 60)
