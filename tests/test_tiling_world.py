"""Interactive tiling as a system of the runtime World: a tiled zone ticks with the crowd and
the flocks, its characters are drawn with the crowd, steered by targets (and by a right-click),
baked like crowd characters, and checked independently."""
import math
import textwrap

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

from runtime.crowd.scenario import ScenarioError, load_scenario
from runtime.tiling.synthetic import synthetic_library
from runtime.tiling.prepared import PreparedLibrary
from runtime.tiling.zone import TeamSpec, TilingZone
from runtime.world import World


@pytest.fixture(scope="module")
def prepared(default_graph):
    return PreparedLibrary(synthetic_library(default_graph, meets=4))


def _zone(prepared, name="z", period=4.0, seed=0):
    teams = [TeamSpec(3, (-3.0, 0.0), math.pi / 2, [(3.0, 0.0), (-0.5, 0.5)]),
             TeamSpec(3, (3.0, 0.0), -math.pi / 2, [(-3.0, 0.0), (0.5, -0.5)])]
    return TilingZone(name, prepared, (-6.0, -5.0, 6.0, 5.0), teams, period=period, seed=seed)


def test_world_ticks_a_tiling_zone_and_draws_its_characters(default_graph, prepared):
    w = World(default_graph, seed=0)
    w.spawn("walker", (0.0, 12.0), 0.0)
    zone = w.add_tiling(_zone(prepared))
    assert len(zone) == 6 and zone.names[0] == "z_0_0"
    start = zone.roots()[:, :2].copy()
    for _ in range(240):
        w.tick()
    pos = w.joint_positions()
    assert pos.shape == (1 + 6, default_graph.skeleton.num_joints, 3)
    roots = zone.roots()
    assert np.isfinite(roots).all()
    # the tiled rows of the drawn poses are where the zone says its characters are
    assert np.abs(pos[1:, 0, [0, 2]] - roots[:, :2]).max() < 0.05
    # they moved toward their first targets (the teams swap ends) and stayed in the zone
    assert np.mean(roots[:3, 0] - start[:3, 0]) > 1.5 and np.mean(roots[3:, 0] - start[3:, 0]) < -1.5
    assert (roots[:, 0] > -6).all() and (roots[:, 0] < 6).all() and (np.abs(roots[:, 1]) < 5).all()
    stats = w.hud_stats()
    assert stats["tiled"] == 6 and "tiling ms" in stats
    rep = zone.check().summary()
    assert rep["danglings"] == 0 and rep["interpenetrations"] == 0 and rep["frames_over_limits"] == 0, rep
    assert rep["characters"] == 6


def test_right_click_steers_a_tiled_characters_team(default_graph, prepared):
    w = World(default_graph, seed=0)
    zone = w.add_tiling(_zone(prepared, period=1000.0))
    for _ in range(10):
        w.tick()
    start = np.linalg.norm(zone.roots()[3:, :2].mean(0) - (-3.0, 3.0))
    w.command_go_to(4, np.array([-3.0, 3.0]))          # character 4 = team 1 (no crowd characters)
    assert np.allclose(zone.tiling.targets[1][0], (-3.0, 3.0))
    assert np.allclose(zone.tiling.targets[0][0], (3.0, 0.0))   # the other team keeps its target
    for _ in range(600):
        w.tick()
    end = np.linalg.norm(zone.roots()[3:, :2].mean(0) - (-3.0, 3.0))
    assert end < 0.5 * start, (start, end)
    w.command_go_to(4, np.array([-40.0, 30.0]))        # clamped into the zone
    assert np.allclose(zone.tiling.targets[1][0], (-5.0, 4.0))


def test_a_failing_zone_becomes_an_event_not_an_exception(default_graph, prepared):
    w = World(default_graph, seed=0)
    zone = w.add_tiling(_zone(prepared))
    events = []
    w.on("warning", events.append)

    def boom(t):
        raise RuntimeError("patch table corrupt")
    zone.step = boom
    w.tick()
    assert w.tilings == [] and events and "patch table corrupt" in events[0].data["message"]
    w.tick()          # the loop goes on
    with pytest.raises(ValueError, match="already in the world"):
        w.add_tiling(_zone(prepared, name="a"))
        w.add_tiling(_zone(prepared, name="a"))


