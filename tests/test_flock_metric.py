"""Configuration frame, discrete-agent metric and its lower bound (Lai, Chenney and Fan 2005,
section 4)."""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from authoring.boids import BoidsParams, record_flock
from runtime.flock.coords import apply_transform, yaw_rotate
from runtime.flock.metric import (best_yaw, bound_features, configuration_frame, energy, lower_bound,
                                  lower_bound_matrix, match, match_batch, take_features)


@pytest.fixture(scope="module", params=[2, 3], ids=["2d", "3d"])
def recording(request):
    return record_flock(BoidsParams(dim=request.param, warmup=3.0), 40.0, seed=11)


def _pairs(rec, n, seed):
    rng = np.random.default_rng(seed)
    F = rec.n_frames
    a = rng.integers(0, F, n)
    b = rng.integers(0, F, n)
    return a, b


def _random_motion(rng, dim):
    yaw = rng.uniform(-np.pi, np.pi)
    t = rng.uniform(-50, 50, dim)
    return yaw, t


def test_configuration_frame_axes(recording):
    X, V = recording.positions[5], recording.velocities[5]
    origin, axes = configuration_frame(X, V)
    D = X.shape[1]
    np.testing.assert_allclose(origin, X.mean(0), atol=1e-12)
    np.testing.assert_allclose(axes @ axes.T, np.eye(D), atol=1e-12)
    vbar = V.mean(0)
    np.testing.assert_allclose(axes[0], vbar / np.linalg.norm(vbar), atol=1e-12)
    if D == 3:
        assert abs(axes[1][1]) < 1e-12            # Y_c = up x X_c is horizontal (no roll)
        assert np.linalg.det(axes) > 0
    # the frame turns with the group: yaw the configuration, the axes yaw along
    rng = np.random.default_rng(0)
    yaw, t = _random_motion(rng, D)
    o2, ax2 = configuration_frame(apply_transform(yaw, t, X), yaw_rotate(V, yaw))
    np.testing.assert_allclose(o2, apply_transform(yaw, t, origin), atol=1e-9)
    np.testing.assert_allclose(ax2, yaw_rotate(axes, yaw), atol=1e-12)


@pytest.mark.parametrize("w", [0.0, 0.5])
def test_alternation_never_increases_distance(recording, w):
    a, b = _pairs(recording, 60, 1)
    X, V = recording.positions, recording.velocities
    rises = []
    for i, j in zip(a, b):
        m = match(X[i], V[i], X[j], V[j], velocity_weight=w, trace=True)
        tr = np.array(m.trace)
        assert len(tr) >= 2
        rises.append(np.max(np.diff(tr)) / max(tr[0], 1e-12))
        assert m.distance <= tr[0] + 1e-12
    assert max(rises) <= 1e-12
    # random (unflocked) configurations take more iterations: the property must hold there too
    rng = np.random.default_rng(2)
    D = X.shape[2]
    steps = 0
    for _ in range(40):
        A, B = rng.normal(size=(2, 12, D)) * 3
        VA, VB = rng.normal(size=(2, 12, D))
        tr = np.array(match(A, VA, B, VB, velocity_weight=w, trace=True).trace)
        steps += len(tr)
        assert np.all(np.diff(tr) <= 1e-12 * tr[0])
    assert steps > 4 * 40                        # several alternations really happened


@pytest.mark.parametrize("w", [0.0, 0.5])
def test_invariant_to_relabelling_and_rigid_motion(recording, w):
    rng = np.random.default_rng(3)
    X, V = recording.positions, recording.velocities
    D = X.shape[2]
    a, b = _pairs(recording, 25, 4)
    for i, j in zip(a, b):
        A, VA, B, VB = X[i], V[i], X[j], V[j]
        ref = match(A, VA, B, VB, velocity_weight=w)
        pa, pb = rng.permutation(len(A)), rng.permutation(len(B))
        m = match(A[pa], VA[pa], B[pb], VB[pb], velocity_weight=w)
        assert abs(m.distance - ref.distance) <= 1e-9
        # the correspondence follows the labels: agent pa[k] of A still meets slot ref.perm[pa[k]] of B
        np.testing.assert_array_equal(pb[m.perm], ref.perm[pa])
        for moved in ("A", "B"):
            yaw, t = _random_motion(rng, D)
            if moved == "A":
                m = match(apply_transform(yaw, t, A), yaw_rotate(VA, yaw), B, VB, velocity_weight=w)
            else:
                m = match(A, VA, apply_transform(yaw, t, B), yaw_rotate(VB, yaw), velocity_weight=w)
            assert abs(m.distance - ref.distance) <= 1e-9
            np.testing.assert_array_equal(m.perm, ref.perm)


