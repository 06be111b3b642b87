"""Environment geometry: exact distances and segment clearance against independent references,
the SDF error bound, footprints of primitives, dict round trip and fingerprint."""
import math

import numpy as np
import pytest

from runtime.crowd.environment import Environment, Marker
from runtime.crowd.geometry import (GeometryError, circle_polygon, convex_hull, footprint_capsule, footprint_cube,
                                    footprint_cylinder, footprint_points, footprint_sphere, polygon_area,
                                    units_matrix)


# -- an independent scalar reference (winding number by angle sum, per-edge projection) ---------

def _ref_point_segment(p, a, b):
    ab = b - a
    L2 = float(ab @ ab)
    t = 0.0 if L2 == 0 else min(1.0, max(0.0, float((p - a) @ ab) / L2))
    return float(np.linalg.norm(p - (a + t * ab)))


def _ref_inside(p, poly):
    ang = 0.0
    for i in range(len(poly)):
        u, v = poly[i] - p, poly[(i + 1) % len(poly)] - p
        ang += math.atan2(u[0] * v[1] - u[1] * v[0], u @ v)
    return abs(ang) > math.pi  # winding number +-1 inside, 0 outside


def _ref_signed(p, env):
    out = []
    for poly in env.polygons:
        d = min(_ref_point_segment(p, poly[i], poly[(i + 1) % len(poly)]) for i in range(len(poly)))
        out.append(-d if _ref_inside(p, poly) else d)
    for x, z, r in env.circles:
        out.append(math.hypot(p[0] - x, p[1] - z) - r)
    return np.array(out)


def _star(center, r_out, r_in, k, rot):
    t = rot + np.arange(2 * k) * np.pi / k
    r = np.where(np.arange(2 * k) % 2 == 0, r_out, r_in)
    return np.asarray(center) + np.stack([r * np.cos(t), r * np.sin(t)], axis=1)


def random_env(seed, n_poly=10, n_circ=6, extent=10.0):
    """Convex hulls, non-convex stars (some clockwise), circles; obstacles may overlap."""
    rng = np.random.default_rng(seed)
    polys = []
    for i in range(n_poly):
        c = rng.uniform(-extent, extent, 2)
        if i % 2:
            polys.append(convex_hull(c + rng.normal(size=(12, 2)) * rng.uniform(0.3, 1.5)))
        else:
            s = _star(c, rng.uniform(0.8, 2.0), rng.uniform(0.3, 0.7), int(rng.integers(3, 7)), rng.uniform(0, 6))
            polys.append(s[::-1] if i % 4 == 0 else s)
    circ = np.c_[rng.uniform(-extent, extent, (n_circ, 2)), rng.uniform(0.2, 1.2, n_circ)]
    return Environment(polys, circ)


@pytest.mark.parametrize("seed", [0, 1])
def test_distance_matches_scalar_reference(seed):
    env = random_env(seed)
    rng = np.random.default_rng(100 + seed)
    pts = rng.uniform(-12, 12, size=(250, 2))
    # points certainly inside some polygons and on the circles' centres too
    pts = np.concatenate([pts, [p.mean(axis=0) for p in env.polygons], env.circles[:, :2]])
    d, idx = env.distance(pts, return_index=True)
    ref = np.array([_ref_signed(p, env) for p in pts])
    np.testing.assert_allclose(d, ref.min(axis=1), atol=1e-12)
    np.testing.assert_array_equal(ref[np.arange(len(pts)), idx], ref.min(axis=1))
    assert (d < 0).sum() > 10 and (d > 0).sum() > 100  # both regimes exercised
    assert d.shape == (len(pts),) and env.distance(pts.reshape(-1, 1, 2)).shape == (len(pts), 1)


def test_distance_tiled_path_matches_dense_on_a_fine_grid():
    """Many points take the tiled, culled path; compare with every-point-against-every-edge."""
    env = random_env(3, n_poly=14, n_circ=10)
    x0, z0, x1, z1 = env.bounds(1.0)
    g = np.stack(np.meshgrid(np.linspace(x0, x1, 201), np.linspace(z0, z1, 173), indexing="ij"), -1).reshape(-1, 2)
    d = env.distance(g)
    px, pz = g[:, 0:1], g[:, 1:2]
    dense = np.minimum(env._pset.signed_distance(px, pz).min(axis=1),
                       (np.hypot(px - env.circles[:, 0], pz - env.circles[:, 1]) - env.circles[:, 2]).min(axis=1))
    np.testing.assert_allclose(d, dense, atol=1e-12)


