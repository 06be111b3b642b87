"""Baked crowds as USD: one SkelRoot per character (UsdSkel cannot bind to a PointInstancer),
dressed in the character's look; optionally sharing its Skeleton and body with every other
character through an instanceable prototype (UsdSkel bind-state instancing).

Layout (default)::

    /World                          Xform (defaultPrim)
    /World/Environment              reference to the world stage (when given; a stage in other
                                    units or Z up: an Xform converting to metres, Y up, whose
                                    child Stage holds the reference)
    /World/Looks/<Part>_<k>         Material (UsdPreviewSurface): palette entry k of a part
                                    (Skin, Shirt, Trousers, Shoes, Prop), shared by characters
    /World/Characters/<name>        SkelRoot, SkelBindingAPI (skel:skeleton -> Skel)
        xformOp:translate           float3[t]  the root joint's world position per frame
        crowdweave:root             double3[t]  (x, z, heading in degrees) per frame
        crowdweave:frameA/B         int[]      library frames shown, one entry per frame from
        crowdweave:frameT           float[]    crowdweave:startFrame (pose = slerp(A, B, T))
        crowdweave:width, :prop     the look's body width factor and prop ("none", "hat", "bag")
        collection:<part>           the part's mesh; material:binding:collection:<part> binds it
                                    to /World/Looks/<Part>_<k>
        primvars:displayColor       the shirt colour (constant, inherited)
    /World/Characters/<name>/Skel       Skeleton (SkelBindingAPI, skel:animationSource -> Anim)
    /World/Characters/<name>/Skel/Anim  SkelAnimation (rotations per frame; translations once:
                                        the root joint's 0, its motion is the SkelRoot's
                                        translate; blendShapeWeights: wide, 0-1 over the width
                                        range)
    /World/Characters/<name>/Body       reference to /Prototypes/Body: Skin, Shirt, Trousers,
                                        Shoes, meshes rigidly skinned, each with blend shape Wide
    /World/Characters/<name>/Hat|Bag    reference to /Prototypes/Hat or /Prototypes/Bag (the prop,
                                        bound to the head or the right hand joint)

``instancing=True`` (``crowdweave bake --instancing``; not with value clips)::

    /World/Characters/<name>        SkelRoot: the crowdweave attributes and the look, as above
    /World/Characters/<name>/Anim   SkelAnimation
    /World/Characters/<name>/Rig    instanceable Xform referencing /Prototypes/Character[_hat|_bag],
                                    skel:animationSource -> ../Anim
    /Prototypes/Character           class: rel skel:skeleton -> Skel; Skel (Skeleton); Skin, Shirt,
                                    Trousers, Shoes; Character_hat and _bag add Hat or Bag

Looks come from the runtime (:func:`runtime.appearance.looks_for` of the seed and the names).

The stage's customData holds the scenario name and the library path, so a checker can read
a bake back (:func:`read_tracks`) without the planner. Poses come from the runtime
(:func:`runtime.crowd.tracks.evaluate_poses`); this module only moves arrays into USD.

Every character is authored at the Sdf level inside one ``Sdf.ChangeBlock``
(:mod:`usd_io.timesamples`: prim and attribute specs, one ``SetTimeSample`` per animated
attribute per frame, values converted from numpy arrays built for many characters at once).
For very large crowds ``build_crowd_stage(..., clips_per=N, out_path=...)`` moves the time
samples into value-clip layers of N characters each, written by parallel worker processes
(:mod:`usd_io.clips`); the top stage then holds the prims, the frame arrays and the clip
metadata.
"""
from __future__ import annotations

import os

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

from runtime.crowd.scenario import prim_name
from runtime.crowd.tracks import Track
from runtime.appearance import (PARTS, PROP_COLOURS, PROPS, SHIRTS, SHOES, SKIN, TROUSERS, WIDTH_RANGE, Looks,
                                looks_for, srgb_to_linear)
from runtime.motion.body import body_parts, prop_mesh

