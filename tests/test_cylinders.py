"""Minimum bounding cylinders (runtime.motion.cylinders): exact circles, poses held inside,
blends placed as the checker places them."""
from itertools import combinations
from types import SimpleNamespace

import numpy as np

from runtime.crowd.checker import _cylinders as checker_cylinders
from runtime.crowd.tracks import Track
from runtime.motion.cylinders import blend_cylinders, enclosing_circles
from runtime.motion.fk import end_site_positions, forward_kinematics


def _brute_circle(P):
    """Smallest circle through 2 or 3 of the points holding them all (exhaustive)."""
    best = np.inf
    for i, j in combinations(range(len(P)), 2):
        c = 0.5 * (P[i] + P[j])
        best = min(best, np.max(np.hypot(*(P - c).T)))
    for i, j, k in combinations(range(len(P)), 3):
        a, b, d = P[i], P[j], P[k]
        den = 2 * ((b - a)[0] * (d - a)[1] - (b - a)[1] * (d - a)[0])
        if abs(den) < 1e-12:
            continue
        nb, nd = np.sum((b - a) ** 2), np.sum((d - a) ** 2)
        c = a + np.array([(d - a)[1] * nb - (b - a)[1] * nd, (b - a)[0] * nd - (d - a)[0] * nb]) / den
        best = min(best, np.max(np.hypot(*(P - c).T)))
    return best


def test_enclosing_circles_are_the_smallest_and_hold_every_point():
    rng = np.random.default_rng(4)
    # clusters like a body from above: a core plus a few far limbs
    pts = rng.normal(0.0, 0.1, (40, 12, 2))
    pts[:, :3] += rng.normal(0.0, 0.4, (40, 3, 2))
    c, r = enclosing_circles(pts)
    assert c.shape == (40, 2) and r.shape == (40,)
    d = np.hypot(pts[..., 0] - c[:, None, 0], pts[..., 1] - c[:, None, 1])
    assert np.all(d <= r[:, None] + 1e-12)
    brute = np.array([_brute_circle(p) for p in pts])
    np.testing.assert_allclose(r, brute, atol=1e-9)
    # collinear and repeated points: a diameter's circle
    c1, r1 = enclosing_circles(np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 0.0], [1.0, 0.0]]))
    np.testing.assert_allclose(c1, [0.5, 0.0], atol=1e-12)
    assert abs(r1 - 0.5) < 1e-12


def test_library_cylinders_hold_every_joint_and_are_tighter_than_about_the_root(default_graph):
    g = default_graph
    inside_worst = -np.inf
    for e in range(0, g.num_edges, 7):
        clip = g.edge_clip(e)
        pos, _ = clip.world_root(origin=np.zeros(3))
        gr, gp = forward_kinematics(clip.skeleton, pos, clip.local_rotations_world_root(np.zeros(3)))
        pts = np.concatenate([gp, end_site_positions(clip.skeleton, gr, gp)], axis=1)[..., [0, 2]]
        a, b = g.edge_start[e], g.edge_start[e + 1]
        centre, r = blend_cylinders(g, np.arange(a, b), np.arange(a, b),
                                    np.column_stack([clip.root_xz, clip.root_heading]))
        d = np.hypot(pts[..., 0] - centre[:, None, 0], pts[..., 1] - centre[:, None, 1]).max(axis=1)
        inside_worst = max(inside_worst, float(np.max(d - r)))
    # snapped and foot-corrected bodies both inside: the build's own clips are within float32 rounding
    assert inside_worst <= 1e-5
    about_root = np.sqrt(np.max(np.sum((pts - pos[:, None, [0, 2]]) ** 2, axis=-1), axis=1))
    assert np.all(r <= about_root + 2e-5)
    np.testing.assert_allclose(g.frame_reach[a:b], about_root, atol=2e-5)
    # the whole library: the circles are well inside those about the root
    reach = g.frame_reach
    assert np.all(g.frame_radius <= reach + 1e-6)
    assert np.all(reach <= np.hypot(*g.frame_axis.T) + g.frame_radius + 1e-5)
    assert np.median(g.frame_radius) < 0.85 * np.median(reach)


