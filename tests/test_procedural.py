"""Procedural capture generator (authoring.procedural): skeleton, determinism, label sidecars,
the acceptance metrics measured by the independent checker, hub poses, the CLI."""
from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from authoring.bvh import read_bvh
from authoring.capture_quality import take_quality
from authoring.procedural import LABELS, generate_session, make_skeleton, write_session
from authoring.procedural import body, gait
from authoring.procedural.locomotion import run_controls
from authoring.procedural.rig import solve
from authoring.procedural.stance import H_STAND
from runtime.motion import Clip
from runtime.motion.skeleton import CMU_MB_NAMES, CMU_MB_PARENTS


@pytest.fixture(scope="module")
def one_minute(tmp_path_factory):
    out = tmp_path_factory.mktemp("cap1")
    manifest = write_session(out, 1.0, seed=3, take_minutes=0.5)
    return out, manifest, take_quality(out)


# -- skeleton ---------------------------------------------------------------------------------
def test_skeleton_is_cmu_motionbuilder_family_in_a_t_pose():
    sk = make_skeleton()
    assert sk.names == CMU_MB_NAMES
    assert tuple(int(p) for p in sk.parents) == CMU_MB_PARENTS
    assert sk.family == "cmu-mb"
    F = 1
    clip = Clip.from_world(sk, 30, np.array([[0.0, 1.0, 0.0]]), np.tile([1.0, 0, 0, 0], (F, sk.num_joints, 1)))
    p = clip.positions()[0]
    J = body.J
    # left is +X, arms horizontal, legs straight down, toes forward (+Z)
    assert p[J.LeftHand, 0] > 0.6 and p[J.RightHand, 0] < -0.6
    assert abs(p[J.LeftHand, 1] - p[J.LeftArm, 1]) < 1e-9
    assert np.allclose(p[J.LeftFoot, [0, 2]], p[J.LeftUpLeg, [0, 2]])
    assert p[J.LeftToeBase, 2] > p[J.LeftFoot, 2] + 0.1
    # plausible adult: hips ~0.96 m above the soles when standing, stature 1.6-1.9 m
    head_top = p[J.Head, 1] + 0.19
    sole = p[J.LeftFoot, 1] - body.ANKLE_HEIGHT
    assert 1.6 < head_top - sole < 1.9
    assert 0.85 < 1.0 - sole < 1.05


# -- determinism and files ----------------------------------------------------------------------
def test_same_seed_gives_byte_identical_files(tmp_path):
    a = write_session(tmp_path / "a", 0.6, seed=11, take_minutes=0.3)
    b = write_session(tmp_path / "b", 0.6, seed=11, take_minutes=0.3)
    assert a == b
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert names == sorted(p.name for p in (tmp_path / "b").iterdir())
    assert "take_001.bvh" in names and "session.json" in names
    for n in names:
        assert (tmp_path / "a" / n).read_bytes() == (tmp_path / "b" / n).read_bytes(), n
    c = write_session(tmp_path / "c", 0.6, seed=12, take_minutes=0.3)
    assert c["files"][0]["sha256"] != a["files"][0]["sha256"]


def test_manifest_lists_every_file_with_its_sha256(one_minute):
    out, manifest, _ = one_minute
    assert manifest["seed"] == 3 and manifest["fps"] == 30.0 and manifest["minutes"] == 1.0
    listed = {f["path"] for f in manifest["files"]}
    on_disk = {p.name for p in out.iterdir()} - {"session.json"}
    assert listed == on_disk
    for f in manifest["files"]:
        assert hashlib.sha256((out / f["path"]).read_bytes()).hexdigest() == f["sha256"]
    assert json.loads((out / "session.json").read_text()) == manifest


def test_bvh_reads_back_as_family_a_with_the_default_scale(one_minute):
    out, manifest, _ = one_minute
    m = read_bvh(out / "take_000.bvh")
    assert m.family == "cmu-mb" and abs(m.scale - 0.05644) < 1e-9
    assert set(m.channel_orders) == {"ZYX"}
    assert not m.dropped_first_frame
    text = (out / "take_000.bvh").read_text()
    assert "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation" in text
    # the root stands ~0.96 m high in frame 0 (written in CMU units, read back in metres)
    assert abs(m.clip.root_height[0] - H_STAND) < 1e-4
    assert m.clip.num_frames == manifest["takes"][0]["frames"]


def test_label_sidecars_tile_every_frame(one_minute):
    out, manifest, q = one_minute
    for t in manifest["takes"]:
        lab = json.loads((out / t["labels"]).read_text())
        assert lab["fps"] == 30.0 and lab["frames"] == t["frames"]
        segs = lab["segments"]
        assert segs[0][0] == 0 and segs[-1][1] == lab["frames"]
        assert all(a[1] == b[0] for a, b in zip(segs[:-1], segs[1:]))
        assert all(s[0] < s[1] and s[2] in LABELS for s in segs)
        # hubs sit on segment boundaries
        bounds = {s[0] for s in segs} | {lab["frames"] - 1}
        assert all(f in bounds for f, _ in lab["hubs"])
    assert q["summary"]["labels_tile_frames"]


# -- acceptance metrics on one minute (the checker is independent of the generator) ----------------
def test_feet_are_planted_while_in_contact(one_minute):
    s = one_minute[2]["summary"]
    assert s["foot_contact_mean_speed_m_s"] <= 0.03
    for t in one_minute[2]["takes"]:
        assert 0.3 < t["foot_contact"]["contact_fraction"] < 0.95


