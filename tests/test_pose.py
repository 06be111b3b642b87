"""Vectorized pose evaluation (runtime/pose.py) against the exact evaluator and a per-character
reference loop built from evaluate_poses + forward_kinematics."""
import math

import numpy as np
import pytest

from runtime.crowd.tracks import evaluate_poses
from runtime.motion import quat
from runtime.motion.fk import forward_kinematics
from runtime import pose_kernels
from runtime.pose import PoseBatch, PoseState, PoseTable, evaluate_world, interpolate_root


def _states(graph, n, rng, consecutive=True):
    """Two consecutive ticks' states of n characters: frames inside edges, roots moving a bit."""
    g = graph
    e = rng.integers(0, g.num_edges, n)
    k = rng.integers(0, np.maximum(g.edge_frames[e] - 2, 1))
    fa = g.edge_start[e] + k
    fb = fa + 1 if consecutive else g.edge_start[rng.integers(0, g.num_edges, n)]
    t = rng.random(n).astype(np.float32)
    root = np.column_stack([rng.uniform(-20, 20, (n, 2)), rng.uniform(-7, 7, n)])
    prev = PoseState(np.maximum(fa - 1, g.edge_start[e]), fa, t, root - rng.normal(size=(n, 3)) * [0.05, 0.05, 0.04])
    cur = PoseState(fa, fb, t, root)
    return prev, cur


def test_table_equals_exact_at_library_frames(default_graph):
    rng = np.random.default_rng(0)
    prev, cur = _states(default_graph, 400, rng)
    for t in (0.0, 1.0):
        for alpha in (0.0, 1.0):
            c = PoseState(cur.frames_a, cur.frames_b, np.full(len(cur), t), cur.root)
            p = PoseState(prev.frames_a, prev.frames_b, np.full(len(cur), t), prev.root)
            args = (default_graph, c.frames_a, c.frames_b, c.frames_t, c.root)
            fast = evaluate_world(*args, prev=p, alpha=alpha)
            exact = evaluate_world(*args, prev=p, alpha=alpha, exact=True)
            assert fast.shape == exact.shape == (400, default_graph.skeleton.num_joints, 3)
            assert np.abs(fast - exact).max() < 2e-4, (t, alpha)


def test_blended_positions_stay_within_the_chord_bound(default_graph):
    """Between library frames and between ticks the table blends positions; the exact path
    slerps rotations. Their gap is the chord-versus-arc error of one frame of motion."""
    rng = np.random.default_rng(1)
    prev, cur = _states(default_graph, 2000, rng)
    alpha = rng.random(2000)
    fast = evaluate_world(default_graph, cur.frames_a, cur.frames_b, cur.frames_t, cur.root, prev=prev, alpha=alpha)
    exact = evaluate_world(default_graph, cur.frames_a, cur.frames_b, cur.frames_t, cur.root, prev=prev,
                           alpha=alpha, exact=True)
    err = np.linalg.norm(fast - exact, axis=-1)
    assert err.max() < 0.015
    assert np.percentile(err, 99) < 0.005
    # and the interpolation really moves things: alpha matters
    at0 = evaluate_world(default_graph, cur.frames_a, cur.frames_b, cur.frames_t, cur.root, prev=prev, alpha=0.0)
    at1 = evaluate_world(default_graph, cur.frames_a, cur.frames_b, cur.frames_t, cur.root, prev=prev, alpha=1.0)
    assert np.linalg.norm(at1 - at0, axis=-1).mean() > 0.02