from .clips import remove_unused_clip_dirs, write_clip_layers
from .stage import check_usd_path, new_stage, open_stage, save_stage, set_default_prim, valid_prim_name
from .timesamples import ROOT_XFORM_ORDER, SkelValues, attribute_spec, author_tracks, prim_spec, relationship_spec

__all__ = ["build_crowd_stage", "write_crowd_stage", "save_crowd_stage", "read_tracks", "write_props",
           "character_path", "reference_world", "CHARACTERS"]

CHARACTERS = "/World/Characters"
LOOKS = "/World/Looks"
PROTOTYPES = "/Prototypes"
BODY_PROTOTYPE = "/Prototypes/Body"
WIDE = "wide"                                     # the body width blend shape
PART_PRIMS = ("Skin", "Shirt", "Trousers", "Shoes")  # mesh names of the parts of runtime.appearance.PARTS
PALETTES = (SKIN, SHIRTS, TROUSERS, SHOES)
_T = Sdf.ValueTypeNames


def prototype_path(prop: str = "none") -> str:
    """The instanced layout's prototype of characters with ``prop`` ("none", "hat", "bag")."""
    return f"{PROTOTYPES}/Character" + ("" if prop == "none" else f"_{prop}")


def wide_weight(width: float) -> float:
    """The ``wide`` blend shape's weight for a body width factor (0 at the narrowest, 1 at the
    widest of :data:`runtime.appearance.WIDTH_RANGE`)."""
    lo, hi = WIDTH_RANGE
    return (width - lo) / (hi - lo)


def anim_relpath(instanced: bool) -> str:
    """The SkelAnimation's path relative to the SkelRoot: ``Anim`` beside the instance, or
    ``Skel/Anim`` under the character's own Skeleton."""
    return "Anim" if instanced else "Skel/Anim"


def character_path(name: str) -> Sdf.Path:
    """The SkelRoot path of the character called ``name`` (:func:`runtime.crowd.scenario.prim_name`:
    a name that is not a USD identifier has its other characters replaced by '_'; the SkelRoot
    then keeps the original in ``crowdweave:name``)."""
    return Sdf.Path(CHARACTERS).AppendChild(prim_name(name))


def _mesh_spec(layer, path: Sdf.Path, mesh, blend: bool = True) -> None:
    """A rest-pose mesh rigidly skinned (one joint per point) (``mesh``: the arrays of
    :func:`runtime.motion.body.body_parts`). With ``blend``, its points are those of the
    narrowest body of :data:`runtime.appearance.WIDTH_RANGE` and the ``wide`` blend shape at
    weight 1 makes it the widest (weights stay in 0-1, the range DCC sliders keep)."""
    pts, counts, idx, joints, radial = mesh
    if blend:
        lo, hi = WIDTH_RANGE
        pts = (pts + (lo - 1.0) * radial).astype(np.float32)
        radial = ((hi - lo) * radial).astype(np.float32)
    m = prim_spec(layer, path, "Mesh", api=True)
    attribute_spec(m, "points", _T.Point3fArray, Vt.Vec3fArray.FromNumpy(pts))
    attribute_spec(m, "faceVertexCounts", _T.IntArray, Vt.IntArray.FromNumpy(counts))
    attribute_spec(m, "faceVertexIndices", _T.IntArray, Vt.IntArray.FromNumpy(idx))
    attribute_spec(m, "extent", _T.Float3Array, Vt.Vec3fArray([Gf.Vec3f(*pts.min(axis=0).tolist()),
                                                              Gf.Vec3f(*pts.max(axis=0).tolist())]))
    attribute_spec(m, "subdivisionScheme", _T.Token, "none", uniform=True)
    ji = attribute_spec(m, "primvars:skel:jointIndices", _T.IntArray, Vt.IntArray.FromNumpy(joints))
    ji.SetInfo("interpolation", UsdGeom.Tokens.vertex)
    ji.SetInfo("elementSize", 1)
    jw = attribute_spec(m, "primvars:skel:jointWeights", _T.FloatArray,
                        Vt.FloatArray.FromNumpy(np.ones(len(joints), np.float32)))
    jw.SetInfo("interpolation", UsdGeom.Tokens.vertex)
    jw.SetInfo("elementSize", 1)
    attribute_spec(m, "primvars:skel:geomBindTransform", _T.Matrix4d, Gf.Matrix4d(1.0))
    if blend:
        attribute_spec(m, "skel:blendShapes", _T.TokenArray, Vt.TokenArray([WIDE]), uniform=True)
        relationship_spec(m, "skel:blendShapeTargets", path.AppendChild("Wide"))
        b = prim_spec(layer, path.AppendChild("Wide"), "BlendShape")
        attribute_spec(b, "offsets", _T.Vector3fArray, Vt.Vec3fArray.FromNumpy(radial), uniform=True)