def test_result_carries_correspondence_and_transform(recording):
    X, V = recording.positions, recording.velocities
    rng = np.random.default_rng(5)
    D = X.shape[2]
    for i, j in zip(*_pairs(recording, 10, 6)):
        m = match(X[i], V[i], X[j], V[j])
        aligned = apply_transform(m.yaw, m.translation, X[j][m.perm])
        assert abs(((X[i] - aligned) ** 2).sum(-1).mean() - m.distance) <= 1e-9
    # a relabelled, moved copy is found exactly, with its labels
    A, VA = X[7], V[7]
    p = rng.permutation(len(A))
    yaw, t = _random_motion(rng, D)
    m = match(A, VA, apply_transform(yaw, t, A[p]), yaw_rotate(VA[p], yaw), velocity_weight=0.5)
    assert m.distance < 1e-18
    np.testing.assert_array_equal(p[m.perm], np.arange(len(A)))
    assert abs(np.angle(np.exp(1j * (m.yaw + yaw)))) < 1e-9


def test_batch_matches_single(recording):
    X, V = recording.positions, recording.velocities
    a, b = _pairs(recording, 30, 7)
    d, perm, yaw, t, _ = match_batch(X[a], V[a], X[b], V[b], 0.5)
    for k in (0, 13, 29):
        m = match(X[a[k]], V[a[k]], X[b[k]], V[b[k]], velocity_weight=0.5)
        assert m.distance == d[k]                 # bit-identical: pairs do not see their batch
        np.testing.assert_array_equal(m.perm, perm[k])


@pytest.mark.parametrize("w", [0.0, 0.5])
def test_lower_bound_never_exceeds_metric(recording, w):
    X, V = recording.positions, recording.velocities
    a, b = _pairs(recording, 300, 8)
    d = match_batch(X[a], V[a], X[b], V[b], w)[0]
    f = bound_features(X, V, w)
    lb = lower_bound(take_features(f, a), take_features(f, b), X.shape[1])
    assert np.all(lb <= d)
    assert np.mean(lb) > 0.02 * np.mean(d)        # and it is not trivially zero
    # matrix form agrees with the pairwise form
    idx = np.arange(0, X.shape[0], 97)
    fm = take_features(f, idx)
    M = lower_bound_matrix(fm, fm, X.shape[1])
    P = lower_bound(take_features(f, np.repeat(idx, len(idx))), take_features(f, np.tile(idx, len(idx))), X.shape[1])
    np.testing.assert_allclose(M.ravel(), P, atol=1e-9)


@pytest.mark.parametrize("dim", [2, 3])
def test_lower_bound_below_brute_force_minimum(dim):
    """Against the true minimum over every correspondence (N = 5) and the best yaw for each."""
    rng = np.random.default_rng(9)
    N = 5
    perms = np.array(list(itertools.permutations(range(N))))
    for _ in range(30):
        A, B = rng.normal(size=(2, N, dim)) * rng.uniform(0.5, 3)
        VA, VB = rng.normal(size=(2, N, dim))
        for w in (0.0, 0.7):
            k = len(perms)
            d = match_batch(np.repeat(A[None], k, 0), np.repeat(VA[None], k, 0), B[perms], VB[perms], w)
            # with every correspondence as a start the alternation's first alignment is optimal
            # for that correspondence; the smallest over all of them is the true minimum
            a0, b0 = A - A.mean(0), B[perms] - B.mean(0)
            va, vb = np.repeat(VA[None], k, 0), VB[perms]
            aa = np.repeat(a0[None], k, 0)
            yaw = best_yaw(aa, va, b0, vb, w * w)
            true_min = energy(aa, va, b0, vb, yaw, w * w).min()
            assert d[0].min() >= true_min - 1e-12
            f = bound_features(np.stack([A, B]), np.stack([VA, VB]), w)
            lb = lower_bound(take_features(f, 0), take_features(f, 1), N)
            assert lb <= true_min + 1e-12


def test_lower_bound_invariant(recording):
    rng = np.random.default_rng(10)
    X, V = recording.positions[3], recording.velocities[3]
    D = X.shape[1]
    yaw, t = _random_motion(rng, D)
    p = rng.permutation(len(X))
    f1 = bound_features(X, V, 0.5)
    f2 = bound_features(apply_transform(yaw, t, X[p]), yaw_rotate(V[p], yaw), 0.5)
    for a, b in zip(f1["pos"] + f1["vel"] + [f1["mean"]], f2["pos"] + f2["vel"] + [f2["mean"]]):
        np.testing.assert_allclose(a, b, atol=1e-9)
