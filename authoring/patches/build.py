"""Motion-patch construction (Kim, Hwang, Hyun and Lee 2012, section 4): multi-character takes -> a patch
library.

Pipeline (:func:`build_patch_library`):

1. **Episodes** of every take (:mod:`.episodes`: contact, proximity with reaction Eq. 4,
   synchronicity Eq. 5, merging).
2. **Boundaries** (:mod:`.boundaries`): eventless candidate frames around each episode, pose
   clustering (complete linkage), the subset of the ``k`` largest pose groups of least
   ``weight * |S| + padding``; every fragment is cut at the frame of a chosen group nearest to
   its episode (the sampled frame is refined to the frame of its run nearest the group's
   representative pose).
3. **Pose classes.** Every chosen group is a pose class. With a motion graph (``graph=``), a
   group whose representative pose is within ``node_match`` of a hub node's pose takes the
   hub's name ``node:<id>`` (the naming of :func:`runtime.tiling.patch.single_character_patches`),
   so the multi-character patches stitch to the graph's single-character patches.
4. **Snapping.** The entry/exit frame of each fragment is set exactly to its class's
   representative pose (joint rotations and root height), the difference being blended out
   over ``snap_frames`` frames (slerp of the per-joint correction), so that matching exit and
   entry poses are identical, as the tiler's stitching assumes.
5. **Patches.** One patch per episode with a fragment per performer (root path and heading in
   the patch frame, times ``t0`` relative to the earliest entry) and interpersonal
   constraints (:class:`runtime.tiling.patch.Constraint`, measured from the data) at the
   first, middle and last frame of every contact and at the peak of every proximity /
   synchronicity event; labels ``multi``, ``<n>p``, the event kinds and the take's annotated
   event labels that overlap the episode (e.g. ``handshake``).
6. **Single-character patches**: from the motion graph (``singles="graph"``) or cut from the
   performers' eventless stretches of the takes between frames of the chosen pose classes
   (``singles="takes"``), labelled by the take's segment labels (walk, turn, idle, ...).

Performers whose skeleton has other bone lengths than the library skeleton (the CMU salsa
dancers) are retargeted the simple way: same joint rotations, root path and height scaled by
the ratio of leg lengths.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from runtime.motion import Clip, quat
from runtime.motion.contacts import contacts_of
from runtime.motion.planar import rotate_xz
from runtime.tiling.patch import Constraint, Fragment, Patch, PatchLibrary

from .boundaries import BoundaryParams, Side, cluster_poses, group_order, select_subset, side_candidates
from .episodes import EpisodeParams, detect_episodes
from .features import boundary_features, person_features

__all__ = ["PatchBuildParams", "BuildResult", "build_patch_library", "PatchBuildError"]

SINGLE_LABEL_MAP = {"wait": "idle", "idle": "idle", "walk": "walk", "start": "start", "stop": "stop",
                    "turn": "turn", "carry": "carry", "dash": "dash"}
SINGLE_LABELS = frozenset(SINGLE_LABEL_MAP.values())


class PatchBuildError(ValueError):
    """Input that cannot become patches (names the take)."""


@dataclass
class PatchBuildParams:
    """Settings of :func:`build_patch_library`: episode detection (:class:`.episodes.
    EpisodeParams`), boundaries (:class:`.boundaries.BoundaryParams`), ``snap_frames`` over which
    the snap to a class's representative pose is blended out, ``node_match`` (RMS metres) for a
    pose group to take a graph hub's name, and the cutting of single-character patches from the
    takes (``single_min_frames``, ``single_max_s``, ``idle_every_s``, ``max_single_per_take``)."""
    episodes: EpisodeParams = field(default_factory=EpisodeParams)
    boundaries: BoundaryParams = field(default_factory=BoundaryParams)
    snap_frames: int = 8
    node_match: float = 0.06           # RMS metres
    single_min_frames: int = 12
    single_max_s: float = 4.0
    idle_every_s: float = 1.5          # cut points inside long stand-stills
    max_single_per_take: int = 40


@dataclass
class BuildResult:
    library: PatchLibrary
    episodes: dict                     # take name -> [Episode]
    dropped: list                      # [(take, episode index, reason)]
    groups: list                       # [(group id, size)] of the k largest groups
    chosen: list                       # chosen group ids
    classes: list                      # class names, in class order
    subset_table: list
    candidates: int
    stride: int
    snap_error: dict                   # class -> largest RMS pose change at snapping (m)

    def summary(self) -> dict:
        s = self.library.summary()
        s["episodes"] = sum(len(v) for v in self.episodes.values())
        s["dropped_episodes"] = len(self.dropped)
        s["chosen_groups"] = len(self.chosen)
        s["classes"] = list(self.classes)
        return s


# ------------------------------------------------------------------------------------------
def _leg(skel) -> float:
    off = skel.offsets
    return float(np.linalg.norm(off[skel.index("LeftLeg")]) + np.linalg.norm(off[skel.index("LeftFoot")]))


def _same_layout(a, b) -> bool:
    return a.names == b.names and np.array_equal(a.parents, b.parents)


def _world_arrays(clip: Clip, scale: float):
    pos, _ = clip.world_root()
    return pos[:, [0, 2]] * scale, clip.world_heading(), clip.root_height * scale, clip.rotations, contacts_of(clip)


def _rep_pose(arrs, f):
    return arrs[3][f].astype(np.float64), float(arrs[2][f])


def _snap(rot, height, at_start: bool, rep_rot, rep_h, n: int):
    """Blend fragment ``rot`` (F, J, 4) / ``height`` so the first (or last) frame equals the
    representative pose; the correction fades out over ``n`` frames."""
    F = len(rot)
    rot = rot.astype(np.float64).copy()
    height = np.asarray(height, np.float64).copy()
    i0 = 0 if at_start else F - 1
    corr = quat.mul(rep_rot, quat.inv(rot[i0]))                      # (J, 4) left correction
    corr = quat.canonical(corr)
    m = min(n, F - 1)
    k = np.arange(F) if at_start else (F - 1 - np.arange(F))
    w = np.where(k < m, 0.5 * (1 + np.cos(np.pi * k / max(m, 1))), 0.0)
    w[i0] = 1.0
    ident = np.zeros_like(corr)
    ident[:, 0] = 1.0
    for i in np.flatnonzero(w > 0):
        c = quat.slerp(ident, corr, np.full(len(corr), w[i]))
        rot[i] = quat.mul(c, rot[i])
    height += (rep_h - height[i0]) * w
    return quat.normalize(rot), height


def _refine(side: Side, cand: int, stride: int, feats, medoid, thr):
    """The frame near sampled candidate ``cand`` (within the stride, inside the window) whose
    boundary feature is nearest the group's representative; ties go to the frame nearer the
    episode."""
    lo, hi = max(side.lo, cand - stride + 1), min(side.hi, cand + stride - 1)
    fr = np.arange(lo, hi + 1)
    d = np.linalg.norm(feats[fr] - medoid, axis=1)
    pad = (side.anchor - fr) if side.kind == "entry" else (fr - side.anchor)
    best = int(fr[np.argmin(d + 1e-4 * pad)])
    return best if np.linalg.norm(feats[best] - medoid) <= thr else cand


def build_patch_library(takes, params: PatchBuildParams | None = None, graph=None, singles: str = "takes",
                        progress=None, log=None, seed: int = 0) -> BuildResult:
    """Detect episodes in ``takes`` and build the patch library (see module docstring).

    singles: ``"takes"`` (cut from the takes), ``"graph"`` (:func:`single_character_patches`
    of ``graph``), or ``"none"``. ``progress(n)`` is called per take processed."""
    p = params or PatchBuildParams()
    bp = p.boundaries
    log = log or (lambda *a: None)
    if singles not in ("takes", "graph", "none"):
        raise ValueError(f"singles must be 'takes', 'graph' or 'none', not {singles!r}")
    if singles == "graph" and graph is None:
        raise ValueError("singles='graph' needs a motion graph")
    if not takes:
        raise PatchBuildError("no takes given")
    target = graph.skeleton if graph is not None else takes[0].clips[0].skeleton
    for tk in takes:
        for n, c in zip(tk.people, tk.clips):
            if not _same_layout(c.skeleton, target):
                raise PatchBuildError(f"take {tk.name!r}: performer {n!r} has a different skeleton layout "
                                      f"({c.skeleton.family}) than the library ({target.family})")
        if abs(tk.fps - takes[0].fps) > 1e-9:
            raise PatchBuildError(f"take {tk.name!r} is at {tk.fps:g} fps, the first take at {takes[0].fps:g}")
    fps = float(takes[0].fps)
    J = target.num_joints
    sq = np.sqrt(J)

    # ---- 1. features and episodes ---------------------------------------------------------
    w = max(int(round(p.episodes.window * fps / 30.0)), 1)
    feats, bfeat, arrs, episodes = [], [], [], {}
    for tk in takes:
        fs = [person_features(c, w) for c in tk.clips]
        feats.append(fs)
        bfeat.append([boundary_features(f) / sq for f in fs])
        arrs.append([_world_arrays(c, _leg(target) / _leg(c.skeleton)) for c in tk.clips])
        episodes[tk.name] = detect_episodes(tk, p.episodes, fs)
        if progress is not None:
            progress(1)
    n_eps = sum(len(v) for v in episodes.values())
    log(f"{n_eps} episodes in {len(takes)} takes")

    # ---- 2. sides and candidate frames -----------------------------------------------------
    margin = int(round(bp.margin_s * fps))
    maxpad = int(round(bp.max_pad_s * fps))
    sides: list[Side] = []
    ep_list = []                                         # (take index, episode)
    busy = {}                                            # (take, person) -> [(lo, hi)] forbidden
    for ti, tk in enumerate(takes):
        for e in episodes[tk.name]:
            for q in e.people:
                busy.setdefault((ti, q), []).append((e.start - margin, e.end + margin))
    for ti, tk in enumerate(takes):
        F = tk.num_frames
        for e in episodes[tk.name]:
            ei = len(ep_list)
            ep_list.append((ti, e))
            for q in e.people:
                bz = busy[(ti, q)]
                prev_end = max([b for a, b in bz if b < e.start - margin] + [-1])
                next_start = min([a for a, b in bz if a > e.end + margin] + [F])
                hi = e.start - margin
                lo = max(0, e.start - maxpad, prev_end + 1)
                sides.append(Side(ei, ti, q, "entry", lo, min(hi, F - 1), e.start,
                                  prev_end < 0 and lo == 0, 0))
                lo2 = e.end + margin
                hi2 = min(F - 1, e.end + maxpad, next_start - 1)
                sides.append(Side(ei, ti, q, "exit", max(lo2, 0), hi2, e.end,
                                  next_start >= F and hi2 == F - 1, F - 1))
    pool = sorted({(s.take, s.person, f) for s in sides for f in range(s.lo, s.hi + 1)})
    stride = max(1, int(np.ceil(len(pool) / bp.max_candidates)))
    sample = [t for t in pool if t[2] % stride == 0]
    log(f"{len(sides)} fragment ends, {len(pool)} candidate frames, clustering {len(sample)} (stride {stride})")
    if sample:
        X = np.stack([bfeat[t][q][f] for t, q, f in sample])
        labels = cluster_poses(X, bp.threshold)
    else:
        X = np.zeros((0, 1))
        labels = np.zeros(0, np.int64)
    order = group_order(labels)[:bp.k] if len(labels) else np.zeros(0, np.int64)
    sizes = [(int(g), int(np.sum(labels == g))) for g in order]
    medoid = {}
    for g in order:
        m = X[labels == g]
        medoid[int(g)] = m[np.argmin(np.linalg.norm(m - m.mean(0), axis=1))]
    samp_by = {}
    for (t, q, f), lab in zip(sample, labels):
        samp_by.setdefault((t, q), ([], []))
        samp_by[(t, q)][0].append(f)
        samp_by[(t, q)][1].append(lab)
    samp_by = {k: (np.array(v[0]), np.array(v[1])) for k, v in samp_by.items()}

    # ---- 3. subset search -----------------------------------------------------------------
    k = len(order)
    pads = np.full((len(sides), max(k, 1)), np.inf)
    cut = np.full((len(sides), max(k, 1)), -1, np.int64)
    close = np.full(len(sides), np.inf)
    for si, s in enumerate(sides):
        if s.can_close:
            close[si] = abs(s.anchor - s.close_frame) + bp.closed_cost
        if (s.take, s.person) not in samp_by or s.hi < s.lo:
            continue
        fr, lab = samp_by[(s.take, s.person)]
        cands = side_candidates(s, fr, lab, order)
        for gi, c in enumerate(cands):
            if c < 0:
                continue
            c = _refine(s, int(c), stride, bfeat[s.take][s.person], medoid[int(order[gi])], bp.threshold)
            cut[si, gi] = c
            pads[si, gi] = (s.anchor - c) if s.kind == "entry" else (c - s.anchor)
    side_ep = np.array([s.episode for s in sides], np.int64)
    if k:
        mask, cost, table = select_subset(pads[:, :k], close, side_ep, len(ep_list), bp)
    else:
        mask, cost, table = np.zeros(0, bool), float("inf"), []
    chosen = [int(g) for g, m in zip(order, mask) if m]
    log(f"pose groups (largest {k}): " + ", ".join(f"{g}:{n}" for g, n in sizes) +
        f"; chosen {chosen} (cost {cost:.0f})")

    # ---- 4. pose classes ------------------------------------------------------------------
    node_feat = _node_features(graph, sq) if graph is not None else None
    class_names, class_rot, class_h, gclass = [], [], [], {}
    rep_of = {}
    for g in chosen:
        # representative: the sampled frame at the medoid
        idx = np.flatnonzero(labels == g)
        mi = idx[np.argmin(np.linalg.norm(X[idx] - medoid[g], axis=1))]
        t, q, f = sample[mi]
        rot, h = _rep_pose(arrs[t][q], f)
        name = f"pose:{len(class_names)}"
        if node_feat is not None:
            d = np.linalg.norm(node_feat - medoid[g], axis=1)
            nn = int(np.argmin(d))
            if d[nn] <= p.node_match:
                name = f"node:{nn}"
                rot = graph.node_rotations[nn].astype(np.float64)
                h = float(graph.node_height[nn])
        if name not in class_names:
            class_names.append(name)
            class_rot.append(rot)
            class_h.append(h)
        gclass[g] = class_names.index(name)
        rep_of[gclass[g]] = (rot, h)

    # ---- 5. multi-character patches ----------------------------------------------------------
    chosen_cols = [list(order).index(g) for g in chosen]
    patches, dropped = [], []
    snap_err: dict = {}
    per_ep_sides: dict = {}
    for si, s in enumerate(sides):
        per_ep_sides.setdefault(s.episode, []).append(si)
    for ei, (ti, e) in enumerate(ep_list):
        tk = takes[ti]
        ends = {}
        ok = True
        for si in per_ep_sides[ei]:
            s = sides[si]
            best, bcls, bpad = None, -1, np.inf
            for gi in chosen_cols:
                if pads[si, gi] < bpad:
                    best, bcls, bpad = int(cut[si, gi]), gclass[int(order[gi])], pads[si, gi]
            if close[si] < bpad:
                best, bcls, bpad = s.close_frame, -1, close[si]
            if best is None:
                ok = False
                break
            ends[(s.person, s.kind)] = (best, bcls)
        if not ok:
            dropped.append((tk.name, ei, "no eventless boundary frame of a chosen pose class"))
            continue
        patches.append(_episode_patch(tk, ti, e, ends, arrs[ti], rep_of, target, fps, p, snap_err,
                                      len(patches)))
    log(f"{len(patches)} multi-character patches, {len(dropped)} episodes dropped")

    lib = PatchLibrary(target, patches, list(class_names),
                       np.asarray(class_rot, np.float32).reshape(-1, J, 4) if class_names else None,
                       np.asarray(class_h, np.float32) if class_names else None, fps,
                       {"source": "authoring.patches", "takes": [t.name for t in takes],
                        **_knee_meta(takes)})

    # ---- 6. single-character patches ------------------------------------------------------------
    if singles == "graph":
        from runtime.tiling.patch import DEFAULT_SINGLE_LABELS, single_character_patches

        # walking and carrying (box movers hand the box over and carry it away)
        single = single_character_patches(graph, labels=tuple(DEFAULT_SINGLE_LABELS) + ("carry",),
                                          states=("walking", "carrying"), seed=seed)
        lib = lib.merged(single) if len(lib.patches) or class_names else single
    elif singles == "takes" and class_names:
        sp = _single_patches(takes, episodes, bfeat, arrs, class_rot, class_h, class_names, rep_of, target,
                             fps, p, margin)
        lib = PatchLibrary(target, list(lib.patches) + sp, lib.pose_class_names, lib.pose_class_rotations,
                           lib.pose_class_height, fps, lib.meta)
    return BuildResult(lib, episodes, dropped, sizes, chosen, list(lib.pose_class_names), table,
                       len(pool), stride, {class_names[c]: v for c, v in snap_err.items() if c < len(class_names)})


def _knee_meta(takes) -> dict:
    """``{"knee_flexion_deg": [[least left, right], [most left, right]]}`` of the takes' knees (what
    the foot check compares a bake with), or {} when their legs are not known."""
    from authoring.motion_graph.footfix import knee_range
    clips = [c for t in takes for c in getattr(t, "clips", [getattr(t, "clip", None)]) if c is not None]
    r = knee_range(clips) if clips else None
    return {} if r is None else {"knee_flexion_deg": np.degrees(r).round(3).tolist()}


# ------------------------------------------------------------------------------------------
def _node_features(graph, sq):
    """Boundary features of the graph's hub poses (from the first two frames of an out-edge)."""
    out = []
    for n in range(graph.num_nodes):
        es = graph.out_edges(n)
        if len(es):
            a = int(graph.edge_start[es[0]])
            sl = slice(a, a + 2)
            clip = Clip(graph.skeleton, graph.fps, graph.frame_xz[sl], graph.frame_heading[sl],
                        graph.frame_height[sl], graph.frame_rotations[sl])
        else:
            r = np.repeat(graph.node_rotations[n][None], 2, axis=0)
            clip = Clip(graph.skeleton, graph.fps, np.zeros((2, 2)), np.zeros(2), np.full(2, graph.node_height[n]), r)
        out.append(boundary_features(person_features(clip, 1))[0] / sq)
    return np.stack(out)


