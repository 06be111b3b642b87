"""Clips to USD: UsdSkel stages whose joint world transforms, computed by
pxr.UsdSkel itself, equal the runtime's forward kinematics; validation; atomic writes; the
``crowdweave convert`` command."""
import importlib.util
import os

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdSkel, Vt

from authoring.cli import main as cli_main
from runtime.motion import Clip, Skeleton, forward_kinematics, quat
from usd_io import stage as usd_stage
from usd_io.skel import (build_clip_stage, joint_paths, joint_world_positions, read_skeleton,
                         write_clip_stage)
from usd_io.stage import StageError
from usd_io.validate import errors, validate_stage
from conftest import random_clip

TOL = 1e-4  # metres: USD joint positions against the runtime's FK

FAMILY_FILES = {
    "A": "cmu_02_01_walk.bvh",
    "B": "cmu_131_02_start_walk_stop_maxfriendly.bvh",
    "C": "cmu_16_15_walk_dazfriendly.bvh",
}


def _bvh_module():
    if importlib.util.find_spec("authoring.bvh") is None:
        pytest.skip("authoring/bvh.py (BVH import) does not exist yet")
    import authoring.bvh
    return authoring.bvh


def _clip(seed=0, frames=45, joints=14, fps=24.0):
    """A random smooth clip placed away from the world origin with a non-zero heading."""
    c = random_clip(np.random.default_rng(seed), frames=frames, n=joints, fps=fps)
    return c.with_origin([3.0, -2.0, 0.7])


@pytest.mark.parametrize("ext", ["usda", "usdc"])
def test_synthetic_clip_matches_runtime_fk(tmp_path, ext):
    clip = _clip()
    path = tmp_path / f"walker.{ext}"
    info = write_clip_stage(path, clip, "Walker")
    assert info.path == path and path.is_file()

    pos = joint_world_positions(path)
    ref = clip.fk()[1]
    assert pos.shape == ref.shape == (45, 14, 3)
    err = np.abs(pos - ref).max()
    print(f"synthetic {ext}: max |UsdSkel - FK| = {err:.2e} m")
    assert err < TOL
    # the clip really moves and turns, so agreement is not trivial
    assert np.ptp(ref[:, 0], axis=0).max() > 0.1

    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert stage.GetTimeCodesPerSecond() == 24.0 and stage.GetFramesPerSecond() == 24.0
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 44.0)
    root = stage.GetDefaultPrim()
    assert root.GetPath() == "/Walker" and root.IsA(UsdSkel.Root)
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(info.skeleton))
    anim = UsdSkel.Animation(stage.GetPrimAtPath(info.animation))
    assert root.HasAPI(UsdSkel.BindingAPI) and skel.GetPrim().HasAPI(UsdSkel.BindingAPI)
    assert UsdSkel.BindingAPI(root).GetSkeleton().GetPath() == skel.GetPath()
    assert UsdSkel.BindingAPI(skel.GetPrim()).GetAnimationSource().GetPath() == anim.GetPath()
    assert list(skel.GetJointsAttr().Get()) == joint_paths(clip.skeleton)
    assert anim.GetRotationsAttr().GetTimeSamples() == [float(i) for i in range(45)]

    # the root joint's translation is the world root position; rotations round-trip (x,y,z,w memory order)
    tr = np.array(anim.GetTranslationsAttr().Get(10))
    np.testing.assert_allclose(tr[0], clip.world_root()[0][10], atol=1e-5)
    np.testing.assert_allclose(tr[1:], clip.skeleton.offsets[1:], atol=1e-6)
    q = anim.GetRotationsAttr().Get(10)
    got = np.array([[r.GetReal(), *r.GetImaginary()] for r in q])
    np.testing.assert_allclose(got, clip.local_rotations_world_root()[10], atol=1e-6)

    # skeleton round trip, and the validators (UsdValidation + project checks) are satisfied
    back = read_skeleton(path, info.skeleton)
    assert back.names == clip.skeleton.names
    np.testing.assert_array_equal(back.parents, clip.skeleton.parents)
    np.testing.assert_allclose(back.offsets, clip.skeleton.offsets, atol=1e-12)
    assert validate_stage(path) == []