def test_cadence_and_step_length_follow_the_human_relation(one_minute):
    s = one_minute[2]["summary"]
    bins = [b for b in s["cadence"]["walk"]["bins"] if b["steps"] >= 5]
    assert bins, "no walking steps detected"
    for b in bins:
        assert 0.85 <= b["cadence_ratio"] <= 1.15, b
        assert abs(b["step_length_m"] - b["reference_step_length_m"]) <= 0.15 * b["reference_step_length_m"], b
    assert s["cadence_within_15pct"]


def test_knees_stay_inside_human_limits(one_minute):
    s = one_minute[2]["summary"]
    assert s["max_knee_flexion_deg"] <= 150.0
    assert s["hyperextended_frames"] == 0


def test_no_pops(one_minute):
    # a knee in fast swing turns ~20 deg per frame at 30 Hz; a pop is a much larger jump
    assert one_minute[2]["summary"]["max_rotation_step_deg"] < 35.0


def test_hub_poses_repeat_nearly_exactly(one_minute):
    hubs = one_minute[2]["summary"]["hubs"]
    assert {"stand", "walk_l", "walk_r"} <= set(hubs)
    for name, h in hubs.items():
        assert h["max_joint_deviation_m"] < 0.02, (name, h)


@pytest.mark.slow
def test_three_minutes_seed_0_acceptance(tmp_path):
    write_session(tmp_path, 3.0, seed=0)
    q = take_quality(tmp_path)
    s = q["summary"]
    assert abs(s["seconds"] - 180.0) < 15.0
    assert s["foot_contact_mean_speed_m_s"] <= 0.03
    assert s["cadence_within_15pct"]
    assert s["max_knee_flexion_deg"] <= 150.0 and s["hyperextended_frames"] == 0
    for lab in LABELS:
        assert s["label_occurrences"].get(lab, 0) >= 2, (lab, s["label_occurrences"])


# -- internals that the metrics rely on ---------------------------------------------------------
def test_planted_ankles_are_exactly_still_between_heel_strike_and_heel_off():
    edges = [("start", 3, 0.0), ("walk", 5, np.radians(60.0), 0.3), ("stop", 2, 0.0)]
    plan = gait.plan_run(gait.WALK, edges, 0.0, 0.0, 0.0, 0, 30.0)
    ankle, fq, toe, swing, roll = gait.foot_tracks(plan.prints, plan.times)
    for p in plan.prints:
        lo = max(p.t_land, 0.0)
        hi = min(p.t_heeloff, plan.times[-1])
        m = (plan.times >= lo) & (plan.times <= hi)
        if m.sum() < 2:
            continue
        a = ankle[m, p.side]
        assert np.abs(a[:, [0, 2]] - a[0, [0, 2]]).max() < 1e-12
    # toes: the ball of the foot stays put through the toe rocker
    sk = make_skeleton()
    c = run_controls(plan, sk)
    sol = solve(sk, c)
    assert sol.leg_reach_error.max() < 1e-9
    gp = Clip.from_world(sk, 30.0, sol.root_pos, sol.local).positions()
    for p in plan.prints:
        if not (np.isfinite(p.t_heeloff) and np.isfinite(p.t_lift)):
            continue
        m = (plan.times >= p.t_heeloff) & (plan.times <= p.t_lift)
        ball = gp[m, body.J.LeftToeBase if p.side == 0 else body.J.RightToeBase]
        if len(ball) > 1:
            assert np.abs(ball - ball[0]).max() < 1e-6


def test_walk_edges_reach_the_hub_exactly_on_whole_frames():
    edges = [("start", 2, 0.2), ("walk", 3, -0.7, -0.4), ("walk", 6, 1.2, 0.4), ("stop", 3, 0.0)]
    plan = gait.plan_run(gait.WALK, edges, 1.0, 2.0, 0.5, 1, 30.0)
    hubs = [f for f, h in plan.hubs if h.startswith("walk")]
    assert len(hubs) == 3
    # at every hub frame: hub speed, no turning, phase an integer
    for f in hubs:
        assert abs(plan.speed[f] - gait.WALK.v_hub) < 1e-9
        assert abs(plan.turn_rate[f]) < 1e-6
        assert abs(plan.phi[f] - round(plan.phi[f])) < 1e-9
    # the run ends standing where its path ends, with the heading turned as planned
    assert abs(plan.end_state[2] - (0.5 + 0.2 - 0.7 + 1.2)) < 1e-9


def test_generation_rejects_bad_arguments():
    with pytest.raises(ValueError):
        generate_session(0.0, 0)
    with pytest.raises(ValueError):
        generate_session(1.0, 0, fps=0.0)


# -- CLI ----------------------------------------------------------------------------------------
def test_capture_command(tmp_path, capsys):
    from authoring.cli import main

    rc = main(["capture", "--minutes", "0.3", "--seed", "5", "--out", str(tmp_path / "cap"),
               "--take-minutes", "0.2", "--quiet"])
    assert rc == 0
    out = capsys.readouterr().out
    assert "wrote 1 takes" in out or "wrote 2 takes" in out
    assert "foot sliding in contact" in out
    assert (tmp_path / "cap" / "session.json").exists()
    rc = main(["capture", "--minutes", "0", "--out", str(tmp_path / "bad"), "--quiet"])
    assert rc == 2
    assert "argument --minutes: must be a finite number greater than 0" in capsys.readouterr().err
