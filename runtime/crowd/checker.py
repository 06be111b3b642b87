"""Independent checker for goal-directed crowds (Sung, Kovar and Gleicher 2005: exact
constraints, per-frame adjustment within eps, no collisions).

It reads what was baked — per character the root path and the library frames shown on every
frame — plus the scenario, the library's own tables and the environment. It does not use the
planner's numbers (costs, splice points, arrival frames, displacement values):

* **Goals.** Arrival is the frame after the previous arrival where the root comes closest
  to the goal (position, plus heading when constrained). Reported: position error, heading
  error, arrival time against its window (relative windows resolved from the *detected*
  arrival of the other character), and whether the pose shown is a library node carrying the
  goal's pose label.
* **Per-frame adjustment** (section 3.3). From the frames shown, the checker
  rebuilds the raw motion of the clips (their own root path) and places it rigidly at the
  segment's start and at its end. A spliced motion is the start-anchored raw motion plus a
  slow drift up to some frame, then the end-anchored raw motion plus a slow drift; the checker
  finds the split that minimises the largest drift rate and reports that rate (m/s, deg/s)
  and the time-warp rate |dsource/dt - 1| (s/s).
* **Collisions.** Every frame, every pair of characters: the library's minimum bounding
  cylinders (per library frame an axis offset from the root and a radius; a frame shown as a
  blend of two is held by the circle holding both) must not overlap; every character against
  every obstacle footprint (exact distances).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..check import CheckReport
from ..motion import quat
from ..motion.planar import compose, relative, wrap_angle

__all__ = ["CrowdReport", "check_crowd", "check_crowd_feet", "adjustment_rates", "summarize", "overlapping_pairs", "obstacle_overlaps"]


def _edge_of(graph, frames):
    return np.searchsorted(graph.edge_start, frames, side="right") - 1


def _source_position(graph, fa, fb, t):
    """(edge, fractional local frame) of each output frame."""
    eb = _edge_of(graph, fb)
    loc_b = fb - graph.edge_start[eb]
    # within one clip b follows a; otherwise a is the last frame of the previous clip, which is
    # the hub pose = local frame 0 of b's clip (a self-loop clip repeats into itself)
    inside = (fb == fa + 1) | (fb == fa)
    loc_a = np.where(inside, fa - graph.edge_start[eb], loc_b - 1)
    # when t == 0 exactly and a is another edge's last frame, the pose is the hub: local 0 of eb
    return eb, loc_a + t.astype(np.float64) * (loc_b - loc_a)


def _local_cfg(graph, e, phi):
    a = graph.edge_start[e]
    i0 = np.floor(phi).astype(np.int64)
    n = graph.edge_start[e + 1] - a
    i0 = np.minimum(i0, n - 2)
    w = phi - i0
    f0, f1 = a + i0, a + i0 + 1
    x = graph.frame_xz[f0, 0] * (1 - w) + graph.frame_xz[f1, 0] * w
    z = graph.frame_xz[f0, 1] * (1 - w) + graph.frame_xz[f1, 1] * w
    h = graph.frame_heading[f0] * (1 - w) + graph.frame_heading[f1] * w
    return np.stack([x, z, h], axis=-1)


def raw_increments(graph, track):
    """Raw root motion between consecutive frames (in the earlier frame's frame) and the
    source frames advanced, rebuilt from the library frames shown."""
    e, phi = _source_position(graph, track.frames_a, track.frames_b, track.frames_t)
    c = _local_cfg(graph, e, phi)
    e0, e1 = e[:-1], e[1:]
    same = (e0 == e1) & (phi[1:] >= phi[:-1])
    inc = relative(c[:-1], c[1:])
    # crossing into the next edge: to the end of the old edge, then from the new edge's hub
    end_local = _local_cfg(graph, e0, (graph.edge_start[e0 + 1] - graph.edge_start[e0] - 1).astype(np.float64))
    cross = compose(relative(c[:-1], end_local), c[1:])
    inc = np.where(same[:, None], inc, cross)
    adv = np.where(same, phi[1:] - phi[:-1],
                   (graph.edge_start[e0 + 1] - graph.edge_start[e0] - 1) - phi[:-1] + phi[1:])
    return inc, adv


def adjustment_rates(graph, track, k0, k1, fps):
    """Largest drift rates (m/s, deg/s) over frames [k0, k1] at the best split between a
    start-anchored and an end-anchored raw motion, and the largest time-warp rate."""
    if k1 - k0 < 2:
        return 0.0, 0.0, 0.0
    inc, adv = raw_increments(graph, track.slice(k0, k1 + 1))
    baked = track.root[k0:k1 + 1]
    n = len(baked)
    fwd = np.empty((n, 3))
    fwd[0] = baked[0]
    for k in range(n - 1):     # integration along one character's frames (checker, not per tick)
        fwd[k + 1] = compose(fwd[k], inc[k])
    bwd = np.empty((n, 3))
    bwd[-1] = baked[-1]
    for k in range(n - 2, -1, -1):
        h = bwd[k + 1, 2] - inc[k, 2]
        ch, sh = np.cos(h), np.sin(h)
        bwd[k] = [bwd[k + 1, 0] - (ch * inc[k, 0] + sh * inc[k, 1]),
                  bwd[k + 1, 1] - (-sh * inc[k, 0] + ch * inc[k, 1]), h]

    def rates(anchor):
        a = baked - anchor
        d = np.diff(a, axis=0)
        return np.hypot(d[:, 0], d[:, 1]) * fps, np.degrees(np.abs(d[:, 2])) * fps

    pf, hf = rates(fwd)
    pb, hb = rates(bwd)
    return _best_split(pf, hf, pb, hb, graph, adv)


def _best_split(pf, hf, pb, hb, graph, adv, eps=(0.02, 2.0)):
    rf = np.maximum(pf / eps[0], hf / eps[1])
    rb = np.maximum(pb / eps[0], hb / eps[1])
    pre = np.concatenate([[0.0], np.maximum.accumulate(rf)])            # max over steps < s
    suf = np.concatenate([np.maximum.accumulate(rb[::-1])[::-1], [0.0]])  # max over steps >= s
    s = int(np.argmin(np.maximum(pre, suf)))
    p = max(pf[:s].max(initial=0.0), pb[s:].max(initial=0.0))
    h = max(hf[:s].max(initial=0.0), hb[s:].max(initial=0.0))
    return float(p), float(h), float(np.abs(adv - 1.0).max(initial=0.0))


def _pose_is_node(graph, fa, fb, t, label, tol_deg=0.5):
    ra = graph.frame_rotations[fa].astype(np.float64)
    rb = graph.frame_rotations[fb].astype(np.float64)
    r = quat.slerp(ra, rb, np.full(ra.shape[:-1], float(t)))
    nodes = graph.nodes_with_label(label)
    if len(nodes) == 0:
        return False
    ang = quat.angle(r[None], graph.node_rotations[nodes].astype(np.float64)).max(axis=1)
    return bool(np.degrees(ang.min()) <= tol_deg)


class CrowdReport(CheckReport):
    """What :func:`check_crowd` found.

    Attributes:
        goals: one row per goal (frame, time, window, errors, in_window, pose_ok).
        characters: per character its worst per-frame adjustment and ``within_eps``.
        character_overlaps: pairs of characters whose cylinders overlap, with frame counts.
        obstacle_overlaps: characters inside obstacles, with frame counts.
    """

    kind = "crowd"

    def __init__(self, goals, characters, character_overlaps, obstacle_overlaps, figures):
        self.goals, self.characters = goals, characters
        self.character_overlaps, self.obstacle_overlaps = character_overlaps, obstacle_overlaps
        self._figures = figures

    @property
    def passed(self) -> bool:
        return self._figures["passed"]

    def figures(self) -> dict:
        return {k: v for k, v in self._figures.items() if k != "passed"}

    def details(self) -> dict:
        return {"goals": self.goals, "characters": self.characters, "character_overlaps": self.character_overlaps,
                "obstacle_overlaps": self.obstacle_overlaps}


def check_crowd(scenario, tracks: dict, graph, env=None, fps: float = 30.0, eps=None) -> CrowdReport:
    """Check baked tracks (name -> Track) against a scenario."""
    eps = tuple(eps or scenario.epsilon)
    names = [c.name for c in scenario.characters]
    goal_rows = []
    per_char = {}
    found = {}
    for c in scenario.characters:
        tr = tracks[c.name]
        prev = 0
        for gi, g in enumerate(c.goals):
            d = np.hypot(tr.root[prev:, 0] - g.position[0], tr.root[prev:, 1] - g.position[1])
            score = d.copy()
            if g.heading is not None:
                score = score + 0.01 * np.degrees(np.abs(wrap_angle(tr.root[prev:, 2] - g.heading)))
            # the first frame within 0.1 mm of the best (idling later can come back as close);
            # with a pose constraint, the first such frame that shows the pose (a seated pelvis
            # can pass the seat point a frame before the sit pose is reached)
            close = prev + np.flatnonzero(score <= score.min() + 1e-4)
            k = int(close[0])
            if g.pose is not None:
                for kk in close[:90]:
                    if _pose_is_node(graph, tr.frames_a[kk], tr.frames_b[kk], tr.frames_t[kk], g.pose):
                        k = int(kk)
                        break
            found[(c.name, gi)] = k
            prev = k
    for c in scenario.characters:
        tr = tracks[c.name]
        for gi, g in enumerate(c.goals):
            k = found[(c.name, gi)]
            pos_err = float(np.hypot(tr.root[k, 0] - g.position[0], tr.root[k, 1] - g.position[1]))
            head_err = None
            if g.heading is not None:
                head_err = float(np.degrees(abs(wrap_angle(tr.root[k, 2] - g.heading))))
            t = (tr.start_frame + k) / fps
            window = g.time
            if g.after is not None:
                ko = found[(g.after["character"], g.after["goal"])]
                to = (tracks[g.after["character"]].start_frame + ko) / fps
                w = (to + g.after["within"][0], to + g.after["within"][1])
                window = w if window is None else (max(w[0], window[0]), min(w[1], window[1]))
            in_window = window is None or (window[0] - 1e-6 <= t <= window[1] + 1e-6)
            pose_ok = True if g.pose is None else _pose_is_node(graph, tr.frames_a[k], tr.frames_b[k], tr.frames_t[k], g.pose)
            goal_rows.append({"character": c.name, "goal": gi, "frame": int(k), "time": round(t, 4),
                              "window": None if window is None else [round(window[0], 4), round(window[1], 4)],
                              "position_error_m": pos_err, "heading_error_deg": head_err,
                              "in_window": bool(in_window), "pose": g.pose, "pose_ok": bool(pose_ok)})
    # per-frame adjustment per segment (between detected arrivals)
    for c in scenario.characters:
        tr = tracks[c.name]
        ks = [0] + [found[(c.name, gi)] for gi in range(len(c.goals))]
        worst = (0.0, 0.0, 0.0)
        for a, b in zip(ks[:-1], ks[1:]):
            r = adjustment_rates(graph, tr, a, b, fps)
            worst = tuple(max(x, y) for x, y in zip(worst, r))
        ok = worst[0] <= eps[0] * 1.001 and worst[1] <= eps[1] * 1.001 and worst[2] <= eps[2] * 1.001
        per_char[c.name] = {"adjust_m_s": worst[0], "adjust_deg_s": worst[1], "adjust_s_s": worst[2], "within_eps": bool(ok)}
    # collisions between characters, every frame
    if not names:
        return CrowdReport(goal_rows, per_char, [], [], summarize(goal_rows, per_char, {}, {}))
    F = min(len(tracks[n]) for n in names)
    cyl = [_cylinders(graph, tracks[n], F) for n in names]
    R = np.stack([c[1] for c in cyl], axis=1)                       # (F, C)
    XZ = np.stack([c[0] for c in cyl], axis=1)                      # (F, C, 2)
    pair_hits = {(names[i], names[j]): k for (i, j), k in overlapping_pairs(XZ, R).items()}
    obstacle_hits = {names[c]: k for c, k in obstacle_overlaps(XZ, R, env).items()}
    return CrowdReport(goal_rows, per_char,
                       [{"a": a, "b": b, "frames": n} for (a, b), n in sorted(pair_hits.items())],
                       [{"character": k, "frames": v} for k, v in sorted(obstacle_hits.items())],
                       summarize(goal_rows, per_char, pair_hits, obstacle_hits))


def _cylinders(graph, track, F):
    """Axis positions (F, 2) and radii (F,) of the first ``F`` frames of ``track``: each library
    frame's circle placed by the root, and for a blend the circle holding both."""
    root = np.asarray(track.root[:F], dtype=np.float64)
    axis = getattr(graph, "frame_axis", None)
    c, s = np.cos(root[:, 2]), np.sin(root[:, 2])
    circles = []
    for fr in (track.frames_a[:F], track.frames_b[:F]):
        r = graph.frame_radius[fr].astype(np.float64)
        off = np.zeros((F, 2)) if axis is None else axis[fr].astype(np.float64)
        circles.append((root[:, :2] + np.stack([c * off[:, 0] + s * off[:, 1], -s * off[:, 0] + c * off[:, 1]], 1), r))
    (pa, ra), (pb, rb) = circles
    d = np.linalg.norm(pb - pa, axis=1)
    big = np.maximum(ra, rb)
    span = 0.5 * (d + ra + rb)
    R = np.maximum(big, span)
    # centre on the line from a to b, R - ra from a (one circle holding the other: its centre)
    w = np.clip(np.where(d > 1e-12, (R - ra) / np.maximum(d, 1e-12), 0.0), 0.0, 1.0)
    w = np.where(ra >= d + rb, 0.0, np.where(rb >= d + ra, 1.0, w))
    R = np.where(ra >= d + rb, ra, np.where(rb >= d + ra, rb, R))
    return pa + w[:, None] * (pb - pa), R


def overlapping_pairs(XZ: np.ndarray, R: np.ndarray, valid: np.ndarray | None = None) -> dict:
    """Frames of overlap per character pair: XZ (F, C, 2) root positions, R (F, C) cylinder
    radii, valid (F, C) which characters exist at each frame. Returns {(i, j): frames}."""
    F = XZ.shape[0]
    rmax = float(R.max()) if R.size else 0.0
    hits = {}
    for f in range(F):
        cols = np.arange(XZ.shape[1]) if valid is None else np.flatnonzero(valid[f])
        if len(cols) < 2:
            continue
        pairs = cKDTree(XZ[f, cols]).query_pairs(2 * rmax, output_type="ndarray")
        if len(pairs) == 0:
            continue
        a, b = cols[pairs[:, 0]], cols[pairs[:, 1]]
        over = np.hypot(*(XZ[f, a] - XZ[f, b]).T) < R[f, a] + R[f, b]
        for i, j in zip(a[over], b[over]):
            key = (int(min(i, j)), int(max(i, j)))
            hits[key] = hits.get(key, 0) + 1
    return hits


def obstacle_overlaps(XZ: np.ndarray, R: np.ndarray, env, valid: np.ndarray | None = None) -> dict:
    """Frames inside an obstacle (distance below the radius) per character: {c: frames}."""
    if env is None or not (len(env.polygons) or len(env.circles)):
        return {}
    F, C = XZ.shape[:2]
    bad = env.distance(XZ.reshape(-1, 2)).reshape(F, C) < R
    if valid is not None:
        bad &= valid
    return {int(c): int(bad[:, c].sum()) for c in np.flatnonzero(bad.any(axis=0))}


def summarize(goal_rows, per_char, pair_hits, obstacle_hits) -> dict:
    """The summary figures of a crowd check, with ``passed``: positions within 1 mm, headings
    within 0.1 deg, every arrival in its window with its pose, at least 99% of the characters
    within eps, no overlapping pair, nobody inside an obstacle."""
    pe = [g["position_error_m"] for g in goal_rows]
    he = [g["heading_error_deg"] for g in goal_rows if g["heading_error_deg"] is not None]
    n = len(per_char)
    within = sum(1 for v in per_char.values() if v["within_eps"])
    return {
        "characters": n, "goals": len(goal_rows),
        "max_position_error_mm": 1000 * max(pe, default=0.0),
        "max_heading_error_deg": max(he, default=0.0),
        "goals_in_window": sum(g["in_window"] for g in goal_rows),
        "poses_ok": sum(g["pose_ok"] for g in goal_rows),
        "characters_within_eps": within, "fraction_within_eps": within / n if n else 1.0,
        "character_overlap_pairs": len(pair_hits), "obstacle_overlap_characters": len(obstacle_hits),
        "max_adjust_m_s": max((v["adjust_m_s"] for v in per_char.values()), default=0.0),
        "max_adjust_deg_s": max((v["adjust_deg_s"] for v in per_char.values()), default=0.0),
        "max_adjust_s_s": max((v["adjust_s_s"] for v in per_char.values()), default=0.0),
        "passed": bool(max(pe, default=0) <= 1e-3 and max(he, default=0) <= 0.1
                       and all(g["in_window"] and g["pose_ok"] for g in goal_rows)
                       and (within >= 0.99 * n) and not pair_hits and not obstacle_hits),
    }


def check_crowd_feet(stage_path, roots, knee_range=None) -> dict:
    """Planted-foot slide of the crowd's characters (their SkelRoot paths ``roots``) as written
    in the baked stage, read through UsdSkel by the detector of :mod:`runtime.footslide` (not
    the synthesizer's contacts): mean, p95, sliding share, lowest
    foot, knee flexion range (against the capture's ``knee_range`` when given), ``within_limits``."""
    from ..footslide import feet_report
    return feet_report(stage_path, roots, knee_range)