def test_rest_pose_is_offsets_with_identity_rotations(tmp_path):
    clip = _clip(seed=3)
    path = tmp_path / "rest.usda"
    write_clip_stage(path, clip)
    rest = joint_world_positions(path, time_codes=[0], at_rest=True)[0]
    J = clip.skeleton.num_joints
    ref = forward_kinematics(clip.skeleton, clip.skeleton.offsets[0], quat.identity((J,)))[1]
    np.testing.assert_allclose(rest, ref, atol=1e-9)


def test_joint_names_become_valid_unique_paths(tmp_path):
    names = ("mixamorig:Hips", "Left Leg", "Left_Leg", "1toe")
    sk = Skeleton(names, np.array([-1, 0, 0, 1]), np.array([[0, 0, 0], [0.1, -0.4, 0], [-0.1, -0.4, 0], [0, -0.4, 0.1]]))
    paths = joint_paths(sk)
    assert paths == ["mixamorig_Hips", "mixamorig_Hips/Left_Leg", "mixamorig_Hips/Left_Leg_1",
                     "mixamorig_Hips/Left_Leg/_toe"]
    rng = np.random.default_rng(5)
    clip = Clip.from_world(sk, 30.0, np.cumsum(rng.normal(size=(20, 3)) * 0.01, axis=0) + [0, 1, 0],
                           quat.normalize(rng.normal(size=(20, 4, 4))))
    path = tmp_path / "names.usdc"
    info = write_clip_stage(path, clip, "my character")
    assert info.root == "/my_character"
    assert read_skeleton(path, info.skeleton).names == names      # jointNames keep the originals
    assert np.abs(joint_world_positions(path) - clip.positions()).max() < TOL
    assert validate_stage(path) == []


@pytest.mark.parametrize("family", sorted(FAMILY_FILES))
def test_convert_cmu_family_matches_fk_and_validates(tmp_path, cmu_dir, family, capsys):
    bvh = _bvh_module()
    src = cmu_dir / FAMILY_FILES[family]
    out = tmp_path / (src.stem + ".usdc")
    assert cli_main(["convert", str(src), str(out)]) == 0
    summary = capsys.readouterr().out
    assert summary.count("\n") == 1 and "validation: 0 errors" in summary

    motion = bvh.read_bvh(src)                       # the same defaults convert uses
    ref = motion.clip.positions()
    pos = joint_world_positions(out)
    assert pos.shape == ref.shape
    err = np.abs(pos - ref).max()
    print(f"family {family} ({src.name}, {motion.family}): {ref.shape[0]} frames x {ref.shape[1]} joints, "
          f"max |UsdSkel - FK| = {err:.2e} m")
    assert err < TOL

    stage = Usd.Stage.Open(str(out))
    assert stage.GetTimeCodesPerSecond() == motion.source_fps == 120.0
    assert stage.GetEndTimeCode() == ref.shape[0] - 1
    assert stage.GetDefaultPrim().GetCustomDataByKey("crowdweave")["family"] == motion.family
    issues = validate_stage(out)
    assert errors(issues) == [], "\n".join(map(str, issues))


def test_cmu_rest_pose_faces_plus_z(tmp_path, cmu_dir):
    bvh = _bvh_module()
    motion = bvh.read_bvh(cmu_dir / FAMILY_FILES["A"])
    path = tmp_path / "a.usda"
    write_clip_stage(path, motion.clip)
    rest = joint_world_positions(path, time_codes=[0], at_rest=True)[0]
    sk = motion.skeleton
    at = {n: rest[sk.index(n)] for n in ("LeftUpLeg", "RightUpLeg", "LeftFoot", "LeftToeBase", "Head")}
    assert at["LeftUpLeg"][0] > 0.05 > -0.05 > at["RightUpLeg"][0]    # left side is +X
    assert at["LeftToeBase"][2] - at["LeftFoot"][2] > 0.05            # toes point +Z
    assert at["Head"][1] > 0.4                                         # Y up


