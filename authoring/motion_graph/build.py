"""Build a snap-together motion graph from takes (Gleicher, Shin, Kovar and Jepsen 2003; the
state subgraphs of Sung, Kovar and Gleicher 2005, sections 3.1, 3.3 and 4).

Pipeline: takes (30 Hz clips + per-frame labels) -> joint positions -> windowed point-cloud
features -> chunked distance, row-wise local minima under the threshold -> greedy hub poses
-> snap every take to its hub occurrences -> cut into edges -> states and labels -> prune
to strongly connected state subgraphs -> per-edge tables -> :class:`MotionGraph`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from runtime.motion import Clip, Skeleton, SkeletonMismatchError
from runtime.motion.contacts import contacts_of
from runtime.motion.cylinders import pose_cylinders
from runtime.motion.graph import MotionGraph

from .derive import runs
from .footfix import added_slide, knee_range, pin_feet, slide_report, take_slide
from .distance import DEFAULT_JOINT_WEIGHTS, frame_features
from .hubs import find_candidates, pick_hubs, still_loops
from .labels import NODE_LABEL, STATES, TRANSITIONS, pose_classes, state_classes, state_of_label
from .snap import cut_edges, snap_take

__all__ = ["SourceClip", "GraphBuildParams", "build_graph", "prune", "BUILDER_VERSION"]

# Bump when the builder's output for the same takes changes (invalidates cached libraries).
BUILDER_VERSION = 4


@dataclass
class SourceClip:
    """One source clip of the graph builder: a take's motion with one label per frame."""
    name: str
    clip: Clip                 # 30 Hz (or the graph's fps), world placement irrelevant
    labels: list[str]          # one per frame
    path: str = ""


@dataclass
class GraphBuildParams:
    """Parameters of :func:`build_graph`."""
    fps: float = 30.0
    threshold_cm: float = 6.0        # RMS point-cloud distance below which frames match
    half_window: int = 4             # distance window: 2 * half_window + 1 frames
    min_edge_frames: int = 20        # occurrences (and so edges) at least this far apart: with 2/3 s,
                                     # walking edges hold a whole gait cycle, so parallel edges of
                                     # one node pair turn by up to +-90 deg
    min_occurrences: int = 3
    max_hubs: int = 40
    snap_window: int = 8             # frames over which the snap displacement fades
    min_degree: int = 2              # in/out degree within the state subgraph after pruning
    match_pose_kind: bool = False    # frames match only frames of the same node label (stand /
                                     # walk): for labels derived from real capture, see labels.pose_classes
    still_eps: tuple | None = None   # (m/s, deg/s): make idle self-loops that drift within this
                                     # in runs of "idle" frames (hubs.still_loops); None: off
    pin_feet: bool = True            # leg IK keeps planted feet where the take has them through
                                     # the snap blend (footfix.pin_feet)
    max_foot_slide: float = 25.0     # cm/s: an edge whose planted feet slide faster than its take's
                                     # own by more than this on any frame is dropped (footfix.added_slide)
    joint_weights: dict = field(default_factory=lambda: dict(DEFAULT_JOINT_WEIGHTS))


def _joint_weights(sk: Skeleton, table: dict) -> np.ndarray:
    return np.array([float(table.get(n, 1.0)) for n in sk.names])