def _define_prototypes(stage, skeleton, instanced: bool, sv: SkelValues) -> None:
    """The shared geometry, as class prims (not drawn themselves).

    Instanced: ``/Prototypes/Character`` (and ``Character_hat``, ``Character_bag``): the
    Skeleton ``Skel`` and the part meshes (``Skin``, ``Shirt``, ``Trousers``, ``Shoes``, and
    ``Hat`` or ``Bag``), bound to ``Skel`` by ``skel:skeleton`` on the prototype's root.
    Not instanced: ``/Prototypes/Body`` holding the part meshes, ``/Prototypes/Hat`` and
    ``/Prototypes/Bag``."""
    layer = stage.GetEditTarget().GetLayer()
    first = Sdf.Path(prototype_path() if instanced else BODY_PROTOTYPE)
    if layer.GetPrimAtPath(first):          # a second set of characters baked into the same stage
        skel = layer.GetAttributeAtPath(first.AppendChild("Skel").AppendProperty("joints"))
        if instanced and (skel is None or list(skel.default) != list(sv.joints)):
            raise ValueError(f"{first} already holds a Skeleton with other joints: characters of one "
                             f"stage share one skeleton")
        return
    parts = body_parts(skeleton)
    props = {k: prop_mesh(skeleton, k) for k in PROPS[1:]}
    with Sdf.ChangeBlock():
        prim_spec(layer, Sdf.Path(PROTOTYPES), None, Sdf.SpecifierClass)
        if instanced:
            for kind in PROPS:
                if kind != "none" and props[kind] is None:
                    continue
                root = Sdf.Path(prototype_path(kind))
                r = prim_spec(layer, root, "Xform", Sdf.SpecifierClass, api=True)
                relationship_spec(r, "skel:skeleton", root.AppendChild("Skel"))
                _skeleton_spec(layer, root.AppendChild("Skel"), sv)
                for k, mesh in parts.items():
                    _mesh_spec(layer, root.AppendChild(PART_PRIMS[k]), mesh)
                if kind != "none":
                    _mesh_spec(layer, root.AppendChild(kind.capitalize()), props[kind], blend=False)
        else:
            body = Sdf.Path(BODY_PROTOTYPE)
            prim_spec(layer, body, "Xform", Sdf.SpecifierClass)
            for k, mesh in parts.items():
                _mesh_spec(layer, body.AppendChild(PART_PRIMS[k]), mesh)
            for kind, mesh in props.items():
                if mesh is not None:
                    _mesh_spec(layer, Sdf.Path(PROTOTYPES).AppendChild(kind.capitalize()), mesh, blend=False)


def _define_materials(stage, looks: Looks) -> None:
    """One UsdPreviewSurface material per palette entry the characters use, under
    ``/World/Looks`` (``Skin_3``, ``Shirt_11``, ..., ``Prop_2``; linear diffuse colours)."""
    layer = stage.GetEditTarget().GetLayer()
    used = [(PART_PRIMS[k], pal, np.unique(looks.part[:, k])) for k, pal in enumerate(PALETTES)]
    used.append(("Prop", PROP_COLOURS, np.unique(looks.prop_colour[looks.prop > 0])))
    with Sdf.ChangeBlock():
        prim_spec(layer, Sdf.Path(LOOKS), "Scope")
        for part, pal, idx in used:
            lin = srgb_to_linear(pal)
            for i in idx.tolist():
                path = Sdf.Path(LOOKS).AppendChild(f"{part}_{i}")
                if layer.GetPrimAtPath(path):
                    continue
                mat = prim_spec(layer, path, "Material")
                sh = prim_spec(layer, path.AppendChild("Surface"), "Shader")
                attribute_spec(sh, "info:id", _T.Token, "UsdPreviewSurface", uniform=True)
                attribute_spec(sh, "inputs:diffuseColor", _T.Color3f, Gf.Vec3f(*lin[i].tolist()))
                attribute_spec(sh, "inputs:roughness", _T.Float, 0.8)
                attribute_spec(sh, "outputs:surface", _T.Token)
                out = attribute_spec(mat, "outputs:surface", _T.Token)
                out.connectionPathList.explicitItems = [path.AppendChild("Surface").AppendProperty("outputs:surface")]


