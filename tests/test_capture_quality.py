"""The capture quality checker (authoring.capture_quality) must catch what it claims to catch:
sliding feet, wrong cadence, hyperextended knees, pops and broken label sidecars. Each test
breaks a good take (or builds a bad one) and checks the figure moves the right way."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from authoring.bvh import read_bvh, write_bvh
from authoring.capture_quality import bvh_take_quality, reference_cadence, take_quality
from authoring.procedural import make_skeleton, write_session
from runtime.motion import Clip, quat

CMU = Path(__file__).resolve().parents[1].parent / "shared" / "mocap" / "cmu"
SCALE = 0.05644


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    out = tmp_path_factory.mktemp("good")
    write_session(out, 0.5, seed=7, take_minutes=1.0)
    clip = read_bvh(out / "take_000.bvh").clip
    labels = json.loads((out / "take_000.labels.json").read_text())
    return out, clip, labels, take_quality(out)["summary"]


def _write(d: Path, clip: Clip, labels: dict | None):
    d.mkdir(parents=True, exist_ok=True)
    write_bvh(d / "take_000.bvh", clip, channel_orders="ZYX", scale=SCALE)
    if labels is not None:
        (d / "take_000.labels.json").write_text(json.dumps(labels))
    return take_quality(d)["summary"]


def test_reference_cadence():
    assert reference_cadence(1.3) == pytest.approx(1.845)
    assert reference_cadence(0.0) == pytest.approx(1.0)


def test_good_take_passes(good):
    s = good[3]
    assert s["foot_contact_mean_speed_m_s"] < 0.03
    assert s["hyperextended_frames"] == 0
    assert s["labels_tile_frames"]


def test_sliding_feet_are_measured(good, tmp_path):
    _, clip, labels, s0 = good
    pos, _ = clip.world_root()
    t = np.arange(clip.num_frames) / clip.fps
    pos[:, 0] += 0.15 * t                       # the whole body drifts sideways at 15 cm/s
    slid = Clip.from_world(clip.skeleton, clip.fps, pos, clip.local_rotations_world_root())
    s = _write(tmp_path / "slid", slid, labels)
    assert s["foot_contact_mean_speed_m_s"] > 0.10
    assert s0["foot_contact_mean_speed_m_s"] < 0.03


def test_slow_motion_fails_the_cadence_check(good, tmp_path):
    _, clip, labels, s0 = good
    assert s0["cadence_within_15pct"]
    slow = clip.copy(fps=20.0)                  # same frames played at 2/3 speed
    lab = dict(labels, fps=20.0)
    s = _write(tmp_path / "slow", slow, lab)
    assert not s["cadence_within_15pct"]
    ratios = [b["cadence_ratio"] for b in s["cadence"]["walk"]["bins"] if b["steps"] >= 3]
    assert ratios and max(ratios) < 0.85


def _standing_clip(knee_rad: float, frames=20):
    sk = make_skeleton()
    rot = np.tile([1.0, 0, 0, 0], (frames, sk.num_joints, 1))
    rot[:, sk.index("LeftLeg")] = quat.from_axis_angle(np.array([1.0, 0, 0]), np.full(frames, knee_rad))
    pos = np.tile([0.0, 0.97, 0.0], (frames, 1))
    return Clip.from_world(sk, 30.0, pos, rot)


def test_knee_flexion_and_hyperextension(tmp_path):
    s = _write(tmp_path / "flex", _standing_clip(np.radians(30.0)), None)
    assert s["max_knee_flexion_deg"] == pytest.approx(30.0, abs=0.01)
    assert s["hyperextended_frames"] == 0
    s = _write(tmp_path / "hyper", _standing_clip(np.radians(-12.0)), None)
    assert s["max_knee_hyperextension_deg"] == pytest.approx(12.0, abs=0.01)
    assert s["hyperextended_frames"] == 20


def test_pop_is_found_where_it_is(good, tmp_path):
    _, clip, labels, s0 = good
    rot = clip.local_rotations_world_root()
    j = clip.skeleton.index("RightForeArm")
    f = clip.num_frames // 2
    rot[f, j] = quat.mul(quat.from_axis_angle(np.array([0.0, 1.0, 0.0]), np.radians(50.0)), rot[f, j])
    pos, _ = clip.world_root()
    popped = Clip.from_world(clip.skeleton, clip.fps, pos, rot)
    d = tmp_path / "pop"
    _write(d, popped, labels)
    q = take_quality(d)["takes"][0]["pops"]
    assert q["joint"] == "RightForeArm" and q["at_frame"] in (f - 1, f)
    assert q["max_rotation_step_deg"] > 45.0 > s0["max_rotation_step_deg"]


def test_broken_sidecar_is_reported(good, tmp_path):
    out, clip, labels, _ = good
    d = tmp_path / "gap"
    d.mkdir()
    shutil.copy(out / "take_000.bvh", d / "take_000.bvh")
    lab = dict(labels)
    segs = [list(s) for s in labels["segments"]]
    segs[1][0] += 3                              # a 3-frame hole
    lab["segments"] = segs
    (d / "take_000.labels.json").write_text(json.dumps(lab))
    assert not take_quality(d)["summary"]["labels_tile_frames"]


def test_label_occurrences_merge_consecutive_segments(good):
    _, _, labels, s = good
    segs = labels["segments"]
    runs = sum(1 for i, x in enumerate(segs) if x[2] == "walk" and (i == 0 or segs[i - 1][2] != "walk"))
    assert s["label_occurrences"].get("walk", 0) == runs
    assert s["label_segments"]["walk"] == sum(1 for x in segs if x[2] == "walk")


@pytest.mark.skipif(not CMU.is_dir(), reason=f"CMU developer set not found at {CMU}")
@pytest.mark.parametrize("name", ["cmu_05_01_walk.bvh", "cmu_16_11_walk_veer_left_retargeted.bvh"])
def test_real_walks_give_human_cadence(name):
    q = bvh_take_quality(CMU / name)
    steps = [b for b in q["steps"]["all"]["bins"]]
    n = sum(b["steps"] for b in steps)
    cad = sum(b["cadence_steps_s"] * b["steps"] for b in steps) / n
    assert n >= 4
    assert 1.5 < cad < 2.3                   # real people walking at ~1 m/s
    assert q["knees"]["hyperextended_frames"] <= 2
    assert 40.0 < q["knees"]["max_flexion_deg"] < 90.0
