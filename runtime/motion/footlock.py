"""Foot locking: planted feet stay where they landed, whatever the root path does to them.

Synthesis moves the root (splices, displacement maps, time resampling, patch deformation), so
a foot that is still in its clip slides in the world. The lock pins each planted foot for the
whole contact and re-solves the leg with a two-bone IK (hip-knee-ankle; the foot keeps its
world orientation and moves rigidly with the ankle), vectorized over characters and both legs:

* **Contacts** are those of the motion played on each frame, gathered at the library frame
  shown (``a`` when the blend ``t < 0.5``, else ``b``): the library's per-frame contact flags
  (``frame_contacts`` / ``contacts`` of the library when it carries them, else detected once
  per library on its own clips with :func:`runtime.motion.contacts.clip_contacts`), and
  wherever the toe is on the ground (:func:`grounded`: near its floor, hardly moving up or
  down; a library clip whose foot slides on the ground is locked too).
* **The pin** is where the toe point was on the frame the foot touched down (in x and z; the
  height stays the clip's). While planted, the foot is moved horizontally by ``target - toe``.
  After lift-off the last correction fades out linearly over :data:`BLEND_FRAMES` frames; a
  foot that touches down while a correction is fading is pinned where it is shown, so the
  shown foot never jumps. A correction over :data:`MAX_CORRECTION` drags the pin along
  (a long pivot is not held forever).
* **The leg** keeps its knee in the plane through the hip, the new ankle and the old knee.
  The hip-ankle distance is kept within what the capture's knee flexion range allows
  (:attr:`FootLockModel.flex_min` .. :attr:`flex_max`: the capture's range the library build kept in
  its ``meta["knee_flexion_deg"]``, else measured over the library's frames):
  no hyperextension, no flexion the capture never shows. When a pinned foot is out of reach
  the whole body is lowered (the hips, up to :data:`MAX_HIP_DROP`, never so far that the
  other knee would bend more than the capture's), then the pin is followed only as far as the
  leg reaches (the foot slides rather than being pushed into the ground).

:func:`lock_step` advances the lock state of many characters by one frame (the runtime's
:class:`runtime.pose.PoseBatch` and the bake both step through it, the batch in a numba kernel
with the same arithmetic); :func:`solve_legs` is the position IK; :func:`lock_skel_arrays`
applies the lock to baked animation arrays (joint rotations of the legs and the root height;
root paths are untouched). Reference for the approach: Kovar, Schreiner and Gleicher (2002),
"Footskate cleanup for motion capture editing".
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from . import quat
from .contacts import LegJoints, clip_contacts, knee_flexion, leg_joints, planted

__all__ = ["BLEND_FRAMES", "MAX_CORRECTION", "MAX_HIP_DROP", "FootLockModel", "LockState", "library_contacts",
           "grounded", "lock_step", "solve_legs", "lock_skel_arrays", "lock_positions", "played_planted"]

BLEND_FRAMES = 5          # frames over which a released foot's correction fades out
MAX_CORRECTION = 0.30     # m: a pin further than this from the clip's foot is dragged along
MAX_HIP_DROP = 0.12       # m: the most the hips are lowered for a foot out of reach
GROUND_HEIGHT = 0.05      # m: a toe this close to its floor ...
GROUND_VSPEED = 0.15      # m/s: ... and this slow vertically is on the ground


def _library_clips(library):
    """(first flat frame, Clip) of every clip of a library's flat frame tables: the edges of a
    :class:`~runtime.motion.graph.MotionGraph`, the fragments of a
    :class:`~runtime.tiling.patch.PatchLibrary`."""
    from .clip import Clip
    if hasattr(library, "edge_start") and hasattr(library, "edge_clip"):
        for e in range(len(library.edge_start) - 1):
            if library.edge_start[e + 1] > library.edge_start[e]:
                yield int(library.edge_start[e]), library.edge_clip(e)
    elif hasattr(library, "patches") and hasattr(library, "fragment_offset"):
        for pi, p in enumerate(library.patches):
            for k, f in enumerate(p.fragments):
                yield (library.fragment_offset(pi, k),
                       Clip(library.skeleton, library.fps, f.root_xz, f.heading, f.root_height, f.rotations))
    else:
        raise TypeError(f"cannot find the clips of a {type(library).__name__} to detect foot contacts in")


def library_contacts(library) -> np.ndarray:
    """Contact flags ``(T, 4)`` bool of every frame of a library's flat frame tables
    (a :class:`~runtime.motion.graph.MotionGraph` or a :class:`~runtime.tiling.patch.PatchLibrary`).

    The library's own flags when it carries them (``frame_contacts`` or ``contacts``, shaped
    (T, 4)); otherwise detected clip by clip (graph edges, patch fragments), with the clips'
    own ``contacts`` when they have them."""
    T = len(library.frame_height)
    for name in ("frame_contacts", "contacts"):
        c = getattr(library, name, None)
        if c is not None and np.shape(c) == (T, 4):
            return np.asarray(c, dtype=bool)
    out = np.zeros((T, 4), dtype=bool)
    for a, clip in _library_clips(library):
        c = getattr(clip, "contacts", None)
        out[a:a + clip.num_frames] = np.asarray(c, dtype=bool) if c is not None else clip_contacts(clip)
    return out


def grounded(library, legs: LegJoints, local: np.ndarray, height: float = GROUND_HEIGHT,
             vspeed: float = GROUND_VSPEED) -> np.ndarray:
    """Per library frame and foot (T, 2): the toe point within ``height`` of that foot's floor
    (its 2nd-percentile height over the library) and moving up or down slower than ``vspeed``
    within its clip. ``local`` (T, J, 3) are the frames' joint positions (any heading)."""
    T = len(local)
    if np.all(legs.toe >= 0):
        y = local[:, legs.toe, 1]
    else:
        y = local[:, legs.ankle, 1]
    vy = np.zeros((T, 2))
    fps = float(library.fps)
    for a, clip in _library_clips(library):
        b = a + clip.num_frames
        if b - a > 1:
            vy[a + 1:b] = np.diff(y[a:b], axis=0) * fps
            vy[a] = vy[a + 1]
    floor = np.percentile(y, 2.0, axis=0) if T else np.zeros(2)
    return (y - floor < height) & (np.abs(vy) < vspeed)


