"""The sample scenarios reproducing paper 000's experiments (issue 4, points 6 and 9).

* every sample parses against its world and the default library (no planning), and its
  layout leaves the room the library's characters need (bounding cylinders: standing ~0.3 m,
  walking up to 0.63 m, sitting 0.62 m);
* ``samples/make_samples.py`` regenerates the committed files byte for byte;
* a reduced meet20 (two facing pairs) bakes end to end through the CLI, the independent
  checker passes and a second bake is byte-identical;
* each bad scenario of issue 4 point 6 is a ``ScenarioError`` naming the character and goal.
"""
from __future__ import annotations

import json
import math
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
sys.path.insert(0, str(SAMPLES))
import make_samples  # noqa: E402

COUNTS = {"meet20": 20, "spell70": 70, "rooms_box": 1, "theater40": 40, "fetch_boxes20": 20,
          "grid300": 300, "grid500": 500}


@pytest.fixture(scope="session")
def graph():
    from authoring.default_library import ensure_library
    from runtime.motion.graph import MotionGraph
    return MotionGraph.load(ensure_library("default", log=lambda m: None, progress=False))


@pytest.fixture(scope="session")
def labels(graph):
    return set(graph.node_labels_all())


def load(name, labels):
    from runtime.crowd.scenario import load_scenario
    from usd_io.world import read_world
    head = tomllib.loads((SAMPLES / name / "scenario.toml").read_text())
    env = read_world(SAMPLES / name / head["world"]) if "world" in head else None
    return load_scenario(SAMPLES / name, env=env, node_labels=labels), env


def test_sample_list_matches_generator():
    assert set(make_samples.SAMPLES) == set(COUNTS)
    for name in COUNTS:
        assert (SAMPLES / name / "scenario.toml").is_file(), name
        assert (SAMPLES / name / "README.md").is_file(), name


@pytest.mark.parametrize("name", sorted(COUNTS))
def test_sample_parses_against_world(name, labels):
    sc, env = load(name, labels)
    assert sc.name == name
    assert len(sc.characters) == COUNTS[name]
    for c in sc.characters:
        assert c.goals, c.name
        if env is not None and c.start_marker is None:
            assert env.distance(c.position[None])[0] >= 0.5, (name, c.name, "start too close to an obstacle")
        for gi, g in enumerate(c.goals):
            if env is not None and g.kind == "position":
                assert env.distance(g.position[None])[0] >= 0.6, (name, c.name, gi)
            if g.time is not None:
                assert 0 < g.time[0] <= g.time[1] <= sc.duration, (name, c.name, gi)
    # start spots leave room for a walker to pass between standing characters
    starts = np.array([c.position for c in sc.characters])
    assert make_samples.min_spacing(starts) >= 1.3, name


def _final(sc):
    return np.array([c.goals[-1].position for c in sc.characters])


def test_meet20_configurations(labels):
    sc, _ = load("meet20", labels)
    final = _final(sc)
    assert make_samples.min_spacing(final) >= 1.19           # partners 1.2 m apart, groups wider
    for c in sc.characters:
        g = c.goals[0]
        assert g.time == (12.0, 12.5) and g.pose == "stand" and g.heading is not None
        # each character faces someone standing 1.2-1.8 m ahead of it
        fwd = np.array([math.sin(g.heading), math.cos(g.heading)])
        rel = final - g.position
        ahead = rel @ fwd
        side = np.abs(rel @ np.array([fwd[1], -fwd[0]]))
        assert np.any((ahead > 1.0) & (ahead < 1.8) & (side < 0.8)), c.name


def test_spell70_letters(labels):
    sc, _ = load("spell70", labels)
    final = _final(sc)
    assert make_samples.min_spacing(final) >= 1.6 - 1e-9
    assert all(c.goals[0].heading == 0.0 for c in sc.characters)          # facing the camera (+Z)
    # 1 s windows opening at 17 s for the front row (+Z) to 17 + stagger for the back one,
    # later the further back
    z = final[:, 1]
    opens = np.array([c.goals[0].time[0] for c in sc.characters])
    assert all(c.goals[0].time[1] - c.goals[0].time[0] == pytest.approx(1.0) for c in sc.characters)
    assert opens[np.argmax(z)] == 17.0 and opens[np.argmin(z)] == 17.0 + make_samples.SPELL_STAGGER
    assert np.all(np.diff(opens[np.argsort(-z, kind="stable")]) >= -1e-9)
    # the letters are read left to right: three clusters along x, 2 m apart (the widest x gaps;
    # inside a letter consecutive points are at most 1.92 m apart along x)
    xs = np.sort(final[:, 0])
    gaps = np.diff(xs)
    assert np.sum(gaps >= 2.0 - 1e-6) == 2 and np.sort(gaps)[-3] < 1.95


