"""Motion-graph libraries as USD previews, so an animator can scrub a library in a DCC tool.

``crowdweave author graph`` writes one (``lib.usda``) beside the pack (``lib.cwpack``). The
runtime loads the pack; this stage is for looking at, and for tools that want the graph's
structure without crowdweave.

Layout (:func:`build_library_stage`)::

    /Library                 SkelRoot (defaultPrim), skel:skeleton -> /Library/Skel
        crowdweave:*         the graph as custom attributes (below)
    /Library/Skel            Skeleton, skel:animationSource -> /Library/Skel/All
    /Library/Skel/All        SkelAnimation: every edge clip back to back on the timeline
    /Library/Clips/E0000..   SkelAnimation per edge clip, time codes 0..F-1, at the origin
        crowdweave:edge, src, dst, state (int), labels (string), timelineStart (double)
    /Library/Nodes/N000..    SkelAnimation per hub pose (default values only), at the origin
        crowdweave:node, state (int), labels (string)

Time. The bound ``All`` animation plays the clips in edge order: frame ``k`` of the graph's
flat frame arrays is time code ``k``, so edge ``e`` occupies time codes
``edge_start[e] .. edge_start[e + 1] - 1`` (``crowdweave:edgeStartTime`` /
``crowdweave:edgeEndTime``). The stage runs from 0 to the last frame at
``timeCodesPerSecond = graph.fps``; pressing play shows the whole library. The per-edge prims
under ``Clips`` each start at time code 0 (point a Skeleton's ``skel:animationSource`` at one
to play that clip alone); their root starts at the origin facing +Z, i.e. they hold exactly
``graph.edge_clip(e)`` with a zero origin.

Space. In ``All`` each clip starts facing +Z (heading 0) at its own placement
``crowdweave:edgePlacement[e] = (x, z, heading=0)``, on a grid of cells: columns along +X,
rows along +Z, ``columns`` per row (default ``ceil(sqrt(E))``; ``columns=E`` gives one row
along +X). A cell is as wide and deep as the largest clip footprint (the cylinder axes' path
widened by the per-frame bounding radius, ``graph.frame_cxz`` and ``graph.frame_radius``) plus
``gap`` metres, and each clip's
footprint is placed at its cell's corner, so no two clips overlap spatially.

Graph attributes on ``/Library`` (arrays indexed by node or by edge):

==============================  ============  ==================================================
``crowdweave:stateNames``       string[]      index -> state name (``runtime.motion.graph.STATES``)
``crowdweave:nodeLabels``       string[]      per node, its labels joined by ","
``crowdweave:nodeState``        int[]         index into stateNames
``crowdweave:nodeHeight``       double[]      hub pose root height (m)
``crowdweave:nodePoses``        rel           the ``Nodes/N...`` prims in node order
``crowdweave:edgeSrc/edgeDst``  int[]         node indices
``crowdweave:edgeState``        int[]         index into stateNames, -1 = transition
``crowdweave:edgeLabels``       string[]      per edge, its labels joined by ","
``crowdweave:edgeFrames``       int[]         frames per clip
``crowdweave:edgeDuration``     double[]      seconds, ``(frames - 1) / fps``
``crowdweave:edgeStartTime``    double[]      first time code of the clip in ``All``
``crowdweave:edgeEndTime``      double[]      last time code of the clip in ``All``
``crowdweave:edgeDisplacement`` double3[]     (dx, dz, dheading in degrees), in the start frame
``crowdweave:edgeRadius``       float[]       largest bounding-cylinder radius (m)
``crowdweave:edgePlacement``    double3[]     (x, z, heading in degrees) of the clip start in All
``crowdweave:edgeClips``        rel           the ``Clips/E...`` prims in edge order
==============================  ============  ==================================================

The root layer's ``customLayerData["crowdweave"]`` holds ``kind = "motion_graph_preview"``,
the pack path (when known) and ``graph.summary()`` (lists become typed arrays; rows of mixed
values become JSON strings).

Everything here moves data: poses come from ``Clip.world_root`` /
``Clip.local_rotations_world_root`` (through :func:`usd_io.skel.clip_joint_arrays`); time
samples are authored with Sdf in change blocks (:func:`usd_io.skel.write_animation`).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdSkel, Vt

from runtime.motion.clip import Clip
from runtime.motion.graph import STATES

from .skel import (bind_animation, bind_skeleton, clip_joint_arrays, define_skel_root, define_skeleton,
                   joint_paths, write_animation)
from .stage import StageError, check_usd_path, new_stage, open_stage, save_stage, set_default_prim

__all__ = ["build_library_stage", "write_library_preview", "read_library_preview", "library_layout",
           "LIBRARY", "SKELETON", "ALL_CLIPS", "CLIPS", "NODES", "PREVIEW_KIND"]

LIBRARY = "/Library"
SKELETON = LIBRARY + "/Skel"
ALL_CLIPS = SKELETON + "/All"
CLIPS = LIBRARY + "/Clips"
NODES = LIBRARY + "/Nodes"
PREVIEW_KIND = "motion_graph_preview"
NS = "crowdweave:"


def clip_path(e: int) -> str:
    return f"{CLIPS}/E{e:04d}"


def node_path(n: int) -> str:
    return f"{NODES}/N{n:03d}"


# -- layout ---------------------------------------------------------------------------------------
def _local_frames_clip(graph) -> Clip:
    """All frames of all edges as one Clip whose frame ``k`` is frame ``k`` of its own edge's
    clip at a zero origin (the root path of every edge is relative to its own start, and the
    world-root evaluation is per frame, so concatenating is exact)."""
    return Clip(graph.skeleton, graph.fps, graph.frame_xz, graph.frame_heading, graph.frame_height,
                graph.frame_rotations)


def library_layout(graph, columns: int | None = None, gap: float = 1.0) -> np.ndarray:
    """Placement (E, 3) = (x, z, heading) of each edge clip's start in the ``All`` animation.

    Headings are 0 (every clip starts facing +Z). Footprints are the path of the clip's
    bounding cylinders at a zero origin (``graph.frame_cxz`` widened by ``graph.frame_radius``,
    which bound every joint and end site), so placed footprints never overlap (see the module
    docstring).
    """
    E = graph.num_edges
    out = np.zeros((E, 3))
    if E == 0:
        return out
    cols = _columns(E, columns)
    starts = graph.edge_start[:-1]
    r = graph.frame_radius.astype(np.float64)
    x, z = graph.frame_cxz[:, 0], graph.frame_cxz[:, 1]
    xmin = np.minimum.reduceat(x - r, starts)
    xmax = np.maximum.reduceat(x + r, starts)
    zmin = np.minimum.reduceat(z - r, starts)
    zmax = np.maximum.reduceat(z + r, starts)
    cell_w = float((xmax - xmin).max()) + gap
    cell_d = float((zmax - zmin).max()) + gap
    e = np.arange(E)
    out[:, 0] = (e % cols) * cell_w - xmin
    out[:, 1] = (e // cols) * cell_d - zmin
    return out


def _columns(E: int, columns: int | None) -> int:
    cols = int(columns) if columns else int(math.ceil(math.sqrt(E)))
    return max(1, min(cols, E))


# -- metadata -------------------------------------------------------------------------------
def _vt_value(v):
    """Plain Python value -> something a VtDictionary stores with a type (None -> omitted)."""
    if isinstance(v, dict):
        return {str(k): x for k, x in ((k, _vt_value(x)) for k, x in v.items()) if x is not None}
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    if isinstance(v, str):
        return v
    if isinstance(v, (list, tuple, np.ndarray)):
        items = list(v)
        if all(isinstance(x, str) for x in items):
            return Vt.StringArray(items)
        if all(isinstance(x, (int, np.integer)) and not isinstance(x, bool) for x in items):
            return Vt.IntArray([int(x) for x in items])
        if all(isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool) for x in items):
            return Vt.DoubleArray([float(x) for x in items])
        return Vt.StringArray([json.dumps(x, default=str) for x in items])
    if v is None:
        return None
    return str(v)


def _join(labels) -> list[str]:
    return [",".join(str(x) for x in labs) for labs in labels]


def _set_attr(prim_spec: Sdf.PrimSpec, name: str, type_name, value) -> None:
    spec = Sdf.AttributeSpec(prim_spec, NS + name, type_name, Sdf.VariabilityUniform, declaresCustom=True)
    spec.default = value


# -- stage ------------------------------------------------------------------------------------------
def build_library_stage(graph, *, columns: int | None = None, gap: float = 1.0,
                        clips: bool = True, nodes: bool = True) -> Usd.Stage:
    """An in-memory stage previewing ``graph`` (a :class:`runtime.motion.graph.MotionGraph`).

    See the module docstring for the layout. ``clips=False`` / ``nodes=False`` leave out the
    per-edge / per-node SkelAnimation prims (the bound ``All`` animation and the attributes
    are always written).
    """
    E, N = graph.num_edges, graph.num_nodes
    if E == 0:
        raise ValueError("the motion graph has no edges: nothing to preview")
    sk = graph.skeleton
    T = int(graph.edge_start[-1])
    stage = new_stage(graph.fps, 0, T - 1)
    root = define_skel_root(stage, LIBRARY)
    skel = define_skeleton(stage, SKELETON, sk)
    paths = joint_paths(sk)
    set_default_prim(stage, root.GetPrim())

    # every frame at its edge's zero origin, from the runtime's own world-root evaluation
    tr_local, rot = clip_joint_arrays(_local_frames_clip(graph), np.zeros(3))
    place = library_layout(graph, columns, gap)
    edge_of_frame = np.repeat(np.arange(E), graph.edge_frames)
    tr_all = tr_local.copy()
    tr_all[:, 0, 0] += place[edge_of_frame, 0]
    tr_all[:, 0, 2] += place[edge_of_frame, 1]
    all_anim = write_animation(stage, ALL_CLIPS, sk, translations=tr_all, rotations=rot, paths=paths,
                               time_codes=np.arange(T, dtype=np.float64))
    bind_skeleton(root, skel)
    bind_animation(skel, all_anim)

    if clips:
        UsdGeom.Scope.Define(stage, CLIPS)
        for e in range(E):
            a, b = graph.edge_start[e], graph.edge_start[e + 1]
            write_animation(stage, clip_path(e), sk, translations=tr_local[a:b], rotations=rot[a:b],
                            paths=paths, start=0.0)
    if nodes and N:
        UsdGeom.Scope.Define(stage, NODES)
        for n in range(N):
            ntr, nrot = clip_joint_arrays(graph.node_pose_clip(n), np.zeros(3))
            write_animation(stage, node_path(n), sk, translations=ntr[0], rotations=nrot[0], paths=paths)

    # -- the graph as attributes (Sdf specs in one change block) --------------------------------
    layer = stage.GetEditTarget().GetLayer()
    disp = graph.edge_disp
    tn = Sdf.ValueTypeNames
    with Sdf.ChangeBlock():
        spec = layer.GetPrimAtPath(LIBRARY)
        _set_attr(spec, "stateNames", tn.StringArray, Vt.StringArray(list(STATES)))
        _set_attr(spec, "nodeLabels", tn.StringArray, Vt.StringArray(_join(graph.node_labels)))
        _set_attr(spec, "nodeState", tn.IntArray, Vt.IntArray.FromNumpy(graph.node_state.astype(np.int32)))
        _set_attr(spec, "nodeHeight", tn.DoubleArray, Vt.DoubleArray.FromNumpy(
            np.asarray(graph.node_height, dtype=np.float64)))
        _set_attr(spec, "edgeSrc", tn.IntArray, Vt.IntArray.FromNumpy(graph.edge_src.astype(np.int32)))
        _set_attr(spec, "edgeDst", tn.IntArray, Vt.IntArray.FromNumpy(graph.edge_dst.astype(np.int32)))
        _set_attr(spec, "edgeState", tn.IntArray, Vt.IntArray.FromNumpy(graph.edge_state.astype(np.int32)))
        _set_attr(spec, "edgeLabels", tn.StringArray, Vt.StringArray(_join(graph.edge_labels)))
        _set_attr(spec, "edgeFrames", tn.IntArray, Vt.IntArray.FromNumpy(graph.edge_frames.astype(np.int32)))
        _set_attr(spec, "edgeDuration", tn.DoubleArray, Vt.DoubleArray.FromNumpy(
            graph.edge_duration.astype(np.float64)))
        _set_attr(spec, "edgeStartTime", tn.DoubleArray, Vt.DoubleArray.FromNumpy(
            graph.edge_start[:-1].astype(np.float64)))
        _set_attr(spec, "edgeEndTime", tn.DoubleArray, Vt.DoubleArray.FromNumpy(
            (graph.edge_start[1:] - 1).astype(np.float64)))
        _set_attr(spec, "edgeDisplacement", tn.Double3Array, Vt.Vec3dArray.FromNumpy(
            np.ascontiguousarray(np.column_stack([disp[:, 0], disp[:, 1], np.degrees(disp[:, 2])]))))
        _set_attr(spec, "edgeRadius", tn.FloatArray, Vt.FloatArray.FromNumpy(
            graph.edge_radius.astype(np.float32)))
        _set_attr(spec, "edgePlacement", tn.Double3Array, Vt.Vec3dArray.FromNumpy(
            np.ascontiguousarray(np.column_stack([place[:, 0], place[:, 1], np.degrees(place[:, 2])]))))
        origin = graph.meta.get("edge_origin") if isinstance(graph.meta, dict) else None
        if isinstance(origin, list) and len(origin) == E and all(isinstance(o, dict) for o in origin):
            _set_attr(spec, "edgeTake", tn.StringArray, Vt.StringArray([str(o.get("take", "")) for o in origin]))
            _set_attr(spec, "edgeTakeFrames", tn.Int2Array, Vt.Vec2iArray(
                [(int(o.get("start", -1)), int(o.get("end", -1))) for o in origin]))
        if clips:
            labels = _join(graph.edge_labels)
            for e in range(E):
                es = layer.GetPrimAtPath(clip_path(e))
                _set_attr(es, "edge", tn.Int, int(e))
                _set_attr(es, "src", tn.Int, int(graph.edge_src[e]))
                _set_attr(es, "dst", tn.Int, int(graph.edge_dst[e]))
                _set_attr(es, "state", tn.Int, int(graph.edge_state[e]))
                _set_attr(es, "labels", tn.String, labels[e])
                _set_attr(es, "timelineStart", tn.Double, float(graph.edge_start[e]))
            rel = Sdf.RelationshipSpec(spec, NS + "edgeClips", custom=True)
            rel.targetPathList.explicitItems = [Sdf.Path(clip_path(e)) for e in range(E)]
        if nodes and N:
            labels = _join(graph.node_labels)
            for n in range(N):
                ns = layer.GetPrimAtPath(node_path(n))
                _set_attr(ns, "node", tn.Int, int(n))
                _set_attr(ns, "state", tn.Int, int(graph.node_state[n]))
                _set_attr(ns, "labels", tn.String, labels[n])
            rel = Sdf.RelationshipSpec(spec, NS + "nodePoses", custom=True)
            rel.targetPathList.explicitItems = [Sdf.Path(node_path(n)) for n in range(N)]

    data = {"kind": PREVIEW_KIND, "layout": {"columns": _columns(E, columns), "gap": float(gap)},
            "summary": graph.summary()}
    if getattr(graph, "path", None):
        data["pack"] = str(graph.path)
    stage.GetRootLayer().customLayerData = {"crowdweave": _vt_value(data)}
    return stage


def write_library_preview(path, graph, **kwargs) -> Path:
    """Write the preview of ``graph`` to ``path`` (.usda text, .usdc/.usd crate) atomically:
    a failed write leaves any previous file intact. Keyword arguments go to
    :func:`build_library_stage`. Returns the path."""
    p = check_usd_path(path)
    stage = build_library_stage(graph, **kwargs)
    return save_stage(stage, p)


# -- reading back ------------------------------------------------------------------------------------
_READ = {
    "stateNames": "state_names", "nodeLabels": "node_labels", "nodeState": "node_state",
    "nodeHeight": "node_height", "edgeSrc": "edge_src", "edgeDst": "edge_dst", "edgeState": "edge_state",
    "edgeLabels": "edge_labels", "edgeFrames": "edge_frames", "edgeDuration": "edge_duration",
    "edgeStartTime": "edge_start_time", "edgeEndTime": "edge_end_time", "edgeDisplacement": "edge_disp",
    "edgeRadius": "edge_radius", "edgePlacement": "edge_placement", "edgeTake": "edge_take",
    "edgeTakeFrames": "edge_take_frames",
}


def read_library_preview(stage_or_path) -> dict:
    """The graph attributes of a library preview as numpy arrays / lists (keys as in
    ``_READ``: ``edge_src``, ``edge_dst``, ``node_labels`` (lists of labels), ...), plus
    ``edge_clips`` / ``node_poses`` (prim paths) and ``custom`` (customLayerData["crowdweave"]).
    Raises StageError when the stage holds no library preview."""
    stage = open_stage(stage_or_path)
    prim = stage.GetPrimAtPath(LIBRARY)
    where = f"{stage.GetRootLayer().identifier}:{LIBRARY}"
    if not prim or not prim.IsA(UsdSkel.Root):
        raise StageError(where, "no library SkelRoot here")
    out = {}
    for attr_name, key in _READ.items():
        a = prim.GetAttribute(NS + attr_name)
        if not a or not a.HasAuthoredValue():
            continue
        v = a.Get()
        if key in ("node_labels", "edge_labels"):
            out[key] = [[x for x in s.split(",") if x] for s in v]
        elif key in ("state_names", "edge_take"):
            out[key] = list(v)
        else:
            out[key] = np.array(v)
    for attr_name, key in (("edgeSrc", "edge_src"), ("edgeDst", "edge_dst")):
        if key not in out:
            raise StageError(where, f"{NS}{attr_name} missing")
    for rel_name, key in (("edgeClips", "edge_clips"), ("nodePoses", "node_poses")):
        r = prim.GetRelationship(NS + rel_name)
        out[key] = [str(t) for t in r.GetTargets()] if r else []
    out["custom"] = dict(stage.GetRootLayer().customLayerData.get("crowdweave", {}))
    return out
