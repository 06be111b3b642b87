"""The bake (crowds out to USD): characters carry a skinned capsule-limb body that follows
their joints, the world's geometry is referenced, and the stage validates."""
import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdSkel, Vt

from runtime.appearance import looks_for
from runtime.crowd.scenario import parse_scenario
from runtime.crowd.scheduler import plan_scenario
from runtime.motion.body import body_parts
from usd_io.crowd import build_crowd_stage
from usd_io.stage import save_stage
from usd_io.validate import validate_stage


@pytest.mark.parametrize("instancing", [True, False])
def test_bake_has_skinned_bodies_and_the_environment(default_graph, tmp_path, instancing):
    """Every part of the body follows its bones rigidly, thickened across them by the look's
    width (the ``wide`` blend shape) and never along them; the world is referenced; the stage
    validates without an issue, instanced or not."""
    from pathlib import Path
    world = Path(__file__).resolve().parents[1] / "samples" / "example_world" / "world.usda"
    sc = parse_scenario({"name": "t", "duration": 4.0, "character": [
        {"name": "a", "start": {"position": [-6.0, -6.0], "pose": "stand"}, "goal": [{"position": [-4.0, -3.0]}]}]})
    res = plan_scenario(sc, default_graph)
    out = tmp_path / "bake.usda"
    stage = build_crowd_stage({c.name: c.track for c in res.characters}, default_graph, 30.0, world_path=world,
                              out_path=out, instancing=instancing)
    save_stage(stage, out)
    assert validate_stage(out) == []
    st = Usd.Stage.Open(str(out))
    assert any(p.IsA(UsdGeom.Gprim) for p in Usd.PrimRange(st.GetPrimAtPath("/World/Environment")))
    width = looks_for(["a"]).width[0]
    assert st.GetPrimAtPath("/World/Characters/a").GetAttribute("crowdweave:width").Get() == pytest.approx(width)
    cache = UsdSkel.Cache()
    cache.Populate(UsdSkel.Root(st.GetPrimAtPath("/World/Characters/a")), Usd.TraverseInstanceProxies())
    geom = "/World/Characters/a/Rig" if instancing else "/World/Characters/a/Body"
    skel_path = "/World/Characters/a/Rig/Skel" if instancing else "/World/Characters/a/Skel"
    assert st.GetPrimAtPath(skel_path).IsInstanceProxy() == instancing
    skq = cache.GetSkelQuery(UsdSkel.Skeleton(st.GetPrimAtPath(skel_path)))
    for part in ("Skin", "Shirt", "Trousers", "Shoes"):
        body = st.GetPrimAtPath(f"{geom}/{part}")
        sq = cache.GetSkinningQuery(body)
        assert sq and sq.HasBlendShapes()
        ji = np.array(sq.GetJointIndicesPrimvar().Get())
        rest = np.array(UsdGeom.Mesh(body).GetPointsAttr().Get())
        radial = np.array(UsdSkel.BlendShape(st.GetPrimAtPath(f"{geom}/{part}/Wide")).GetOffsetsAttr().Get())
        jr = np.array([np.array(m)[3, :3] for m in skq.ComputeJointSkelTransforms(0.0, True)])   # skeleton space
        # the mesh and its blend shape at the character's weight are the runtime's body with every
        # point moved (width - 1) x its offset from its limb's axis
        p0, _, _, _, r0 = body_parts(default_graph.skeleton)[("Skin", "Shirt", "Trousers", "Shoes").index(part)]
        wide = rest + skq.GetAnimQuery().ComputeBlendShapeWeights(0.0)[0] * radial
        np.testing.assert_allclose(wide, p0 + (width - 1.0) * r0, atol=1e-5)
        reach = np.linalg.norm(wide - jr[ji], axis=1)              # each vertex's distance from its joint
        assert np.abs(np.linalg.norm(p0 - jr[ji], axis=1) - reach).max() > 1e-3  # the width shows
        for t in (0.0, 60.0, 119.0):
            pts = _skinned(st, sq, skq, body, t)
            jw = np.array([np.array(m)[3, :3] for m in skq.ComputeJointSkelTransforms(t)])
            d = np.linalg.norm(pts - jw[ji], axis=1)
            np.testing.assert_allclose(d, reach, atol=1e-4)     # rigidly bound: the body moves with its bones
    moved = joint_world_positions(st, "/World/Characters/a", [0.0, 119.0])[:, 0]
    assert np.linalg.norm(moved[1, [0, 2]] - moved[0, [0, 2]]) > 1.0   # and the character did move


