"""Skeletons and clips as UsdSkel prims: SkelRoot, Skeleton, SkelAnimation.

Layout written for one clip (``build_clip_stage``)::

    /<Name>              SkelRoot   (defaultPrim; SkelBindingAPI, skel:skeleton -> Skel)
    /<Name>/Skel         Skeleton   (SkelBindingAPI, skel:animationSource -> Anim)
    /<Name>/Skel/Anim    SkelAnimation

Conventions (ARCHITECTURE.md):

- joints are paths of joint names from the root, e.g. ``Hips/LHipJoint/LeftUpLeg``
  (names made valid USD identifiers; the original names go to ``jointNames``);
- the rest pose (``restTransforms``, local) and the bind pose (``bindTransforms``, world)
  carry the skeleton offsets with identity rotations, so a character stands in its rest
  pose facing +Z exactly as the runtime's skeleton does;
- the animation's root joint translation carries the world root position and its rotation
  the root's world rotation; every other joint's translation is its rest offset and its
  rotation the clip's local rotation. With metersPerUnit 1 the joint world transforms that
  UsdSkel computes are the runtime's forward kinematics, in metres;
- frame ``i`` is time code ``start + i``; rotations are stored as ``quatf`` (GfQuatf is
  real-first in its constructor, but its memory, and so every numpy view, is x, y, z, w).

Time samples are authored at the Sdf level inside one ``Sdf.ChangeBlock`` (one
``SetTimeSample`` per attribute per frame, arrays built with numpy), not with
``Usd.Attribute.Set``, which costs more per sample.

This module moves data only: forward kinematics, resampling and retargeting happen in the
runtime before anything reaches it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdSkel, Vt

from runtime.motion import quat
from runtime.motion.fk import forward_kinematics
from runtime.motion.skeleton import Skeleton

from .stage import (StageError, check_usd_path, new_stage, open_stage, save_stage, set_default_prim,
                    valid_prim_name)

__all__ = [
    "joint_paths", "define_skel_root", "define_skeleton", "clip_joint_arrays", "write_animation",
    "bind_animation", "bind_skeleton", "build_clip_stage", "write_clip_stage", "ClipStage", "joint_world_positions",
    "read_skeleton", "to_quatf_array", "translation_matrices", "rest_and_bind_transforms",
]


# -- value conversion ---------------------------------------------------------------------------
def to_quatf_array(q_wxyz: np.ndarray) -> Vt.QuatfArray:
    """(N, 4) w-x-y-z quaternions -> VtQuatfArray (whose memory layout is x, y, z, w)."""
    q = np.asarray(q_wxyz, dtype=np.float32).reshape(-1, 4)
    return Vt.QuatfArray.FromNumpy(np.ascontiguousarray(q[:, [1, 2, 3, 0]]))


def translation_matrices(t: np.ndarray) -> Vt.Matrix4dArray:
    """(J, 3) translations -> VtMatrix4dArray of pure translations (USD is row-vector: row 3)."""
    m = np.tile(np.eye(4), (len(t), 1, 1))
    m[:, 3, :3] = t
    return Vt.Matrix4dArray.FromNumpy(m)


# -- skeleton ---------------------------------------------------------------------------------
def joint_paths(skeleton: Skeleton) -> list[str]:
    """UsdSkel joint paths ("Hips/LHipJoint/LeftUpLeg", ...) in the skeleton's joint order.

    Each name is made a valid identifier; siblings that would collide get a numeric suffix.
    """
    out: list[str] = []
    used: set[str] = set()
    for j, (name, p) in enumerate(zip(skeleton.names, skeleton.parents)):
        base = valid_prim_name(name, f"joint{j}")
        prefix = "" if p < 0 else out[p] + "/"
        cand, k = base, 1
        while prefix + cand in used:
            cand, k = f"{base}_{k}", k + 1
        out.append(prefix + cand)
        used.add(out[-1])
    return out


def define_skel_root(stage: Usd.Stage, path) -> UsdSkel.Root:
    """A SkelRoot prim with SkelBindingAPI applied (its skel:skeleton is set when the skeleton is bound)."""
    root = UsdSkel.Root.Define(stage, Sdf.Path(str(path)))
    UsdSkel.BindingAPI.Apply(root.GetPrim())
    return root


def define_skeleton(stage: Usd.Stage, path, skeleton: Skeleton, *, paths: list[str] | None = None
                    ) -> UsdSkel.Skeleton:
    """Define a Skeleton prim: joints, jointNames, rest (local) and bind (world) transforms.

    Rest and bind poses are the skeleton's offsets with identity rotations (the runtime's
    rest pose: standing, facing +Z). The root joint's rest translation is its offset.
    """
    paths = joint_paths(skeleton) if paths is None else list(paths)
    if len(paths) != skeleton.num_joints:
        raise ValueError(f"{len(paths)} joint paths for {skeleton.num_joints} joints")
    skel = UsdSkel.Skeleton.Define(stage, Sdf.Path(str(path)))
    UsdSkel.BindingAPI.Apply(skel.GetPrim())
    skel.CreateJointsAttr(Vt.TokenArray(paths))
    skel.CreateJointNamesAttr(Vt.TokenArray(list(skeleton.names)))
    rest, bind = rest_and_bind_transforms(skeleton)
    skel.CreateRestTransformsAttr(rest)
    skel.CreateBindTransformsAttr(bind)
    return skel


def rest_and_bind_transforms(skeleton: Skeleton) -> tuple[Vt.Matrix4dArray, Vt.Matrix4dArray]:
    """A Skeleton prim's ``restTransforms`` (local: the joint offsets) and ``bindTransforms``
    (world: forward kinematics of the rest pose), both pure translations."""
    J = skeleton.num_joints
    rest_world = forward_kinematics(skeleton, skeleton.offsets[0], quat.identity((J,)))[1]
    return translation_matrices(skeleton.offsets), translation_matrices(rest_world)


def read_skeleton(stage_or_path, path) -> Skeleton:
    """A runtime Skeleton from a Skeleton prim (names from jointNames when authored, parents
    from the joint paths, offsets from the rest translations). Rest rotations must be
    identity, as the runtime's skeletons have none."""
    stage = open_stage(stage_or_path)
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(Sdf.Path(str(path))))
    where = f"{stage.GetRootLayer().identifier}:{path}"
    if not skel:
        raise StageError(where, "not a Skeleton prim")
    joints = list(skel.GetJointsAttr().Get() or [])
    if not joints:
        raise StageError(where, "skeleton has no joints")
    names = list(skel.GetJointNamesAttr().Get() or [])
    if len(names) != len(joints):
        names = [Sdf.Path(j).name for j in joints]
    parents = np.array(UsdSkel.Topology(Vt.TokenArray(joints)).GetParentIndices(), dtype=np.int64)
    rest = skel.GetRestTransformsAttr().Get()
    if rest is None or len(rest) != len(joints):
        raise StageError(where, "restTransforms missing or of the wrong length")
    m = np.array(rest, dtype=np.float64).reshape(-1, 4, 4)
    if not np.allclose(m[:, :3, :3], np.eye(3), atol=1e-6):
        raise StageError(where, "rest pose has joint rotations; runtime skeletons need identity rest rotations")
    return Skeleton(tuple(names), parents, m[:, 3, :3].copy())


