import numpy as np
import pytest

from runtime.motion import quat


def _rot_elem(axis, a):
    c, s = np.cos(a), np.sin(a)
    if axis == "X":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "Y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@pytest.mark.parametrize("order", ["ZYX", "ZXY", "XYZ", "XZY", "YXZ", "YZX"])
def test_euler_matches_matrix_composition_and_round_trips(order):
    rng = np.random.default_rng(1)
    ang = rng.uniform(-170, 170, size=(200, 3))
    ang[:, 1] = rng.uniform(-89, 89, size=200)
    q = quat.from_euler(ang, order)
    for k in range(0, 200, 37):
        r = np.radians(ang[k])
        m = _rot_elem(order[0], r[0]) @ _rot_elem(order[1], r[1]) @ _rot_elem(order[2], r[2])
        np.testing.assert_allclose(quat.to_matrix(q[k]), m, atol=1e-12)
    back = quat.to_euler(q, order)
    np.testing.assert_allclose(back, ang, atol=1e-9)


def test_matrix_round_trip_and_rotate():
    rng = np.random.default_rng(2)
    q = quat.normalize(rng.normal(size=(500, 4)))
    q2 = quat.from_matrix(quat.to_matrix(q))
    np.testing.assert_allclose(np.abs(np.sum(q * q2, -1)), 1.0, atol=1e-12)
    v = rng.normal(size=(500, 3))
    np.testing.assert_allclose(quat.rotate(q, v), np.einsum("nij,nj->ni", quat.to_matrix(q), v), atol=1e-12)


def test_mul_is_composition():
    rng = np.random.default_rng(3)
    a = quat.normalize(rng.normal(size=(50, 4)))
    b = quat.normalize(rng.normal(size=(50, 4)))
    np.testing.assert_allclose(quat.to_matrix(quat.mul(a, b)), quat.to_matrix(a) @ quat.to_matrix(b), atol=1e-12)


def test_slerp_endpoints_and_constant_speed():
    rng = np.random.default_rng(4)
    a = quat.normalize(rng.normal(size=(20, 4)))
    b = quat.normalize(rng.normal(size=(20, 4)))
    np.testing.assert_allclose(np.abs(np.sum(quat.slerp(a, b, 0.0) * a, -1)), 1, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(quat.slerp(a, b, 1.0) * b, -1)), 1, atol=1e-12)
    mid = quat.slerp(a, b, 0.5)
    np.testing.assert_allclose(quat.angle(a, mid), quat.angle(mid, b), atol=1e-9)


def test_yaw_split_is_exact_and_robust_to_pitch():
    th = np.linspace(-3, 3, 13)
    pitch = quat.from_axis_angle([1, 0, 0], 1.2)  # bend forward 69 deg
    q = quat.mul(quat.from_yaw(th), pitch)
    got, rest = quat.remove_yaw(q)
    np.testing.assert_allclose(got, th, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(quat.mul(quat.from_yaw(got), rest) * q, -1)), 1, atol=1e-12)
    # +Z faces heading 0, heading pi/2 faces +X
    f = quat.rotate(quat.from_yaw(np.pi / 2), np.array([0.0, 0, 1]))
    np.testing.assert_allclose(f, [1, 0, 0], atol=1e-12)


def test_log_exp_and_between():
    rng = np.random.default_rng(5)
    v = rng.normal(size=(100, 3))
    v *= (rng.uniform(0, 3, 100) / np.linalg.norm(v, axis=-1))[:, None]
    np.testing.assert_allclose(quat.log(quat.exp(v)), v, atol=1e-9)
    u = rng.normal(size=(100, 3))
    w = rng.normal(size=(100, 3))
    r = quat.between(u, w)
    got = quat.rotate(r, u / np.linalg.norm(u, axis=-1, keepdims=True))
    np.testing.assert_allclose(got, w / np.linalg.norm(w, axis=-1, keepdims=True), atol=1e-9)
    opp = quat.between(np.array([0.0, 1, 0]), np.array([0.0, -1, 0]))
    np.testing.assert_allclose(quat.rotate(opp, np.array([0.0, 1, 0])), [0, -1, 0], atol=1e-9)


def test_unroll_makes_sequence_continuous():
    rng = np.random.default_rng(6)
    q = quat.slerp(quat.identity(), quat.normalize(rng.normal(size=4)), np.linspace(0, 1, 30))
    flipped = q * np.where(rng.random(30) < 0.5, -1, 1)[:, None]
    u = quat.unroll(flipped)
    assert np.all(np.sum(u[1:] * u[:-1], -1) > 0)