def _skinned(stage, sq, skq, mesh_prim, t):
    """Points of a skinned mesh at time ``t`` as UsdSkel computes them: blend shapes, then skinning."""
    pts = Vt.Vec3fArray(UsdGeom.Mesh(mesh_prim).GetPointsAttr().Get(t))
    weights = skq.GetAnimQuery().ComputeBlendShapeWeights(t)
    sub = sq.GetBlendShapeMapper().Remap(weights)
    assert len(sub) == 1
    shapes = [UsdSkel.BlendShape(stage.GetPrimAtPath(p)) for p in sq.GetBlendShapeTargetsRel().GetForwardedTargets()]
    points = np.array(pts)
    for w, shape in zip(sub, shapes):
        points += w * np.array(shape.GetOffsetsAttr().Get())
    pts = Vt.Vec3fArray.FromNumpy(points.astype(np.float32))
    assert sq.ComputeSkinnedPoints(skq.ComputeSkinningTransforms(t), pts, t)
    return np.array(pts)


def test_carried_box_moves_with_the_hands(default_graph):
    from pathlib import Path
    from runtime.crowd.tracks import box_trajectories, joint_positions
    from usd_io.world import read_world
    env = read_world(Path(__file__).resolve().parents[1] / "samples" / "example_world" / "world.usda")
    box = sorted(m.path for m in env.markers_with_role("box"))[0]
    m = env.markers[box]
    # turning round with the box takes a walk in a loop (the carrying clips have no turn on
    # the spot): the put-down is at about 27 s
    sc = parse_scenario({"name": "t", "duration": 32.0, "character": [
        {"name": "a", "start": {"position": [float(m.position[0]) + 2.5, float(m.position[1]) + 2.5], "pose": "stand"},
         "goal": [{"box": box}, {"position": [float(m.position[0]) + 2.0, float(m.position[1]) + 3.5], "pose": "stand"}]}]},
        env=env)
    res = plan_scenario(sc, default_graph, env)
    c = res.characters[0]
    assert c.warnings == []
    pos, head = box_trajectories(sc, res.characters, default_graph, env, res.num_frames)[box]
    f_pick, f_put = c.arrivals
    np.testing.assert_allclose(pos[0, [0, 2]], m.position, atol=1e-9)          # waits at its marker
    sk = default_graph.skeleton
    hands = joint_positions(default_graph, c.track)[:, [sk.index("LeftHand"), sk.index("RightHand")]].mean(axis=1)
    for f in (f_pick, f_pick + 5, (f_pick + f_put) // 2, f_put):
        np.testing.assert_allclose(pos[f], hands[f], atol=1e-9)                 # carried between the hands
    assert pos[f_pick + 5, 1] > 0.6                                              # held up, not dragged
    assert abs(pos[-1, 1] - 0.2) < 1e-9 and np.linalg.norm(pos[-1, [0, 2]] - m.position) > 0.5   # put down elsewhere


# -- round trip: crowdweave:root and joint world positions, single layer and value clips ----------
import json  # noqa: E402
import os  # noqa: E402
import pytest  # noqa: E402
from pxr import Sdf  # noqa: E402

from runtime.crowd.tracks import Track, joint_positions  # noqa: E402
from runtime.pose import locked_joint_positions  # noqa: E402
from usd_io import clips as usd_clips  # noqa: E402
from usd_io import stage as usd_stage  # noqa: E402
from usd_io.crowd import read_tracks, save_crowd_stage  # noqa: E402
from usd_io.skel import joint_world_positions  # noqa: E402
from usd_io.validate import errors, format_issues  # noqa: E402


def _synthetic(graph, rng, frames, start):
    """A track playing library frames from a random place, wandering, starting at clock frame ``start``."""
    a = int(rng.integers(0, len(graph.frame_heading) - frames - 1))
    fa = np.arange(a, a + frames)
    root = np.column_stack([rng.uniform(-5, 5) + np.cumsum(rng.normal(0, 0.03, frames)),
                            rng.uniform(-5, 5) + np.cumsum(rng.normal(0, 0.03, frames)),
                            rng.uniform(-3, 3) + np.cumsum(rng.normal(0, 0.05, frames))])
    return Track(fa, fa + 1, rng.uniform(0, 1, frames).astype(np.float32), root, start)


@pytest.fixture(scope="module")
def crowd_tracks(default_graph):
    """One planned character (the planner's track) and three synthetic ones, one of them entering
    at clock frame 7 and leaving early, one with a name that is not a USD identifier."""
    sc = parse_scenario({"name": "t", "duration": 4.0, "character": [
        {"name": "a", "start": {"position": [-6.0, -6.0], "pose": "stand"}, "goal": [{"position": [-4.0, -3.0]}]}]})
    res = plan_scenario(sc, default_graph)
    rng = np.random.default_rng(3)
    tracks = {"a": res.characters[0].track}
    tracks["late one"] = _synthetic(default_graph, rng, 50, 7)
    tracks["c"] = _synthetic(default_graph, rng, 121, 0)
    tracks["d"] = _synthetic(default_graph, rng, 90, 0)
    return tracks


def _bake(tracks, graph, out, **kw):
    stage = build_crowd_stage(tracks, graph, 30.0, out_path=out, metadata={"scenario": "t"}, **kw)
    save_crowd_stage(stage, out)
    return out


def _assert_round_trip(path, tracks, graph):
    issues = validate_stage(path)
    assert errors(issues) == [], format_issues(issues)
    st = Usd.Stage.Open(str(path))
    assert (st.GetStartTimeCode(), st.GetEndTimeCode()) == (0.0, 120.0)
    prims = st.GetPrimAtPath("/World/Characters").GetChildren()
    assert sorted(p.GetName() for p in prims) == sorted(["a", "late_one", "c", "d"])
    for name, tr in tracks.items():
        prim_path = f"/World/Characters/{name.replace(' ', '_')}"
        attr = st.GetPrimAtPath(prim_path).GetAttribute("crowdweave:root")
        times = np.array(attr.GetTimeSamples())
        np.testing.assert_array_equal(times, tr.start_frame + np.arange(len(tr)))
        baked = np.array([attr.Get(t) for t in times])
        plan = np.column_stack([tr.root[:, 0], tr.root[:, 1], np.degrees(tr.root[:, 2])])
        np.testing.assert_allclose(baked, plan, rtol=0, atol=1e-12)       # the plan's x, z, heading (deg)
        usd = joint_world_positions(st, prim_path, times)                  # UsdSkel's own evaluation
        # runtime FK of the track with planted feet locked (legs and hip height differ from the clips)
        np.testing.assert_allclose(usd, locked_joint_positions(graph, tr), rtol=0, atol=1e-4)
    back = read_tracks(path)
    assert sorted(back) == sorted(tracks)          # by the original names ("late one" is kept on its prim)
    for name, tr in tracks.items():
        b = back[name]
        np.testing.assert_allclose(b.root, tr.root, atol=1e-12)
        np.testing.assert_array_equal(b.frames_a, tr.frames_a)
        assert b.start_frame == tr.start_frame


def test_round_trip_single_layer(crowd_tracks, default_graph, tmp_path):
    out = _bake(crowd_tracks, default_graph, tmp_path / "crowd.usdc")
    _assert_round_trip(out, crowd_tracks, default_graph)
    assert sorted(os.listdir(tmp_path)) == ["crowd.usdc"]


def test_round_trip_value_clips(crowd_tracks, default_graph, tmp_path):
    """Value clips, two characters per layer, written by two worker processes: the same poses and
    roots read back through UsdSkel and Usd's clip resolution; the stage itself holds no samples."""
    out = _bake(crowd_tracks, default_graph, tmp_path / "crowd.usdc", clips_per=2, workers=2)
    _assert_round_trip(out, crowd_tracks, default_graph)
    dirs = [d for d in tmp_path.iterdir() if d.is_dir()]
    assert len(dirs) == 1 and usd_clips.clip_dir_pattern(out).fullmatch(dirs[0].name)
    assert sorted(os.listdir(dirs[0])) == ["chunk_0000.usdc", "chunk_0001.usdc", "manifest.usda"]
    assert sorted(os.listdir(tmp_path)) == sorted(["crowd.usdc", dirs[0].name])   # no temporary left
    top = Sdf.Layer.FindOrOpen(str(out))
    for p in ("/World/Characters/a/Skel/Anim.rotations", "/World/Characters/a.crowdweave:root"):
        assert top.GetAttributeAtPath(p) and top.ListTimeSamplesForPath(p) == []
    assert top.customLayerData["crowdweave:clipDirectory"] == dirs[0].name
    st = Usd.Stage.Open(str(out))
    clip = Usd.ClipsAPI(st.GetPrimAtPath("/World/Characters/late_one")).GetClips()["default"]
    assert clip["primPath"] == "/World/Characters/late_one"
    assert [tuple(v) for v in clip["active"]] == [(7.0, 0.0)]
    assert clip["assetPaths"][0].path == f"./{dirs[0].name}/chunk_0000.usdc"
    # the stage copied without its clip directory does not validate, naming the missing layers
    lone = tmp_path / "copy" / "crowd.usdc"
    lone.parent.mkdir()
    lone.write_bytes(out.read_bytes())
    missing = errors(validate_stage(lone))
    assert any("chunk_0001.usdc" in i.message for i in missing), format_issues(missing)


def test_bakes_are_byte_identical(crowd_tracks, default_graph, tmp_path):
    """The same input gives the same bytes in every file (single layer and clips; the clip layers
    from one in-process writer equal those from two worker processes)."""
    for sub, kw in (("one", {}), ("clips", {"clips_per": 3, "workers": 1}), ("clips2", {"clips_per": 3, "workers": 2})):
        _bake(crowd_tracks, default_graph, tmp_path / sub / "x" / "crowd.usda", **kw)
        _bake(crowd_tracks, default_graph, tmp_path / sub / "y" / "crowd.usda", **kw)

    def files(d):
        return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}
    for sub in ("one", "clips", "clips2"):
        x, y = files(tmp_path / sub / "x"), files(tmp_path / sub / "y")
        assert x == y and len(x) == (1 if sub == "one" else 4)
    assert files(tmp_path / "clips" / "x") == files(tmp_path / "clips2" / "x")


