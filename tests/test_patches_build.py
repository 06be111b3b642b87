"""Patch construction (authoring.patches, Kim, Hwang, Hyun and Lee 2012, section 4): Eq. 4 and Eq. 5, episode
detection against the ground truth of the procedural takes, pose clustering and the boundary
subset search, the patches built (constraints, snapped boundary poses, eventless cuts), and
``crowdweave author patches`` end to end."""
from __future__ import annotations

import numpy as np
import pytest

from authoring.patches.boundaries import BoundaryParams, cluster_poses, group_order, select_subset
from authoring.patches.build import PatchBuildParams, build_patch_library
from authoring.patches.episodes import (EpisodeParams, detect_episodes, pair_signals,
                                        score_against_ground_truth)
from authoring.patches.features import PersonFeatures, motion_variation, pose_vectors
from authoring.takes import generate_takes, import_cmu_duet
from runtime.tiling.patch import PatchLibrary

SALSA = ("cmu_60_10_salsa_duet_A_male.bvh", "cmu_61_10_salsa_duet_B_female.bvh")


@pytest.fixture(scope="module")
def takes0():
    return generate_takes(0)


@pytest.fixture(scope="module")
def small_build():
    takes = generate_takes(4, kinds=("handshake", "bow", "box_pass", "walker"))
    return takes, build_patch_library(takes)


# -- Eq. 4 and Eq. 5 ------------------------------------------------------------------------------
def test_motion_variation_is_eq4():
    rng = np.random.default_rng(1)
    pose = rng.normal(size=(40, 7, 3))
    w = 3
    v = motion_variation(pose, w)
    for i in (0, 2, 10, 25, 39):
        lo, hi = max(i - w, 0), min(i + w, 39)
        brute = sum(np.sum((pose[a] - pose[b]) ** 2) for a in range(lo, hi + 1) for b in range(a + 1, hi + 1))
        assert v[i] == pytest.approx(brute / 7, rel=1e-9)
    still = np.repeat(pose[:1], 20, axis=0)
    assert np.allclose(motion_variation(still, w), 0.0)


def test_pose_vectors_ignore_ground_position_and_heading(takes0):
    c = takes0[0].clips[0]
    moved = c.with_origin(c.origin + np.array([3.0, -2.0, 1.1]))
    assert np.abs(pose_vectors(c) - pose_vectors(moved)).max() < 1e-6     # float32 rotations
    assert np.abs(c.positions() - moved.positions()).max() > 1.0


def _still_person(x, z, gaze, F=10):
    pts = np.zeros((F, 13, 3))
    pts[:, :, 0], pts[:, :, 2] = x, z
    pts[:, :, 1] = np.linspace(0.1, 1.7, 13)
    return PersonFeatures(root_xz=np.tile([x, z], (F, 1)), heading=np.zeros(F), pose=np.zeros((F, 3, 3)),
                          points=pts, radii=np.full(13, 0.05), gaze=np.tile(gaze, (F, 1)),
                          face=np.tile([x, 1.6, z], (F, 1)), chest=np.tile([x, 1.3, z], (F, 1)),
                          variation=np.zeros(F), fps=30.0)


def test_synchronicity_needs_both_acting_and_looking():
    a = _still_person(0.0, 0.0, [0.0, -0.2, 1.0])
    b = _still_person(0.0, 3.0, [0.0, -0.2, -1.0])
    away = _still_person(0.0, 3.0, [0.0, 0.0, 1.0])
    act = np.full(10, 0.3)
    _, _, dist, s_face = pair_signals(a, b, act, act)
    _, _, _, s_away = pair_signals(a, away, act, act)
    _, _, _, s_one = pair_signals(a, b, act, np.zeros(10))
    assert np.allclose(dist, 3.0)
    assert s_face.min() > 0.05 and s_away.max() < 0.5 * s_face.min() and np.all(s_one == 0)
    # Eq. 5 by hand: V_A V_B exp(-g(A,B)) exp(-g(B,A)); g = angle(gaze, chest_B - face_A)
    g = np.arccos(np.dot([0, -0.2, 1.0], [0, -0.3, 3.0]) / (np.linalg.norm([0, -0.2, 1.0]) * np.linalg.norm([0, -0.3, 3.0])))
    assert s_face[0] == pytest.approx(0.09 * np.exp(-2 * g), rel=1e-9)


# -- episode detection against the ground truth ---------------------------------------------------
def _score(takes, params=None):
    tot = {"gt": 0, "found": 0, "eps": 0, "correct": 0}
    per = {}
    for tk in takes:
        eps = detect_episodes(tk, params)
        r = score_against_ground_truth(eps, tk.events, tk.fps)
        per[tk.name] = (eps, r)
        tot["gt"] += r["gt_events"]
        tot["found"] += r["found"]
        tot["eps"] += r["episodes"]
        tot["correct"] += r["correct"]
    return tot, per


