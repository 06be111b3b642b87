"""Planted feet stay planted through snapping, and the foot slide of every edge.

Snapping a take to its hub poses (:mod:`.snap`) blends every joint towards the hub pose over a
few frames; a foot on the ground then slides (up to 20 cm/s over the blend). :func:`pin_feet`
puts each planted foot back with leg IK (hip-knee-ankle, the knee kept in the plane of the
hip, the old knee and the new ankle, the thigh and shin turned by the least rotations; the foot
gets its target orientation): over a contact of a foot the foot is where the
unsnapped take has it, plus the snap's own offset at the hub frames inside that contact,
interpolated between them (a foot planted across two hub frames, standing, moves from one
offset to the other over the frames between). Knees stay within the capture's flexion range
(:func:`knee_range`) and on the front side of the hip-ankle line. Where a pinned foot is out of the
leg's reach the hips are lowered (smoothly, up to :data:`MAX_DROP`). The hub frames themselves are not touched (they are exactly the hub
pose, so edges still join seamlessly), and after a foot lifts off (or before it lands) the
correction fades out over a few frames of the swing. This is the footskate cleanup of Kovar,
Schreiner and Gleicher (2002) applied where the edit happens.

:func:`edge_slide` measures each edge: the horizontal speed of its planted contact points;
:func:`added_slide` compares it with the take's own, frame by frame (the build drops an edge
whose feet slide faster than the capture by more than a limit: what the pinning could not fix).
"""
from __future__ import annotations

import numpy as np

from runtime.motion import Clip, quat
from runtime.motion.contacts import contact_point_positions, knee_flexion, leg_joints, planted, planted_speeds

__all__ = ["pin_feet", "knee_range", "edge_slide", "take_slide", "added_slide", "slide_report", "FADE_FRAMES",
           "MAX_DROP"]

FADE_FRAMES = 6          # frames of swing over which a foot's correction fades out (or in)
MAX_DROP = 0.05          # m: the most the hips are lowered where a pinned foot is out of reach


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    d = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _foot_targets(pl, fixed, a_orig, r_orig, a_snap, r_snap, fade):
    """Per frame the corrections (ankle position (F, 3), foot rotation (F, 4)) that take the
    snapped foot of one leg to its target; zero at ``fixed`` frames. ``pl`` (F,): the foot is
    planted. Over a contact the target is the original foot moved rigidly by the snap's offset
    at the hub frames in it (the rigid motion taking the original foot to the snapped one
    there), interpolated between them: with one hub frame every point of the foot that stays
    still in the take (heel, toe, or the ball while the heel rises) stays still."""
    F = len(pl)
    dp = np.zeros((F, 3))
    dq = np.broadcast_to(quat.identity(), (F, 4)).copy()
    runs = _runs(pl)
    is_fixed = np.zeros(F, dtype=bool)
    is_fixed[fixed] = True
    for a, b in runs:
        t = np.arange(a, b)
        anchors = t[is_fixed[a:b]]
        if len(anchors):
            off_q = quat.unroll(quat.mul(r_snap[anchors], quat.conj(r_orig[anchors])), axis=0)
            k = np.clip(np.searchsorted(anchors, t, "right") - 1, 0, len(anchors) - 1)
            k1 = np.minimum(k + 1, len(anchors) - 1)
            u = np.clip((t - anchors[k]) / np.maximum(anchors[k1] - anchors[k], 1), 0.0, 1.0)

            def moved(j):      # the original ankle under the rigid offset of anchor j
                return a_snap[anchors[j]] + quat.rotate(off_q[j], a_orig[a:b] - a_orig[anchors[j]])
            target_p = (1.0 - u)[:, None] * moved(k) + u[:, None] * moved(k1)
            target_q = quat.mul(quat.slerp(off_q[k], off_q[k1], u), r_orig[a:b])
        else:
            target_p, target_q = a_orig[a:b], r_orig[a:b]
        dp[a:b] = target_p - a_snap[a:b]
        dq[a:b] = quat.mul(target_q, quat.conj(r_snap[a:b]))
    # fades into the swings: the correction at a contact's end (start) dies out after (before) it
    swing = ~pl
    for a, b in runs:
        for edge, step in ((b - 1, 1), (a, -1)):
            n, f = 0, edge + step
            while 0 <= f < F and swing[f] and n < fade:
                n += 1
                f += step
            frames = edge + step * np.arange(1, n + 1)
            w = 1.0 - np.arange(1, n + 1) / (n + 1.0)
            w = w * w * (3.0 - 2.0 * w)
            dp[frames] += w[:, None] * dp[edge]
            dq[frames] = quat.mul(quat.slerp(np.broadcast_to(quat.identity(), (n, 4)),
                                             np.broadcast_to(dq[edge], (n, 4)), w), dq[frames])
    # a fixed frame in a swing gets no correction: ramp the swing corrections down next to it
    if is_fixed.any():
        fx = np.flatnonzero(is_fixed)
        near = np.abs(np.arange(F)[:, None] - fx[None, :]).min(axis=1)
        r = np.where(swing, np.clip(near / 3.0, 0.0, 1.0), 1.0)
        dp *= r[:, None]
        dq = quat.slerp(np.broadcast_to(quat.identity(), (F, 4)), dq, r)
    dp[is_fixed] = 0.0
    dq[is_fixed] = quat.identity()
    return dp, dq


