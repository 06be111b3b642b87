"""Baked crowds as USD: one SkelRoot per character (UsdSkel cannot bind to a PointInstancer).

Layout::

    /World                          Xform (defaultPrim)
    /World/Characters/<name>        SkelRoot, SkelBindingAPI (skel:skeleton -> Skel)
        crowdweave:root             double3[t]  (x, z, heading in degrees) per frame
        crowdweave:frameA/B         int[]      library frames shown, one entry per frame from
        crowdweave:frameT           float[]    crowdweave:startFrame (pose = slerp(A, B, T))
    /World/Characters/<name>/Skel       Skeleton (SkelBindingAPI, skel:animationSource -> Anim)
    /World/Characters/<name>/Skel/Anim  SkelAnimation (root joint translation = world position)

The stage's customData holds the scenario name and the library path, so a checker can read
a bake back (:func:`read_tracks`) without the planner. Poses come from the runtime
(:func:`runtime.crowd.tracks.evaluate_poses`); this module only moves arrays into USD.
"""
from __future__ import annotations

import numpy as np
from pxr import Sdf, UsdGeom, Vt

from runtime.crowd.tracks import Track, evaluate_poses

from .skel import bind_animation, bind_skeleton, define_skel_root, define_skeleton, joint_paths, write_animation
from .stage import check_usd_path, new_stage, open_stage, save_stage, set_default_prim, valid_prim_name

__all__ = ["build_crowd_stage", "write_crowd_stage", "read_tracks", "CHARACTERS"]

CHARACTERS = "/World/Characters"


BODY_PROTOTYPE = "/Prototypes/Body"


def _define_body_prototype(stage, skeleton, paths):
    """The skinned capsule-limb body every character references (a class prim: not drawn)."""
    from pxr import Gf, UsdSkel
    from runtime.motion.body import body_mesh
    pts, counts, idx, joints = body_mesh(skeleton)
    stage.CreateClassPrim("/Prototypes")
    mesh = UsdGeom.Mesh.Define(stage, BODY_PROTOTYPE)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(idx))
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*pts.min(axis=0).tolist()), Gf.Vec3f(*pts.max(axis=0).tolist())]))
    mesh.CreateSubdivisionSchemeAttr("none")
    mesh.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(0.75, 0.62, 0.5)]))
    b = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    b.CreateJointIndicesPrimvar(False, 1).Set(Vt.IntArray.FromNumpy(joints))
    b.CreateJointWeightsPrimvar(False, 1).Set(Vt.FloatArray.FromNumpy(np.ones(len(joints), np.float32)))
    b.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    return mesh


def build_crowd_stage(tracks: dict, graph, fps: float, *, metadata: dict | None = None, stage=None,
                      num_frames: int | None = None, world_path=None, out_path=None, body: bool = True):
    """Author every character of ``tracks`` (name -> Track) into a new (or given) stage: one
    SkelRoot each with Skeleton, SkelAnimation and a skinned capsule-limb body (a reference to
    one prototype mesh). ``world_path`` (a Y-up, metre world stage) is referenced as
    ``/World/Environment`` (by a path relative to ``out_path`` when given)."""
    n = max([len(t) for t in tracks.values()] + ([num_frames] if num_frames else []))
    if stage is None:
        stage = new_stage(fps, 0, n - 1)
    world = UsdGeom.Xform.Define(stage, "/World")
    set_default_prim(stage, world.GetPrim())
    UsdGeom.Scope.Define(stage, CHARACTERS)
    sk = graph.skeleton
    paths = joint_paths(sk)
    layer = stage.GetEditTarget().GetLayer()
    if world_path is not None:
        import os
        ref = str(world_path)
        if out_path is not None:
            ref = os.path.relpath(os.path.abspath(world_path), os.path.dirname(os.path.abspath(out_path)))
        stage.DefinePrim("/World/Environment").GetReferences().AddReference(ref.replace(os.sep, "/"))
    if body and tracks:
        _define_body_prototype(stage, sk, paths)
    for name, tr in tracks.items():
        root_path = Sdf.Path(CHARACTERS).AppendChild(valid_prim_name(name, "Character"))
        root = define_skel_root(stage, root_path)
        skel = define_skeleton(stage, root_path.AppendChild("Skel"), sk, paths=paths)
        pos, rot = evaluate_poses(graph, tr.frames_a, tr.frames_b, tr.frames_t, tr.root)
        trans = np.empty(pos.shape[:1] + (sk.num_joints, 3))
        trans[:] = sk.offsets
        trans[:, 0] = pos
        times = float(tr.start_frame) + np.arange(len(tr), dtype=np.float64)
        anim = write_animation(stage, skel.GetPath().AppendChild("Anim"), sk, translations=trans, rotations=rot,
                               time_codes=times, paths=paths)
        bind_skeleton(root, skel)
        bind_animation(skel, anim)
        if body:
            stage.DefinePrim(root_path.AppendChild("Body")).GetReferences().AddInternalReference(BODY_PROTOTYPE)
        prim = root.GetPrim()
        a_root = prim.CreateAttribute("crowdweave:root", Sdf.ValueTypeNames.Double3)
        prim.CreateAttribute("crowdweave:startFrame", Sdf.ValueTypeNames.Int).Set(int(tr.start_frame))
        prim.CreateAttribute("crowdweave:frameA", Sdf.ValueTypeNames.IntArray).Set(
            Vt.IntArray.FromNumpy(np.asarray(tr.frames_a, dtype=np.int32)))
        prim.CreateAttribute("crowdweave:frameB", Sdf.ValueTypeNames.IntArray).Set(
            Vt.IntArray.FromNumpy(np.asarray(tr.frames_b, dtype=np.int32)))
        prim.CreateAttribute("crowdweave:frameT", Sdf.ValueTypeNames.FloatArray).Set(
            Vt.FloatArray.FromNumpy(np.asarray(tr.frames_t, dtype=np.float32)))
        rootv = np.column_stack([tr.root[:, 0], tr.root[:, 1], np.degrees(tr.root[:, 2])]).astype(np.float64)
        sp = a_root.GetPath()
        with Sdf.ChangeBlock():
            for t, v in zip(times.tolist(), rootv.tolist()):
                layer.SetTimeSample(sp, t, tuple(v))
    if metadata:
        stage.GetRootLayer().customLayerData = {"crowdweave": dict(metadata)}
    return stage