# -- animation --------------------------------------------------------------------------------
def clip_joint_arrays(clip, origin=None):
    """Per-frame SkelAnimation arrays of a runtime Clip.

    Returns translations (F, J, 3) (root: world position; others: rest offsets) and rotations
    (F, J, 4) w-x-y-z (root: world rotation; others: the clip's local rotations), both taken
    from what the runtime computes (``Clip.world_root``, ``Clip.local_rotations_world_root``).
    """
    pos, _ = clip.world_root(origin)
    rot = clip.local_rotations_world_root(origin)
    F, J = rot.shape[:2]
    tr = np.empty((F, J, 3))
    tr[:] = clip.skeleton.offsets
    tr[:, 0] = pos
    return tr, rot


def _author(layer: Sdf.Layer, spec_path: Sdf.Path, times, values: np.ndarray, vt_type) -> None:
    """Author ``values`` (already in the Vt element layout and dtype) as one time sample per row,
    or as the default value when ``times`` is None."""
    if times is None:
        layer.GetAttributeAtPath(spec_path).default = vt_type.FromNumpy(values)
        return
    for t, v in zip(times.tolist(), values):
        layer.SetTimeSample(spec_path, t, vt_type.FromNumpy(v))


def write_animation(stage: Usd.Stage, path, skeleton: Skeleton, clip=None, *, translations=None,
                    rotations=None, scales=None, start: float = 0.0, time_codes=None,
                    paths: list[str] | None = None, origin=None) -> UsdSkel.Animation:
    """Define a SkelAnimation at ``path`` for ``skeleton`` and author its joint arrays.

    Either pass a runtime ``clip`` (arrays from :func:`clip_joint_arrays`, with ``origin``
    overriding the clip's own), or the arrays directly: ``translations`` (F, J, 3),
    ``rotations`` (F, J, 4) w-x-y-z, optional ``scales`` (F, J, 3); an array without the
    frame axis ((J, 3) / (J, 4)) is authored once as the attribute's default value.
    Scales default to ones (authored as a default value). Frame ``i`` is time code
    ``start + i`` unless ``time_codes`` (F,) is given. All time samples are authored with
    Sdf inside one change block on the stage's edit target (set the edit target to write into
    another layer, e.g. a value-clip layer). Do not call this inside your own
    ``Sdf.ChangeBlock``: it defines prims through the Usd API, which fails inside one.
    """
    if clip is not None:
        if translations is not None or rotations is not None:
            raise ValueError("pass either a clip or translations/rotations, not both")
        if clip.skeleton.num_joints != skeleton.num_joints:
            raise ValueError(f"clip has {clip.skeleton.num_joints} joints, skeleton has {skeleton.num_joints}")
        translations, rotations = clip_joint_arrays(clip, origin)
    if translations is None or rotations is None:
        raise ValueError("translations and rotations are required")
    J = skeleton.num_joints
    tr = np.asarray(translations, dtype=np.float64)
    rot = np.asarray(rotations, dtype=np.float64)
    sc = np.ones((J, 3)) if scales is None else np.asarray(scales, dtype=np.float64)
    frames = set()
    for name, a, w in (("translations", tr, 3), ("rotations", rot, 4), ("scales", sc, 3)):
        if a.ndim not in (2, 3) or a.shape[-2:] != (J, w):
            raise ValueError(f"{name} shape {a.shape} is not (frames, {J}, {w}) or ({J}, {w})")
        if a.ndim == 3:
            frames.add(a.shape[0])
    if len(frames) > 1:
        raise ValueError(f"translations/rotations/scales have different frame counts {sorted(frames)}")
    F = frames.pop() if frames else None
    times = None
    if F is not None:
        times = (np.asarray(time_codes, dtype=np.float64) if time_codes is not None
                 else float(start) + np.arange(F, dtype=np.float64))
        if times.shape != (F,):
            raise ValueError(f"time_codes shape {times.shape} != ({F},)")
    paths = joint_paths(skeleton) if paths is None else list(paths)

    anim = UsdSkel.Animation.Define(stage, Sdf.Path(str(path)))
    anim.CreateJointsAttr(Vt.TokenArray(paths))
    attrs = (anim.CreateTranslationsAttr(), anim.CreateRotationsAttr(), anim.CreateScalesAttr())
    target = stage.GetEditTarget()
    layer = target.GetLayer()
    # convert whole arrays once (dtype, and quaternions to the x, y, z, w memory order of GfQuatf)
    values = (np.ascontiguousarray(tr, dtype=np.float32),
              np.ascontiguousarray(rot[..., [1, 2, 3, 0]], dtype=np.float32),
              np.ascontiguousarray(sc, dtype=np.float16))
    with Sdf.ChangeBlock():
        for attr, a, vt_type in zip(attrs, values, (Vt.Vec3fArray, Vt.QuatfArray, Vt.Vec3hArray)):
            _author(layer, target.MapToSpecPath(attr.GetPath()), times if a.ndim == 3 else None, a, vt_type)
    return anim


