"""Pose evaluation for every character in one vectorized pass .

A character's state on a tick is what a track holds for that tick (``runtime.crowd.tracks``):
two library frames ``a``, ``b``, a blend ``t`` (the pose is ``slerp(a, b, t)``) and its planar
root ``(x, z, heading)``. Rendering happens between ticks, so the drawn pose is interpolated
between the last two ticks' states with ``alpha`` in [0, 1]: the root is lerped (heading along
the shorter arc) and the pose is blended.

Two evaluators, both vectorized over characters and joints (no per-character Python loop):

* **Exact** (:func:`evaluate_world` with ``exact=True`` or ``rotations=True``,
  :meth:`PoseBatch.transforms`): the reference path -- gather library frames, slerp
  (``evaluate_poses`` of :mod:`runtime.crowd.tracks`), slerp again between the two ticks, then
  forward kinematics (:func:`runtime.motion.fk.forward_kinematics`) -- giving global rotations
  and positions in float64.

* **Table** (the default for positions, :class:`PoseTable`): forward kinematics is linear in
  the root's rigid transform, so the joint positions of every library frame are computed once,
  in the root's heading-free frame (root at ``(0, height, 0)``), with the exact evaluator. A
  character's joints on a tick are then

      p_j = R_y(heading) * ((1 - t) L[a]_j + t L[b]_j) + (x, 0, z)

  and between ticks the world positions are interpolated, ``(1 - alpha) * p_prev + alpha *
  p_cur``. Blending positions instead of rotations differs from the exact path only by the
  chord-versus-arc gap of one frame's (or one tick's) joint motion, ``L * theta^2 / 8`` for a
  limb (or a joint at distance ``L`` from the root axis, for the root's turn) turning ``theta``:
  for library frames and ticks 1/30 s apart, 1-3 mm typically and under 1.5 cm at worst over the
  default library (``tests/test_pose.py`` checks both). It is exact (to float32) at ``t, alpha in
  {0, 1}``. Positions are kept as component planes (3, N, J) so that every operation is one
  contiguous loop over N * J floats; the (N, J, 3) results are views of those planes. Placing
  the poses in the world once per tick leaves two passes per rendered frame.

:class:`PoseBatch` is the render-side state a world keeps: :meth:`PoseBatch.push` once per tick
(gathers of the frames' positions and of the step to the next frame, a blend, the root
transform), and :meth:`PoseBatch.positions` once per rendered frame (an interpolation over
preallocated buffers).
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np

from .crowd.tracks import evaluate_poses
from . import pose_kernels as _kernels
from .motion import quat
from .motion.fk import forward_kinematics
from .motion.footlock import (BLEND_FRAMES, MAX_CORRECTION, MAX_HIP_DROP, FootLockModel, LockState, lock_positions,
                              lock_skel_arrays)

__all__ = ["PoseState", "PoseTable", "PoseBatch", "Scratch", "evaluate_world", "interpolate_root", "skel_arrays",
           "locked_joint_positions"]


@dataclass
class PoseState:
    """One tick's state of N characters (the render-facing slice of their tracks)."""
    frames_a: np.ndarray   # (N,) int64 global library frame
    frames_b: np.ndarray   # (N,) int64
    frames_t: np.ndarray   # (N,) float32 blend in [0, 1]
    root: np.ndarray       # (N, 3) float64 x, z, heading (rad)

    def __post_init__(self):
        self.frames_a = np.asarray(self.frames_a, dtype=np.int64).reshape(-1)
        self.frames_b = np.asarray(self.frames_b, dtype=np.int64).reshape(-1)
        self.frames_t = np.asarray(self.frames_t, dtype=np.float32).reshape(-1)
        self.root = np.asarray(self.root, dtype=np.float64).reshape(-1, 3)
        n = len(self.frames_a)
        if not (len(self.frames_b) == len(self.frames_t) == len(self.root) == n):
            raise ValueError(f"pose state arrays disagree in length: frames_a {n}, frames_b {len(self.frames_b)}, "
                             f"frames_t {len(self.frames_t)}, root {len(self.root)}")

    def __len__(self):
        return len(self.frames_a)

    def take(self, idx) -> "PoseState":
        return PoseState(self.frames_a[idx], self.frames_b[idx], self.frames_t[idx], self.root[idx])

    def copy(self) -> "PoseState":
        return PoseState(self.frames_a.copy(), self.frames_b.copy(), self.frames_t.copy(), self.root.copy())

    def check(self, num_frames: int) -> None:
        for name in ("frames_a", "frames_b"):
            f = getattr(self, name)
            if len(f) and (f.min() < 0 or f.max() >= num_frames):
                raise ValueError(f"pose state {name} out of range [0, {num_frames}) of the library")