def build_graph(takes: list[SourceClip], params: GraphBuildParams | None = None, progress=None,
                log=print, map_blocks=None) -> MotionGraph:
    """The motion graph of ``takes`` (all at ``params.fps``, one skeleton family): hub poses,
    snapped edges between them, states and labels, pruned to strongly connected state
    subgraphs. ``progress(n)`` is called as frame distances are computed; ``log`` prints
    the build's figures. ``map_blocks`` computes the blocks of frame distances elsewhere (see
    :func:`hubs.find_candidates`; :func:`authoring.batch.cluster.block_mapper` runs them on a
    Dask cluster): the graph is the same."""
    params = params or GraphBuildParams()
    if not takes:
        raise ValueError("no takes to build a graph from")
    sk = takes[0].clip.skeleton
    for t in takes[1:]:
        if not t.clip.skeleton.same_family(sk):
            raise SkeletonMismatchError(
                f"skeleton family mismatch: {t.path or t.name} is {t.clip.skeleton.family}, "
                f"{takes[0].path or takes[0].name} is {sk.family}; retarget before mixing")
        if abs(t.clip.fps - params.fps) > 1e-9:
            raise ValueError(f"{t.path or t.name}: take is at {t.clip.fps} fps, graph at {params.fps}")
        if len(t.labels) != t.clip.num_frames:
            raise ValueError(f"{t.path or t.name}: {len(t.labels)} labels for {t.clip.num_frames} frames")

    # -- distance features and transition candidates ------------------------------------------
    positions = [t.clip.positions(origin=np.zeros(3)) for t in takes]
    feats = frame_features(positions, _joint_weights(sk, params.joint_weights), params.half_window)
    labels = [lab for t in takes for lab in t.labels]
    cls, cls_names, compatible = state_classes(labels)
    S = len(STATES)
    is_state = cls < S
    threshold = (params.threshold_cm / 100.0) ** 2
    match_cls, match_ok = pose_classes(labels, cls, compatible) if params.match_pose_kind else (cls, compatible)
    cand = find_candidates(feats, threshold, match_cls, match_ok, row_ok=feats.valid & is_state,
                           col_ok=feats.valid, band=params.min_edge_frames, progress=progress,
                           map_blocks=map_blocks)
    hubs = pick_hubs(feats, cand, params.min_edge_frames, params.min_occurrences, params.max_hubs,
                     hub_ok=feats.valid & is_state)
    if not hubs:
        raise ValueError("no hub poses found: the takes share no pose below the threshold "
                         f"({params.threshold_cm} cm); raise --threshold or add data")
    occ_d = np.sqrt(np.concatenate([h.distances for h in hubs])) * 100.0
    log(f"  {len(hubs)} hub poses from {len(cand.cols)} transition candidates "
        f"(occurrences within {occ_d.max():.1f} cm of their hub, median {np.median(occ_d):.1f} cm)")
    if params.still_eps is not None:
        root = np.concatenate([np.column_stack([t.clip.root_xz, t.clip.root_heading]) for t in takes])
        idle = np.array([lab == "idle" for lab in labels]) & feats.valid
        standing = [(a, b) for a, b in runs(idle) if feats.take[a] == feats.take[b - 1]]
        stand = np.array([NODE_LABEL.get(labels[h.frame]) == "stand" for h in hubs])
        n_loops = still_loops(feats, hubs, standing, root, threshold, params.min_edge_frames, params.fps,
                              params.still_eps, stand)
        log(f"  {n_loops} idle loop(s) standing still")

    # -- snap and cut ------------------------------------------------------------------------
    offsets = np.concatenate([[0], np.cumsum([t.clip.num_frames for t in takes])])
    take_of = feats.take
    rot_all = np.concatenate([t.clip.rotations for t in takes]).astype(np.float64)
    height_all = np.concatenate([t.clip.root_height for t in takes])
    hub_rot = np.stack([rot_all[h.frame] for h in hubs])
    hub_height = np.array([height_all[h.frame] for h in hubs])
    occ_frame = np.concatenate([h.occurrences for h in hubs])
    occ_hub = np.concatenate([np.full(len(h.occurrences), k) for k, h in enumerate(hubs)])
    edges = []   # (src, dst, take, start, end, clip)
    spans = {}   # take -> [first, last] hub occurrence (frames outside them are on no edge)
    slid, slide = [], []    # edges dropped for foot slide; per kept edge its planted-point speeds
    flex = knee_range([t.clip for t in takes]) if params.pin_feet else None   # the capture's knees
    for ti, t in enumerate(takes):
        m = take_of[occ_frame] == ti
        if m.sum() < 2:
            continue
        local = occ_frame[m] - offsets[ti]
        spans[t.name] = [int(local.min()), int(local.max())]
        hk = occ_hub[m]
        contacts = contacts_of(t.clip)
        snapped = snap_take(t.clip, local, hub_rot[hk], hub_height[hk], params.snap_window)
        body = snapped
        if params.pin_feet:
            snapped = pin_feet(t.clip, snapped, contacts, local, flex_range=flex)
        # the collision cylinders hold the snapped body and the one with its feet corrected
        axis, radius, reach, top = pose_cylinders(snapped, also=body if params.pin_feet else None)
        own = take_slide(t.clip, contacts)
        for a, b, s, e, c in cut_edges(snapped, local, hk):
            v, added = added_slide(c, own[s:e])
            if 100.0 * added > params.max_foot_slide:
                slid.append({"take": t.name, "start": s, "end": e, "added_cm_s": round(100.0 * added, 1)})
                continue
            edges.append((a, b, ti, s, e, c, (axis[s:e + 1], radius[s:e + 1], reach[s:e + 1], top[s:e + 1])))
            slide.append(v)
    if slid:
        log(f"  {len(slid)} edge(s) dropped: planted feet slide over {params.max_foot_slide:g} cm/s faster than "
            "in their take")
    if not edges:
        raise ValueError("no edges: no take passes through two hub occurrences")

    # -- states and labels -----------------------------------------------------------------------
    node_state = np.array([STATES.index(cls_names[cls[h.frame]]) for h in hubs])
    node_labels = []
    for h in hubs:
        labs = sorted({NODE_LABEL.get(labels[o], labels[o]) for o in h.occurrences if labels[o] not in TRANSITIONS})
        node_labels.append(labs)
    edge_labels, edge_state = [], []
    for a, b, ti, s, e, c, _ in edges:
        labs = takes[ti].labels[s:e + 1]
        uniq = sorted(set(labs))
        edge_labels.append(uniq)
        states = {state_of_label(x) for x in uniq}
        if None in states or node_state[a] != node_state[b] or len(states) > 1:
            edge_state.append(-1)   # transition between states
        else:
            edge_state.append(STATES.index(states.pop()))
    edge_state = np.array(edge_state)

    src = np.array([x[0] for x in edges])
    dst = np.array([x[1] for x in edges])
    keep_nodes, keep_edges = prune(len(hubs), src, dst, node_state, edge_state, params.min_degree)
    n_pruned_edges = int(len(edges) - keep_edges.sum())
    log(f"  {len(edges)} edges, {n_pruned_edges} pruned; {int(keep_nodes.sum())}/{len(hubs)} nodes kept")
    if not keep_nodes.any():
        raise ValueError("pruning removed every node: the data has no strongly connected locomotion")
    new_id = -np.ones(len(hubs), dtype=np.int64)
    new_id[keep_nodes] = np.arange(keep_nodes.sum())
    kept = [k for k in range(len(edges)) if keep_edges[k]]
    clips = [edges[k][5] for k in kept]
    foot_slide = slide_report([slide[k] for k in kept], slid, params.max_foot_slide)
    meta_edges = [{"take": takes[edges[k][2]].name, "start": edges[k][3], "end": edges[k][4]} for k in kept]
    nodes_kept = np.flatnonzero(keep_nodes)
    return MotionGraph.from_clips(
        skeleton=sk, fps=params.fps,
        node_rotations=hub_rot[nodes_kept].astype(np.float32), node_height=hub_height[nodes_kept],
        node_state=node_state[nodes_kept], node_labels=[node_labels[n] for n in nodes_kept],
        edge_src=new_id[src[kept]], edge_dst=new_id[dst[kept]], edge_state=edge_state[kept],
        edge_labels=[edge_labels[k] for k in kept], clips=clips, cylinders=[edges[k][6] for k in kept],
        meta={"sources": [t.path or t.name for t in takes], "edge_origin": meta_edges,
              "pruned_edges": n_pruned_edges, "pruned_nodes": int(len(hubs) - keep_nodes.sum()),
              "hub_frames": [{"take": takes[take_of[h.frame]].name, "frame": int(h.frame - offsets[take_of[h.frame]]),
                              "occurrences": int(len(h.occurrences))} for h in np.array(hubs, dtype=object)[nodes_kept]],
              "params": {k: v for k, v in params.__dict__.items() if k != "joint_weights"},
              "candidates": int(len(cand.cols)), "pairs_evaluated": int(cand.pairs_evaluated),
              "occurrence_span": spans, "foot_slide": foot_slide,
              **({"knee_flexion_deg": np.degrees(flex).round(3).tolist()} if flex is not None else {})})