def knee_range(clips) -> np.ndarray | None:
    """The knee flexion range of some takes, ``(2, 2)`` radians: row 0 the least flexion of the
    left and right knee, row 1 the most; None when the skeleton's legs are not known."""
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for c in clips:
        try:
            legs = leg_joints(c.skeleton)
        except ValueError:
            return None
        flex = knee_flexion(legs, c.fk()[1])
        if len(flex):
            lo, hi = np.minimum(lo, flex.min(axis=0)), np.maximum(hi, flex.max(axis=0))
    return np.stack([lo, hi]) if np.all(np.isfinite(lo)) else None


def pin_feet(original: Clip, snapped: Clip, contacts: np.ndarray, fixed_frames, fade: int = FADE_FRAMES,
             flex_range: np.ndarray | None = None) -> Clip:
    """``snapped`` with each planted foot moved back (see the module docstring) by leg IK.

    Args:
        original: the take before snapping; snapped: the same take snapped (same root path).
        contacts: (F, 4) contact flags of the take (CONTACT_POINTS order).
        fixed_frames: frames left exactly as snapped (the hub occurrences).
        flex_range: (2, 2) the capture's knee flexion range (:func:`knee_range`); a solved knee
            stays inside it (a pin out of that reach is followed only as far as it allows);
            default: the original take's own range.
    Returns ``snapped`` unchanged when the skeleton's legs are not known.
    """
    try:
        legs = leg_joints(snapped.skeleton)
    except ValueError:
        return snapped
    sk = snapped.skeleton
    fixed = np.sort(np.asarray(fixed_frames, dtype=np.int64))
    gr_o, gp_o = original.fk()
    gr_s, gp_s = snapped.fk(origin=original.origin)
    rot = snapped.rotations.astype(np.float64)
    F = snapped.num_frames
    feet = planted(contacts)
    flex = knee_range([original]) if flex_range is None else np.asarray(flex_range, dtype=np.float64)
    corr = [_foot_targets(feet[:, s], fixed, gp_o[:, legs.ankle[s]], gr_o[:, legs.ankle[s]], gp_s[:, legs.ankle[s]],
                          gr_s[:, legs.ankle[s]], fade) for s in range(2)]
    # hips lowered where a target is out of reach (a leg as straight as the capture's knees get)
    need = np.zeros(F)
    for s, (dp, _) in enumerate(corr):
        hip, knee, ankle = int(legs.hip[s]), int(legs.knee[s]), int(legs.ankle[s])
        reach = _reach(sk, knee, ankle, flex[:, s])[1]
        v = gp_s[:, ankle] + dp - gp_s[:, hip]
        h2 = v[:, 0] ** 2 + v[:, 2] ** 2
        need = np.maximum(need, -v[:, 1] - np.sqrt(np.maximum(reach ** 2 - h2, 0.0)))
    drop = _smooth_drop(need, fixed)
    height = snapped.root_height - drop
    gp_s = gp_s - drop[:, None, None] * np.array([0.0, 1.0, 0.0])
    for s, (dp, dq) in enumerate(corr):
        hip, knee, ankle = int(legs.hip[s]), int(legs.knee[s]), int(legs.ankle[s])
        m = (np.abs(dp).max(axis=1) > 1e-7) | (np.abs(dq[:, 1:]).max(axis=1) > 1e-9) | (drop > 0)
        m[fixed] = False
        if not m.any():
            continue
        H, K, A = gp_s[m, hip], gp_s[m, knee], gp_s[m, ankle]
        T = A + dp[m] + drop[m, None] * np.array([0.0, 1.0, 0.0])
        l1 = np.linalg.norm(K - H, axis=1)
        l2 = np.linalg.norm(A - K, axis=1)
        v = T - H
        D = np.linalg.norm(v, axis=1)
        d_min, d_max = _reach(sk, knee, ankle, flex[:, s])
        Dc = np.clip(D, d_min, d_max)
        u = v / np.maximum(D, 1e-12)[:, None]
        T = H + u * Dc[:, None]
        # the knee's side: the old knee's, and for a leg near straight the thigh's forward axis
        fwd = quat.rotate(gr_s[m, hip], np.broadcast_to([0.0, 0.0, 1.0], H.shape))
        fwd = fwd - np.sum(fwd * u, axis=1, keepdims=True) * u
        pole = K - H
        pole = pole - np.sum(pole * u, axis=1, keepdims=True) * u
        fn = fwd / np.maximum(np.linalg.norm(fwd, axis=1), 1e-12)[:, None]
        pole = pole + 0.02 * fn
        pole = pole - 2.0 * np.minimum(np.sum(pole * fn, axis=1, keepdims=True), 0.0) * fn   # never behind
        pole = pole / np.maximum(np.linalg.norm(pole, axis=1), 1e-12)[:, None]
        a = (l1 ** 2 - l2 ** 2 + Dc ** 2) / (2 * Dc)
        K2 = H + u * a[:, None] + pole * np.sqrt(np.maximum(l1 ** 2 - a ** 2, 0.0))[:, None]
        q_hip = quat.between(K - H, K2 - H)           # the least turn of the thigh: no twist flips
        q_knee = quat.between(quat.rotate(q_hip, A - K), T - K2)
        g_hip = quat.mul(q_hip, gr_s[m, hip])
        g_knee = quat.mul(q_knee, quat.mul(q_hip, gr_s[m, knee]))
        g_foot = quat.mul(dq[m], gr_s[m, ankle])
        parent = int(sk.parents[hip])
        rot[m, hip] = quat.mul(quat.conj(gr_s[m, parent]), g_hip)
        rot[m, knee] = quat.mul(quat.conj(g_hip), g_knee)
        rot[m, ankle] = quat.mul(quat.conj(g_knee), g_foot)
    rot = quat.normalize(rot)
    rot[fixed] = snapped.rotations[fixed]             # exact hub poses
    height[fixed] = snapped.root_height[fixed]
    return snapped.copy(rotations=quat.unroll(rot, axis=0).astype(np.float32), root_height=height)