def test_theater_and_fetch_seats(labels):
    for name, spacing in (("theater40", 1.5), ("fetch_boxes20", 1.6)):
        sc, env = load(name, labels)
        seats = np.array([m.position for m in env.markers.values() if m.role == "seat"])
        assert make_samples.min_spacing(seats) >= spacing - 1e-9, name
        used = [g.marker for c in sc.characters for g in c.goals if g.kind == "seat"]
        assert len(used) == len(sc.characters) and len(set(used)) == len(used), name
    sc, env = load("fetch_boxes20", labels)
    for c in sc.characters:
        kinds = [g.kind for g in c.goals]
        assert kinds == ["box", "position", "seat"], c.name
        assert c.start_marker == c.goals[2].marker, c.name                 # back to its own seat
        assert c.goals[1].pose == "stand"                                   # the put-down
    boxes = [c.goals[0].marker for c in sc.characters]
    assert len(set(boxes)) == 20
    # no one turns round with a box: the put-down is straight on from the pick-up, along the
    # direction the character faces to pick it up (the carrying clips only turn walking on)
    for c in sc.characters:
        pick, place = c.goals[0], c.goals[1]
        facing = np.array([np.sin(pick.heading), np.cos(pick.heading)])
        np.testing.assert_allclose(place.position - pick.position, make_samples.FETCH_CARRY * facing, atol=1e-9)


def test_rooms_box_route_needs_every_room(labels):
    """The box is reachable from the start room only through the other four rooms."""
    sc, env = load("rooms_box", labels)
    main = sc.character("main")
    assert sc.characters[-1] is main and main.goals[0].kind == "box"
    # the wall between the lower-right and upper-right rooms has no opening
    x = np.linspace(16.3, 23.7, 200)
    assert np.all(env.distance(np.stack([x, np.zeros_like(x)], axis=1)) < 0)
    # and a straight walk from the start to the box is blocked
    assert not env.segment_clear(main.position[None], main.goals[0].position[None], 0.3)[0]


def test_grid_targets_are_a_perturbed_translation():
    data = make_samples.grid_scenario(8, 5, spacing=2.0, seed=3)
    start = np.array([c["start"]["position"] for c in data["character"]])
    target = np.array([c["goal"][0]["position"] for c in data["character"]])
    shift = 0.5 * 8 * 2.0 + 10.0
    # a permutation of the translated grid; every path is the shift along x, and a target is
    # its own cell or a neighbouring row's (a swap: the neighbour takes this one's)
    assert sorted(map(tuple, np.round(target - [shift, 0], 6))) == sorted(map(tuple, np.round(start, 6)))
    off = target - start - [shift, 0.0]
    np.testing.assert_allclose(off[:, 0], 0.0, atol=1e-9)
    assert set(np.round(off[:, 1], 6)) <= {-2.0, 0.0, 2.0}
    swapped = np.flatnonzero(np.abs(off[:, 1]) > 1e-9)
    for k in swapped:
        partner = np.flatnonzero(np.all(np.abs(start - (start[k] + [0.0, off[k, 1]])) < 1e-9, axis=1))
        assert len(partner) == 1 and np.allclose(off[partner[0], 1], -off[k, 1])
    assert len(swapped) >= len(start) // 3                                 # most are perturbed
    assert data == make_samples.grid_scenario(8, 5, spacing=2.0, seed=3)  # seeded
    assert data != make_samples.grid_scenario(8, 5, spacing=2.0, seed=4)


def test_generator_reproduces_committed_files(tmp_path):
    for name in make_samples.SAMPLES:
        make_samples.BUILDERS[name](tmp_path / name)
        for f in sorted((tmp_path / name).iterdir()):
            committed = SAMPLES / name / f.name
            assert committed.read_bytes() == f.read_bytes(), f"{committed} is stale: run samples/make_samples.py"