def _skeleton_spec(layer, path: Sdf.Path, sv: SkelValues, anim_path: Sdf.Path | None = None) -> None:
    skel = prim_spec(layer, path, "Skeleton", api=True)
    attribute_spec(skel, "joints", _T.TokenArray, sv.joints, uniform=True)
    attribute_spec(skel, "jointNames", _T.TokenArray, sv.names, uniform=True)
    attribute_spec(skel, "restTransforms", _T.Matrix4dArray, sv.rest, uniform=True)
    attribute_spec(skel, "bindTransforms", _T.Matrix4dArray, sv.bind, uniform=True)
    if anim_path is not None:
        relationship_spec(skel, "skel:animationSource", anim_path)


def _look_specs(layer, root, root_path: Sdf.Path, geom: Sdf.Path, looks: Looks, i: int) -> None:
    """Character ``i``'s look on its SkelRoot spec ``root``: one collection per part holding the
    part's mesh under ``geom`` (the instance, or the referenced body) and a collection-based
    material binding to the shared material of its colour; its shirt colour as the inherited
    constant ``primvars:displayColor``; ``crowdweave:width`` and ``crowdweave:prop``."""
    schemas = ["MaterialBindingAPI"]
    parts = [(PART_PRIMS[k].lower(), geom.AppendChild(PART_PRIMS[k]), f"{PART_PRIMS[k]}_{int(looks.part[i, k])}")
             for k in range(len(PARTS))]
    kind = PROPS[int(looks.prop[i])]
    if kind != "none":
        where = geom if geom.name == "Rig" else root_path
        parts.append(("prop", where.AppendChild(kind.capitalize()), f"Prop_{int(looks.prop_colour[i])}"))
    for name, target, material in parts:
        schemas.append(f"CollectionAPI:{name}")
        rel = Sdf.RelationshipSpec(root, f"collection:{name}:includes", False)
        rel.targetPathList.explicitItems = [target]
        b = Sdf.RelationshipSpec(root, f"material:binding:collection:{name}", False)
        b.targetPathList.explicitItems = [root_path.AppendProperty(f"collection:{name}"),
                                          Sdf.Path(LOOKS).AppendChild(material)]
    old = list(root.GetInfo("apiSchemas").prependedItems) if root.HasInfo("apiSchemas") else []
    root.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=old + schemas))
    c = attribute_spec(root, "primvars:displayColor", _T.Color3fArray,
                       Vt.Vec3fArray([Gf.Vec3f(*srgb_to_linear(looks.colours()[i, 1]).tolist())]))
    c.SetInfo("interpolation", UsdGeom.Tokens.constant)
    attribute_spec(root, "crowdweave:width", _T.Float, float(looks.width[i]), custom=True)
    attribute_spec(root, "crowdweave:prop", _T.Token, kind, custom=True)


