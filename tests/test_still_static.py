"""Characters who stay put for a whole segment are obstacles of the search's static filter
(``CrowdPolicy.still_static``): the discs (``Reservations.still``), the clearance grid with them
(``clearance.with_discs``) and the segment planner that hands it to the search."""
import numpy as np
import pytest

from runtime.crowd import clearance
from runtime.crowd.clearance import Clearance, with_discs
from runtime.crowd.environment import Environment
from runtime.crowd.planner import Config, Goal, MotionLibrary, SegmentPlanner, kernels, run_to_completion
from runtime.crowd.planner.costs import pairs_static_clear
from runtime.crowd.reservations import Reservations


def _static():
    env = Environment([[[1.0, 1.0], [3.0, 1.0], [3.0, 4.0], [1.0, 4.0]]], [])
    sdf = env.sdf(resolution=0.05, margin=2.0)
    return Clearance(sdf, sdf.max_error)


def test_the_grid_with_discs_reads_the_distance_to_walls_and_discs():
    """Within the pad round each disc the grid reads min(walls, disc) up to the grid's error,
    and nowhere less; outside the square it writes round each disc, the walls' grid is
    unchanged."""
    base = _static()                                   # the grid covers x -1..5, z -1..6
    xz, r = np.array([[-0.5, 5.0], [4.5, 0.0]]), np.array([0.3, 0.4])
    still = with_discs(base, xz, r, pad=1.0)
    rng = np.random.default_rng(3)
    pts = rng.uniform((-1.0, -1.0), (5.0, 6.0), (4000, 2))
    disc = np.min(np.hypot(pts[:, None, 0] - xz[:, 0], pts[:, None, 1] - xz[:, 1]) - r, axis=1)
    want = np.minimum(base.grid.sample(pts), disc)      # the grid's own values, before the offset
    near = disc < 1.0
    assert near.sum() > 200 and (~near).sum() > 200
    np.testing.assert_allclose(still.grid.sample(pts)[near], want[near], atol=base.grid.max_error + 1e-9)
    assert np.all(still.grid.sample(pts) >= want - base.grid.max_error - 1e-9)
    each = np.hypot(pts[:, None, 0] - xz[:, 0], pts[:, None, 1] - xz[:, 1])
    far = np.all(each > (r + 1.0) * np.sqrt(2.0) + 2 * base.grid.resolution, axis=1)
    assert far.sum() > 200
    np.testing.assert_array_equal(still(pts)[far], base(pts)[far])
    assert np.all(still(xz) < 0)                       # inside each disc
    assert base.grid.values.min() > -1.1               # the walls' own grid is not written to


def test_the_compiled_filter_reads_the_discs_as_the_sample_by_sample_test_does(default_graph, random_pairs):
    """The compiled static filter passes a whole clip when its start is farther from every
    obstacle than its samples reach; with discs written only within a pad of each, it still
    decides every pair as the sample-by-sample test does, and the discs take pairs out."""
    if not (kernels.AVAILABLE and clearance.AVAILABLE):
        pytest.skip("numba is not installed: only the numpy paths exist")
    g = default_graph
    lib = MotionLibrary(g)
    base = _static()
    pad = float(lib.samp_reach.max()) + 4 * base.offset + 0.5
    still = with_discs(base, np.array([[0.0, 0.5], [-0.5, 4.0], [4.0, 5.0]]), np.array([0.3, 0.3, 0.4]), pad)
    rng = np.random.default_rng(11)
    P = 300
    F, B, i, j = random_pairs(rng, P, 14)
    start, goal = np.array([-1.0, -1.0, 0.4]), np.array([0.0, 5.5, 2.0])
    fast = pairs_static_clear(lib, still, 0.02, F, B, i, j, start, goal, slack=0.1)
    plain = pairs_static_clear(lib, lambda q: still(q), 0.02, F, B, i, j, start, goal, slack=0.1)
    walls = pairs_static_clear(lib, base, 0.02, F, B, i, j, start, goal, slack=0.1)
    assert np.array_equal(fast, plain)
    assert not np.any(fast & ~walls)                   # discs only take pairs out
    assert np.sum(walls & ~fast) >= 10                 # ... and they do


def test_still_lists_the_held_starts_and_the_characters_who_stop_for_good():
    idx = Reservations(cell=1.6, n_frames=300)
    walk = np.stack([np.linspace(0.0, 5.0, 100), np.zeros(100)], axis=1)
    idx.insert(0, np.arange(300), np.concatenate([walk, np.tile([[5.0, 0.0]], (200, 1))]), 0.3)
    idx.insert(1, np.arange(300), np.concatenate([np.tile([[-4.0, 0.0]], (150, 1)),
                                                  np.stack([np.linspace(-4.0, -9.0, 150), np.zeros(150)], 1)]), 0.3)
    idx.hold(2, (0.0, 3.0), 0.35, until=300)
    xz, r = idx.still(50)                              # the walker is still walking; the other leaves later
    assert xz.tolist() == [[0.0, 3.0]] and r.tolist() == [0.35]
    xz, r = idx.still(120)
    assert sorted(map(tuple, np.round(xz, 3))) == [(0.0, 3.0), (5.0, 0.0)]
    assert np.allclose(sorted(r), [0.3, 0.35])
    xz, _ = idx.still(120, ignore_owner=2)
    assert np.round(xz, 3).tolist() == [[5.0, 0.0]]
    idx.release_hold(2)
    assert len(idx.still(120, ignore_owner=0)[0]) == 0


def test_a_segment_search_sees_who_stays_put_but_not_who_stands_at_its_ends(default_graph):
    """The planner hands the search a clearance with the disc of someone standing on the way
    for the whole segment; someone standing at the goal is left to the final test."""
    lib = MotionLibrary(default_graph)
    base = _static()
    planner = SegmentPlanner(lib, static=base)
    planner.still = lambda f: (np.array([[-0.5, 2.5], [-0.5, 5.5]]), np.array([0.3, 0.3]))
    node = int(default_graph.nodes_with_label("stand")[0])
    start = Config(node, -0.5, -0.5, 0.0, 0)
    goal = Goal(np.array([-0.5, 5.5]), 0.0)
    run_to_completion(planner.run(start, goal, np.random.default_rng(0), n_max=1))
    still = planner.collider.still_static
    assert still is not None
    on_way, at_goal = still(np.array([[-0.5, 2.5], [-0.5, 5.5]]))
    assert on_way < -0.2
    assert at_goal == pytest.approx(base(np.array([[-0.5, 5.5]]))[0])
    planner.still = None
    run_to_completion(planner.run(start, goal, np.random.default_rng(0), n_max=1))
    assert planner.collider.still_static is None
