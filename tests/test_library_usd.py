"""Motion-graph library previews as USD: validation, the bound all-clips animation against the
runtime's FK, per-clip prims, layout, attribute round trip."""
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdSkel

from runtime.motion.graph import STATES, MotionGraph
from usd_io.library import (ALL_CLIPS, CLIPS, LIBRARY, NODES, SKELETON, build_library_stage, library_layout,
                            read_library_preview, write_library_preview)
from usd_io.skel import joint_world_positions
from usd_io.validate import errors, format_issues, validate_stage

TOL = 1e-4  # metres


@pytest.fixture(scope="module")
def small_graph(tmp_path_factory):
    """A small graph from 30 s of generated capture (about 5 nodes, 40+ edges; ~3 s)."""
    from authoring.motion_graph.build import GraphBuildParams, build_graph
    from authoring.motion_graph.sources import load_takes
    from authoring.procedural import write_session
    d = tmp_path_factory.mktemp("capture")
    write_session(d, 0.5, 3)
    g = build_graph(load_takes([d]), GraphBuildParams(), log=lambda *a: None)
    assert g.num_edges >= 4 and g.num_nodes >= 2
    return g


def _placed_positions(g: MotionGraph, e: int, placement_deg):
    x, z, h = placement_deg[e]
    return g.edge_clip(e).positions(origin=np.array([x, z, np.radians(h)]))


def _sampled_edges(g: MotionGraph, n_random: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    picks = {0, g.num_edges - 1, int(np.argmax(g.edge_frames)),
             int(np.argmax(np.abs(g.edge_disp[:, 2])))}   # the longest and the most turning edge
    picks.update(rng.choice(g.num_edges, size=min(n_random, g.num_edges), replace=False).tolist())
    return sorted(picks)


def _check_all_clips_fk(stage, g: MotionGraph, edges, data):
    """The bound animation at each sampled edge's time codes, as UsdSkel poses it, equals the
    runtime FK of that edge clip placed at its edgePlacement."""
    worst = 0.0
    for e in edges:
        t0, t1 = data["edge_start_time"][e], data["edge_end_time"][e]
        times = np.arange(t0, t1 + 0.5)
        assert len(times) == g.edge_frames[e]
        usd = joint_world_positions(stage, LIBRARY, times)
        ref = _placed_positions(g, e, data["edge_placement"])
        worst = max(worst, float(np.abs(usd - ref).max()))
    assert worst < TOL, f"largest joint position error {worst:.2e} m"


def _check_metadata(stage, g: MotionGraph):
    T = int(g.edge_start[-1])
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert stage.GetTimeCodesPerSecond() == g.fps
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, T - 1.0)
    assert stage.GetDefaultPrim().GetPath() == Sdf.Path(LIBRARY)
    assert stage.GetPrimAtPath(LIBRARY).IsA(UsdSkel.Root)
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(SKELETON))
    assert skel and len(skel.GetJointsAttr().Get()) == g.skeleton.num_joints
    assert UsdSkel.BindingAPI(skel.GetPrim()).GetInheritedAnimationSource().GetPath() == Sdf.Path(ALL_CLIPS)


def _check_round_trip(data, g: MotionGraph):
    np.testing.assert_array_equal(data["edge_src"], g.edge_src)
    np.testing.assert_array_equal(data["edge_dst"], g.edge_dst)
    np.testing.assert_array_equal(data["edge_state"], g.edge_state)
    np.testing.assert_array_equal(data["node_state"], g.node_state)
    np.testing.assert_array_equal(data["edge_frames"], g.edge_frames)
    assert data["state_names"] == list(STATES)
    assert data["node_labels"] == g.node_labels
    assert data["edge_labels"] == g.edge_labels
    np.testing.assert_array_equal(data["edge_start_time"], g.edge_start[:-1])
    np.testing.assert_array_equal(data["edge_end_time"], g.edge_start[1:] - 1)
    np.testing.assert_allclose(data["edge_disp"][:, :2], g.edge_disp[:, :2], atol=1e-12)
    np.testing.assert_allclose(np.radians(data["edge_disp"][:, 2]), g.edge_disp[:, 2], atol=1e-12)
    np.testing.assert_allclose(data["edge_duration"], g.edge_duration, atol=1e-12)
    np.testing.assert_allclose(data["node_height"], g.node_height, atol=1e-12)
    assert data["edge_clips"] == [f"{CLIPS}/E{e:04d}" for e in range(g.num_edges)]
    assert data["node_poses"] == [f"{NODES}/N{n:03d}" for n in range(g.num_nodes)]
    summary = data["custom"]["summary"]
    assert (summary["nodes"], summary["edges"]) == (g.num_nodes, g.num_edges)
    assert summary["seconds"] == pytest.approx(g.summary()["seconds"])
    assert data["custom"]["kind"] == "motion_graph_preview"


@pytest.mark.parametrize("ext", [".usda", ".usdc"])
def test_small_library_preview_validates_matches_fk_and_round_trips(small_graph, tmp_path, ext):
    g = small_graph
    out = write_library_preview(tmp_path / f"lib{ext}", g)
    assert out.is_file() and not list(tmp_path.glob("*.tmp*"))
    issues = validate_stage(out)
    assert not errors(issues), format_issues(issues)
    stage = Usd.Stage.Open(str(out))
    _check_metadata(stage, g)
    data = read_library_preview(stage)
    _check_round_trip(data, g)
    _check_all_clips_fk(stage, g, _sampled_edges(g, 4), data)