def _as_state(s) -> PoseState:
    if isinstance(s, PoseState):
        return s
    return PoseState(*s)


def interpolate_root(prev, cur, alpha):
    """Planar roots (..., 3) between two ticks: lerp x, z; heading along the shorter arc."""
    prev = np.asarray(prev, dtype=np.float64)
    cur = np.asarray(cur, dtype=np.float64)
    a = np.asarray(alpha, dtype=np.float64)
    if a.ndim:
        a = a[..., None]
    d = cur - prev
    d[..., 2] = (d[..., 2] + math.pi) % (2.0 * math.pi) - math.pi
    return prev + a * d


# -- the table evaluator -------------------------------------------------------------------------

_TABLES: dict[int, tuple] = {}


class PoseTable:
    """Root-local joint positions of every library frame, laid out for blending.

    ``local`` is (3, T, J) float32: component planes (x, y, z) over library frames and joints,
    root at ``(0, height, 0)`` with the heading removed; ``delta[:, f]`` is the difference to
    frame ``f + 1`` (zero for the last frame), so the common case ``b == a + 1`` needs no second
    lookup of a different frame. Blended poses come out as (3, N, J) planes, so every later
    operation runs over one contiguous run of N * J floats per component.
    Computed with the exact evaluator (:func:`evaluate_poses` + :func:`forward_kinematics`)."""

    def __init__(self, graph):
        self.graph = graph
        T = len(graph.frame_height)
        J = graph.skeleton.num_joints
        frames = np.arange(T)
        pos, rot = evaluate_poses(graph, frames, frames, np.zeros(T), np.zeros((T, 3)))
        local = forward_kinematics(graph.skeleton, pos, rot)[1]          # (T, J, 3), root at (0, h, 0)
        self.local = np.ascontiguousarray(local.transpose(2, 0, 1), dtype=np.float32)  # (3, T, J)
        self.delta = np.zeros_like(self.local)
        self.delta[:, :-1] = self.local[:, 1:] - self.local[:, :-1]
        self.num_frames = T
        self.num_joints = J

    @classmethod
    def for_graph(cls, graph) -> "PoseTable":
        """The table of ``graph``, built once per graph object and reused."""
        hit = _TABLES.get(id(graph))
        if hit is not None and hit[0]() is graph:
            return hit[1]
        table = cls(graph)
        key = id(graph)
        _TABLES[key] = (weakref.ref(graph, lambda _r, k=key, t=_TABLES: t.pop(k, None) if t is not None else None),
                        table)
        return table

    def blend(self, frames_a, frames_b, frames_t, out=None, scratch=None) -> np.ndarray:
        """Root-local positions (3, N, J) float32 of the ``slerp(a, b, t)`` poses (positions
        blended). ``out`` and ``scratch`` (a :class:`Scratch`) avoid allocating per call."""
        fa = np.asarray(frames_a, dtype=np.int64)
        fb = np.asarray(frames_b, dtype=np.int64)
        t = np.asarray(frames_t, dtype=np.float32)
        n, J = len(fa), self.num_joints
        ws = scratch if scratch is not None else Scratch()
        if out is None:
            out = np.empty((3, n, J), dtype=np.float32)
        np.take(self.local, fa, axis=1, out=out, mode="clip")  # indices checked by the callers
        step = fb == fa + 1
        if np.any(step & (t != 0)):
            d = np.take(self.delta, fa, axis=1, out=ws.get("delta", (3, n, J)), mode="clip")
            w = np.repeat(np.where(step, t, np.float32(0.0)).astype(np.float32), J)
            d2 = d.reshape(3, n * J)
            d2 *= w
            o2 = out.reshape(3, n * J)
            o2 += d2
        odd = np.flatnonzero(~step & (fb != fa) & (t != 0))
        if len(odd):  # blends between non-consecutive frames (rare): general lerp
            pa = self.local[:, fa[odd]]
            out[:, odd] = pa + t[odd][None, :, None] * (self.local[:, fb[odd]] - pa)
        return out