# -- validation -------------------------------------------------------------------------------
def _break_rotations(stage, info):
    a = UsdSkel.Animation(stage.GetPrimAtPath(info.animation))
    good = a.GetRotationsAttr().Get(3)
    a.GetRotationsAttr().Set(Vt.QuatfArray(list(good)[:-1]), 3.0)   # one joint short at frame 3


def _unknown_joint(stage, info):
    a = UsdSkel.Animation(stage.GetPrimAtPath(info.animation))
    joints = list(a.GetJointsAttr().Get())
    a.GetJointsAttr().Set(Vt.TokenArray(joints[:-1] + ["Nowhere/Joint"]))


def _no_scales(stage, info):
    stage.GetPrimAtPath(info.animation).GetAttribute("scales").Clear()


def _nan_translation(stage, info):
    a = UsdSkel.Animation(stage.GetPrimAtPath(info.animation))
    t = np.array(a.GetTranslationsAttr().Get(5))
    t[2, 1] = np.nan
    a.GetTranslationsAttr().Set(Vt.Vec3fArray.FromNumpy(t), 5.0)


def _short_rest(stage, info):
    s = UsdSkel.Skeleton(stage.GetPrimAtPath(info.skeleton))
    s.GetRestTransformsAttr().Set(Vt.Matrix4dArray(list(s.GetRestTransformsAttr().Get())[:-2]))


@pytest.mark.parametrize("breakage, check, fragment", [
    (_break_rotations, "crowdweave:skelAnimationArrays", "rotations has 13 entries at time 3"),
    (_unknown_joint, "crowdweave:skelBinding", "do not exist in the bound Skeleton"),
    (_no_scales, "crowdweave:skelAnimationArrays", "scales not authored"),
    (_nan_translation, "crowdweave:skelAnimationArrays", "NaN"),
    (_short_rest, "crowdweave:skeleton", "restTransforms has 12 entries"),
])
def test_project_checks_catch_broken_skel_data(breakage, check, fragment):
    clip = _clip(joints=14)
    stage, info = build_clip_stage(clip, "Broken")
    assert validate_stage(stage) == []
    breakage(stage, info)
    errs = errors(validate_stage(stage))
    assert any(e.check == check and fragment in e.message for e in errs), errs
    # the stock validators alone do not see any of this
    assert errors(validate_stage(stage, project_checks=False)) == []


def test_broken_rotations_silently_fall_back_in_usdskel():
    """Why the array-length check exists: UsdSkel drops the frame's animation without an error."""
    clip = _clip()
    stage, info = build_clip_stage(clip, "Broken")
    _break_rotations(stage, info)
    pos = joint_world_positions(stage, time_codes=[2, 3])
    ref = clip.positions()
    assert np.abs(pos[0] - ref[2]).max() < TOL
    assert np.abs(pos[1] - ref[3]).max() > 0.05


def test_usd_validators_run():
    stage = Usd.Stage.CreateInMemory("bare.usda")
    stage.DefinePrim("/Thing", "Xform")
    found = {(i.check, i.message.split(":")[0]) for i in errors(validate_stage(stage))}
    assert ("usdGeomValidators:StageMetadataChecker", "MissingUpAxisMetadata") in found
    assert ("usdGeomValidators:StageMetadataChecker", "MissingMetersPerUnitMetadata") in found
    assert ("usdValidation:StageMetadataChecker", "MissingDefaultPrim") in found