def bind_animation(skeleton_prim, animation_prim) -> None:
    """Apply SkelBindingAPI to the Skeleton and set skel:animationSource to the animation."""
    prim = skeleton_prim.GetPrim() if hasattr(skeleton_prim, "GetPrim") else skeleton_prim
    anim = animation_prim.GetPrim() if hasattr(animation_prim, "GetPrim") else animation_prim
    UsdSkel.BindingAPI.Apply(prim).CreateAnimationSourceRel().SetTargets([anim.GetPath()])


def bind_skeleton(skel_root, skeleton_prim) -> None:
    """Set skel:skeleton on a SkelRoot (inherited by skinnable prims beneath it)."""
    root = skel_root.GetPrim() if hasattr(skel_root, "GetPrim") else skel_root
    skel = skeleton_prim.GetPrim() if hasattr(skeleton_prim, "GetPrim") else skeleton_prim
    UsdSkel.BindingAPI.Apply(root).CreateSkeletonRel().SetTargets([skel.GetPath()])


# -- one clip, one stage ----------------------------------------------------------------------
@dataclass(frozen=True)
class ClipStage:
    """What :func:`write_clip_stage` wrote."""
    path: Path | None
    root: str          # SkelRoot path (the defaultPrim)
    skeleton: str      # Skeleton path
    animation: str     # SkelAnimation path
    frames: int
    fps: float
    joints: int


def build_clip_stage(clip, name: str = "Character", *, origin=None, metadata: dict | None = None):
    """An in-memory stage holding one clip: SkelRoot ``/<name>`` (defaultPrim) with a Skeleton and
    a bound SkelAnimation; metres, Y up, timeCodesPerSecond = clip.fps, time codes 0..F-1.

    ``metadata`` (plain str/int/float values) goes to the SkelRoot's customData["crowdweave"].
    Returns ``(stage, ClipStage)``.
    """
    F = clip.num_frames
    stage = new_stage(clip.fps, 0, F - 1)
    root_path = Sdf.Path("/" + valid_prim_name(name, "Character"))
    root = define_skel_root(stage, root_path)
    skel = define_skeleton(stage, root_path.AppendChild("Skel"), clip.skeleton)
    anim = write_animation(stage, skel.GetPath().AppendChild("Anim"), clip.skeleton, clip, origin=origin)
    bind_skeleton(root, skel)
    bind_animation(skel, anim)
    set_default_prim(stage, root.GetPrim())
    if metadata:
        root.GetPrim().SetCustomDataByKey("crowdweave", dict(metadata))
    info = ClipStage(None, str(root_path), str(skel.GetPath()), str(anim.GetPath()), F, float(clip.fps),
                     clip.skeleton.num_joints)
    return stage, info


