"""Motion libraries from real capture without labels: labels derived from the motion
(authoring.motion_graph.derive), the build report (seconds kept of seconds given per file, what
the library can do and lacks), and the library built from the CMU MotionBuilder-family files
planning a 20-character meeting scenario that the independent checker passes.

The CMU files are read from ``../shared/mocap/cmu`` beside the repository (never copied into
it); the tests that need them are skipped when it is absent."""
from __future__ import annotations

import collections
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
CMU = ROOT.parent / "shared" / "mocap" / "cmu"

# The MotionBuilder-family files (A and A'): walks, a run, hops with turns on the spot, walking
# on uneven ground with turns, dribbling with 90-degree turns on the spot, walking forward /
# backward / sideways.
MB_FILES = ["cmu_02_01_walk.bvh", "cmu_07_05_slow_walk.bvh", "cmu_05_01_walk.bvh",
            "cmu_16_11_walk_veer_left_retargeted.bvh", "cmu_09_06_run.bvh", "cmu_01_01_jumps_turn_around.bvh",
            "cmu_03_03_walk_uneven_terrain_turns.bvh", "cmu_06_10_dribble_fwd_90deg_left_turns.bvh",
            "cmu_06_11_dribble_fwd_90deg_right_turns.bvh", "cmu_09_12_navigate_walk_fwd_back_sideways.bvh"]


def _quiet(*_a, **_k):
    pass


# -- derived labels against a generator's ground truth (no CMU data needed) -----------------------

@pytest.fixture(scope="module")
def generated_takes():
    from authoring.procedural.session import generate_session
    return generate_session(2.0, 3)


def test_derived_labels_agree_with_the_generators_labels(generated_takes):
    """The procedural generator knows what it made: walking frames are derived as walking,
    standing as standing, turns on the spot as turning (or standing, where it turns slowly),
    none of its flat-ground locomotion is left out, and sitting is left out as crouching or
    sitting."""
    from authoring.motion_graph.derive import DROPPED, derive_labels
    pairs = collections.Counter()
    for tk in generated_takes:
        truth = np.empty(tk.clip.num_frames, dtype=object)
        for a, b, lab in tk.labels_json()["segments"]:
            truth[a:b] = lab
        for t, d in zip(truth, derive_labels(tk.clip)):
            pairs[(t, d)] += 1

    def share(truth, derived):
        n = sum(v for (t, _), v in pairs.items() if t == truth)
        return sum(pairs[(truth, d)] for d in derived) / n

    assert share("walk", ["walk"]) >= 0.95
    assert share("idle", ["idle"]) >= 0.95
    assert share("turn", ["turn", "idle"]) >= 0.95 and share("turn", ["turn"]) >= 0.3
    flat = ("walk", "idle", "turn", "start", "stop")
    assert not any(d in DROPPED for (t, d) in pairs if t in flat), {k: v for k, v in pairs.items() if k[1] in DROPPED}
    assert share("sit", ["low"]) >= 0.95             # seated: left out, never a standing pose


def _legs_clip(root, swing_l, swing_r, fps=30.0):
    """A clip of a hip with two 0.9 m legs: ``root`` (F, 3) positions (facing +Z), each leg
    swung 20 deg forward (its foot lifted 5 cm) on the frames where ``swing_*`` is True."""
    from runtime.motion import Clip, Skeleton, quat
    names = ["Hips", "LeftUpLeg", "LeftFoot", "RightUpLeg", "RightFoot"]
    offsets = np.array([[0, 0, 0], [0.1, 0, 0], [0, -0.9, 0], [-0.1, 0, 0], [0, -0.9, 0]], dtype=float)
    sk = Skeleton(names, np.array([-1, 0, 1, 0, 3]), offsets)
    rot = np.tile(quat.identity(), (len(root), 5, 1))
    lift = quat.from_axis_angle(np.array([1.0, 0.0, 0.0]), np.radians(-20.0))
    rot[swing_l, 1] = lift
    rot[swing_r, 3] = lift
    return Clip.from_world(sk, fps, root, rot)