_MODELS: dict[int, tuple] = {}


@dataclass(frozen=True)
class FootLockModel:
    """What the lock needs of one library, computed once per library object (:meth:`for_library`).

    ``planted`` (T, 2) per library frame (left, right); ``thigh``, ``shin`` (2,) bone lengths;
    ``flex_min``, ``flex_max`` (2,) the capture's knee flexion range (radians) and ``reach_min``,
    ``reach_max`` (2,) the hip-ankle distances they give; ``foot`` (2, K) the joints that move
    rigidly with each ankle (the ankle's subtree, padded with -1)."""
    legs: LegJoints
    planted: np.ndarray
    thigh: np.ndarray
    shin: np.ndarray
    flex_min: np.ndarray
    flex_max: np.ndarray
    reach_min: np.ndarray
    reach_max: np.ndarray
    foot: np.ndarray

    @classmethod
    def for_library(cls, library) -> "FootLockModel":
        hit = _MODELS.get(id(library))
        if hit is not None and hit[0]() is library:
            return hit[1]
        model = cls.build(library)
        key = id(library)
        _MODELS[key] = (weakref.ref(library, lambda _r, k=key, t=_MODELS: t.pop(k, None) if t is not None else None),
                        model)
        return model

    @classmethod
    def build(cls, library, contacts: np.ndarray | None = None) -> "FootLockModel":
        from ..crowd.tracks import evaluate_poses
        from .fk import forward_kinematics
        sk = library.skeleton
        legs = leg_joints(sk)
        T = len(library.frame_height)
        c = library_contacts(library) if contacts is None else np.asarray(contacts, dtype=bool)
        off = np.asarray(sk.offsets, dtype=np.float64)
        thigh = np.linalg.norm(off[legs.knee], axis=-1)
        shin = np.linalg.norm(off[legs.ankle], axis=-1)
        f = np.arange(T)
        pos, rot = evaluate_poses(library, f, f, np.zeros(T), np.zeros((T, 3)))
        gr, gp = forward_kinematics(sk, pos, rot)
        stored = (getattr(library, "meta", None) or {}).get("knee_flexion_deg")
        if stored is not None:         # the capture's own range, kept by the library build
            fmin, fmax = np.radians(np.asarray(stored[0], float)), np.radians(np.asarray(stored[1], float))
        elif T:
            flex = knee_flexion(legs, gp)
            fmin, fmax = flex.min(axis=0), flex.max(axis=0)
        else:
            fmin, fmax = np.zeros(2), np.full(2, np.pi / 2)
        if not np.all(legs.toe >= 0):      # toe points from the ankles' end sites
            gp = gp.copy()
            gp[:, legs.ankle] += quat.rotate(gr[:, legs.ankle], legs.toe_offset)
        # |hip - ankle|^2 = thigh^2 + shin^2 + 2 thigh shin cos(flexion)
        reach = lambda fl: np.sqrt(thigh ** 2 + shin ** 2 + 2 * thigh * shin * np.cos(fl))  # noqa: E731
        kids = [[] for _ in range(sk.num_joints)]
        for j in range(1, sk.num_joints):
            kids[int(sk.parents[j])].append(j)
        feet = []
        for a in legs.ankle:
            sub, todo = [], [int(a)]
            while todo:
                j = todo.pop()
                sub.append(j)
                todo += kids[j]
            feet.append(sorted(sub))
        K = max(len(s) for s in feet)
        foot = np.full((2, K), -1, dtype=np.int64)
        for s, sub in enumerate(feet):
            foot[s, :len(sub)] = sub
        return cls(legs, planted(c) | grounded(library, legs, gp), thigh, shin, fmin, fmax, reach(fmax), reach(fmin),
                   foot)