def test_distance_open_ground_and_single_circle():
    env = Environment.open_ground()
    assert np.all(np.isinf(env.distance(np.zeros((3, 2)))))
    assert env.segment_clear([0, 0], [5, 5], 1.0)
    one = Environment(circles=[[1.0, 2.0, 0.5]])
    np.testing.assert_allclose(one.distance([[1.0, 4.0], [1.0, 2.0]]), [1.5, -0.5])


def test_segment_clear_against_sampled_reference():
    env = random_env(5)
    rng = np.random.default_rng(7)
    a = rng.uniform(-11, 11, size=(400, 2))
    b = a + rng.normal(size=(400, 2)) * 3
    radius = 0.4
    clear = env.segment_clear(a, b, radius)
    # reference: min distance along the segment by dense sampling (over-estimates by <= step/2)
    t = np.linspace(0, 1, 801)
    samples = a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]
    dmin = env.distance(samples).min(axis=1)
    step = np.linalg.norm(b - a, axis=1) / 800
    sure_blocked = dmin < radius
    sure_clear = dmin - step / 2 >= radius
    assert sure_blocked.sum() > 50 and sure_clear.sum() > 50
    assert not np.any(clear[sure_blocked])
    assert np.all(clear[sure_clear])
    # segment_distance (dense implementation) agrees with the sampled minimum
    sd = env.segment_distance(a, b)
    np.testing.assert_allclose(sd, np.maximum(dmin, 0) , atol=float(step.max()))
    # per-segment radius broadcasting
    r2 = np.where(np.arange(400) % 2 == 0, 0.0, 10.0)
    c2 = env.segment_clear(a, b, r2)
    assert not np.any(c2[1::2] & (dmin[1::2] < 10.0))


def test_segment_inside_polygon_is_not_clear():
    env = Environment([[[-5, -5], [5, -5], [5, 5], [-5, 5]]])
    assert not env.segment_clear([0, 0], [1, 1], 0.0)        # wholly inside: no edge is crossed
    assert not env.segment_clear([-6, 0], [6, 0], 0.0)       # crosses
    assert env.segment_clear([-6, 6], [6, 6], 0.9)           # passes 1 m away
    assert not env.segment_clear([-6, 6], [6, 6], 1.1)
    assert not env.segment_clear([7, 0], [7, 0], 2.5)        # a point segment 2 m away
    assert env.segment_clear([7, 0], [7, 0], 1.5)


def test_sdf_error_bound_and_outside_behaviour():
    env = random_env(11, n_poly=6, n_circ=4, extent=6)
    sdf = env.sdf(resolution=0.1, margin=1.0)
    assert math.isclose(sdf.max_error, 0.1 / math.sqrt(2))
    x0, z0 = sdf.origin
    x1 = x0 + 0.1 * (sdf.shape[0] - 1)
    z1 = z0 + 0.1 * (sdf.shape[1] - 1)
    rng = np.random.default_rng(1)
    p = rng.uniform((x0, z0), (x1, z1), size=(20000, 2))
    err = sdf.sample(p) - env.distance(p)
    assert np.abs(err).max() <= sdf.max_error + 1e-12
    assert np.all(sdf.sample(p) <= env.distance(p) + sdf.resolution)  # the promised conservative bound
    # grid nodes reproduce the samples exactly
    nodes = sdf.origin + 0.1 * np.array([[3, 4], [10, 2]])
    np.testing.assert_allclose(sdf.sample(nodes), env.distance(nodes), atol=1e-12)
    # outside the grid: a lower bound, at least the margin, never above the true distance
    far = np.array([[x1 + 5.0, z1 + 3.0], [x0 - 7.0, 0.0]])
    got = sdf.sample(far)
    assert np.all(got >= 1.0) and np.all(got <= env.distance(far) + 1e-12)
    assert np.all(np.isinf(Environment.open_ground().sdf().sample(far)))


def test_bounds_markers_and_roles():
    m = [Marker("/World/Seats/a", "seat", [1, 2], 0.5),
         Marker("/World/R", "region", [0, 0], 0.0, polygon=[[-9, -1], [1, -1], [1, 1]])]
    env = Environment([[[0, 0], [1, 0], [0, 1]]], [[5, 5, 1]], m)
    assert env.bounds() == (-9.0, -1.0, 6.0, 6.0)
    assert env.bounds(1.0) == (-10.0, -2.0, 7.0, 7.0)
    assert [x.path for x in env.markers_with_role("seat")] == ["/World/Seats/a"]
    assert env.markers_with_role("box") == []
    with pytest.raises(ValueError, match="unknown"):
        env.markers_with_role("chair")
    with pytest.raises(ValueError, match="/World/x.*unknown role"):
        Marker("/World/x", "chair", [0, 0], 0.0)
    assert Environment.open_ground().bounds(2.0) == (-2.0, -2.0, 2.0, 2.0)