# -- Sdf-level authoring ------------------------------------------------------------------------
def define_character_specs(layer, root_path: Sdf.Path, sv: SkelValues, track: Track, body: bool,
                           instanced: bool = False, look: tuple | None = None) -> list:
    """Author one character's prims and its crowdweave attributes into ``layer`` through Sdf;
    the animated attributes are declared without values. Returns their AttributeSpecs
    (the SkelRoot's ``xformOp:translate``, rotations, crowdweave:root).

    Not instanced: SkelRoot, Skeleton ``Skel``, SkelAnimation ``Skel/Anim``, a reference to the
    body (and its prop). Instanced: SkelRoot, SkelAnimation ``Anim`` and the instance ``Rig``
    (Skeleton and meshes) bound to ``Anim`` by ``skel:animationSource``. ``look``:
    (:class:`runtime.appearance.Looks`, row) of the character, with ``body``."""
    root = prim_spec(layer, root_path, "SkelRoot", api=not instanced)
    anim_path = root_path.AppendPath(Sdf.Path(anim_relpath(instanced)))
    attribute_spec(root, "crowdweave:startFrame", _T.Int, int(track.start_frame), custom=True)
    attribute_spec(root, "crowdweave:frameA", _T.IntArray, Vt.IntArray.FromNumpy(np.asarray(track.frames_a, np.int32)),
                   custom=True)
    attribute_spec(root, "crowdweave:frameB", _T.IntArray, Vt.IntArray.FromNumpy(np.asarray(track.frames_b, np.int32)),
                   custom=True)
    attribute_spec(root, "crowdweave:frameT", _T.FloatArray,
                   Vt.FloatArray.FromNumpy(np.asarray(track.frames_t, np.float32)), custom=True)
    kind = "none" if look is None else PROPS[int(look[0].prop[look[1]])]
    if instanced:
        rig_path = root_path.AppendChild("Rig")
        rig = prim_spec(layer, rig_path, "Xform", api=True)
        rig.SetInfo("instanceable", True)
        rig.referenceList.Prepend(Sdf.Reference(primPath=prototype_path(kind if body else "none")))
        relationship_spec(rig, "skel:animationSource", anim_path)
        geom = rig_path
    else:
        skel_path = root_path.AppendChild("Skel")
        relationship_spec(root, "skel:skeleton", skel_path)
        _skeleton_spec(layer, skel_path, sv, anim_path)
        geom = root_path.AppendChild("Body")
    anim = prim_spec(layer, anim_path, "SkelAnimation")
    attribute_spec(anim, "joints", _T.TokenArray, sv.joints, uniform=True)
    attribute_spec(anim, "scales", _T.Half3Array, sv.scales)
    if body and look is not None:
        attribute_spec(anim, "blendShapes", _T.TokenArray, Vt.TokenArray([WIDE]), uniform=True)
        # one time sample, not a default: Blender's importer keys a shape from samples only
        w = attribute_spec(anim, "blendShapeWeights", _T.FloatArray)
        w.SetTimeSample(float(track.start_frame), Vt.FloatArray([wide_weight(float(look[0].width[look[1]]))]))
    attribute_spec(anim, "translations", _T.Float3Array, sv.translations)
    attribute_spec(root, "xformOpOrder", _T.TokenArray, ROOT_XFORM_ORDER, uniform=True)
    specs = [attribute_spec(root, "xformOp:translate", _T.Float3),
             attribute_spec(anim, "rotations", _T.QuatfArray),
             attribute_spec(root, "crowdweave:root", _T.Double3, custom=True)]
    if body and not instanced:
        b = prim_spec(layer, geom, None)
        b.referenceList.Prepend(Sdf.Reference(primPath=BODY_PROTOTYPE))
        if kind != "none":
            p = prim_spec(layer, root_path.AppendChild(kind.capitalize()), None)
            p.referenceList.Prepend(Sdf.Reference(primPath=f"{PROTOTYPES}/{kind.capitalize()}"))
    if body and look is not None:
        _look_specs(layer, root, root_path, geom, look[0], look[1])
    return specs