def played_planted(model: FootLockModel, frames_a, frames_b, frames_t) -> np.ndarray:
    """Planted flags (..., 2) of the frames shown: the library frame ``a`` while ``t < 0.5``, else ``b``."""
    fa = np.asarray(frames_a, dtype=np.int64)
    f = np.where(np.asarray(frames_t) < 0.5, fa, np.asarray(frames_b, dtype=np.int64))
    return model.planted[f]


@dataclass
class LockState:
    """Lock state of N characters' two feet: ``locked`` (N, 2), the pinned toe ``target``
    (N, 2, 2) in x, z, the last correction ``res`` (N, 2, 2) and the frames since lift-off ``k``
    (N, 2)."""
    locked: np.ndarray
    target: np.ndarray
    res: np.ndarray
    k: np.ndarray

    @classmethod
    def empty(cls, n: int, dtype=np.float64) -> "LockState":
        return cls(np.zeros((n, 2), bool), np.zeros((n, 2, 2), dtype), np.zeros((n, 2, 2), dtype),
                   np.full((n, 2), BLEND_FRAMES + 1, np.int32))

    def take(self, idx) -> "LockState":
        return LockState(self.locked[idx], self.target[idx], self.res[idx], self.k[idx])

    def reset(self, idx) -> None:
        self.locked[idx] = False
        self.target[idx] = 0
        self.res[idx] = 0
        self.k[idx] = BLEND_FRAMES + 1


def lock_step(state: LockState, toe_xz: np.ndarray, plant: np.ndarray, blend: int = BLEND_FRAMES,
              max_correction: float = MAX_CORRECTION) -> np.ndarray:
    """One frame of the lock for N characters: the horizontal correction ``(N, 2, 2)`` (x, z) to
    add to each foot, from the toe points ``toe_xz`` (N, 2, 2) and the planted flags ``plant``
    (N, 2). Updates ``state`` in place."""
    dt = state.res.dtype
    k = np.where(state.locked, 0, state.k) + 1
    np.minimum(k, blend + 1, out=k)
    w = np.clip(1.0 - k / (blend + 1.0), 0.0, 1.0).astype(dt)
    d_free = state.res * w[..., None]
    new = plant & ~state.locked
    target = np.where(new[..., None], toe_xz + d_free, state.target)
    d = np.where(plant[..., None], target - toe_xz, d_free)
    m = np.sqrt(np.sum(d * d, axis=-1))
    over = plant & (m > max_correction)
    if np.any(over):
        scale = np.where(over, max_correction / np.maximum(m, 1e-12), 1.0).astype(dt)
        d = d * scale[..., None]
        target = np.where(over[..., None], toe_xz + d, target)
    state.target = target.astype(dt)
    state.res = np.where(plant[..., None], d, state.res).astype(dt)
    state.locked = plant.copy()
    state.k = k.astype(np.int32)
    return d.astype(dt)