def test_rebake_replaces_the_clip_directory(crowd_tracks, default_graph, tmp_path):
    out = tmp_path / "crowd.usdc"
    _bake(crowd_tracks, default_graph, out, clips_per=2, workers=1)
    first = {d.name for d in tmp_path.iterdir() if d.is_dir()}
    changed = dict(crowd_tracks)
    changed["c"] = Track(changed["c"].frames_a, changed["c"].frames_b, changed["c"].frames_t,
                         changed["c"].root + [1.0, 0.0, 0.0], 0)
    _bake(changed, default_graph, out, clips_per=2, workers=1)
    second = {d.name for d in tmp_path.iterdir() if d.is_dir()}
    assert len(first) == len(second) == 1 and first != second        # new content, new name; old removed
    np.testing.assert_allclose(read_tracks(out)["c"].root, changed["c"].root, atol=1e-12)
    _bake(changed, default_graph, out)                                # single layer: no clip directory left
    assert sorted(os.listdir(tmp_path)) == ["crowd.usdc"]


# -- the bake never leaves a half-written file ----------------------------------------------------
def _listing(d):
    return sorted(str(p.relative_to(d)) for p in d.rglob("*"))


def test_failed_clip_layer_leaves_nothing_half_written(crowd_tracks, default_graph, tmp_path, monkeypatch):
    """A clip layer export that dies midway (in-process writer) and a worker process that fails
    (a track pointing past the library): no clip directory, no temporary, the earlier bake intact."""
    out = tmp_path / "crowd.usdc"
    _bake(crowd_tracks, default_graph, out, clips_per=2, workers=1)
    before = {p: (tmp_path / p).read_bytes() for p in _listing(tmp_path) if (tmp_path / p).is_file()}
    real_export = usd_clips.export_with_digest
    calls = []

    def crash_on_second(layer, path):
        calls.append(path)
        if len(calls) == 2:
            path.write_bytes(b"PXR-USDC half")
            raise OSError("disk full")
        return real_export(layer, path)
    monkeypatch.setattr(usd_clips, "export_with_digest", crash_on_second)
    changed = {k: Track(t.frames_a, t.frames_b, t.frames_t, t.root + [0.5, 0.0, 0.0], t.start_frame)
               for k, t in crowd_tracks.items()}
    with pytest.raises(OSError, match="disk full"):
        _bake(changed, default_graph, out, clips_per=2, workers=1)
    assert len(calls) == 2
    monkeypatch.setattr(usd_clips, "export_with_digest", real_export)
    bad = dict(changed)
    bad["d"] = Track(bad["d"].frames_a + 10 ** 7, bad["d"].frames_b + 10 ** 7, bad["d"].frames_t, bad["d"].root, 0)
    with pytest.raises(ValueError, match="character 'd': track frames_a reaches frame"):
        _bake(bad, default_graph, out, clips_per=2, workers=2)
    after = {p: (tmp_path / p).read_bytes() for p in _listing(tmp_path) if (tmp_path / p).is_file()}
    assert after == before
    _assert_round_trip(out, crowd_tracks, default_graph)