def _reach(sk, knee: int, ankle: int, flex: np.ndarray) -> tuple[float, float]:
    """(least, most) hip-ankle distance of a leg whose knee flexion stays in ``flex`` (lo, hi):
    ``|hip - ankle|^2 = thigh^2 + shin^2 + 2 thigh shin cos(flexion)``, a hair inside."""
    l1, l2 = float(np.linalg.norm(sk.offsets[knee])), float(np.linalg.norm(sk.offsets[ankle]))
    d = np.sqrt(l1 * l1 + l2 * l2 + 2.0 * l1 * l2 * np.cos(np.clip(flex, 0.0, np.pi)))
    return float(d[1]) + 1e-4, float(d[0]) - 1e-4


def _smooth_drop(need: np.ndarray, fixed: np.ndarray, half: int = 4) -> np.ndarray:
    """A smooth hip drop covering ``need`` (m per frame, clipped to [0, MAX_DROP]): the largest
    need within ``half`` frames, smoothed with a triangle of the same width; brought down to zero
    over ``half`` frames next to ``fixed`` frames (the covering is then partial there)."""
    n = np.clip(need, 0.0, MAX_DROP)
    if not n.any():
        return np.zeros_like(n)
    F = len(n)
    pad = np.concatenate([np.zeros(half), n, np.zeros(half)])
    wide = np.max(np.stack([pad[k:k + F] for k in range(2 * half + 1)]), axis=0)
    w = np.concatenate([np.arange(1, half + 2), np.arange(half, 0, -1)]).astype(float)
    out = np.convolve(np.concatenate([np.zeros(half), wide, np.zeros(half)]), w / w.sum(), mode="valid")
    out = np.maximum(out, n)
    if len(fixed):                  # zero at the hub frames, reached smoothly
        near = np.abs(np.arange(F)[:, None] - fixed[None, :]).min(axis=1)
        out *= np.clip(near / float(half), 0.0, 1.0)
    return out