def solve_legs(model: FootLockModel, hip, knee, ankle, d, forward, max_drop: float = MAX_HIP_DROP):
    """Two-bone IK of both legs with the ankles moved horizontally by ``d``.

    Args:
        hip, knee, ankle: (..., 2, 3) joint positions (left, right).
        d: (..., 2, 2) horizontal corrections (x, z) of the feet.
        forward: (..., 3) the character's facing direction (the knee's side: a straight leg bends
            towards it, and a knee is never put behind the hip-ankle line).

    Returns ``(drop (...,), knee (..., 2, 3), ankle (..., 2, 3))``: how far the whole body is
    lowered, and the new knee and ankle positions (the hips are at ``hip - drop * Y``)."""
    hip = np.asarray(hip, dtype=np.float64)
    tgt = np.array(ankle, dtype=np.float64)
    tgt[..., 0] += d[..., 0]
    tgt[..., 2] += d[..., 1]
    v = tgt - hip
    h2 = v[..., 0] ** 2 + v[..., 2] ** 2
    need = -v[..., 1] - np.sqrt(np.maximum(model.reach_max ** 2 - h2, 0.0))
    # no lower than the most bent knee of the capture allows either leg (a foot is never pushed down)
    room = -v[..., 1] - np.sqrt(np.maximum(model.reach_min ** 2 - h2, 0.0))
    moved = np.any(d != 0, axis=-1)
    drop = np.minimum(np.max(np.where(moved, need, 0.0), axis=-1), np.min(room, axis=-1))
    drop = np.clip(drop, 0.0, max_drop)
    h = hip.copy()
    h[..., 1] -= drop[..., None]
    # a pin the leg cannot reach is followed only as far as the knee's range allows
    w = np.asarray(ankle, dtype=np.float64) - h
    dv = np.zeros_like(w)
    dv[..., 0], dv[..., 2] = d[..., 0], d[..., 1]
    s = np.minimum(_reach_fraction(w, dv, model.reach_max, True), _reach_fraction(w, dv, model.reach_min, False))
    tgt = h + w + s[..., None] * dv
    v = tgt - h
    D = np.linalg.norm(v, axis=-1)
    Dc = np.clip(D, model.reach_min, model.reach_max)     # only poses outside the range to begin with
    u = v / np.maximum(D, 1e-12)[..., None]
    tgt = h + u * Dc[..., None]
    # knee: in the plane of the hip, the new ankle and the old knee, on the front side
    pole = knee - hip
    pole = pole - np.sum(pole * u, axis=-1, keepdims=True) * u
    pn = np.linalg.norm(pole, axis=-1)
    fwd = np.broadcast_to(np.asarray(forward, dtype=np.float64)[..., None, :], pole.shape)
    fwd = fwd - np.sum(fwd * u, axis=-1, keepdims=True) * u
    pole = np.where((pn > 1e-6)[..., None], pole, fwd)
    # never behind the line: a knee the moved ankle leaves behind it is mirrored to the front
    fn = fwd / np.maximum(np.linalg.norm(fwd, axis=-1), 1e-12)[..., None]
    pf = np.sum(pole * fn, axis=-1, keepdims=True)
    pole = pole - 2.0 * np.minimum(pf, 0.0) * fn
    pole = pole / np.maximum(np.linalg.norm(pole, axis=-1), 1e-12)[..., None]
    a = (model.thigh ** 2 - model.shin ** 2 + Dc ** 2) / (2 * Dc)
    b = np.sqrt(np.maximum(model.thigh ** 2 - a ** 2, 0.0))
    k = h + u * a[..., None] + pole * b[..., None]
    return drop, k, tgt


def _reach_fraction(w, dv, r, outer: bool):
    """The largest s in [0, 1] keeping |w + s dv| <= r (``outer``) or >= r from s = 0 on
    (1 where s = 0 itself is outside: that pose is clamped afterwards)."""
    a = np.sum(dv * dv, axis=-1)
    b = 2 * np.sum(w * dv, axis=-1)
    c = np.sum(w * w, axis=-1) - r ** 2
    disc = b * b - 4 * a * c
    sq = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        if outer:          # inside at s = 0 (c <= 0): leaves the sphere at the larger root
            root = (-b + sq) / (2 * a)
            ok = (c <= 0) & (a > 0)
        else:              # outside the inner sphere at s = 0: enters it at the smaller root, if ahead
            root = (-b - sq) / (2 * a)
            ok = (c >= 0) & (a > 0) & (disc > 0) & (root >= 0)
    return np.where(ok, np.clip(np.nan_to_num(root, nan=1.0, posinf=1.0), 0.0, 1.0), 1.0)