class Scratch:
    """Reusable float32 work arrays by name (fresh multi-megabyte arrays cost page faults on
    every call; a per-tick path keeps its buffers)."""

    def __init__(self):
        self._arrays = {}

    def get(self, name: str, shape) -> np.ndarray:
        a = self._arrays.get(name)
        if a is None or a.shape != tuple(shape):
            a = self._arrays[name] = np.empty(shape, dtype=np.float32)
        return a


def _place(local, root, out, scratch=None):
    """World positions ``R_y(heading) local + (x, 0, z)``; ``local`` and ``out`` are (3, N, J)
    planes (``out`` may be ``local``: placed in place), ``root`` (N, 3). Per-character factors
    are repeated over joints so every operation is one contiguous loop."""
    _, n, J = local.shape
    ws = scratch if scratch is not None else Scratch()
    c, s, rep, ta, tb = (ws.get(k, (n * J,)) for k in ("cos", "sin", "rep", "tmp", "tmp2"))
    h = np.asarray(root[:, 2], dtype=np.float64)
    c.reshape(n, J)[...] = np.cos(h).astype(np.float32)[:, None]
    s.reshape(n, J)[...] = np.sin(h).astype(np.float32)[:, None]
    lx, ly, lz = (local[k].reshape(-1) for k in range(3))
    ox, oy, oz = (out[k].reshape(-1) for k in range(3))
    np.multiply(lz, s, out=ta)
    np.multiply(lx, s, out=tb)
    np.multiply(lx, c, out=ox)          # lx is not read after this (out may be local)
    ox += ta
    rep.reshape(n, J)[...] = np.asarray(root[:, 0], dtype=np.float32)[:, None]
    ox += rep
    np.multiply(lz, c, out=oz)
    oz -= tb
    rep.reshape(n, J)[...] = np.asarray(root[:, 1], dtype=np.float32)[:, None]
    oz += rep
    if oy is not ly and not np.shares_memory(oy, ly):
        oy[...] = ly
    return out


# -- stateless entry point -----------------------------------------------------------------------

def evaluate_world(graph, frames_a, frames_b, frames_t, root, prev=None, alpha=1.0,
                   rotations: bool = False, exact: bool = False):
    """Joint world positions (N, J, 3) of N characters, optionally interpolated from ``prev``.

    ``frames_a``, ``frames_b``, ``frames_t``, ``root`` are the current tick's state (N,), (N,),
    (N,), (N, 3); ``prev`` (a :class:`PoseState` or the same four arrays) is the previous tick's
    and ``alpha`` in [0, 1] (scalar or (N,)) how far the render time is from it to the current
    tick (1 = current). With ``rotations=True`` returns ``(global rotations (N, J, 4),
    positions (N, J, 3))`` from the exact evaluator (float64); ``exact=True`` uses it for
    positions too. The table evaluator returns float32 (see the module docstring for its bound).
    """
    cur = PoseState(frames_a, frames_b, frames_t, root)
    cur.check(len(graph.frame_height))
    p = None if prev is None else _as_state(prev)
    if p is not None:
        if len(p) != len(cur):
            raise ValueError(f"previous state has {len(p)} characters, current {len(cur)}")
        p.check(len(graph.frame_height))
    if rotations or exact:
        gr, gp = _exact(graph, cur, p, alpha)
        return (gr, gp) if rotations else gp
    table = PoseTable.for_graph(graph)
    local = table.blend(cur.frames_a, cur.frames_b, cur.frames_t)
    out = _place(local, cur.root, np.empty_like(local))
    a = np.asarray(alpha, dtype=np.float32)
    if p is not None and not (a.ndim == 0 and a == 1.0):
        lp = table.blend(p.frames_a, p.frames_b, p.frames_t)
        wp = _place(lp, p.root, lp)
        out -= wp
        out *= a[None, :, None] if a.ndim else a
        out += wp
    return out.transpose(1, 2, 0)


