"""Foot locking (runtime/motion/footlock.py) and the planted-foot slide measure (runtime/footslide.py)."""
from dataclasses import replace

import numpy as np
import pytest

from runtime.crowd.tracks import Track, joint_positions
from runtime.footslide import planted_slide, slide_passed, slide_summary
from runtime.motion.footlock import (BLEND_FRAMES, MAX_HIP_DROP, FootLockModel, LockState, lock_skel_arrays,
                                     lock_step, played_planted, solve_legs)
from runtime.pose import locked_joint_positions, skel_arrays


# -- the measure ------------------------------------------------------------------------------------
def _foot(speed, F=90, fps=30.0):
    """A toe on the ground (y = 0.02) moving horizontally at ``speed`` m/s, with a swing of 20 frames."""
    p = np.zeros((F, 1, 3))
    p[:, 0, 1] = 0.02
    p[:, 0, 0] = speed * np.arange(F) / fps
    sw = np.arange(40, 60)
    p[sw, 0, 1] += 0.12 * np.sin(np.pi * (sw - 39) / 21)
    return p, fps


def test_a_sliding_planted_foot_is_caught():
    p, fps = _foot(0.20)
    plant, v = planted_slide(p, fps)
    s = slide_summary(v[plant])
    assert plant[:38].sum() >= 36 and not plant[45:55].any()      # the swing is not planted
    assert abs(s["mean_cm_s"] - 20.0) < 0.5 and s["sliding_share"] > 0.95
    assert not slide_passed({**s, "lowest_foot_m": 0.0})


def test_a_still_foot_is_not_sliding():
    p, fps = _foot(0.0)
    plant, v = planted_slide(p, fps)
    s = slide_summary(v[plant])
    assert s["planted_frames"] > 60 and s["mean_cm_s"] < 1e-9 and s["sliding_share"] == 0.0
    assert slide_passed(s)


def test_a_foot_falling_fast_is_not_planted():
    p, fps = _foot(0.0)
    p[:, 0, 1] = 0.02 + 0.3 * np.maximum(0, 30 - np.arange(90)) / 30.0     # comes down at 0.3 m/s
    plant, _ = planted_slide(p, fps)
    assert not plant[:26].any() and plant[35:].all()


# -- the lock state -------------------------------------------------------------------------------
def test_a_planted_foot_is_pinned_where_it_landed_and_released_smoothly():
    st = LockState.empty(1)
    F = 30
    toe = np.zeros((F, 1, 2, 2))
    toe[:, 0, 0, 0] = 0.01 * np.arange(F)          # left toe drifts 1 cm per frame in x
    plant = np.zeros((F, 1, 2), bool)
    plant[5:15, 0, 0] = True
    shown = np.array([toe[f] + lock_step(st, toe[f], plant[f]) for f in range(F)])[:, 0, 0]
    assert np.allclose(shown[5:15], toe[5, 0, 0])                  # pinned at touch-down
    assert np.allclose(shown[:5], toe[:5, 0, 0, :])                # untouched before
    after = shown[15:15 + BLEND_FRAMES + 2, 0] - toe[15:15 + BLEND_FRAMES + 2, 0, 0, 0]
    fade = np.abs(after)
    assert np.all(np.diff(fade[:BLEND_FRAMES + 1]) < 0) and not fade[BLEND_FRAMES:].any()   # fades out
    assert np.all(np.abs(np.diff(shown[:, 0])) <= 0.0101 + 0.1 / (BLEND_FRAMES + 1))   # no jump


def test_a_foot_landing_while_fading_is_pinned_where_it_is_shown():
    st = LockState.empty(1)
    toe = np.zeros((1, 2, 2))
    plant = np.zeros((1, 2), bool)
    plant[0, 1] = True
    lock_step(st, toe, plant)
    toe[0, 1, 1] = 0.1
    lock_step(st, toe, plant)                      # pinned at z = 0: correction -0.1
    plant[0, 1] = False
    d1 = lock_step(st, toe, plant)                 # released: fading
    plant[0, 1] = True
    d2 = lock_step(st, toe, plant)                 # lands again
    assert 0 > d1[0, 1, 1] > -0.1 and np.isclose(d2[0, 1, 1], d1[0, 1, 1] * (BLEND_FRAMES - 1) / BLEND_FRAMES)