def _tiling_sample(tmp_path, teams_toml):
    stage = Usd.Stage.CreateNew(str(tmp_path / "world.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    m = UsdGeom.Mesh.Define(stage, "/World/Regions/zone")
    m.CreatePointsAttr([(-6, 0, -5), (6, 0, -5), (6, 0, 5), (-6, 0, 5)])
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    m.GetPrim().CreateAttribute("crowdweave:role", Sdf.ValueTypeNames.String).Set("region")
    post = UsdGeom.Cylinder.Define(stage, "/World/Obstacles/post")
    post.CreateRadiusAttr(0.4)
    UsdGeom.Xformable(post).AddTranslateOp().Set(Gf.Vec3d(0.0, 1.0, -3.5))
    stage.GetRootLayer().Save()
    (tmp_path / "scenario.toml").write_text(textwrap.dedent("""\
        name = "zone"
        world = "world.usda"
        duration = 8.0
        [[tiling]]
        name = "stage"
        zone = "/World/Regions/zone"
        period = 4.0
        """) + teams_toml)
    return tmp_path


TEAMS = """
  [[tiling.team]]
  count = 2
  start = [-3.0, 0.0]
  heading = 90.0
  targets = [[3.0, 0.0], [-3.0, 0.0]]
  [[tiling.team]]
  count = 2
  start = [3.0, 0.0]
  heading = -90.0
  targets = [[-3.0, 0.0], [3.0, 0.0]]
"""


def test_scenario_tiling_entries_are_validated(tmp_path):
    from usd_io.world import read_world
    d = _tiling_sample(tmp_path, TEAMS)
    env = read_world(d / "world.usda")
    sc = load_scenario(d / "scenario.toml", env=env)
    (spec,) = sc.tilings
    assert spec.bounds == (-6.0, -5.0, 6.0, 5.0) and len(spec.teams) == 2 and spec.period == 4.0
    assert spec.teams[1]["heading"] == pytest.approx(-math.pi / 2)
    bad = (d / "scenario.toml").read_text().replace("[3.0, 0.0], [-3.0, 0.0]]", "[30.0, 0.0]]")
    (d / "scenario.toml").write_text(bad)
    with pytest.raises(ScenarioError, match=r"tiling 'stage' team 0: point \[30.0, 0.0\] is outside the zone"):
        load_scenario(d / "scenario.toml", env=env)
    (d / "scenario.toml").write_text(bad.replace("/World/Regions/zone", "/World/Regions/nope"))
    with pytest.raises(ScenarioError, match="tiling 'stage': needs zone = a region marker"):
        load_scenario(d / "scenario.toml", env=env)


def test_tiled_characters_bake_like_crowd_characters(tmp_path, capsys):
    """``crowdweave bake`` of a scenario with a tiled zone: one SkelRoot per tiled character
    with its crowdweave:root equal to the zone's roots, the independent tiling check in the
    report, and a valid stage."""
    import json

    from authoring.cli import main
    from usd_io.crowd import read_tracks
    from usd_io.validate import errors, validate_stage
    (tmp_path / "s").mkdir()
    d = _tiling_sample(tmp_path / "s", TEAMS)
    out = tmp_path / "zone.usda"
    rc = main(["bake", str(d), "--out", str(out), "--report", str(tmp_path / "r.json"), "--quiet"])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert "tiling stage: 4 characters" in text and "interpenetrations 0" in text
    rep = json.loads((tmp_path / "r.json").read_text())["tiling"]
    assert rep["passed"] and rep["zones"][0]["danglings"] == 0
    tracks = read_tracks(out)
    assert sorted(tracks) == ["stage_0_0", "stage_0_1", "stage_1_0", "stage_1_1"]
    tr = tracks["stage_0_0"]
    assert len(tr) >= 8 * 30 - 1
    # the team started on the west side and walked east, toward its first target
    assert tr.root[0, 0] < -2.0 and tr.root[:, 0].max() > tr.root[0, 0] + 1.5
    stage = Usd.Stage.Open(str(out))
    root = stage.GetPrimAtPath("/World/Characters/stage_1_1")
    assert root.IsA(UsdGeom.Xformable) and root.GetTypeName() == "SkelRoot"
    bad = errors(validate_stage(stage))
    assert not bad, bad