def test_failed_stage_save_keeps_the_previous_bake(crowd_tracks, default_graph, tmp_path, monkeypatch):
    """The top stage is written to a temporary file and renamed: an export that dies midway leaves
    the earlier stage (and the clip directory it refers to) in place and no temporary file."""
    out = tmp_path / "crowd.usdc"
    _bake(crowd_tracks, default_graph, out, clips_per=2, workers=1)
    old = out.read_bytes()

    def crash_midway(layer, path):
        with open(path, "wb") as f:
            f.write(b"PXR-USDC half")
        raise usd_stage.StageError(path, "USD export failed: disk full")
    monkeypatch.setattr(usd_stage, "export_layer", crash_midway)
    changed = {k: Track(t.frames_a, t.frames_b, t.frames_t, t.root + [0.5, 0.0, 0.0], t.start_frame)
               for k, t in crowd_tracks.items()}
    for kw in ({}, {"clips_per": 2, "workers": 1}):
        with pytest.raises(usd_stage.StageError, match="disk full"):
            _bake(changed, default_graph, out, **kw)
        assert out.read_bytes() == old
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    monkeypatch.undo()
    _assert_round_trip(out, crowd_tracks, default_graph)   # still the first bake, clips and all


def test_clips_need_an_output_path(crowd_tracks, default_graph):
    with pytest.raises(ValueError, match="out_path"):
        build_crowd_stage(crowd_tracks, default_graph, 30.0, clips_per=2)
    with pytest.raises(ValueError, match="at least 1"):
        build_crowd_stage(crowd_tracks, default_graph, 30.0, clips_per=0, out_path="x.usdc")