def test_exact_path_matches_a_per_character_loop(default_graph):
    g = default_graph
    rng = np.random.default_rng(2)
    prev, cur = _states(g, 25, rng)
    alpha = rng.random(25)
    rot, pos = evaluate_world(g, cur.frames_a, cur.frames_b, cur.frames_t, cur.root, prev=prev, alpha=alpha,
                              rotations=True)
    for i in range(25):
        # root: lerp x, z; heading along the shorter arc
        d = cur.root[i] - prev.root[i]
        d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
        r = prev.root[i] + alpha[i] * d
        p0, q0 = evaluate_poses(g, prev.frames_a[i], prev.frames_b[i], prev.frames_t[i], r)
        p1, q1 = evaluate_poses(g, cur.frames_a[i], cur.frames_b[i], cur.frames_t[i], r)
        q = quat.slerp(q0, q1, np.full(q0.shape[:-1], alpha[i]))
        gr, gp = forward_kinematics(g.skeleton, p0 + alpha[i] * (p1 - p0), q)
        assert np.abs(gp - pos[i]).max() < 1e-9
        assert np.abs(np.abs(np.sum(gr * rot[i], axis=-1)) - 1).max() < 1e-9


def test_general_blends_between_any_two_frames(default_graph):
    """frames_b need not follow frames_a: t = 0 gives a, t = 1 gives b, b == a gives a."""
    g = default_graph
    rng = np.random.default_rng(3)
    _, cur = _states(g, 300, rng, consecutive=False)
    table = PoseTable.for_graph(g)
    fa, fb = cur.frames_a, cur.frames_b
    exact_a = evaluate_world(g, fa, fa, np.zeros(300), cur.root, exact=True)
    exact_b = evaluate_world(g, fb, fb, np.zeros(300), cur.root, exact=True)
    assert np.abs(evaluate_world(g, fa, fb, np.zeros(300), cur.root) - exact_a).max() < 2e-4
    assert np.abs(evaluate_world(g, fa, fb, np.ones(300), cur.root) - exact_b).max() < 2e-4
    assert np.abs(evaluate_world(g, fa, fa, rng.random(300), cur.root) - exact_a).max() < 2e-4
    half = table.blend(fa, fb, np.full(300, 0.5))
    assert np.allclose(half, 0.5 * (table.local[:, fa] + table.local[:, fb]), atol=1e-5)
    assert PoseTable.for_graph(g) is table


def test_interpolate_root_takes_the_shorter_arc():
    prev = np.array([[0.0, 0.0, math.pi - 0.1], [1.0, 2.0, 0.0]])
    cur = np.array([[2.0, -2.0, -math.pi + 0.1], [3.0, 2.0, 0.5]])
    r = interpolate_root(prev, cur, 0.5)
    assert np.allclose(r[:, :2], [[1.0, -1.0], [2.0, 2.0]])
    assert abs(abs(r[0, 2]) - math.pi) < 1e-12   # through +-pi, not through 0
    assert abs(r[1, 2] - 0.25) < 1e-12
    r = interpolate_root(prev, cur, np.array([0.0, 1.0]))
    assert np.allclose(r[0], prev[0]) and np.allclose(r[1], cur[1])