def _chain_fk(sk, joints, root_pos, lr):
    """Global rotations and positions of ``joints`` (sorted, closed under parents) only."""
    gr, gp = {0: lr[:, 0]}, {0: root_pos}
    for j in joints:
        if j == 0:
            continue
        p = int(sk.parents[j])
        gr[j] = quat.mul(gr[p], lr[:, j])
        gp[j] = gp[p] + quat.rotate(gr[p], np.broadcast_to(sk.offsets[j], gp[p].shape))
    return gr, gp


def _twist_align(t0, n0, t1, n1):
    """The rotation taking direction t0 to t1 and then the plane normal n0 to n1 (about t1)."""
    qa = quat.between(t0, t1)
    na = quat.rotate(qa, n0)
    u = t1 / np.maximum(np.linalg.norm(t1, axis=-1, keepdims=True), 1e-12)
    na = na - np.sum(na * u, axis=-1, keepdims=True) * u
    nb = n1 - np.sum(n1 * u, axis=-1, keepdims=True) * u
    return quat.mul(quat.between(na, nb), qa)


def _normal(a, b, fallback):
    n = np.cross(a, b)
    ln = np.linalg.norm(n, axis=-1, keepdims=True)
    return np.where(ln > 1e-9, n / np.maximum(ln, 1e-12), fallback)


def segment_frames(seg_start: np.ndarray):
    """Padded frame indices ``(S, L)`` (-1 past a segment's end) of the segments of M frames
    that start where ``seg_start`` is True (frame 0 always starts one)."""
    M = len(seg_start)
    starts = np.flatnonzero(np.asarray(seg_start, bool) | (np.arange(M) == 0))
    lens = np.diff(np.append(starts, M))
    L = int(lens.max()) if len(lens) else 0
    idx = starts[:, None] + np.arange(L)[None, :]
    return np.where(np.arange(L)[None, :] < lens[:, None], idx, -1)


def lock_corrections(model: FootLockModel, toe_xz: np.ndarray, plant: np.ndarray, seg_start) -> np.ndarray:
    """Corrections (M, 2, 2) of M frames of several segments (each starting unlocked), stepped
    frame by frame through :func:`lock_step`, vectorized over segments and feet."""
    M = len(toe_xz)
    d = np.zeros((M, 2, 2))
    idx = segment_frames(seg_start)
    if M == 0:
        return d
    st = LockState.empty(len(idx))
    for f in range(idx.shape[1]):
        rows = idx[:, f]
        live = rows >= 0
        r = np.where(live, rows, 0)
        step = lock_step(st, toe_xz[r], plant[r] & live[:, None])
        d[rows[live]] = step[live]
    return d