def test_bake_command_writes_value_clips(tmp_path, capsys):
    """``crowdweave bake ... --clips-per 1``: the checker reads the baked stage back through the
    clips and reports exactly what it reports for the single-layer bake of the same scenario; a bad
    --clips-per is a clear CLI error."""
    from authoring.cli import main
    d = tmp_path / "two"
    d.mkdir()
    (d / "scenario.toml").write_text(
        'name = "two"\nduration = 4.0\nseed = 0\n'
        '[[character]]\nname = "a"\nstart = { position = [-6.0, -6.0], pose = "stand" }\n'
        '  [[character.goal]]\n  position = [-4.0, -3.0]\n')
    one, clip = tmp_path / "one" / "two.usdc", tmp_path / "clips" / "two.usdc"
    rc_one = main(["bake", str(d), "--out", str(one), "--report", str(tmp_path / "one.json"), "--quiet"])
    rc_clip = main(["bake", str(d), "--out", str(clip), "--report", str(tmp_path / "clips.json"),
                    "--clips-per", "1", "--workers", "1", "--quiet"])
    assert rc_one == rc_clip
    reports = [json.loads((tmp_path / f"{n}.json").read_text()) for n in ("one", "clips")]
    assert reports[0]["summary"] == reports[1]["summary"] and reports[0]["summary"]["characters"] == 1
    dirs = [p for p in clip.parent.iterdir() if p.is_dir()]
    assert len(dirs) == 1 and sorted(os.listdir(dirs[0])) == ["chunk_0000.usdc", "manifest.usda"]
    assert errors(validate_stage(clip)) == []
    capsys.readouterr()
    assert main(["bake", str(d), "--out", str(clip), "--clips-per", "0"]) == 2
    assert "argument --clips-per: must be an integer from 1 to 5000, got '0'" in capsys.readouterr().err