def test_pose_batch_interpolates_and_keeps_characters_across_spawns(default_graph):
    g = default_graph
    rng = np.random.default_rng(4)
    prev, cur = _states(g, 6, rng)
    batch = PoseBatch(g, foot_lock=False)        # the evaluator itself (the lock: tests/test_footlock.py)
    batch.push(prev)
    assert np.allclose(batch.positions(0.3), evaluate_world(g, prev.frames_a, prev.frames_b, prev.frames_t, prev.root))
    batch.push(cur)
    for a in (0.0, 0.4, 1.0):
        want = evaluate_world(g, cur.frames_a, cur.frames_b, cur.frames_t, cur.root, prev=prev, alpha=a)
        assert np.abs(batch.positions(a) - want).max() < 1e-5
    # one removed (3), one spawned: new order [0, 2, new, 4, 5]
    _, nxt = _states(g, 5, np.random.default_rng(5))
    keep = np.array([0, 2, -1, 4, 5])
    batch.push(nxt, keep=keep)
    p0 = batch.positions(0.0).copy()
    cur_pos = evaluate_world(g, cur.frames_a, cur.frames_b, cur.frames_t, cur.root)
    new_pos = evaluate_world(g, nxt.frames_a, nxt.frames_b, nxt.frames_t, nxt.root)
    assert np.abs(p0[[0, 1, 3, 4]] - cur_pos[[0, 2, 4, 5]]).max() < 1e-5
    assert np.abs(p0[2] - new_pos[2]).max() < 1e-5          # a new character is not interpolated
    assert np.abs(batch.positions(1.0) - new_pos).max() < 1e-5
    rot, pos = batch.transforms(0.5)
    remapped = cur.take([0, 2, 0, 4, 5])
    for name in ("frames_a", "frames_b", "frames_t", "root"):
        getattr(remapped, name)[2] = getattr(nxt, name)[2]
    want_rot, want_pos = evaluate_world(g, nxt.frames_a, nxt.frames_b, nxt.frames_t, nxt.root, prev=remapped,
                                        alpha=0.5, rotations=True)
    assert rot.shape == (5, g.skeleton.num_joints, 4)
    assert np.abs(pos - want_pos).max() < 1e-9 and np.abs(rot - want_rot).max() < 1e-9
    # a change of count without keep restarts interpolation
    batch.push(prev)
    assert np.abs(batch.positions(0.0) - batch.positions(1.0)).max() == 0.0


def test_bad_input_is_reported(default_graph):
    g = default_graph
    T = len(g.frame_height)
    with pytest.raises(ValueError, match="out of range"):
        evaluate_world(g, [0, T], [1, 1], [0, 0], np.zeros((2, 3)))
    with pytest.raises(ValueError, match="disagree in length"):
        evaluate_world(g, [0, 1], [1, 2], [0.0], np.zeros((2, 3)))
    with pytest.raises(ValueError, match="previous state has 1"):
        evaluate_world(g, [0, 1], [1, 2], [0, 0], np.zeros((2, 3)), prev=([0], [1], [0], np.zeros((1, 3))))
    batch = PoseBatch(g)
    batch.push(([0, 1], [1, 2], [0, 0], np.zeros((2, 3))))
    with pytest.raises(ValueError, match="keep refers to character 5"):
        batch.push(([0, 1], [1, 2], [0, 0], np.zeros((2, 3))), keep=[0, 5])


def test_pose_batch_restarts_after_reset(default_graph):
    g = default_graph
    prev, cur = _states(g, 7, np.random.default_rng(6))
    batch = PoseBatch(g, foot_lock=False)
    batch.push(prev)
    batch.push(cur)
    batch.reset()
    batch.push(cur)
    batch.push(prev)
    want = evaluate_world(g, prev.frames_a, prev.frames_b, prev.frames_t, prev.root, prev=cur, alpha=0.25)
    assert np.abs(batch.positions(0.25) - want).max() < 1e-5


@pytest.mark.parametrize("fused", [False, pytest.param(True, marks=pytest.mark.skipif(
    not pose_kernels.AVAILABLE, reason="numba is not importable here"))])
def test_pose_batch_over_ticks_equals_the_stateless_evaluator(default_graph, fused):
    """Ticks where most characters advance one library frame, some jump to another clip, some
    stay, some blend between unrelated frames: every tick's interpolated positions equal the
    stateless evaluator, on the fused (numba) path and on the numpy path."""
    g = default_graph
    rng = np.random.default_rng(11)
    n, T = 300, len(g.frame_height)
    _, st = _states(g, n, rng)
    batch = PoseBatch(g, fused=fused, foot_lock=False)
    assert batch.fused == fused
    batch.push(st)
    for tick in range(8):
        fa = np.minimum(st.frames_a + 1, T - 2)
        jump = rng.random(n) < 0.2
        fa[jump] = rng.integers(0, T - 2, jump.sum())
        stay = rng.random(n) < 0.1
        fa[stay] = st.frames_a[stay]
        fb = fa + 1
        odd = rng.random(n) < 0.05
        fb[odd] = rng.integers(0, T, odd.sum())
        nxt = PoseState(fa, fb, rng.random(n).astype(np.float32), st.root + rng.normal(0, 0.05, (n, 3)))
        batch.push(nxt)
        for alpha in (0.0, 0.6, 1.0):
            want = evaluate_world(g, nxt.frames_a, nxt.frames_b, nxt.frames_t, nxt.root, prev=st, alpha=alpha)
            assert np.abs(batch.positions(alpha) - want).max() < 1e-5, (tick, alpha)
        st = nxt