def edge_slide(clip: Clip, contacts: np.ndarray | None = None) -> np.ndarray:
    """Horizontal speeds (m/s) of the planted contact points of ``clip`` between consecutive
    frames (:func:`runtime.motion.contacts.planted_speeds`; NaN where not planted), by forward
    kinematics at its own origin. ``contacts`` default to the clip's."""
    c = clip.contacts if contacts is None else contacts
    gr, gp = clip.fk(origin=np.zeros(3))
    return planted_speeds(contact_point_positions(leg_joints(clip.skeleton), gr, gp), c, clip.fps)


def take_slide(clip: Clip, contacts: np.ndarray) -> np.ndarray:
    """Planted-point speeds ``(F - 1, 4)`` of a take (:func:`edge_slide`); NaN everywhere when
    its skeleton's legs are not known."""
    try:
        return edge_slide(clip, contacts)
    except ValueError:
        return np.full((max(clip.num_frames - 1, 0), 4), np.nan)


def added_slide(edge: Clip, own: np.ndarray) -> tuple[np.ndarray, float]:
    """(planted-point speeds of ``edge``, the most its planted points move faster than in the
    take on the same frames, m/s). ``own``: the take's speeds over the edge's frames."""
    try:
        v = edge_slide(edge)
    except ValueError:
        return np.full(own.shape, np.nan), 0.0
    d = v - own
    d = d[np.isfinite(d)]
    return v, float(d.max()) if len(d) else 0.0


def slide_report(speeds: list, dropped: list, limit: float) -> dict:
    """The build's ``meta["foot_slide"]``: the figures over all kept edges
    (:func:`runtime.motion.contacts.slide_figures`), the largest planted-point speed of every
    kept edge (cm/s), the limit and the edges dropped."""
    from runtime.motion.contacts import slide_figures
    flat = np.concatenate([v.reshape(-1) for v in speeds]) if speeds else np.zeros(0)
    per_edge = [round(100.0 * float(np.nanmax(v)), 1) if np.isfinite(v).any() else 0.0 for v in speeds]
    return {**slide_figures(flat), "edge_max_cm_s": per_edge, "limit_cm_s": float(limit), "dropped": dropped}