def _exact(graph, cur: PoseState, prev: PoseState | None, alpha):
    """Global rotations and positions through evaluate_poses (slerp) and forward_kinematics."""
    if prev is None:
        pos, rot = evaluate_poses(graph, cur.frames_a, cur.frames_b, cur.frames_t, cur.root)
        return forward_kinematics(graph.skeleton, pos, rot)
    r = interpolate_root(prev.root, cur.root, alpha)
    # Both ticks evaluated with the interpolated root in one call (leading axis 2): their root
    # rotations share the yaw, and slerp(Y q0, Y q1) = Y slerp(q0, q1) ("lerp root, slerp poses").
    fa = np.stack([prev.frames_a, cur.frames_a])
    fb = np.stack([prev.frames_b, cur.frames_b])
    ft = np.stack([prev.frames_t, cur.frames_t])
    pos, rot = evaluate_poses(graph, fa, fb, ft, np.stack([r, r]))
    a = np.broadcast_to(np.asarray(alpha, dtype=np.float64), (len(cur),))
    rot = quat.slerp(rot[0], rot[1], np.broadcast_to(a[:, None], rot.shape[1:-1]))
    pos = pos[0] + a[:, None] * (pos[1] - pos[0])
    return forward_kinematics(graph.skeleton, pos, rot)


# -- baked animation arrays ----------------------------------------------------------------------

def skel_arrays(graph, frames_a, frames_b, frames_t, root, fused: bool | None = None, lock_segments=None):
    """UsdSkel animation arrays of M frames (any mix of characters): joint translations (M, J, 3)
    float32 (the root joint's is its world position and height, the others' the rest offsets),
    local joint rotations (M, J, 4) float32 in the x-y-z-w memory order of ``GfQuatf`` (the
    root's includes the heading), and ``crowdweave:root`` (M, 3) float64 (x, z, heading deg).

    The arithmetic of :func:`runtime.crowd.tracks.evaluate_poses` (float32 slerp of library
    frames); ``fused`` (default: numba available) runs it as one parallel kernel
    (:func:`runtime.pose_kernels.skel_arrays`), else as numpy passes.

    ``lock_segments`` (M,) bool, True on the first frame of each character's frames, applies
    the foot lock (:func:`runtime.motion.footlock.lock_skel_arrays`: planted feet pinned where
    they landed; the legs' rotations and the root height change, the root path does not)."""
    fa = np.asarray(frames_a, dtype=np.int64).reshape(-1)
    fb = np.asarray(frames_b, dtype=np.int64).reshape(-1)
    ft = np.asarray(frames_t, dtype=np.float32).reshape(-1)
    root = np.asarray(root, dtype=np.float64).reshape(-1, 3)
    PoseState(fa, fb, ft, root).check(len(graph.frame_height))
    offsets = np.asarray(graph.skeleton.offsets, dtype=np.float64)
    if _kernels.AVAILABLE if fused is None else fused:
        trans, q, rootv = _kernels.skel_arrays(graph.frame_rotations, graph.frame_height, offsets, fa, fb, ft, root)
    else:
        pos, rot = evaluate_poses(graph, fa, fb, ft, root)
        trans = np.empty(pos.shape[:1] + offsets.shape, np.float32)
        trans[:] = offsets
        trans[:, 0] = pos
        q = np.ascontiguousarray(rot[..., [1, 2, 3, 0]], dtype=np.float32)
        rootv = np.column_stack([root[:, 0], root[:, 1], np.degrees(root[:, 2])])
    if lock_segments is not None:
        seg = np.asarray(lock_segments, dtype=bool).reshape(-1)
        if len(seg) != len(fa):
            raise ValueError(f"lock_segments has {len(seg)} entries for {len(fa)} frames")
        lock_skel_arrays(FootLockModel.for_library(graph), graph.skeleton, fa, fb, ft, seg, trans, q)
    return trans, q, rootv


