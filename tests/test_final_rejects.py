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