def test_backward_walking_and_hops_are_left_out():
    """Synthetic legs: the same alternating steps are walking when the root travels the way
    it faces and backward travel the other way; both feet off the ground at once is a hop."""
    from authoring.motion_graph.derive import derive_labels
    F, fps = 150, 30.0
    t = np.arange(F) / fps
    root = np.column_stack([np.zeros(F), np.full(F, 0.95), 1.0 * t])
    left = np.sin(2 * np.pi * t) > 0.1
    right = np.sin(2 * np.pi * t) < -0.1
    fwd = collections.Counter(derive_labels(_legs_clip(root, left, right)))
    assert fwd["walk"] >= 0.9 * F, fwd
    back = collections.Counter(derive_labels(_legs_clip(root * [1, 1, -1], left, right)))
    assert back["backward"] >= 0.8 * F, back
    hop = (t > 2.0) & (t < 2.4)
    hopping = root.copy()
    hopping[hop, 1] += 0.3
    lab = derive_labels(_legs_clip(hopping, left | hop, right | hop))
    assert all(lab[k] == "jump" for k in np.flatnonzero(hop)), lab
    assert collections.Counter(lab)["walk"] >= 0.5 * F


def test_a_library_from_unlabelled_generated_bvh_reports_what_it_kept_and_lacks(generated_takes, tmp_path):
    """Generated takes written as BVH without their label sidecars: the whole pipeline on
    derived labels. Every second is accounted for; the library stands, stands still, stops,
    starts and walks; sitting and carrying cannot be derived from the motion, and the report
    says so."""
    from authoring.bvh import write_bvh
    from authoring.motion_graph.library import build_library
    from authoring.procedural import body
    for i, tk in enumerate(generated_takes):
        write_bvh(tmp_path / f"take_{i}.bvh", tk.clip, channel_orders="ZYX", scale=body.CMU_UNIT, precision=6)
    g, lines = build_library([tmp_path], log=_quiet)
    rep = g.meta["build_report"]
    for r in rep["sources"]:
        assert r["kept_s"] + sum(r["dropped"].values()) == pytest.approx(r["given_s"], abs=0.05), r
        assert r["kept_mirrored_s"] is None
        assert r["dropped"].get("not walking-like: crouching or sitting (root low over the feet)", 0) > 0
    assert sum(r["kept_s"] for r in rep["sources"]) == pytest.approx(g.total_seconds, abs=0.05)
    caps = rep["capabilities"]
    assert set(g.node_labels_all()) == {"stand", "walk"}
    assert caps["still_nodes"] >= 1 and caps["stop_edges"] >= 1 and caps["start_edges"] >= 1
    assert [m.split(":")[0] for m in caps["missing"] if m.startswith(("sit", "carry"))] == ["sit", "carry"]
    assert lines[0] == "per file: seconds kept of seconds given (dropped: reason)"


# -- the CMU MotionBuilder-family library -----------------------------------------------------------

@pytest.fixture(scope="session")
def cmu_library(tmp_path_factory):
    """(pack path, graph, report lines) of the library built from the MotionBuilder-family
    files with their mirrored copies, once per session."""
    if not CMU.is_dir():
        pytest.skip(f"CMU motion capture not found at {CMU} (../shared/mocap/cmu beside the project)")
    from authoring.motion_graph.library import build_library
    from runtime.motion.graph import MotionGraph
    g, lines = build_library([CMU / f for f in MB_FILES], mirror=True, log=_quiet)
    path = tmp_path_factory.mktemp("cmu_library") / "cmu_mb.cwpack"
    g.save(path)
    return path, MotionGraph.load(path), lines


def test_report_accounts_for_every_second_of_every_file(cmu_library):
    _, g, _ = cmu_library
    rep = {r["file"]: r for r in g.meta["build_report"]["sources"]}
    assert sorted(rep) == sorted(MB_FILES)
    for r in rep.values():
        assert r["kept_s"] + sum(r["dropped"].values()) == pytest.approx(r["given_s"], abs=0.05), r
        assert 0 <= r["kept_s"] <= r["given_s"] and r["kept_mirrored_s"] is not None
    # what is left out, and why
    uneven = rep["cmu_03_03_walk_uneven_terrain_turns.bvh"]
    assert uneven["dropped"].get("uneven ground: steps up or down", 0) >= 0.9 * uneven["given_s"]
    hops = rep["cmu_01_01_jumps_turn_around.bvh"]
    assert hops["dropped"]["not walking-like: hops or jumps (both feet off the ground)"] >= 8.0
    assert hops["kept_s"] >= 2.0                     # its standing and turns on the spot
    back = rep["cmu_09_12_navigate_walk_fwd_back_sideways.bvh"]
    assert back["dropped"]["not walking-like: walks backward"] >= 5.0 and back["kept_s"] >= 5.0
    for f in ("cmu_02_01_walk.bvh", "cmu_07_05_slow_walk.bvh", "cmu_05_01_walk.bvh",
              "cmu_16_11_walk_veer_left_retargeted.bvh", "cmu_06_10_dribble_fwd_90deg_left_turns.bvh",
              "cmu_06_11_dribble_fwd_90deg_right_turns.bvh"):
        assert rep[f]["kept_s"] >= 0.6 * rep[f]["given_s"], rep[f]
    # the graph holds exactly what the report says it kept
    kept = sum(r["kept_s"] + r["kept_mirrored_s"] for r in rep.values())
    assert kept == pytest.approx(g.total_seconds, abs=0.05 * len(rep))