def _fragment(arr, a, b, origin, h0, cls_in, cls_out, rep_of, p, snap_err, pose_fn):
    xz, hd, ht, rot, contacts = arr
    r = rot[a:b + 1].astype(np.float64)
    h = np.asarray(ht[a:b + 1], np.float64)
    for at_start, cls in ((True, cls_in), (False, cls_out)):
        if cls >= 0:
            rep_rot, rep_h = rep_of[cls]
            i0 = 0 if at_start else len(r) - 1
            before = pose_fn(r[i0], h[i0])
            r, h = _snap(r, h, at_start, rep_rot, rep_h, p.snap_frames)
            after = pose_fn(r[i0], h[i0])
            snap_err[cls] = max(snap_err.get(cls, 0.0), float(np.sqrt(np.mean(np.sum((before - after) ** 2, -1)))))
    pxz = rotate_xz(xz[a:b + 1] - origin, -h0)
    return Fragment(0.0, pxz, hd[a:b + 1] - h0, h.astype(np.float32), r.astype(np.float32), cls_in, cls_out,
                    contacts=contacts[a:b + 1])


def _pose_fn(skel):
    from runtime.motion.fk import forward_kinematics

    def f(rot, h):
        _, gp = forward_kinematics(skel, np.array([0.0, h, 0.0]), rot)
        return gp
    return f