def test_bake_errors_name_the_missing_file(tmp_path, capsys):
    """A scenario whose world stage is missing, or a missing scenario: exit code 2, the error names
    the file, and nothing is written."""
    from authoring.cli import main
    d = tmp_path / "s"
    d.mkdir()
    (d / "scenario.toml").write_text(
        'name = "s"\nworld = "nowhere.usda"\nduration = 2.0\n'
        '[[character]]\nname = "a"\nstart = { position = [0.0, 0.0], pose = "stand" }\n'
        '  [[character.goal]]\n  position = [1.0, 0.0]\n')
    out = tmp_path / "out.usdc"
    assert main(["bake", str(d), "--out", str(out), "--quiet"]) == 2
    assert f"{d / 'nowhere.usda'}: file not found" in capsys.readouterr().err
    assert main(["bake", str(tmp_path / "nosuch"), "--out", str(out), "--quiet"]) == 2
    assert "nosuch" in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == ["s"]


def test_colliding_character_names_are_an_error(crowd_tracks, default_graph):
    tracks = {"a b": crowd_tracks["c"], "a_b": crowd_tracks["d"]}
    with pytest.raises(ValueError, match="'a b' and 'a_b' both map to the USD prim /World/Characters/a_b"):
        build_crowd_stage(tracks, default_graph, 30.0)


def test_characters_added_to_a_stage_extend_its_time_range(crowd_tracks, default_graph, tmp_path):
    """A second set of characters baked into the same stage (a bake's tiled zones) that runs
    longer than the first stretches the stage's end time code over it, so every time sample is
    inside the stage's range (the validator warns otherwise)."""
    first = {k: crowd_tracks[k] for k in ("a", "d")}
    stage = build_crowd_stage(first, default_graph, 30.0)
    assert stage.GetEndTimeCode() == max(int(t.start_frame) + len(t) for t in first.values()) - 1
    rng = np.random.default_rng(9)
    longer = _synthetic(default_graph, rng, 150, 20)          # frames 20..169
    build_crowd_stage({"tiled": longer}, default_graph, 30.0, stage=stage)
    assert stage.GetEndTimeCode() == 169
    out = tmp_path / "two.usdc"
    save_stage(stage, out)
    assert validate_stage(out) == []