def test_library_can_stand_still_stop_start_and_turn_and_says_what_it_lacks(cmu_library):
    from runtime.crowd.idle import still_nodes
    _, g, lines = cmu_library
    caps = g.meta["build_report"]["capabilities"]
    assert set(g.node_labels_all()) == {"stand", "walk"}
    still = still_nodes(g, (0.02, 2.0, 1 / 15))
    assert still.any() and all("stand" in g.node_labels[n] for n in np.flatnonzero(still))
    assert caps["still_nodes"] == int(still.sum())
    assert caps["stop_edges"] >= 2 and caps["start_edges"] >= 2 and caps["turn_on_spot_edges"] >= 4
    lo, hi = caps["turn_on_spot_deg"]
    assert lo <= -90 and hi >= 90                    # mirrored copies turn both ways
    assert [m.split(":")[0] for m in caps["missing"]] == ["sit", "carry"]
    assert any(line.startswith("  missing: sit") for line in lines)
    # no hub mixes standing and walking poses
    assert all(len(labs) == 1 for labs in g.node_labels)


def test_a_pose_the_library_lacks_is_an_error_naming_the_library(cmu_library):
    from runtime.crowd.scenario import ScenarioError, parse_scenario
    path, g, _ = cmu_library
    sc = {"name": "sit", "library": str(path), "duration": 10.0,
          "character": [{"name": "a", "start": {"position": [0.0, 0.0], "pose": "stand"},
                         "goal": [{"position": [3.0, 0.0], "pose": "sit"}]}]}
    with pytest.raises(ScenarioError, match=r"pose 'sit' is not in the library '.*cmu_mb\.cwpack' "
                                            r"\(it has \['stand', 'walk'\]\)"):
        parse_scenario(sc, "sit.toml", node_labels=set(g.node_labels_all()))


def test_info_prints_the_build_report(cmu_library, capsys):
    from authoring.cli import main as cli_main
    path, _, lines = cmu_library
    assert cli_main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "build report:" in out
    for line in lines:
        assert line in out


def test_meeting_scenario_planned_with_the_cmu_library_passes_the_checker(cmu_library, tmp_path):
    """20 characters in the meeting layout of the samples (Sung, Kovar and Gleicher 2005,
    Experiment 1): pairs, triangles and a square on a ring, all arriving in [12, 12.5] s at an
    exact position and heading, pose "stand"; the scenario names the CMU library by path."""
    sys.path.insert(0, str(ROOT / "samples"))
    from crowd_samples.meet import meet_scenario
    from crowd_samples.scenario_file import scenario_toml
    from runtime.crowd.checker import check_crowd
    from runtime.crowd.scenario import load_scenario
    from runtime.crowd.scheduler import plan_scenario
    from runtime.library import load_library
    path, _, _ = cmu_library
    d = meet_scenario(name="meet20_cmu")
    d["library"] = str(path)
    toml = tmp_path / "scenario.toml"
    toml.write_text(scenario_toml(d))
    g = load_library(d["library"], tmp_path)
    sc = load_scenario(toml, node_labels=set(g.node_labels_all()))
    assert len(sc.characters) == 20 and all(gl.time is not None and gl.heading is not None
                                           for c in sc.characters for gl in c.goals)
    res = plan_scenario(sc, g)
    rep = check_crowd(sc, {c.name: c.track for c in res.characters}, g)
    assert rep.passed, rep.summary()
    # "stand" means standing: from its arrival on, every character plays standing clips only
    arrived = {r["character"]: r["frame"] for r in rep.goals}
    for c in res.characters:
        f = c.track.frames_a[arrived[c.name] + 1:]
        edges = np.unique(np.searchsorted(g.edge_start, f, side="right") - 1)
        assert {lab for e in edges for lab in g.edge_labels[e]} <= {"idle", "turn"}, c.name