# -- on the default library -------------------------------------------------------------------------
def _sliding_track(graph, stretch=1.2):
    """A walking edge played with its root path stretched: the clip's planted feet slide."""
    e = next(e for e in range(graph.num_edges) if "walk" in graph.edge_labels[e] and graph.edge_frames[e] > 40)
    a, b = graph.edge_start[e], graph.edge_start[e + 1]
    fa = np.arange(a, b - 1)
    root = np.column_stack([graph.frame_xz[a:b - 1] * stretch, graph.frame_heading[a:b - 1]])
    return Track(fa, fa + 1, np.zeros(len(fa), np.float32), root, 0)


@pytest.fixture(scope="module")
def model(default_graph):
    return FootLockModel.for_library(default_graph)


def test_the_model_is_built_once_per_library(default_graph, model):
    assert FootLockModel.for_library(default_graph) is model
    assert model.planted.shape == (len(default_graph.frame_height), 2) and 0.3 < model.planted.mean() < 0.95
    assert np.all(model.flex_min >= 0) and np.all(model.flex_max > model.flex_min)
    assert np.all(model.reach_max > model.reach_min)


def test_locking_stops_the_slide_and_keeps_the_root_path(default_graph, model):
    tr = _sliding_track(default_graph)
    legs = model.legs
    raw = joint_positions(default_graph, tr)
    locked = locked_joint_positions(default_graph, tr)
    plant = played_planted(model, tr.frames_a, tr.frames_b, tr.frames_t)
    sp = lambda p: np.linalg.norm(np.diff(p[:, legs.toe][..., [0, 2]], axis=0), axis=-1) * 30   # noqa: E731
    both = plant[1:] & plant[:-1]
    assert sp(raw)[both].mean() > 0.1                                # the stretched clip slides
    assert sp(locked)[both].max() < 1e-3                             # pinned
    # the root path is untouched; only the hips may come down, by at most MAX_HIP_DROP
    np.testing.assert_allclose(locked[:, 0, [0, 2]], raw[:, 0, [0, 2]], atol=1e-6)
    drop = raw[:, 0, 1] - locked[:, 0, 1]
    assert np.all(drop >= -1e-6) and np.all(drop <= MAX_HIP_DROP + 1e-6)
    # the upper body moves rigidly with the hips; bones keep their lengths (FK); knees within the capture's range
    spine = default_graph.skeleton.index("Head")
    np.testing.assert_allclose(locked[:, spine] - locked[:, 0], raw[:, spine] - raw[:, 0], atol=1e-5)
    t = locked[:, legs.knee] - locked[:, legs.hip]
    s = locked[:, legs.ankle] - locked[:, legs.knee]
    flex = np.arccos(np.clip(np.sum(t * s, -1) / np.linalg.norm(t, axis=-1) / np.linalg.norm(s, axis=-1), -1, 1))
    assert np.all(flex >= model.flex_min - 1e-3) and np.all(flex <= model.flex_max + 1e-3)
    assert locked[:, legs.toe, 1].min() > raw[:, legs.toe, 1].min() - 0.01     # no foot pushed into the ground