def test_clockwise_polygons_are_reoriented_and_bad_ones_rejected():
    env = Environment([[[0, 0], [0, 1], [1, 1], [1, 0]]])  # clockwise
    assert polygon_area(env.polygons[0]) == 1.0
    with pytest.raises(ValueError, match="zero area"):
        Environment([[[0, 0], [1, 1], [2, 2]]])
    with pytest.raises(ValueError, match="radii"):
        Environment(circles=[[0, 0, -1]])


def test_dict_round_trip_and_fingerprint():
    env = random_env(2, n_poly=4, n_circ=2)
    env.markers["/m"] = Marker("/m", "spawn", [1, 1], 1.0)
    d = env.to_dict()
    import json
    env2 = Environment.from_dict(json.loads(json.dumps(d)))
    assert env2.to_dict() == d
    assert env2.fingerprint() == env.fingerprint()
    p = np.random.default_rng(0).uniform(-10, 10, (50, 2))
    np.testing.assert_array_equal(env2.distance(p), env.distance(p))
    moved = Environment([q + [0.001, 0] for q in env.polygons], env.circles)
    assert moved.fingerprint() != env.fingerprint()
    # markers do not change free space, so not the fingerprint
    assert Environment(env.polygons, env.circles).fingerprint() == env.fingerprint()
    with pytest.raises(ValueError):
        Environment.from_dict({"version": 99})


# -- footprints of primitives ---------------------------------------------------------------

def _trs(t=(0, 0, 0), rot_y=0.0, rot_x=0.0, scale=(1, 1, 1)):
    cy, sy = math.cos(math.radians(rot_y)), math.sin(math.radians(rot_y))
    cx, sx = math.cos(math.radians(rot_x)), math.sin(math.radians(rot_x))
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    T = np.eye(4)
    T[:3, :3] = Ry @ Rx @ np.diag(scale)
    T[:3, 3] = t
    return T


def test_cube_footprint_rotated_and_scaled():
    fp = footprint_cube(_trs((1, 0, 2), rot_y=30, scale=(2, 1, 0.5)), 1.0)
    assert fp.kind == "polygon" and len(fp.polygon) == 4
    assert math.isclose(fp.area, 1.0, rel_tol=1e-12)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    corner = np.array([1, 2]) + np.array([c * 1.0 + s * 0.25, -s * 1.0 + c * 0.25])  # local (+1, +0.25)
    assert np.min(np.linalg.norm(fp.polygon - corner, axis=1)) < 1e-12
    assert polygon_area(fp.polygon) > 0  # counter-clockwise


def test_round_primitives_become_circles_only_when_upright_and_round():
    fp = footprint_cylinder(_trs((1, 5, 2), rot_y=40, scale=(2, 3, 2)), 0.5, 0.5, 2.0, "Y")
    assert fp.kind == "circle"
    np.testing.assert_allclose(fp.circle, [1, 2, 1.0])
    # a cylinder lying down (axis X) is a polygon: its footprint is exactly height x 2 radius
    fp = footprint_cylinder(_trs(), 0.5, 0.5, 2.0, "X")
    assert fp.kind == "polygon" and math.isclose(fp.area, 2.0 * 1.0, rel_tol=1e-12)
    # tilted 90 degrees about X, an axis-Z cylinder is upright
    assert footprint_cylinder(_trs(rot_x=90), 0.5, 0.5, 2.0, "Z").kind == "circle"
    # a squashed sphere is an ellipse polygon that contains the true ellipse
    fp = footprint_sphere(_trs(scale=(2, 1, 1)), 1.0)
    assert fp.kind == "polygon"
    t = np.linspace(0, 2 * np.pi, 400)
    ellipse = np.stack([2 * np.cos(t), np.sin(t)], 1)
    assert np.all(Environment([fp.polygon]).distance(ellipse) <= 1e-12)
    assert math.pi * 2 < fp.area < math.pi * 2 * 1.02
    assert footprint_sphere(_trs((3, 1, 4), scale=(2, 5, 2)), 1.0).kind == "circle"
    # capsules: circle when upright; a lying capsule is a stadium of area 2r*h + pi r^2
    fp = footprint_capsule(_trs((0, 1, 0)), 0.3, 0.3, 1.0, "Y")
    assert fp.kind == "circle" and math.isclose(fp.circle[2], 0.3)
    fp = footprint_capsule(_trs(), 0.3, 0.3, 1.0, "Z")
    assert fp.kind == "polygon"
    assert 0.6 * 1.0 + math.pi * 0.09 < fp.area < (0.6 * 1.0 + math.pi * 0.09) * 1.01
    # a cone standing on its base: the base circle
    fp = footprint_cylinder(_trs(), 0.7, 0.0, 1.0, "Y")
    assert fp.kind == "circle" and math.isclose(fp.circle[2], 0.7)