def write_crowd_stage(path, tracks: dict, graph, fps: float, *, metadata: dict | None = None):
    p = check_usd_path(path)
    stage = build_crowd_stage(tracks, graph, fps, metadata=metadata)
    save_stage(stage, p)
    return p


def read_tracks(stage_or_path) -> dict:
    """Tracks (name -> Track) back from a baked stage, from its crowdweave attributes."""
    stage = open_stage(stage_or_path)
    out = {}
    chars = stage.GetPrimAtPath(CHARACTERS)
    if not chars:
        return out
    for prim in chars.GetChildren():
        a = prim.GetAttribute("crowdweave:root")
        if not a:
            continue
        times = a.GetTimeSamples()
        root = np.array([a.Get(t) for t in times], dtype=np.float64)
        fa = np.array(prim.GetAttribute("crowdweave:frameA").Get(), dtype=np.int64)
        fb = np.array(prim.GetAttribute("crowdweave:frameB").Get(), dtype=np.int64)
        ft = np.array(prim.GetAttribute("crowdweave:frameT").Get(), dtype=np.float32)
        root[:, 2] = np.radians(root[:, 2])
        start = int(prim.GetAttribute("crowdweave:startFrame").Get() or 0)
        if not (len(fa) == len(fb) == len(ft) == len(root)):
            raise ValueError(f"{prim.GetPath()}: crowdweave frame arrays and crowdweave:root disagree in length")
        out[prim.GetName()] = Track(fa, fb, ft, root, start)
    return out


def write_props(stage, boxes: dict, size: float = 0.4) -> None:
    """Boxes as Cube prims under /World/Props with time-sampled translate and rotateY
    (``boxes``: marker path -> (centres (F, 3), headings (F,) radians), from the runtime)."""
    if not boxes:
        return
    UsdGeom.Scope.Define(stage, "/World/Props")
    for path, (pos, head) in boxes.items():
        cube = UsdGeom.Cube.Define(stage, Sdf.Path("/World/Props").AppendChild(valid_prim_name(path.split("/")[-1], "Box")))
        cube.CreateSizeAttr(size)
        cube.GetPrim().CreateAttribute("crowdweave:marker", Sdf.ValueTypeNames.String).Set(path)
        tr = cube.AddTranslateOp()
        ry = cube.AddRotateYOp()
        layer = stage.GetEditTarget().GetLayer()
        moving = np.any(np.abs(np.diff(pos, axis=0)) > 1e-9)
        if not moving:
            tr.Set(tuple(float(v) for v in pos[0]))
            ry.Set(float(np.degrees(head[0])))
            continue
        with Sdf.ChangeBlock():
            for k in range(len(pos)):
                layer.SetTimeSample(tr.GetAttr().GetPath(), float(k), tuple(float(v) for v in pos[k]))
                layer.SetTimeSample(ry.GetAttr().GetPath(), float(k), float(np.degrees(head[k])))