def write_clip_stage(path, clip, name: str = "Character", *, origin=None, metadata: dict | None = None
                     ) -> ClipStage:
    """Write one clip to ``path`` (.usda/.usdc/.usd) atomically; see :func:`build_clip_stage`."""
    p = check_usd_path(path)
    stage, info = build_clip_stage(clip, name, origin=origin, metadata=metadata)
    save_stage(stage, p)
    return ClipStage(p, info.root, info.skeleton, info.animation, info.frames, info.fps, info.joints)


# -- reading back -----------------------------------------------------------------------------
def _find_skeleton(stage: Usd.Stage, prim: Usd.Prim) -> UsdSkel.Skeleton:
    if prim.IsA(UsdSkel.Skeleton):
        return UsdSkel.Skeleton(prim)
    bound = UsdSkel.BindingAPI(prim).GetInheritedSkeleton() if prim.HasAPI(UsdSkel.BindingAPI) else None
    if bound:
        return bound
    found = [p for p in Usd.PrimRange(prim, Usd.TraverseInstanceProxies()) if p.IsA(UsdSkel.Skeleton)]
    if len(found) != 1:
        raise StageError(f"{stage.GetRootLayer().identifier}:{prim.GetPath()}",
                         f"expected one Skeleton beneath the prim, found {len(found)}")
    return UsdSkel.Skeleton(found[0])


def joint_world_positions(stage_or_path, prim_path=None, time_codes=None, *, at_rest: bool = False
                          ) -> np.ndarray:
    """Joint world positions (T, J, 3) in metres, computed by UsdSkel itself.

    ``prim_path`` names a Skeleton or a prim above one (SkelRoot); default the defaultPrim.
    Uses ``UsdSkel.Cache`` -> ``SkeletonQuery.ComputeJointSkelTransforms`` times the
    Skeleton's local-to-world (``UsdGeom.XformCache``, instance proxies included) at each time code
    (default: every integer time code from the stage's start to end, else the animation's
    time samples), so it checks what a DCC tool would see. Joints are in the Skeleton's order;
    positions are scaled by the stage's metersPerUnit (axes are left as the stage has them).
    ``at_rest=True`` poses the Skeleton's restTransforms instead of its animation.
    """
    stage = open_stage(stage_or_path)
    prim = stage.GetDefaultPrim() if prim_path is None else stage.GetPrimAtPath(Sdf.Path(str(prim_path)))
    if not prim:
        raise StageError(stage.GetRootLayer().identifier, f"no prim at {prim_path or '(defaultPrim)'}")
    skel = _find_skeleton(stage, prim)
    cache = UsdSkel.Cache()
    skel_root = UsdSkel.Root.Find(skel.GetPrim())
    if skel_root:
        cache.Populate(skel_root, Usd.TraverseInstanceProxies())     # instanced Skeletons too
    query = cache.GetSkelQuery(skel)
    if not query:
        raise StageError(f"{stage.GetRootLayer().identifier}:{skel.GetPath()}", "UsdSkel cannot query this skeleton")
    if time_codes is None:
        if stage.HasAuthoredTimeCodeRange():
            time_codes = np.arange(stage.GetStartTimeCode(), stage.GetEndTimeCode() + 0.5, 1.0)
        else:
            anim_q = query.GetAnimQuery()
            time_codes = list(anim_q.GetJointTransformTimeSamples()) if anim_q else []
    times = [Usd.TimeCode(float(t)) for t in time_codes] or [Usd.TimeCode.Default()]
    xf = UsdGeom.XformCache()
    out = np.empty((len(times), len(query.GetJointOrder()), 3))
    for i, t in enumerate(times):
        xf.SetTime(t)
        # skeleton space, then the Skeleton prim's own local-to-world: a query of an instanced
        # Skeleton is its prototype's, whose transform is not the instance's
        m = np.array(query.ComputeJointSkelTransforms(t, at_rest), dtype=np.float64).reshape(-1, 4, 4)
        w = np.array(xf.GetLocalToWorldTransform(skel.GetPrim()), dtype=np.float64)
        out[i] = (m @ w)[:, 3, :3]
    return out * UsdGeom.GetStageMetersPerUnit(stage)
