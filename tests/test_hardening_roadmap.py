"""Roadmaps over many obstacles: the obstacle grid finds exactly the pairs a brute-force test
finds, and the grid paths of ``Environment.distance`` / ``segment_clear`` agree with the dense
ones (bench/roadmap_scale.py measures the speed)."""
import numpy as np
import pytest

import runtime.crowd.environment as environment
from runtime.crowd.environment import Environment
from runtime.crowd.geometry import BoxGrid, convex_hull


def _brute(lo, hi, qlo, qhi):
    ov = np.all((lo[None] <= qhi[:, None]) & (hi[None] >= qlo[:, None]), axis=2)
    return set(zip(*np.nonzero(ov)))


@pytest.mark.parametrize("seed", range(6))
def test_box_grid_reports_every_overlapping_pair_once(seed):
    rng = np.random.default_rng(seed)
    k = int(rng.integers(1, 400))
    c = rng.uniform(-50, 50, (k, 2))
    size = rng.exponential(1.5, (k, 2)) * (rng.random((k, 1)) < 0.97) + (rng.random((k, 1)) < 0.03) * 60
    lo, hi = c - size / 2, c + size / 2
    n = 300
    q = rng.uniform(-80, 80, (n, 2))
    qs = rng.exponential(2.0, (n, 2))
    qs[::37] = 500.0                     # queries larger than the grid: tested against every box
    qs[::41] = 0.0                       # points
    qlo, qhi = q - qs, q + qs
    grid = BoxGrid(lo, hi)
    got = []
    for rows, ids in grid.pairs(qlo, qhi, budget=257):
        assert np.all(np.diff(rows) >= 0)
        got += list(zip(rows.tolist(), ids.tolist()))
    assert len(got) == len(set(got))
    assert set(got) == _brute(lo, hi, qlo, qhi)


def _many_obstacles(seed, n=300, side=60.0):
    rng = np.random.default_rng(seed)
    polys = [convex_hull(rng.uniform(0, side, 2) + rng.normal(size=(8, 2)) * rng.uniform(0.2, 1.5))
             for _ in range(n)]
    circles = np.c_[rng.uniform(0, side, (n // 3, 2)), rng.uniform(0.1, 1.0, n // 3)]
    return Environment(polys, circles), rng


@pytest.mark.parametrize("seed", range(3))
def test_grid_paths_agree_with_the_dense_paths(seed, monkeypatch):
    env, rng = _many_obstacles(seed)
    pts = rng.uniform(-5, 65, (5000, 2))
    a = rng.uniform(-5, 65, (4000, 2))
    b = a + rng.normal(size=(4000, 2)) * rng.choice([0.5, 3.0, 40.0], size=(4000, 1))
    r = rng.uniform(0.0, 0.8, 4000)
    d, i = env.distance(pts, return_index=True)
    clear = env.segment_clear(a, b, r)
    monkeypatch.setattr(environment, "_DENSE_LIMIT", 1 << 62)    # every query through the dense path
    dense = Environment(env.polygons, env.circles)
    d0, i0 = dense.distance(pts, return_index=True)
    np.testing.assert_allclose(d, d0, rtol=0, atol=1e-12)   # the two paths round differently
    assert np.mean(i == i0) > 0.999          # equal distances may name either obstacle
    np.testing.assert_array_equal(clear, dense.segment_clear(a, b, r))
    assert 0.05 < clear.mean() < 0.95        # both outcomes occur


def test_distance_of_points_that_are_not_finite_is_nan():
    env, _ = _many_obstacles(0, n=100)
    p = np.random.default_rng(1).uniform(0, 60, (2000, 2))
    p[5] = np.nan
    p[7, 0] = np.inf
    d, i = env.distance(p, return_index=True)
    assert np.isnan(d[5]) and np.isnan(d[7]) and i[5] == i[7] == -1
    assert np.all(np.isfinite(np.delete(d, [5, 7])))