def test_frames_without_a_correction_are_written_as_they_were(default_graph, model):
    tr = _sliding_track(default_graph)
    seg = np.zeros(len(tr), bool)
    seg[0] = True
    free = replace(model, planted=np.zeros_like(model.planted))      # no foot ever planted
    raw = skel_arrays(default_graph, tr.frames_a, tr.frames_b, tr.frames_t, tr.root)
    trans, q, _ = skel_arrays(default_graph, tr.frames_a, tr.frames_b, tr.frames_t, tr.root)
    lock_skel_arrays(free, default_graph.skeleton, tr.frames_a, tr.frames_b, tr.frames_t, seg, trans, q)
    np.testing.assert_array_equal(trans, raw[0])
    np.testing.assert_array_equal(q, raw[1])
    lock_skel_arrays(model, default_graph.skeleton, tr.frames_a, tr.frames_b, tr.frames_t, seg, trans, q)
    changed = np.flatnonzero(np.any(q != raw[1], axis=(1, 2)))
    assert len(changed) and changed[0] > 0                           # touch-down frames need no correction
    legs = model.legs
    other = np.setdiff1d(np.arange(q.shape[1]), np.concatenate([legs.hip, legs.knee, legs.ankle]))
    np.testing.assert_array_equal(q[:, other], raw[1][:, other])     # only hips, knees and ankles turn


def test_an_unreachable_pin_lowers_the_hips_then_clamps(model):
    hip = np.array([[[0.1, 0.9, 0.0], [-0.1, 0.9, 0.0]]])
    knee = hip + [0.0, -0.42, 0.05]
    ankle = hip + [0.0, -0.82, 0.0]
    d = np.array([[[0.0, -0.3], [0.0, 0.0]]])                # left foot pinned 30 cm behind
    drop, k, a = solve_legs(model, hip, knee, ankle, d, np.array([[0.0, 0.0, 1.0]]))
    assert 0 < drop[0] <= MAX_HIP_DROP
    reach = np.linalg.norm(a - (hip - [0, drop[0], 0]), axis=-1)
    assert np.all(reach <= model.reach_max + 1e-9)
    assert np.allclose(np.linalg.norm(k - (hip - [0, drop[0], 0]), axis=-1), model.thigh)
    assert np.allclose(np.linalg.norm(a - k, axis=-1), model.shin)
    h = hip - [0, drop[0], 0]
    u = (a - h) / np.linalg.norm(a - h, axis=-1, keepdims=True)
    pole = (k - h) - np.sum((k - h) * u, -1, keepdims=True) * u
    assert np.all(pole[..., 2] > 0)                             # knees bend forward, as they were


def test_the_measure_reads_the_feet_a_bake_wrote(default_graph, model, tmp_path):
    from usd_io.crowd import build_crowd_stage, character_path, save_crowd_stage
    from runtime.footslide import measure_stage, stage_feet
    tr = _sliding_track(default_graph)
    out = save_crowd_stage(build_crowd_stage({"walker": tr}, default_graph, 30.0), tmp_path / "w.usda")
    (t0, toe, ankle, knee), = stage_feet(out, [character_path("walker")]).values()
    legs = model.legs
    np.testing.assert_allclose(toe, locked_joint_positions(default_graph, tr)[:, legs.toe], atol=1e-4)
    plant, v = planted_slide(joint_positions(default_graph, tr)[:, legs.toe], 30.0)
    before = slide_summary(v[plant])
    plant, v = planted_slide(locked_joint_positions(default_graph, tr)[:, legs.toe], 30.0)
    after = measure_stage(out)
    assert after["planted_frames"] == slide_summary(v[plant])["planted_frames"]
    assert np.isclose(after["mean_cm_s"], slide_summary(v[plant])["mean_cm_s"], atol=0.05)
    assert before["mean_cm_s"] > 20 and after["mean_cm_s"] < before["mean_cm_s"] * 0.6
    assert after["characters"] == 1 and after["lowest_foot_m"] > -0.01
    assert stage_feet(out, ["/World/Characters/nobody"]) == {}