def test_letters_exactly_n_points():
    for n in (40, 70, 90):
        p = make_samples.letter_points("SCA", n, 1.3)
        assert len(p) == n and make_samples.min_spacing(p) >= 1.3 - 1e-9
    with pytest.raises(ValueError):
        make_samples.letter_points("SCA", 2, 1.3)


# ------------------------------------------------------------------------------------------
def test_small_meet_bakes_and_checker_passes(tmp_path, graph):
    """Two facing pairs (a reduced meet20) through ``crowdweave bake``: exit code 0, one
    SkelRoot per character, the checker's report says passed, and a second bake of the same
    scenario and seed writes a byte-identical stage."""
    from pxr import Usd

    from authoring.cli import main
    data = make_samples.meet_scenario(groups=(2, 2))
    assert len(data["character"]) == 4
    d = tmp_path / "meet4"
    d.mkdir()
    (d / "scenario.toml").write_text(make_samples.scenario_toml(data))
    out, rep = tmp_path / "meet4.usdc", tmp_path / "meet4.json"
    rc = main(["bake", str(d), "--out", str(out), "--report", str(rep), "--quiet"])
    report = json.loads(rep.read_text())
    s = report["summary"]
    assert s["passed"], (s, report.get("warnings"))
    assert rc == 0
    assert s["max_position_error_mm"] <= 1.0 and s["max_heading_error_deg"] <= 0.1
    assert s["goals_in_window"] == s["goals"] == 4
    stage = Usd.Stage.Open(str(out))
    names = sorted(p.GetName() for p in stage.GetPrimAtPath("/World/Characters").GetChildren())
    assert names == [c["name"] for c in data["character"]]
    out2 = tmp_path / "again.usdc"
    assert main(["bake", str(d), "--out", str(out2), "--quiet"]) == 0
    assert out2.read_bytes() == out.read_bytes()


# ------------------------------------------------------------------------------------------
# Issue 4 point 6: bad scenarios are ScenarioErrors before planning, naming character and goal
def _scenario(chars, **top):
    return {"name": "bad", "duration": 30.0, **top, "character": chars}


def _char(name, goals, start=(0.0, 0.0)):
    return {"name": name, "start": {"position": list(start), "heading": 0.0, "pose": "stand"}, "goal": goals}


def _parse(data, labels, env=None):
    from runtime.crowd.scenario import parse_scenario
    return parse_scenario(data, "bad.toml", env=env, node_labels=labels)


def test_bad_dependency_cycle(labels):
    from runtime.crowd.scenario import ScenarioError
    data = _scenario([
        _char("alice", [{"position": [3.0, 0.0]}, {"position": [5.0, 0.0], "after": {"character": "bob", "goal": 0}}]),
        _char("bob", [{"position": [0.0, 4.0], "after": {"character": "alice", "goal": 1}}], start=(0.0, 2.0)),
    ])
    with pytest.raises(ScenarioError) as e:
        _parse(data, labels)
    msg = str(e.value)
    assert "bad.toml" in msg and "cycle" in msg
    assert "alice" in msg and "bob" in msg
    assert "goal 1" in msg or "goal 0" in msg, f"the cycle error should name the goals: {msg}"
    # no cycle: fine
    data["character"][1]["goal"][0]["after"]["goal"] = 0
    data["character"][0]["goal"][1].pop("after")
    _parse(data, labels)


def test_bad_goal_inside_obstacle(labels):
    from runtime.crowd.scenario import ScenarioError
    from usd_io.world import read_world
    env = read_world(SAMPLES / "rooms_box" / "world.usda")
    inside = [11.9, 4.6]                                 # in the lower-middle room's sofa
    assert env.distance(np.array([inside]))[0] < 0
    data = _scenario([_char("walker", [{"position": [14.0, 2.0]}, {"position": inside}], start=(14.0, 6.0))])
    with pytest.raises(ScenarioError) as e:
        _parse(data, labels, env)
    msg = str(e.value)
    assert "'walker'" in msg and "goal 1" in msg and "obstacle" in msg
    data["character"][0]["goal"][1]["position"] = [10.0, 3.0]
    _parse(data, labels, env)