def test_episode_detection_finds_the_ground_truth(takes0):
    tot, per = _score(takes0)
    assert tot["gt"] >= 10
    recall, precision = tot["found"] / tot["gt"], tot["correct"] / tot["eps"]
    assert recall == 1.0, [r["missed"] for _, r in per.values() if r["missed"]]
    assert precision >= 0.9, [r["spurious"] for _, r in per.values() if r["spurious"]]
    for name, (eps, _) in per.items():
        if name.startswith(("walker", "pair_apart")):
            assert eps == [], name                       # nothing on performers that never meet
        if name.startswith("handshake_bystander"):
            assert all(2 not in e.people for e in eps)   # the bystander 11 m away is never involved
        if name.startswith(("relay", "bow3")):
            assert any(len(e.people) == 3 for e in eps)  # nearby events merged into one 3-person episode


def test_contact_detection_matches_the_designed_contact(takes0):
    from authoring.patches.episodes import detect_events
    for tk in takes0:
        for g in tk.events:
            if g["kind"] != "contact":
                continue
            got = [e for e in detect_events(tk) if e.kind == "contact" and set(e.people) == set(g["people"])
                   and e.start <= g["end"] and e.end >= g["start"]]
            assert got, (tk.name, g)
            covered = set().union(*[set(e.contact_frames) for e in got])
            want = set(range(g["start"], g["end"] + 1))
            assert len(want & covered) >= 0.8 * len(want), (tk.name, g)


def test_thresholds_matter(takes0):
    """Without the approach requirement and the locomotion exclusion, walking past and
    walking off are taken for reactions: the detector's precision drops."""
    loose = EpisodeParams(approach_m=-1.0, locomotion_speed=99.0, baseline_factor=0.0)
    tot, _ = _score(takes0, loose)
    assert tot["correct"] / tot["eps"] < 0.9


@pytest.mark.slow
def test_episode_detection_over_more_seeds():
    takes = [t for s in (1, 2, 3) for t in generate_takes(s)]
    tot, per = _score(takes)
    assert tot["found"] / tot["gt"] >= 0.97
    assert tot["correct"] / tot["eps"] >= 0.95


# -- clustering and boundary selection -------------------------------------------------------------
def test_complete_linkage_groups_are_tight_and_deterministic():
    rng = np.random.default_rng(3)
    X = np.concatenate([rng.normal(c, 0.01, size=(30, 4)) for c in (0.0, 0.2, 0.5)] + [rng.normal(0, 0.3, (20, 4))])
    lab = cluster_poses(X, 0.06)
    assert np.array_equal(lab, cluster_poses(X.copy(), 0.06))
    for g in np.unique(lab):
        m = X[lab == g]
        if len(m) > 1:
            assert np.linalg.norm(m[:, None] - m[None], axis=-1).max() <= 0.06 + 1e-12
    order = group_order(lab)
    sizes = [np.sum(lab == g) for g in order]
    assert sizes == sorted(sizes, reverse=True) and sizes[0] >= 30


def test_subset_search_trades_diversity_against_size():
    # 3 episodes x 2 sides; group 0 reaches every side but far away, group 1 only some, close by
    pads = np.array([[90, 5], [90, 5], [90, 8], [90, np.inf], [90, 4], [90, 6]], float)
    close = np.full(6, np.inf)
    ep = np.array([0, 0, 1, 1, 2, 2])
    cheap = BoundaryParams(weight=10.0)
    mask, cost, _ = select_subset(pads, close, ep, 3, cheap)
    assert mask.tolist() == [True, True] and cost == pytest.approx(2 * 10 + 5 + 5 + 8 + 90 + 4 + 6)
    dear = BoundaryParams(weight=500.0)
    mask, cost, _ = select_subset(pads, close, ep, 3, dear)
    assert mask.tolist() == [True, False] and cost == pytest.approx(500 + 6 * 90)
    # a group that leaves an episode without a boundary costs the infeasible price
    only1 = select_subset(pads[:, 1:], close, ep, 3, cheap)
    assert only1[1] == pytest.approx(10 + 5 + 5 + 4 + 6 + cheap.infeasible_cost)