# -- the runtime: PoseBatch ------------------------------------------------------------------------------
def _walk_states(graph, n, ticks, seed=0):
    """Characters walking on through stretched clips, as pose states per tick (with each track)."""
    from runtime.pose import PoseState
    rng = np.random.default_rng(seed)
    tracks = [_sliding_track(graph, stretch=s) for s in rng.uniform(1.05, 1.3, n)]
    L = min(len(t) for t in tracks)
    off = rng.uniform(-20, 20, (n, 2))
    states = [PoseState([t.frames_a[k] for t in tracks], [t.frames_b[k] for t in tracks],
                        [t.frames_t[k] for t in tracks], [t.root[k] + [*o, 0.0] for t, o in zip(tracks, off)])
              for k in range(min(L, ticks))]
    return states


@pytest.mark.parametrize("fused", [False, True])
def test_pose_batch_pins_planted_feet_like_the_bake(default_graph, model, fused):
    from runtime import pose_kernels
    from runtime.pose import PoseBatch
    if fused and not pose_kernels.AVAILABLE:
        pytest.skip("numba is not importable here")
    states = _walk_states(default_graph, 5, 40)
    locked, free = PoseBatch(default_graph, fused=fused), PoseBatch(default_graph, fused=fused, foot_lock=False)
    toe = model.legs.toe
    got, raw = [], []
    for st in states:
        locked.push(st)
        free.push(st)
        got.append(locked.positions(1.0)[:, toe].copy())
        raw.append(free.positions(1.0)[:, toe].copy())
    got, raw = np.array(got), np.array(raw)
    plant = np.array([played_planted(model, st.frames_a, st.frames_b, st.frames_t) for st in states])
    both = plant[1:] & plant[:-1]
    sp = lambda p: np.linalg.norm(np.diff(p[..., [0, 2]], axis=0), axis=-1)  # noqa: E731
    assert sp(raw)[both].mean() > 0.002 and sp(got)[both].max() < 1e-4     # metres per tick
    # character 0 as the bake locks it (its whole track, one segment)
    tr = Track(np.array([s.frames_a[0] for s in states]), np.array([s.frames_b[0] for s in states]),
               np.array([s.frames_t[0] for s in states], np.float32), np.array([s.root[0] for s in states]), 0)
    np.testing.assert_allclose(got[:, 0], locked_joint_positions(default_graph, tr)[:, toe], atol=1e-4)


def test_pose_batch_fused_and_numpy_locks_agree_across_spawns(default_graph):
    from runtime import pose_kernels
    from runtime.pose import PoseBatch
    if not pose_kernels.AVAILABLE:
        pytest.skip("numba is not importable here")
    states = _walk_states(default_graph, 6, 30, seed=2)
    a, b = PoseBatch(default_graph, fused=True), PoseBatch(default_graph, fused=False)
    for k, st in enumerate(states):
        keep = None
        if k == 15:                       # character 1 leaves, one arrives: [0, 2, 3, 4, 5, new]
            keep = np.array([0, 2, 3, 4, 5, -1])
            st = st.take([0, 2, 3, 4, 5, 1])
        elif k > 15:
            st = st.take([0, 2, 3, 4, 5, 1])
        a.push(st, keep=keep)
        b.push(st, keep=keep)
        np.testing.assert_allclose(a.positions(0.5), b.positions(0.5), atol=1e-5)
        if k == 15:
            assert not a._lock.locked[5].any() or np.allclose(a._lock.res[5], 0)   # arrives unlocked
    np.testing.assert_array_equal(a._lock.locked, b._lock.locked)


def _leg(knee_forward: float, knee_side: float = 0.0, frames: int = 4):
    """(F, 2, 4, 3) legs (toe, ankle, knee, hip) of a character facing +Z (hips along X, left at
    +X): the knee ``knee_forward`` m in front of the straight hip-ankle line (negative: behind),
    ``knee_side`` m outwards."""
    pos = np.zeros((frames, 2, 4, 3))
    for s, x in enumerate((0.1, -0.1)):
        pos[:, s, 3] = (x, 0.9, 0.0)                                   # hip
        pos[:, s, 1] = (x, 0.1, 0.0)                                   # ankle straight below
        pos[:, s, 0] = (x, 0.02, 0.12)                                 # toe ahead
        pos[:, s, 2] = (x + (knee_side if s == 0 else -knee_side), 0.5, knee_forward)
    return pos


