import numpy as np
import pytest

from runtime.motion import Clip, Skeleton, forward_kinematics, ops, quat
from runtime.motion.skeleton import CMU_MB_NAMES, CMU_MB_PARENTS
from conftest import random_clip, random_skeleton


def naive_fk(sk, root_pos, rots):
    """Per-joint, per-frame matrices: the plain reference for the level-by-level FK."""
    F, J = rots.shape[:2]
    out = np.zeros((F, J, 3))
    for f in range(F):
        mats = [None] * J
        for j in range(J):
            m = np.eye(4)
            m[:3, :3] = quat.to_matrix(rots[f, j])
            m[:3, 3] = root_pos[f] if j == 0 else sk.offsets[j]
            mats[j] = m if j == 0 else mats[sk.parents[j]] @ m
            out[f, j] = mats[j][:3, 3]
    return out


def test_fk_matches_naive_matrices():
    rng = np.random.default_rng(0)
    sk = random_skeleton(rng, 15)
    rots = quat.normalize(rng.normal(size=(7, 15, 4)))
    pos = rng.normal(size=(7, 3))
    gr, gp = forward_kinematics(sk, pos, rots)
    np.testing.assert_allclose(gp, naive_fk(sk, pos, rots), atol=1e-12)
    # broadcasting over an extra agent axis gives the same numbers
    gr2, gp2 = forward_kinematics(sk, np.stack([pos, pos]), np.stack([rots, rots]))
    np.testing.assert_allclose(gp2[1], gp, atol=1e-12)


def test_from_world_round_trip_keeps_world_positions():
    rng = np.random.default_rng(1)
    c = random_clip(rng, smooth=False)
    pos, rot = c.world_root()
    assert np.allclose(c.root_xz[0], 0) and c.root_heading[0] == 0
    c2 = Clip.from_world(c.skeleton, c.fps, pos, c.local_rotations_world_root())
    np.testing.assert_allclose(c2.positions(), c.positions(), atol=1e-6)


def test_cut_reverse_resample_keep_world_placement():
    rng = np.random.default_rng(2)
    c = random_clip(rng, frames=61)
    p = c.positions()
    sub = ops.cut(c, 10, 40)
    assert sub.num_frames == 30 and np.allclose(sub.root_xz[0], 0) and sub.root_heading[0] == 0
    np.testing.assert_allclose(sub.positions(), p[10:40], atol=1e-9)
    np.testing.assert_allclose(ops.reverse(c).positions(), p[::-1], atol=1e-9)
    up = ops.resample(c, 60.0)
    assert up.num_frames == 121 and up.duration == pytest.approx(c.duration)
    np.testing.assert_allclose(up.positions()[::2], p, atol=1e-6)
    n = ops.resample(c, num_frames=31)
    np.testing.assert_allclose(n.positions()[[0, -1]], p[[0, -1]], atol=1e-6)
    with pytest.raises(IndexError):
        ops.cut(c, 50, 70)


def test_append_aligns_second_clip_to_end_of_first():
    rng = np.random.default_rng(3)
    a = random_clip(rng, frames=20)
    b = random_clip(rng, frames=25).copy(skeleton=a.skeleton)
    ab = ops.append(a, b)
    assert ab.num_frames == 44
    # b's local motion, placed at a's last frame
    end = a.root_xz[-1]
    h = a.root_heading[-1]
    from runtime.motion import rotate_xz
    np.testing.assert_allclose(ab.root_xz[19:], rotate_xz(b.root_xz, h) + end, atol=1e-12)
    np.testing.assert_allclose(ab.root_heading[19:], b.root_heading + h, atol=1e-12)
    ab2 = ops.append(a, b, shared_frame=False)
    assert ab2.num_frames == 45
    np.testing.assert_allclose(ab2.root_xz[20] - ab2.root_xz[19], ab2.root_xz[19] - ab2.root_xz[18], atol=1e-12)


def test_mirror_reflects_world_positions():
    rng = np.random.default_rng(4)
    off = rng.normal(size=(31, 3)) * 0.1
    sk0 = Skeleton(CMU_MB_NAMES, np.array(CMU_MB_PARENTS), off)
    m = sk0.mirror_map()
    # make the rest skeleton symmetric: right offsets = mirrored left ones
    sym = off.copy()
    for j in range(31):
        if m[j] != j:
            sym[j] = off[min(j, m[j])] * ([1, 1, 1] if j < m[j] else [-1, 1, 1])
        else:
            sym[j, 0] = 0
    sk = Skeleton(CMU_MB_NAMES, np.array(CMU_MB_PARENTS), sym)
    rots = quat.exp(rng.normal(size=(10, 31, 3)) * 0.3)
    pos = rng.normal(size=(10, 3))
    c = Clip.from_world(sk, 30, pos, rots, keep_origin=False)
    mc = ops.mirror(c)
    p = c.positions()
    pm = mc.positions()
    np.testing.assert_allclose(pm[:, m], p * [-1, 1, 1], atol=1e-6)
    np.testing.assert_allclose(ops.mirror(mc).positions(), p, atol=1e-6)