# -- the patches ---------------------------------------------------------------------------------------
def test_built_patches_are_consistent(small_build):
    takes, res = small_build
    lib = res.library
    multi = [p for p in lib.patches if "multi" in p.labels]
    single = [p for p in lib.patches if "single" in p.labels]
    assert len(multi) == sum(len(v) for v in res.episodes.values()) - len(res.dropped) >= 3
    assert len(single) >= 5 and {"walk", "turn"} <= {lab for p in single for lab in p.labels}
    labels = {lab for p in multi for lab in p.labels}
    assert {"handshake", "bow", "box_pass", "contact", "2p"} <= labels
    ncls = lib.num_pose_classes
    assert 1 <= ncls == len(res.chosen) <= 10
    margin = int(round(BoundaryParams().margin_s * 30))
    for p in multi:
        assert p.constraint_error() < 1e-9 and len(p.constraints) >= 1
        assert all(0 <= c.frag_a < p.num_characters for c in p.constraints)
        tk = next(t for t in takes if t.name == p.meta["take"])
        a, b = p.meta["frames"]
        for f, e0, e1 in zip(p.fragments, p.meta["entry_frames"], p.meta["exit_frames"]):
            assert e0 <= a - margin and e1 >= b + margin                    # cuts outside the episode
            assert f.num_frames == e1 - e0 + 1
            for cls, i in ((f.entry_class, 0), (f.exit_class, -1)):
                if cls >= 0:                                                # snapped to the class pose
                    q = np.abs(np.sum(f.rotations[i].astype(np.float64) * lib.pose_class_rotations[cls], axis=-1))
                    assert q.min() > 1 - 1e-5
                    assert abs(f.root_height[i] - lib.pose_class_height[cls]) < 1e-5
        assert p.duration == pytest.approx(max(f.t1(30.0) for f in p.fragments))
        del tk
    # every class has both an entry and an exit somewhere (the library can be stitched)
    ins = {f.entry_class for p in lib.patches for f in p.fragments}
    outs = {f.exit_class for p in lib.patches for f in p.fragments}
    assert set(range(ncls)) <= ins and set(range(ncls)) <= outs


def test_build_is_deterministic(small_build, tmp_path):
    takes, res = small_build
    again = build_patch_library(takes)
    res.library.save(tmp_path / "a.cwpack")
    again.library.save(tmp_path / "b.cwpack")
    assert (tmp_path / "a.cwpack").read_bytes() == (tmp_path / "b.cwpack").read_bytes()
    back = PatchLibrary.load(tmp_path / "a.cwpack")
    assert back.summary() == res.library.summary()


def test_weight_controls_the_number_of_pose_classes(small_build):
    takes, res = small_build
    few = build_patch_library(takes, PatchBuildParams(boundaries=BoundaryParams(weight=5000.0)), singles="none")
    many = build_patch_library(takes, PatchBuildParams(boundaries=BoundaryParams(weight=0.0)), singles="none")
    assert len(few.chosen) <= len(res.chosen) <= len(many.chosen)
    size = lambda r: sum(p.num_frames for p in r.library.patches)          # noqa: E731
    assert len(few.chosen) < len(many.chosen)
    assert size(many) <= size(few)


# -- CLI ------------------------------------------------------------------------------------------------
def test_author_patches_cli_end_to_end(tmp_path, capsys):
    from authoring.cli import main

    tk = tmp_path / "takes"
    assert main(["capture", "--takes", "--kinds", "high_five,bump,walker", "--seed", "1", "--out", str(tk),
                 "--quiet", "--no-check"]) == 0
    out = tmp_path / "p.cwpack"
    rc = main(["author", "patches", str(tk), "--out", str(out), "--singles", "takes", "--quiet"])
    text = capsys.readouterr().out
    assert rc == 0, text
    lib = PatchLibrary.load(out)
    s = lib.summary()
    assert s["labels"].get("high_five", 0) >= 1 and s["labels"].get("bump", 0) >= 1
    assert s["characters_per_patch"].get(1, 0) >= 3 and s["characters_per_patch"].get(2, 0) >= 2
    assert "multi-character" in text and "labels:" in text
    # errors name the file
    rc = main(["author", "patches", str(tmp_path / "missing"), "--out", str(tmp_path / "x.cwpack"), "--quiet"])
    assert rc == 2 and "missing" in capsys.readouterr().err
    bad = tk / "walker_002" / "A.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n")
    rc = main(["author", "patches", str(tk), "--out", str(tmp_path / "y.cwpack"), "--quiet"])
    assert rc == 2 and "A.bvh" in capsys.readouterr().err


@pytest.mark.slow
def test_patches_stitch_to_the_default_library(small_build, default_graph):
    takes, _ = small_build
    res = build_patch_library(takes, graph=default_graph, singles="graph")
    lib = res.library
    multi = [p for p in lib.patches if "multi" in p.labels]
    assert multi and any("single" in p.labels for p in lib.patches)
    used = {lib.pose_class_names[c] for p in multi for f in p.fragments for c in (f.entry_class, f.exit_class) if c >= 0}
    assert used and all(n.startswith("node:") for n in used)      # boundary classes are the graph's hubs
    single_in = {f.entry_class for p in lib.patches if "single" in p.labels for f in p.fragments}
    assert {lib.pose_class_names.index(n) for n in used} <= single_in


@pytest.mark.slow
def test_salsa_episodes_and_patches(cmu_dir):
    tk = import_cmu_duet(cmu_dir / SALSA[0], cmu_dir / SALSA[1])
    eps = detect_episodes(tk)
    assert len(eps) >= 2 and all(e.people == (0, 1) for e in eps)
    res = build_patch_library([tk], PatchBuildParams(boundaries=BoundaryParams(threshold=0.15)), singles="none")
    assert len(res.library.patches) >= 1
    assert all(p.constraint_error() < 1e-9 for p in res.library.patches)