def test_footprint_errors():
    with pytest.raises(GeometryError, match="negative"):
        footprint_sphere(np.eye(4), -1.0)
    with pytest.raises(GeometryError, match="zero footprint area"):
        footprint_cube(np.eye(4), 0.0)
    with pytest.raises(GeometryError, match="zero footprint area"):
        footprint_cube(_trs(scale=(1, 1, 0)), 1.0)  # flattened onto a vertical plane
    with pytest.raises(GeometryError, match="no points"):
        footprint_points(np.eye(4), np.zeros((0, 3)))
    with pytest.raises(GeometryError, match="zero footprint area"):
        footprint_points(np.eye(4), [[0, 0, 0], [1, 5, 0], [2, 1, 0], [0, 3, 0]])  # wall in the XY plane
    with pytest.raises(GeometryError, match="axis"):
        footprint_cylinder(np.eye(4), 1, 1, 1, "W")
    with pytest.raises(GeometryError, match="finite"):
        footprint_cube(np.full((4, 4), np.nan), 1.0)


def test_units_matrix_zup_centimetres():
    K = units_matrix(0.01, "Z")
    np.testing.assert_allclose(K[:3, :3] @ [0, 0, 100], [0, 1, 0])   # Z-up up -> Y-up up
    np.testing.assert_allclose(K[:3, :3] @ [0, -100, 0], [0, 0, 1])  # Z-up front (-Y) -> +Z
    np.testing.assert_allclose(K[:3, :3] @ [100, 0, 0], [1, 0, 0])
    assert np.linalg.det(K[:3, :3]) > 0
    with pytest.raises(GeometryError):
        units_matrix(0.0, "Y")


def test_circle_polygon_circumscribes():
    poly = circle_polygon([1, 1], 2.0, 16)
    t = np.linspace(0, 2 * np.pi, 500)
    circle = np.array([1, 1]) + 2 * np.stack([np.cos(t), np.sin(t)], 1)
    assert np.all(Environment([poly]).distance(circle) <= 1e-12)


def test_segment_segment_distance_against_sampling():
    from runtime.crowd.geometry import point_segment_distance, segment_segment_distance
    rng = np.random.default_rng(9)
    p0, p1, q0, q1 = (rng.uniform(-2, 2, size=(300, 2)) for _ in range(4))
    p1[:20] = p0[:20]  # degenerate (point) segments
    d = segment_segment_distance(p0, p1, q0, q1)
    t = np.linspace(0, 1, 401)
    P = p0[:, None, :] + t[None, :, None] * (p1 - p0)[:, None, :]
    ref = point_segment_distance(P, q0[:, None, :], q1[:, None, :]).min(axis=1)  # sampled over one segment
    step = np.linalg.norm(p1 - p0, axis=1) / 400
    assert np.all(d <= ref + 1e-12) and np.all(ref - d <= step / 2 + 1e-12)
    assert (d == 0).sum() > 20  # crossing pairs exist and give exactly 0
    # point-segment distance: projection inside, and clamped to the ends
    np.testing.assert_allclose(point_segment_distance([[0, 1], [3, 0], [-1, -1]], [0, 0], [2, 0]), [1, 1, math.sqrt(2)])


def test_the_distance_field_outside_its_grid_is_a_lower_bound_beyond_the_margin():
    """Outside the grid (obstacles grown by the margin) the field returns at least the margin and
    never more than the true distance, so any clearance test below the margin decides as the
    exact distance does."""
    from runtime.crowd.environment import Environment
    env = Environment([np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])], np.array([[5.0, 5.0, 0.5]]))
    sdf = env.sdf(0.05, 2.0)
    p = np.random.default_rng(0).uniform(-20, 25, (20000, 2))
    hi = sdf.origin + sdf.resolution * (np.array(sdf.shape) - 1)
    outside = np.any((p < sdf.origin) | (p > hi), axis=1)
    assert outside.sum() > 10000 and (~outside).sum() > 500
    got, exact = sdf.sample(p), env.distance(p)
    assert np.all(got[outside] >= 2.0) and np.all(got[outside] <= exact[outside] + 1e-9)
    assert np.all(np.abs(got[~outside] - exact[~outside]) <= sdf.max_error + 1e-9)
    for r in (0.3, 1.0, 1.99):
        assert np.array_equal(got[outside] < r, exact[outside] < r)