def test_signed_knee_flexion_sees_hyperextension():
    from runtime.footslide import signed_knee_flexion
    front = np.degrees(signed_knee_flexion(_leg(0.08)))
    behind = np.degrees(signed_knee_flexion(_leg(-0.08)))
    sideways = np.degrees(signed_knee_flexion(_leg(0.0, knee_side=0.15)))
    assert np.all(front > 15.0) and np.allclose(behind, -front)
    assert np.all(sideways > 15.0)                       # a knee turned out is bent, not hyperextended
    # the facing comes from the hips and the feet: the same leg turned round reads the same
    turned = _leg(-0.08)
    turned[..., [0, 2]] *= -1.0
    assert np.allclose(np.degrees(signed_knee_flexion(turned)), behind)


def test_limits_hold_the_feet_the_knees_and_a_fair_share():
    from runtime.footslide import MIN_SHARE_FRAMES
    good = {"planted_frames": 5000, "mean_cm_s": 1.0, "p95_cm_s": 2.0, "sliding_share": 0.01,
            "lowest_foot_m": -0.005, "knee_flexion_deg": [5.0, 100.0]}
    assert slide_passed(good) and slide_passed(good, [4.6, 111.9])
    assert not slide_passed({**good, "lowest_foot_m": -0.02})               # a foot through the ground
    assert not slide_passed({**good, "knee_flexion_deg": [-3.0, 100.0]})    # hyperextension
    assert not slide_passed(good, [4.6, 90.0])                              # more bent than the capture
    assert slide_passed({**good, "knee_flexion_deg": [4.0, 112.5]}, [4.6, 111.9])   # within the tolerance
    few = {**good, "planted_frames": MIN_SHARE_FRAMES - 1, "sliding_share": 0.05}
    assert slide_passed(few) and not slide_passed({**few, "planted_frames": MIN_SHARE_FRAMES})


def test_leg_ik_never_puts_the_knee_behind_the_leg():
    # a bent leg whose ankle is pinned 15 cm ahead: the old knee (2 cm forward) lies behind the new
    # hip-ankle line; the solved knee must bend forward (the character faces +Z)
    from runtime.motion.footlock import FootLockModel, solve_legs
    thigh, shin = np.array([0.4, 0.4]), np.array([0.4, 0.4])
    flex = np.radians([[5.0, 5.0], [110.0, 110.0]])
    reach = lambda f: np.sqrt(thigh ** 2 + shin ** 2 + 2 * thigh * shin * np.cos(f))  # noqa: E731
    model = FootLockModel(None, np.zeros((1, 2), bool), thigh, shin, flex[0], flex[1], reach(flex[1]), reach(flex[0]),
                          np.full((2, 1), -1))
    hip = np.array([[[0.1, 0.9, 0.0], [-0.1, 0.9, 0.0]]])
    knee = hip + [0.0, -0.3, 0.02]
    ankle = hip + [0.0, -0.6, 0.0]
    d = np.array([[[0.0, 0.15], [0.0, 0.0]]])
    drop, k1, a1 = solve_legs(model, hip, knee, ankle, d, np.array([[0.0, 0.0, 1.0]]))
    h1 = hip - drop[:, None, None] * np.array([0.0, 1.0, 0.0])
    u = (a1 - h1) / np.linalg.norm(a1 - h1, axis=-1, keepdims=True)
    off = (k1 - h1) - np.sum((k1 - h1) * u, axis=-1, keepdims=True) * u
    assert off[0, 0, 2] > 0.05                                     # the pinned leg's knee is in front
    np.testing.assert_allclose(np.linalg.norm(k1 - h1, axis=-1), thigh[None], atol=1e-9)
