"""Way points bent around characters who stand still (runtime.crowd.planner.bend)."""
import numpy as np

from runtime.crowd.planner.bend import BEND_EXTRA, bend_around


def _seg_dist(p, a, b):
    ab = b - a
    t = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
    return float(np.hypot(*(p - (a + t * ab))))


def _min_clearance(pts, c):
    return min(_seg_dist(c, pts[i], pts[i + 1]) for i in range(len(pts) - 1))


def test_a_disc_on_the_way_is_passed_on_the_side_the_path_already_passes():
    pts = np.array([[0.0, 0.0], [10.0, 0.0]])
    c, r, radius = np.array([5.0, 0.2]), 0.3, 0.5
    out = bend_around(pts, c[None], [r], radius)
    assert len(out) == 3 and np.array_equal(out[0], pts[0]) and np.array_equal(out[-1], pts[-1])
    assert out[1][1] < 0                                  # the path passed below the centre
    assert np.isclose(np.hypot(*(out[1] - c)), r + radius + BEND_EXTRA)
    assert _min_clearance(out, c) >= r + radius - 1e-9    # it was 0.2 m from the centre
    # a disc clear of the path, or none at all: the points as they were
    assert bend_around(pts, [[5.0, 3.0]], [r], radius) is pts
    assert bend_around(pts, np.zeros((0, 2)), [], radius) is pts


def test_discs_beside_the_start_or_the_goal_are_left_alone():
    pts = np.array([[0.0, 0.0], [10.0, 0.0]])
    out = bend_around(pts, [[0.6, 0.1], [9.5, -0.2]], [0.3, 0.3], 0.5)
    assert np.array_equal(out, pts)


class _Wall:
    """An obstacle filling z < -0.5 (signed distance and segment test)."""

    def distance(self, p):
        return np.asarray(p)[:, 1] + 0.5

    def segment_clear(self, a, b, r):
        return min(a[1], b[1]) + 0.5 >= r


def test_the_other_side_is_taken_when_an_obstacle_is_there():
    pts = np.array([[0.0, 0.0], [10.0, 0.0]])
    c = np.array([5.0, 0.1])
    free = bend_around(pts, c[None], [0.3], 0.5)
    walled = bend_around(pts, c[None], [0.3], 0.5, env=_Wall())
    assert free[1][1] < 0 < walled[1][1]
    assert _min_clearance(walled, c) >= 0.8 - 1e-9


def test_several_discs_in_a_row_are_each_passed():
    pts = np.array([[0.0, 0.0], [12.0, 0.0]])
    discs = np.array([[3.0, 0.1], [6.0, -0.1], [9.0, 0.05]])
    out = bend_around(pts, discs, [0.3] * 3, 0.5)
    assert len(out) == 5
    for c in discs:
        assert _min_clearance(out, c) >= 0.8 - 1e-9