def _scc_largest(n, src, dst, mask_nodes, mask_edges):
    """Boolean mask of the nodes in the largest strongly connected component of the subgraph."""
    e = mask_edges & mask_nodes[src] & mask_nodes[dst]
    if not e.any():
        return np.zeros(n, dtype=bool)
    g = coo_matrix((np.ones(e.sum()), (src[e], dst[e])), shape=(n, n)).tocsr()
    _, lab = connected_components(g, directed=True, connection="strong")
    # only components that actually contain an edge (a lone node is its own component)
    has_edge = np.zeros(n, dtype=bool)
    has_edge[src[e]] = True
    cand = lab[mask_nodes & has_edge]
    if len(cand) == 0:
        return np.zeros(n, dtype=bool)
    sizes = np.bincount(cand, minlength=lab.max() + 1)
    # ties: the component with the lowest node index
    best = int(np.argmax(sizes))
    return (lab == best) & mask_nodes


def prune(n_nodes, src, dst, node_state, edge_state, min_degree=2):
    """Dead-end trimming that keeps state changes possible (Sung, Kovar and Gleicher 2005,
    sections 3.2 and 4).

    Repeats until nothing changes:
    1. per state, keep only the largest strongly connected component of that state's
       subgraph, and drop nodes whose in- or out-degree inside it is below ``min_degree``;
    2. over the whole graph (state edges plus transition edges between kept nodes), keep
       the largest strongly connected component, so that walk -> sit -> walk and
       walk -> pick up -> carry -> put down -> walk remain possible.
    Returns (keep_nodes (N,) bool, keep_edges (E,) bool).
    """
    src = np.asarray(src)
    dst = np.asarray(dst)
    keep = np.ones(n_nodes, dtype=bool)
    while True:
        before = keep.copy()
        for s in range(len(STATES)):
            in_s = keep & (node_state == s)
            if not in_s.any():
                continue
            em = edge_state == s
            while True:
                comp = _scc_largest(n_nodes, src, dst, in_s, em)
                e = em & comp[src] & comp[dst]
                outdeg = np.bincount(src[e], minlength=n_nodes)
                indeg = np.bincount(dst[e], minlength=n_nodes)
                ok = comp & (outdeg >= min_degree) & (indeg >= min_degree)
                if np.array_equal(ok, in_s):
                    break
                in_s = ok
            keep &= ~((node_state == s) & ~in_s)
        keep &= _scc_largest(n_nodes, src, dst, keep, np.ones(len(src), dtype=bool))
        if np.array_equal(keep, before):
            break
    keep_edges = keep[src] & keep[dst]
    return keep, keep_edges