# -- the stage ------------------------------------------------------------------------------------
def reference_world(stage, world_path, out_path=None):
    """Reference the world stage as ``/World/Environment`` (by a path relative to ``out_path``
    when given). The referenced prim is the world's defaultPrim, else its first root prim; a
    world without prims is not referenced (returns None). A world in other units or Z up (as its
    metadata says; unauthored means metres and Y up, as the world reader reads it) goes under an
    Xform that scales by its metersPerUnit and turns Z up into Y up (-90 degrees about X), the
    reference on its child ``Stage``. Returns the prim holding the reference."""
    world = Usd.Stage.Open(str(world_path), Usd.Stage.LoadNone)
    root = world.GetDefaultPrim()
    if not root:
        roots = [p for p in world.GetPseudoRoot().GetChildren() if p.IsDefined() and not p.IsAbstract()]
        if not roots:
            return None
        root = roots[0]
    ref = str(world_path)
    if out_path is not None:
        ref = os.path.relpath(os.path.abspath(world_path), os.path.dirname(os.path.abspath(out_path)))
    ref = ref.replace(os.sep, "/")
    mpu = float(UsdGeom.GetStageMetersPerUnit(world)) if world.HasAuthoredMetadata("metersPerUnit") else 1.0
    up = str(UsdGeom.GetStageUpAxis(world)) if world.HasAuthoredMetadata("upAxis") else "Y"
    if (mpu, up) == (1.0, "Y"):
        prim = stage.DefinePrim("/World/Environment")
    else:
        env = UsdGeom.Xform.Define(stage, "/World/Environment")
        env.AddScaleOp().Set(Gf.Vec3f(mpu, mpu, mpu))
        if up == "Z":
            env.AddRotateXOp().Set(-90.0)
        prim = stage.DefinePrim("/World/Environment/Stage")
    if world.GetDefaultPrim():
        prim.GetReferences().AddReference(ref)
    else:
        prim.GetReferences().AddReference(ref, root.GetPath())
    return prim