def test_each_clip_prim_plays_its_edge_alone_from_time_zero(small_graph):
    """Pointing the Skeleton's animationSource at Clips/E#### plays that edge clip at the origin,
    facing +Z, from time code 0 (as documented); per-clip attributes name the edge."""
    g = small_graph
    stage = build_library_stage(g)
    skel = stage.GetPrimAtPath(SKELETON)
    rel = UsdSkel.BindingAPI(skel).GetAnimationSourceRel()
    for e in _sampled_edges(g, 3, seed=1):
        path = f"{CLIPS}/E{e:04d}"
        prim = stage.GetPrimAtPath(path)
        assert prim.IsA(UsdSkel.Animation)
        assert (prim.GetAttribute("crowdweave:src").Get(), prim.GetAttribute("crowdweave:dst").Get()) == \
            (g.edge_src[e], g.edge_dst[e])
        assert prim.GetAttribute("crowdweave:timelineStart").Get() == g.edge_start[e]
        rel.SetTargets([Sdf.Path(path)])
        usd = joint_world_positions(stage, LIBRARY, np.arange(g.edge_frames[e], dtype=float))
        ref = g.edge_clip(e).positions(origin=np.zeros(3))
        assert np.abs(usd - ref).max() < TOL
    # hub poses: each node prim poses the node's hub pose at the origin
    for n in range(g.num_nodes):
        rel.SetTargets([Sdf.Path(f"{NODES}/N{n:03d}")])
        usd = joint_world_positions(stage, LIBRARY, [0.0])
        assert np.abs(usd - g.node_pose_clip(n).positions(origin=np.zeros(3))).max() < TOL


def test_placed_clips_do_not_overlap_and_follow_the_grid(small_graph):
    g = small_graph
    for columns in (None, g.num_edges):          # default grid, and one row along +X
        place = library_layout(g, columns=columns, gap=0.5)
        assert np.all(place[:, 2] == 0.0)
        boxes = []
        for e in range(g.num_edges):
            p = _placed_positions(g, e, np.column_stack([place[:, :2], np.zeros(len(place))]))
            boxes.append((p[..., 0].min(), p[..., 0].max(), p[..., 2].min(), p[..., 2].max()))
        b = np.array(boxes)
        x_sep = (b[:, None, 1] < b[None, :, 0]) | (b[None, :, 1] < b[:, None, 0])
        z_sep = (b[:, None, 3] < b[None, :, 2]) | (b[None, :, 3] < b[:, None, 2])
        apart = x_sep | z_sep
        np.fill_diagonal(apart, True)
        assert apart.all(), "two placed clips overlap"
        if columns == g.num_edges:   # one row: every clip lies beyond the previous one along +X
            assert np.all(b[1:, 0] > b[:-1, 1])


def test_preview_is_deterministic_and_writes_atomically(small_graph, tmp_path, monkeypatch):
    import usd_io.stage as stage_mod
    from usd_io.stage import StageError
    g = small_graph
    a = write_library_preview(tmp_path / "a.usda", g)
    b = write_library_preview(tmp_path / "b.usda", g)
    assert a.read_bytes() == b.read_bytes()
    before = a.read_bytes()

    def boom(layer, path):
        with open(path, "wb") as f:
            f.write(b"#usda 1.0\n(half")
        raise StageError(path, "simulated failure")
    monkeypatch.setattr(stage_mod, "export_layer", boom)
    with pytest.raises(StageError):
        write_library_preview(a, g)
    assert a.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.usda", "b.usda"]
    with pytest.raises(StageError, match="unsupported extension"):
        write_library_preview(tmp_path / "lib.fbx", g)


def test_author_graph_cli_writes_a_valid_preview(cmu_dir, tmp_path, capsys):
    """`crowdweave author graph` on five CMU MotionBuilder-family files writes x.usda."""
    from authoring.cli import main as cli_main
    files = [str(cmu_dir / f"cmu_{n}.bvh") for n in
             ("01_01_jumps_turn_around", "02_01_walk", "05_01_walk", "07_05_slow_walk", "09_06_run")]
    assert all(Path(f).is_file() for f in files)
    out = tmp_path / "x.cwpack"
    assert cli_main(["author", "graph", *files, "--out", str(out), "--quiet"]) == 0
    usd = tmp_path / "x.usda"
    assert f"wrote {usd}" in capsys.readouterr().out
    issues = validate_stage(usd)
    assert not errors(issues), format_issues(issues)
    g = MotionGraph.load(out)
    stage = Usd.Stage.Open(str(usd))
    data = read_library_preview(stage)
    _check_round_trip(data, g)
    _check_all_clips_fk(stage, g, _sampled_edges(g, 2), data)


@pytest.mark.slow
def test_default_library_preview_validates_and_matches_fk(tmp_path):
    from authoring.default_library import ensure_library
    g = MotionGraph.load(ensure_library("default", log=lambda *a: None, progress=False))
    out = write_library_preview(tmp_path / "default.usdc", g)
    issues = validate_stage(out)
    assert not errors(issues), format_issues(issues)
    stage = Usd.Stage.Open(str(out))
    _check_metadata(stage, g)
    data = read_library_preview(stage)
    _check_round_trip(data, g)
    _check_all_clips_fk(stage, g, _sampled_edges(g, 4), data)