def test_bad_pose_not_in_library(labels):
    from runtime.crowd.scenario import ScenarioError
    assert "dance" not in labels
    data = _scenario([_char("dancer", [{"position": [2.0, 0.0], "pose": "stand"},
                                       {"position": [4.0, 0.0], "pose": "dance"}])])
    with pytest.raises(ScenarioError) as e:
        _parse(data, labels)
    msg = str(e.value)
    assert "'dancer'" in msg and "goal 1" in msg and "dance" in msg
    data["character"][0]["goal"][1]["pose"] = "sit"
    _parse(data, labels)


def test_bad_window_too_short(labels):
    from runtime.crowd.scenario import ScenarioError
    # 20 m in at most 2 s: faster than anything in the library
    data = _scenario([_char("runner", [{"position": [0.0, 20.0], "time": [1.5, 2.0]}])])
    with pytest.raises(ScenarioError) as e:
        _parse(data, labels)
    msg = str(e.value)
    assert "'runner'" in msg and "goal 0" in msg and "too short" in msg
    # a second goal whose window leaves no time after the first one's
    data = _scenario([_char("runner", [{"position": [0.0, 5.0], "time": [8.0, 9.0]},
                                       {"position": [0.0, 25.0], "time": [9.5, 10.0]}])])
    with pytest.raises(ScenarioError) as e:
        _parse(data, labels)
    assert "'runner'" in str(e.value) and "goal 1" in str(e.value)
    # a window holding no frame of the 30 Hz clock
    data = _scenario([_char("runner", [{"position": [0.0, 5.0], "time": [8.01, 8.02]}])])
    with pytest.raises(ScenarioError) as e:
        _parse(data, labels)
    assert "'runner'" in str(e.value) and "goal 0" in str(e.value)
    # reachable: fine
    data = _scenario([_char("runner", [{"position": [0.0, 5.0], "time": [8.0, 9.0]}])])
    _parse(data, labels)


def test_bad_synthesis_start_still(labels):
    from runtime.crowd.scenario import ScenarioError
    data = _scenario([_char("walker", [{"position": [3.0, 0.0]}])], synthesis={"start_still": "yes"})
    with pytest.raises(ScenarioError) as e:
        _parse(data, labels)
    assert "bad.toml" in str(e.value) and "start_still" in str(e.value)
    data["synthesis"]["start_still"] = True
    assert _parse(data, labels).synthesis["start_still"] is True


@pytest.mark.parametrize("bad", ["far", -0.5, 9.0, True])
def test_bad_synthesis_approach_point(labels, bad):
    from runtime.crowd.scenario import ScenarioError
    data = _scenario([_char("walker", [{"position": [3.0, 0.0]}])], synthesis={"approach_point": bad})
    with pytest.raises(ScenarioError) as e:
        _parse(data, labels)
    assert "bad.toml" in str(e.value) and "approach_point" in str(e.value)
    data["synthesis"]["approach_point"] = 1.2
    assert _parse(data, labels).synthesis["approach_point"] == 1.2


def test_bad_start_too_close_to_an_obstacle(labels):
    """A start position nearer an obstacle than a standing character's cylinder overlaps it
    from the first frame: a ScenarioError naming the character and the distance."""
    from runtime.crowd.scenario import START_CLEARANCE, ScenarioError
    from usd_io.world import read_world
    env = read_world(SAMPLES / "rooms_box" / "world.usda")
    inside = np.array([11.9, 4.6])                       # in the lower-middle room's sofa
    # walk out of the sofa until just clear of it, then a little further
    d = np.array([0.0, 1.0])
    ts = np.linspace(0.0, 3.0, 3001)
    dist = env.distance(inside[None] + ts[:, None] * d[None])
    near = inside + ts[np.argmax(dist > 0.5 * START_CLEARANCE)] * d
    far = inside + ts[np.argmax(dist > START_CLEARANCE + 0.05)] * d
    data = _scenario([_char("walker", [{"position": [14.0, 2.0]}], start=tuple(near))])
    with pytest.raises(ScenarioError) as e:
        _parse(data, labels, env)
    msg = str(e.value)
    assert "'walker'" in msg and "start" in msg and "from an obstacle" in msg
    data["character"][0]["start"]["position"] = far.tolist()
    _parse(data, labels, env)