# -- atomic writes ----------------------------------------------------------------------------
def test_failed_write_leaves_previous_file_intact(tmp_path, monkeypatch):
    path = tmp_path / "clip.usdc"
    write_clip_stage(path, _clip(seed=1))
    before = path.read_bytes()

    def crash_midway(layer, tmp):
        with open(tmp, "wb") as f:
            f.write(before[: len(before) // 3])      # a partial file, then the writer dies
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(usd_stage, "export_layer", crash_midway)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_clip_stage(path, _clip(seed=2))
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["clip.usdc"]           # no temporary file left behind
    monkeypatch.undo()
    assert np.abs(joint_world_positions(path) - _clip(seed=1).positions()).max() < TOL


def test_write_rejects_unknown_extension(tmp_path):
    with pytest.raises(StageError, match=r"clip\.abc.*unsupported extension"):
        write_clip_stage(tmp_path / "clip.abc", _clip())
    assert not any(tmp_path.iterdir())


# -- the convert command ----------------------------------------------------------------------
def _synthetic_bvh(tmp_path, bvh):
    clip = _clip(seed=7, frames=61, fps=30.0)
    src = tmp_path / "synthetic.bvh"
    bvh.write_bvh(src, clip)
    return src


def test_convert_cli_end_to_end(tmp_path, capsys):
    bvh = _bvh_module()
    src = _synthetic_bvh(tmp_path, bvh)

    out = tmp_path / "out" / "synthetic.usda"
    assert cli_main(["convert", str(src), str(out), "--drop-first-frame", "no"]) == 0
    line = capsys.readouterr().out.strip()
    assert line.startswith(f"wrote {out}: SkelRoot /synthetic, 14 joints, 61 frames at 30 fps")
    ref = bvh.read_bvh(src, drop_first_frame=False).clip.positions()
    assert np.abs(joint_world_positions(out) - ref).max() < TOL

    # --fps resamples (keeping the native rate is the default), --scale scales every position
    out15 = tmp_path / "synthetic15.usdc"
    assert cli_main(["convert", str(src), str(out15), "--fps", "15", "--scale", "0.5",
                     "--drop-first-frame", "no", "--name", "Half"]) == 0
    assert "resampled from 30 fps" in capsys.readouterr().out
    st = Usd.Stage.Open(str(out15))
    assert st.GetTimeCodesPerSecond() == 15.0 and st.GetEndTimeCode() == 30.0
    assert st.GetDefaultPrim().GetName() == "Half"
    ref15 = bvh.read_bvh(src, scale=0.5, drop_first_frame=False, fps=15).clip.positions()
    pos15 = joint_world_positions(out15)
    assert np.abs(pos15 - ref15).max() < TOL
    np.testing.assert_allclose(pos15[0], 0.5 * ref[0], atol=TOL)

    # the same input gives byte-identical files
    again = tmp_path / "again.usda"
    assert cli_main(["convert", str(src), str(again), "--drop-first-frame", "no", "--name", "synthetic"]) == 0
    assert again.read_bytes() == out.read_bytes()


def test_convert_cli_errors(tmp_path, capsys):
    bvh = _bvh_module()
    src = _synthetic_bvh(tmp_path, bvh)
    assert cli_main(["convert", str(tmp_path / "missing.bvh"), str(tmp_path / "x.usda")]) == 2
    assert "missing.bvh: file not found" in capsys.readouterr().err
    assert cli_main(["convert", str(src), str(tmp_path / "x.fbx")]) == 2
    assert "x.fbx: output must end in .usda, .usdc, .usd" in capsys.readouterr().err
    bad = tmp_path / "bad.bvh"
    bad.write_text(src.read_text().replace("MOTION", "MOTOIN"))
    assert cli_main(["convert", str(bad), str(tmp_path / "bad.usda")]) == 2
    err = capsys.readouterr().err
    assert "bad.bvh:" in err and "MOTION" in err
    assert not (tmp_path / "x.usda").exists() and not (tmp_path / "bad.usda").exists()