def _episode_patch(tk, ti, e, ends, arr, rep_of, skel, fps, p: PatchBuildParams, snap_err, index):
    people = list(e.people)
    first = min(ends[(q, "entry")][0] for q in people)
    k0 = e.start
    roots = np.array([arr[q][0][k0] for q in people])
    origin = roots.mean(axis=0)
    h0 = float(arr[people[0]][1][k0])
    pose_fn = _pose_fn(skel)
    frags, entry = [], {}
    for q in people:
        a, ca = ends[(q, "entry")]
        b, cb = ends[(q, "exit")]
        fr = _fragment(arr[q], a, b, origin, h0, ca, cb, rep_of, p, snap_err, pose_fn)
        fr.t0 = (a - first) / fps
        frags.append(fr)
        entry[q] = a
    cons = []
    for ev in e.events:
        qa, qb = ev.people
        ia, ib = people.index(qa), people.index(qb)
        if ev.kind == "contact" and ev.contact_frames:
            cf = ev.contact_frames
            picks = sorted({cf[0], cf[len(cf) // 2], cf[-1]})
        else:
            picks = [ev.peak]
        for f in picks:
            fa, fb = f - entry[qa], f - entry[qb]
            if 0 <= fa < frags[ia].num_frames and 0 <= fb < frags[ib].num_frames:
                cons.append(Constraint.measure(frags, ia, fa, ib, fb, ev.kind, fps))
    gt = sorted({g["label"] for g in tk.events
                 if int(g["start"]) <= e.end and int(g["end"]) >= e.start and set(g["people"]) <= set(people)})
    labels = ["multi", f"{len(people)}p"] + list(e.kinds) + gt + [lab for lab in tk.labels if lab not in gt]
    labels = list(dict.fromkeys(labels))
    meta = {"take": tk.name, "frames": [int(e.start), int(e.end)], "people": [tk.people[q] for q in people],
            "kinds": list(e.kinds), "entry_frames": [int(ends[(q, 'entry')][0]) for q in people],
            "exit_frames": [int(ends[(q, 'exit')][0]) for q in people]}
    return Patch.from_fragments(f"{tk.name}_ep{index:03d}", labels, skel, frags, cons, fps, meta=meta)


def _single_patches(takes, episodes, bfeat, arrs, class_rot, class_h, class_names, rep_of, skel, fps,
                    p: PatchBuildParams, margin):
    """Single-character patches between frames of the chosen pose classes in the eventless
    stretches of every performer."""
    # representative boundary features of the classes: from a frame that matches exactly
    pose_fn = _pose_fn(skel)
    rep_pose = np.stack([pose_fn(np.asarray(r, np.float64), h).reshape(-1) for r, h in zip(class_rot, class_h)])
    sq = np.sqrt(skel.num_joints)
    thr = p.boundaries.threshold
    out = []
    snap_dummy: dict = {}
    for ti, tk in enumerate(takes):
        F = tk.num_frames
        made = 0
        for q in range(tk.num_people):
            free = np.ones(F, bool)
            for e in episodes[tk.name]:
                if q in e.people:
                    free[max(e.start - margin, 0):e.end + margin + 1] = False
            # RMS pose distance (root-relative, heading-free) to every class pose, per frame
            pose = bfeat[ti][q][:, :skel.num_joints * 3]
            d = np.linalg.norm(pose[:, None, :] - rep_pose[None] / sq, axis=-1)      # (F, C)
            cls = np.argmin(d, axis=1)
            ok = (d[np.arange(F), cls] <= thr) & free
            cuts = _cut_points(ok, cls, d, fps, p.idle_every_s)
            for (a, ca), (b, cb) in zip(cuts[:-1], cuts[1:]):
                if not (p.single_min_frames <= b - a <= p.single_max_s * fps) or not free[a:b + 1].all():
                    continue
                labs = Counter()
                for sa, sb, sl in tk.segments[q]:
                    ov = min(sb, b + 1) - max(sa, a)
                    if ov > 0:
                        labs[SINGLE_LABEL_MAP.get(sl, sl)] += ov
                lab = labs.most_common(1)[0][0] if labs else "idle"
                if lab not in SINGLE_LABELS:          # leftovers of an interaction group
                    continue
                fr = _fragment(arrs[ti][q], a, b, arrs[ti][q][0][a], float(arrs[ti][q][1][a]), int(ca), int(cb),
                               rep_of, p, snap_dummy, pose_fn)
                out.append(Patch.from_fragments(f"{tk.name}_{tk.people[q]}_s{made:03d}", (lab, "single"), skel,
                                                [fr], (), fps, meta={"take": tk.name, "frames": [int(a), int(b)],
                                                                     "people": [tk.people[q]]}))
                made += 1
                if made >= p.max_single_per_take:
                    break
    return out


def _cut_points(ok, cls, d, fps, every_s):
    """One cut per run of frames matching a class (its best frame), plus extra cuts every
    ``every_s`` seconds inside long runs (stand-stills)."""
    out = []
    F = len(ok)
    i = 0
    step = max(int(round(every_s * fps)), 1)
    while i < F:
        if not ok[i]:
            i += 1
            continue
        j = i
        while j + 1 < F and ok[j + 1] and cls[j + 1] == cls[i]:
            j += 1
        c = int(cls[i])
        seg = np.arange(i, j + 1)
        if j - i + 1 > 2 * step:
            for f in range(i, j + 1, step):
                out.append((int(f), c))
        else:
            out.append((int(seg[np.argmin(d[seg, c])]), c))
        i = j + 1
    return out