def build_crowd_stage(tracks: dict, graph, fps: float, *, metadata: dict | None = None, stage=None,
                      num_frames: int | None = None, world_path=None, out_path=None, body: bool = True,
                      clips_per: int | None = None, workers: int | None = None, scheduler: str | None = None,
                      foot_lock: bool = True, instancing: bool = False, look_seed: int = 0):
    """Author every character of ``tracks`` (name -> Track) into a new (or given) stage: one
    SkelRoot each with Skeleton, SkelAnimation and a skinned capsule-limb body (a reference to
    one prototype mesh). ``world_path`` (a world stage) is referenced as
    ``/World/Environment`` (:func:`reference_world`: by a path relative to ``out_path`` when
    given, converted to metres and Y up when the world is not).

    ``clips_per=N`` (requires ``out_path``) writes the time samples (the root's translate op,
    joint rotations, ``crowdweave:root``) as value clips, one layer per N characters, in ``workers``
    parallel processes (default 2) or on the Dask cluster at ``scheduler``, into a directory beside ``out_path`` that is assembled under a
    temporary name and renamed into place (:func:`usd_io.clips.write_clip_layers`); the returned
    stage refers to it by a relative path. Save the stage to ``out_path`` (:func:`save_crowd_stage`
    also removes clip directories of earlier bakes to the same path).

    Planted feet are locked (:mod:`runtime.motion.footlock`); ``foot_lock=False`` writes the
    library's poses as they are (single-layer stages only).

    ``instancing=True`` shares one Skeleton and body per prop kind between all characters as
    instanceable prototypes (UsdSkel bind-state instancing; not with value clips); by default
    each character has its own Skeleton (Blender 4.2 skins no mesh inside an instance). Either
    way each character gets its look from (``look_seed``, its name)
    (:func:`runtime.appearance.looks_for`)."""
    n = max([int(t.start_frame) + len(t) for t in tracks.values()] + ([num_frames] if num_frames else []))
    if clips_per is not None:
        if out_path is None:
            raise ValueError("clips_per needs out_path: the clip layers are written beside the stage")
        if int(clips_per) < 1:
            raise ValueError(f"clips_per must be at least 1, got {clips_per}")
        if not foot_lock:
            raise ValueError("foot_lock=False is for single-layer stages: value-clip layers always lock feet")
    if stage is None:
        stage = new_stage(fps, 0, n - 1)
    elif stage.GetEndTimeCode() < n - 1:      # characters added to a stage: its time range covers them too
        stage.SetEndTimeCode(n - 1)
    world = UsdGeom.Xform.Define(stage, "/World")
    set_default_prim(stage, world.GetPrim())
    UsdGeom.Scope.Define(stage, CHARACTERS)
    sk = graph.skeleton
    if world_path is not None:
        reference_world(stage, world_path, out_path)
    instanced = bool(instancing) and clips_per is None
    sv = SkelValues.of(sk)
    looks = looks_for(list(tracks), look_seed) if body else None
    if body and tracks:
        _define_prototypes(stage, sk, instanced, sv)
        _define_materials(stage, looks)
    elif instanced and tracks:
        _define_prototypes(stage, sk, instanced, sv)
    target = stage.GetEditTarget()
    layer = target.GetLayer()
    items = [(character_path(name), tr) for name, tr in tracks.items()]
    row = {p: (looks, i) for i, (p, _) in enumerate(items)} if looks is not None else {}
    T = len(graph.frame_height)
    for name, tr in tracks.items():
        for what in ("frames_a", "frames_b"):
            f = np.asarray(getattr(tr, what))
            if len(f) and (f.min() < 0 or f.max() >= T):
                raise ValueError(f"character {name!r}: track {what} reaches frame {int(f.max() if f.max() >= T else f.min())}, "
                                 f"outside the library's {T} frames")
    seen = {}
    for name, (p, _) in zip(tracks, items):
        if p in seen:
            raise ValueError(f"characters {seen[p]!r} and {name!r} both map to the USD prim {p}")
        seen[p] = name

    renamed = [(p, name) for name, (p, _) in zip(tracks, items) if p.name != name]
    if clips_per is None:
        with Sdf.ChangeBlock():
            author_tracks(layer, items, graph, sv,
                          lambda path, tr: define_character_specs(layer, target.MapToSpecPath(path), sv, tr, body,
                                                                  instanced, row.get(path)),
                          foot_lock)
    else:
        with write_clip_layers(out_path, items, graph, fps, int(clips_per), workers, scheduler) as clips:
            # the workers write the clip layers while this process authors the prims
            with Sdf.ChangeBlock():
                for path, tr in items:
                    define_character_specs(layer, target.MapToSpecPath(path), sv, tr, body, False, row.get(path))
            clips.wait()
            with Sdf.ChangeBlock():
                for path, tr in items:
                    clips.author_clip_set(layer.GetPrimAtPath(target.MapToSpecPath(path)), path, tr)
    with Sdf.ChangeBlock():      # the original of a name that is not a USD identifier
        for p, name in renamed:
            attribute_spec(layer.GetPrimAtPath(target.MapToSpecPath(p)), "crowdweave:name", _T.String, str(name),
                           custom=True)
    data = {}
    if metadata:
        data["crowdweave"] = dict(metadata)
    if clips_per is not None:
        data["crowdweave:clipDirectory"] = clips.dir_name
    if data:
        stage.GetRootLayer().customLayerData = data
    return stage


def save_crowd_stage(stage, path):
    """Save a baked stage atomically (:func:`usd_io.stage.save_stage`); afterwards remove value-clip
    directories that earlier bakes to the same path left and this stage no longer uses."""
    p = save_stage(stage, path)
    remove_unused_clip_dirs(p, keep=stage.GetRootLayer().customLayerData.get("crowdweave:clipDirectory", ""))
    return p


def write_crowd_stage(path, tracks: dict, graph, fps: float, *, metadata: dict | None = None,
                      clips_per: int | None = None, workers: int | None = None):
    p = check_usd_path(path)
    stage = build_crowd_stage(tracks, graph, fps, metadata=metadata, out_path=p, clips_per=clips_per, workers=workers)
    save_crowd_stage(stage, p)
    return p


def read_tracks(stage_or_path) -> dict:
    """Tracks (name -> Track) back from a baked stage, from its crowdweave attributes; a character
    is named by its ``crowdweave:name`` when it has one (a name that is not a USD identifier)."""
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
        original = prim.GetAttribute("crowdweave:name")
        out[(original.Get() if original else None) or prim.GetName()] = Track(fa, fb, ft, root, start)
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