def test_blends_hold_both_frames_and_match_the_checker(default_graph):
    g = default_graph
    rng = np.random.default_rng(2)
    n = 500
    fa = rng.integers(0, len(g.frame_radius), n)
    fb = np.where(rng.random(n) < 0.5, np.minimum(fa + 1, len(g.frame_radius) - 1), rng.integers(0, len(g.frame_radius), n))
    root = np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-5, 5, n), rng.uniform(-np.pi, np.pi, n)])
    c, r = blend_cylinders(g, fa, fb, root)
    for f in (fa, fb):
        ca, ra = blend_cylinders(g, f, f, root)
        assert np.all(np.hypot(*(ca - c).T) + ra <= r + 1e-9)
    # the smallest such circle: the larger one, or the two side by side
    ca, ra = blend_cylinders(g, fa, fa, root)
    cb, rb = blend_cylinders(g, fb, fb, root)
    np.testing.assert_allclose(r, np.maximum(np.maximum(ra, rb), 0.5 * (np.hypot(*(cb - ca).T) + ra + rb)), atol=1e-9)
    # batches of any shape (numpy) place them as one run of frames (compiled when numba is there)
    c2, r2 = blend_cylinders(g, fa.reshape(5, -1), fb.reshape(5, -1), root.reshape(5, -1, 3))
    np.testing.assert_allclose(c2.reshape(-1, 2), c, atol=1e-12)
    np.testing.assert_allclose(r2.ravel(), r, atol=1e-12)
    tr = Track(fa, fb, np.zeros(n, np.float32), root, 0)
    kc, kr = checker_cylinders(g, tr, n)
    np.testing.assert_allclose(kc, c, atol=1e-9)
    np.testing.assert_allclose(kr, r, atol=1e-9)


def test_a_graph_without_axes_keeps_cylinders_about_the_root():
    g = SimpleNamespace(frame_radius=np.array([0.3, 0.5], np.float32))
    c, r = blend_cylinders(g, np.array([0, 1]), np.array([1, 1]), np.array([[1.0, 2.0, 0.3], [0.0, 0.0, 0.0]]))
    np.testing.assert_allclose(c, [[1.0, 2.0], [0.0, 0.0]])
    np.testing.assert_allclose(r, [0.5, 0.5])


def test_a_held_seat_holds_the_seated_clips_at_its_heading_in_a_smaller_disc(default_graph):
    """A seat held for a character not planned yet (scheduler.held_disc) holds every frame of
    the sitting clips as they play from the seat, placed by the seat's heading; it is smaller
    than the disc about the seat that holds them at any heading."""
    from runtime.crowd.idle import still_nodes
    from runtime.crowd.scheduler import held_disc, seated_radius
    from runtime.motion.graph import STATES
    from runtime.motion.planar import compose
    g = default_graph
    still = still_nodes(g, (0.02, 2.0, 1 / 15), 30.0)
    seat, heading = np.array([2.0, -1.0]), np.radians(130.0)
    centre, radius = held_disc(g, still, "sit", seat, heading)
    assert radius < 0.8 * seated_radius(g)
    for e in np.flatnonzero(g.edge_state == STATES.index("sitting")):
        fr = np.arange(g.edge_start[e], g.edge_start[e + 1])
        local = np.column_stack([g.frame_xz[fr], g.frame_heading[fr]])
        root = compose(np.array([seat[0], seat[1], heading])[None], local)
        c, r = blend_cylinders(g, fr, fr, root)
        assert np.all(np.hypot(*(c - centre).T) + r <= radius + 1e-9)
    # without a heading: the disc about the seat
    c0, r0 = held_disc(g, still, "sit", seat, None)
    assert np.array_equal(c0, seat) and r0 == seated_radius(g)