def lock_skel_arrays(model: FootLockModel, sk, frames_a, frames_b, frames_t, seg_start, trans, quats) -> None:
    """Apply the foot lock to baked animation arrays in place: ``trans`` (M, J, 3) float32 (the
    root's is its world position), ``quats`` (M, J, 4) float32 x-y-z-w local rotations, for M
    frames of segments (characters) starting where ``seg_start`` is True. Changes the local
    rotations of both hips, knees and ankles and the root height, only on frames where a foot
    is corrected."""
    legs = model.legs
    M = len(trans)
    if M == 0:
        return
    need = set()
    for j in np.concatenate([legs.ankle, legs.toe[legs.toe >= 0]]):
        j = int(j)
        while j >= 0:
            need.add(j)
            j = int(sk.parents[j])
    lr = np.asarray(quats, dtype=np.float64)[..., [3, 0, 1, 2]]
    gr, gp = _chain_fk(sk, sorted(need), np.asarray(trans[:, 0], dtype=np.float64), lr)
    stack = lambda src, js: np.stack([src[int(j)] for j in js], axis=1)  # noqa: E731
    H, K, A = stack(gp, legs.hip), stack(gp, legs.knee), stack(gp, legs.ankle)
    GA = stack(gr, legs.ankle)
    if np.all(legs.toe >= 0):
        toe = stack(gp, legs.toe)
    else:
        toe = A + quat.rotate(GA, legs.toe_offset)
    plant = played_planted(model, frames_a, frames_b, frames_t)
    d = lock_corrections(model, toe[..., [0, 2]], plant, seg_start)
    moved = np.any(d != 0, axis=(1, 2))
    if not moved.any():
        return
    f = np.flatnonzero(moved)
    H, K, A, GA, d = H[f], K[f], A[f], GA[f], d[f]
    GH, GK = stack(gr, legs.hip)[f], stack(gr, legs.knee)[f]
    GP = stack(gr, sk.parents[legs.hip])[f]
    fwd = quat.rotate(gr[0][f], np.array([0.0, 0.0, 1.0]))
    fwd[:, 1] = 0.0
    drop, K1, A1 = solve_legs(model, H, K, A, d, fwd)
    H1 = H.copy()
    H1[..., 1] -= drop[:, None]
    lat = np.cross(np.broadcast_to([0.0, 1.0, 0.0], fwd.shape), fwd)[:, None, :] * np.ones((1, 2, 1))
    n0 = _normal(K - H, A - K, lat)
    n1 = _normal(K1 - H1, A1 - K1, n0)
    R1 = _twist_align(K - H, n0, K1 - H1, n1)
    GH1 = quat.mul(R1, GH)
    shin = quat.rotate(R1, A - K)
    GK1 = quat.mul(quat.mul(quat.between(shin, A1 - K1), R1), GK)
    LH = quat.mul(quat.conj(GP), GH1)
    LK = quat.mul(quat.conj(GH1), GK1)
    LA = quat.mul(quat.conj(GK1), GA)
    for s in range(2):
        for j, q in ((legs.hip[s], LH[:, s]), (legs.knee[s], LK[:, s]), (legs.ankle[s], LA[:, s])):
            quats[f, int(j)] = q[:, [1, 2, 3, 0]].astype(np.float32)
    trans[f, 0, 1] -= drop.astype(np.float32)


def lock_positions(model: FootLockModel, planes: np.ndarray, frames_a, frames_b, frames_t, heading,
                   state: LockState) -> None:
    """The lock on one tick of joint world positions, in place: ``planes`` (3, N, J) float32
    component planes (as :class:`runtime.pose.PoseBatch` keeps them), ``heading`` (N,) radians,
    ``state`` the characters' :class:`LockState` (advanced by one frame). Knees and feet (the
    ankles' subtrees) move, and the whole body comes down by the hip drop. Positions only: on
    skeletons without toe joints the ankle is the pinned point."""
    legs = model.legs
    P = planes
    pick = lambda js: np.moveaxis(P[:, :, js], 0, -1).astype(np.float64)  # noqa: E731  (N, 2, 3)
    H, K, A = pick(legs.hip), pick(legs.knee), pick(legs.ankle)
    toe = pick(legs.toe) if np.all(legs.toe >= 0) else A
    plant = played_planted(model, frames_a, frames_b, frames_t)
    d = lock_step(state, toe[..., [0, 2]], plant)
    rows = np.flatnonzero(np.any(d != 0, axis=(1, 2)))
    if not len(rows):
        return
    h = np.asarray(heading, dtype=np.float64)[rows]
    fwd = np.stack([np.sin(h), np.zeros_like(h), np.cos(h)], axis=-1)
    drop, K1, A1 = solve_legs(model, H[rows], K[rows], A[rows], d[rows], fwd)
    shift = A1 - A[rows]                                    # (R, 2, 3)
    up = np.array([0.0, 1.0, 0.0])
    for s in range(2):                # placed absolutely; the whole body's drop follows
        leg = np.flatnonzero(np.any(d[rows, s] != 0, axis=-1) | (drop > 0))   # a leg that stays is not solved
        r = rows[leg]
        K1[:, s] += drop[:, None] * up
        shift[:, s] += drop[:, None] * up
        for c in range(3):
            P[c, r, legs.knee[s]] = K1[leg, s, c].astype(np.float32)
        foot = model.foot[s][model.foot[s] >= 0]
        for c in range(3):
            P[c, r[:, None], foot[None, :]] += shift[leg, s, c].astype(np.float32)[:, None]
    P[1, rows] -= drop.astype(np.float32)[:, None]