@pytest.mark.skipif(not pose_kernels.AVAILABLE, reason="numba is not importable here")
def test_fused_skel_arrays_equal_the_numpy_path(default_graph):
    """The bake's animation arrays from the fused kernel equal the numpy evaluation (slerp in
    float32, root heading in float64) for blends at t = 0, inside (0, 1) and between unrelated
    frames; translations carry the rest offsets and the root's world position and height."""
    from runtime.pose import skel_arrays
    g = default_graph
    rng = np.random.default_rng(21)
    M, T = 5000, len(g.frame_height)
    fa = rng.integers(0, T, M)
    fb = np.minimum(fa + 1, T - 1)
    fb[::7] = rng.integers(0, T, len(fb[::7]))
    t = rng.random(M).astype(np.float32)
    t[::5] = 0.0
    root = np.column_stack([rng.uniform(-30, 30, (M, 2)), rng.uniform(-9, 9, M)])
    tf, qf, rf = skel_arrays(g, fa, fb, t, root, fused=True)
    tn, qn, rn = skel_arrays(g, fa, fb, t, root, fused=False)
    assert tf.dtype == tn.dtype == np.float32 and qf.dtype == np.float32
    assert np.abs(tf - tn).max() < 1e-5
    assert np.abs(qf - qn).max() < 2e-6
    assert np.abs(rf - rn).max() < 1e-9
    assert np.allclose(tf[:, 1:], g.skeleton.offsets[1:])
    assert np.allclose(tf[:, 0, [0, 2]], root[:, :2], atol=1e-5)
    with pytest.raises(ValueError, match="out of range"):
        skel_arrays(g, [T], [0], [0.0], np.zeros((1, 3)))


@pytest.mark.skipif(not pose_kernels.AVAILABLE, reason="numba is not importable here")
def test_fused_kernels_are_the_same_on_one_thread_and_on_all(default_graph, monkeypatch):
    """The per-frame kernels run small batches on the calling thread and large ones in parallel
    (pose_kernels.SERIAL_MAX): placement, foot lock and interpolation agree bit for bit."""
    g = default_graph
    T = len(g.frame_height)
    runs = []
    for limit in (0, 10 ** 9):                       # parallel, then serial
        monkeypatch.setattr(pose_kernels, "SERIAL_MAX", limit)
        rng = np.random.default_rng(4)
        _, st = _states(g, 200, rng)
        got = []
        for lock in (False, True):
            batch = PoseBatch(g, fused=True, foot_lock=lock)
            batch.push(st)
            for _ in range(4):
                fa = np.minimum(st.frames_a + 1, T - 2)
                root = st.root + rng.normal(0, 0.05, (len(fa), 3))
                st = PoseState(fa, fa + 1, rng.random(len(fa)).astype(np.float32), root)
                batch.push(st)
                got.append(batch.positions(0.37).copy())
        p, q = (rng.normal(size=(3, 700, 31)).astype(np.float32) * 20 for _ in range(2))
        out = np.empty_like(p)
        assert pose_kernels.lerp(p, q, 0.37, out) is out
        assert np.array_equal(out, p + np.float32(0.37) * (q - p))
        runs.append(got)
    assert all(np.array_equal(a, b) for a, b in zip(*runs))