def locked_joint_positions(graph, track) -> np.ndarray:
    """Joint world positions (F, J, 3) float64 of one track as a bake writes it (foot lock
    applied: :func:`skel_arrays` with ``lock_segments``, then forward kinematics)."""
    seg = np.zeros(len(track), dtype=bool)
    seg[:1] = True
    trans, q, _ = skel_arrays(graph, track.frames_a, track.frames_b, track.frames_t, track.root, lock_segments=seg)
    return forward_kinematics(graph.skeleton, trans[:, 0].astype(np.float64), q[..., [3, 0, 1, 2]])[1]


# -- render-side state ---------------------------------------------------------------------------

class PoseBatch:
    """The last two ticks' poses of N characters, for rendering between ticks.

    ``push(state)`` after every tick (its cost: one gather and a blend per character, and the
    placement in the world); ``positions(alpha)`` per rendered frame (two passes).
    ``push(state, keep=idx)`` handles spawned and removed characters: ``idx[i]`` is the index
    character ``i`` had in the previously pushed state, or -1 for a new character (drawn at its
    current pose, not interpolated). Without ``keep``, a change of N restarts interpolation
    (both ticks = the new state).

    :meth:`positions` returns a view of an internal buffer that the next call overwrites.

    ``fused`` (default: when numba is available) evaluates a push and an interpolation each in
    one parallel pass per character (:mod:`runtime.pose_kernels`); ``fused=False`` runs the
    numpy passes described in the module docstring. Both compute the same float32 formula.

    ``foot_lock`` (default on) pins planted feet where they landed, tick by tick, with a state
    per character (:func:`runtime.motion.footlock.lock_positions`; on the fused path in the
    same pass as the placement, :func:`runtime.pose_kernels.blend_place_lock`): knees and feet
    move, the body comes down when a foot is out of reach, the root path does not change.
    :meth:`transforms` stays the unlocked exact evaluation.
    """

    def __init__(self, graph, fused: bool | None = None, foot_lock: bool = True):
        self.graph = graph
        self.fused = _kernels.AVAILABLE if fused is None else bool(fused)
        if self.fused and not _kernels.AVAILABLE:
            raise RuntimeError("fused pose kernels need numba, which could not be imported")
        self.table = PoseTable.for_graph(graph)
        self.foot_lock = bool(foot_lock)
        self.lock_model = FootLockModel.for_library(graph) if self.foot_lock else None
        self._lock: LockState | None = None    # per character: which feet are pinned, and where
        self.num_joints = self.table.num_joints
        self.prev: PoseState | None = None
        self.cur: PoseState | None = None
        self._wc = None     # current tick's world positions, planes (3, N, J)
        self._wp = None     # previous tick's
        self._d = None      # current - previous
        self._out = None    # interpolated world positions
        self._spare = None  # the buffer the next push places into
        self._ws = Scratch()

    def __len__(self):
        return 0 if self.cur is None else len(self.cur)

    def reset(self) -> None:
        self.prev = self.cur = None
        self._wc = self._wp = self._d = None
        self._lock = None

    def push(self, state, keep=None) -> None:
        st = _as_state(state).copy()
        st.check(self.table.num_frames)
        n = len(st)
        J = self.num_joints
        spare = self._spare if self._spare is not None and self._spare.shape == (3, n, J) else None
        lock = self._lock_state(n, keep) if self.foot_lock else None
        if self.fused:
            wc = spare if spare is not None else np.empty((3, n, J), dtype=np.float32)
            if lock is None:
                _kernels.blend_place(self.table.local, st.frames_a, st.frames_b, st.frames_t, st.root, wc)
            else:       # placed and locked in one pass per character
                _kernels.blend_place_lock(self.table.local, st.frames_a, st.frames_b, st.frames_t, st.root, wc,
                                          self.lock_model, lock, BLEND_FRAMES, MAX_CORRECTION, MAX_HIP_DROP)
        else:
            wc = self.table.blend(st.frames_a, st.frames_b, st.frames_t, out=spare, scratch=self._ws)
            _place(wc, st.root, wc, self._ws)
            if lock is not None:
                lock_positions(self.lock_model, wc, st.frames_a, st.frames_b, st.frames_t, st.root[:, 2], lock)
        self._lock = lock
        if self.cur is None or (keep is None and len(self.cur) != n):
            prev, wp = st.copy(), wc.copy()
        elif keep is None:
            prev, wp = self.cur, self._wc
        else:
            keep = np.asarray(keep, dtype=np.int64).reshape(-1)
            if len(keep) != n:
                raise ValueError(f"keep has {len(keep)} entries for {n} characters")
            if len(keep) and keep.max() >= len(self.cur):
                raise ValueError(f"keep refers to character {int(keep.max())} of {len(self.cur)}")
            old = keep >= 0
            src = np.where(old, keep, 0)
            prev = self.cur.take(src) if len(self.cur) else st.copy()
            # C order: this buffer is reused by a later push, whose numpy path writes through reshapes
            wp = np.ascontiguousarray(self._wc[:, src]) if len(self.cur) else wc.copy()
            new = np.flatnonzero(~old)
            prev.frames_a[new] = st.frames_a[new]
            prev.frames_b[new] = st.frames_b[new]
            prev.frames_t[new] = st.frames_t[new]
            prev.root[new] = st.root[new]
            wp[:, new] = wc[:, new]
        self.prev, self.cur = prev, st
        old_wp = self._wp
        self._wp, self._wc = wp, wc
        # the previous tick's buffer is free again (unless it is still in use as wp)
        self._spare = old_wp if old_wp is not None and old_wp is not wp and old_wp is not wc else None
        if self._out is None or self._out.shape[1] != n:
            self._out = np.empty_like(wc)
            self._d = None if self.fused else np.empty_like(wc)
        if not self.fused:
            np.subtract(wc, wp, out=self._d)

    def _lock_state(self, n: int, keep) -> LockState:
        """Each character's lock state carried over (``keep`` as in :meth:`push`; new characters
        start unlocked)."""
        lock = self._lock
        if lock is None or self.cur is None or (keep is None and len(lock.locked) != n):
            return LockState.empty(n)
        if keep is None:
            return lock
        idx = np.asarray(keep, dtype=np.int64).reshape(-1)
        if len(idx) != n or (len(idx) and idx.max() >= len(lock.locked)):
            return LockState.empty(n)       # push raises below; the kernel must not read past the state
        lock = lock.take(np.where(idx >= 0, idx, 0))
        lock.reset(idx < 0)
        return lock

    def roots(self, alpha: float = 1.0) -> np.ndarray:
        """Interpolated planar roots (N, 3): x, z, heading."""
        if self.cur is None:
            return np.zeros((0, 3))
        if alpha >= 1.0:
            return self.cur.root.copy()
        return interpolate_root(self.prev.root, self.cur.root, alpha)

    def positions(self, alpha: float = 1.0) -> np.ndarray:
        """Joint world positions (N, J, 3) float32 at ``alpha`` between the previous tick (0)
        and the current one (1). A view of an internal buffer (see the class docstring)."""
        if self.cur is None:
            return np.zeros((0, self.num_joints, 3), dtype=np.float32)
        alpha = float(min(max(alpha, 0.0), 1.0))
        if alpha >= 1.0:
            out = self._wc
        elif alpha <= 0.0:
            out = self._wp
        elif self.fused:
            out = _kernels.lerp(self._wp, self._wc, alpha, self._out)
        else:
            out = np.multiply(self._d, np.float32(alpha), out=self._out)
            out += self._wp
        return out.transpose(1, 2, 0)

    def transforms(self, alpha: float = 1.0):
        """Exact global rotations (N, J, 4) and positions (N, J, 3), float64 (slerp + FK)."""
        if self.cur is None:
            J = self.num_joints
            return np.zeros((0, J, 4)), np.zeros((0, J, 3))
        prev = None if alpha >= 1.0 else self.prev
        return _exact(self.graph, self.cur, prev, float(alpha))
