"""The reservation table of an offline crowd plan: the space-time index of planned characters'
bounding cylinders (:class:`~runtime.crowd.spacetime.SpaceTimeIndex`), plus, per character, its
cylinder on every frame as a dense array, so "who is where at frame f" is one slice -- what a
space-time route search (:mod:`runtime.crowd.planner.route`) reads step by step.

*Holds* are characters not planned yet standing (or sitting) at their start -- one disc on
every frame before a last one (negative frames too: a backward seed's queries) -- or, from the
frame they may first arrive, at their last goal (:meth:`Reservations.hold`). They answer every query like cylinders
stored on each of those frames, but are kept as one row each in a 2D grid beside the index,
so holding the starts of a 500-character crowd costs 500 rows, not 500 per frame.

Limits: owners are small non-negative ints (character indices); frames are in ``[0, n_frames)``
(a cylinder beyond is kept in the index only); a hold's radius counts in the index's cell-size
check like any cylinder's.
"""
from __future__ import annotations

import numpy as np

from .spacetime import SpaceTimeIndex

try:  # pragma: no cover - depends on the environment
    import numba as _nb
except Exception:
    _nb = None

__all__ = ["Reservations"]


def _hold_hits_numpy(frames, xz, radius, margin, ignore_owner, first_only, rows, active):
    """(query sample indices, owners) of the (sample, hold) overlaps; rows: x, z, r, owner,
    until, from."""
    live = np.flatnonzero(active & (rows[:, 3] != ignore_owner))
    if len(live) == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    h = rows[live]
    d = np.hypot(xz[:, None, 0] - h[None, :, 0], xz[:, None, 1] - h[None, :, 1])
    bad = (d < h[None, :, 2] + radius[:, None] + margin) & (frames[:, None] < h[None, :, 4]) \
        & (frames[:, None] >= h[None, :, 5])
    q, k = np.nonzero(bad)
    if first_only and len(q):
        q, k = q[:1], k[:1]
    return q.astype(np.int64), h[k, 3]


if _nb is not None:
    from .spacetime import push_hit

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _hold_hits_compiled(frames, xz, radius, margin, ignore_owner, first_only, rows, active, cell, ox, oz, nx,
                            nz, start, items):  # pragma: no cover - compiled
        """As :func:`_hold_hits_numpy`, through the holds' 2D grid (3 x 3 cells per sample)."""
        n = len(frames)
        out_q = np.empty(16, np.int64)
        out_o = np.empty(16)
        m = 0
        for s in range(n):
            ix = np.int64(np.floor((xz[s, 0] - ox) / cell))
            iz = np.int64(np.floor((xz[s, 1] - oz) / cell))
            for i in range(ix - 1, ix + 2):
                if i < 0 or i >= nx:
                    continue
                for j in range(iz - 1, iz + 2):
                    if j < 0 or j >= nz:
                        continue
                    c = i * nz + j
                    for t in range(start[c], start[c + 1]):
                        h = items[t]
                        if not active[h] or np.int64(rows[h, 3]) == ignore_owner or frames[s] >= rows[h, 4] \
                                or frames[s] < rows[h, 5]:
                            continue
                        if np.hypot(rows[h, 0] - xz[s, 0], rows[h, 1] - xz[s, 1]) < rows[h, 2] + radius[s] + margin:
                            out_q, out_o = push_hit(out_q, out_o, m, s, rows[h, 3])
                            m += 1
                            if first_only:
                                return out_q[:m], out_o[:m]
        return out_q[:m], out_o[:m]


class Reservations(SpaceTimeIndex):
    """A space-time index that also keeps every owner's cylinders densely by frame, and holds.

    Args:
        cell: the index's cell size (m).
        n_frames: the scenario's frames.
        owners: owners expected (the characters): room for all their frames is made up front.
    """

    def __init__(self, cell: float, n_frames: int, owners: int = 0):
        super().__init__(cell=cell, capacity=int(owners) * int(n_frames))
        self.n_frames = int(n_frames)
        self._xzr = np.full((int(owners), self.n_frames, 3), np.nan, dtype=np.float32)
        self._holds = np.zeros((0, 6))            # x, z, r, owner, until (frames before it), from
        self._hold_of: dict[tuple, int] = {}      # (owner, kind) -> row
        self._active = np.zeros(0, dtype=bool)
        self._grid = None

    # -- holds -------------------------------------------------------------------------------
    def hold(self, owner: int, xz, radius: float, until: int, start: int | None = None, kind: str = "start") -> None:
        """Hold a disc at ``xz`` (2,) of ``radius`` for frames before ``until`` (from ``start``
        on; None: every frame before) for ``owner`` (again after :meth:`release_hold`: the same
        disc comes back). An owner has one hold of each ``kind`` ("start": where it stands until
        planned; "goal": where it will stand)."""
        owner = int(owner)
        row = np.array([float(xz[0]), float(xz[1]), float(radius), owner, float(until),
                        -np.inf if start is None else float(start)])
        k = self._hold_of.get((owner, kind))
        if k is None or not np.array_equal(self._holds[k], row):
            k = len(self._holds)
            self._holds = np.concatenate([self._holds, row[None]])
            self._active = np.concatenate([self._active, [False]])
            self._hold_of[(owner, kind)] = k
            self._grid = None
        self._active[k] = True
        self.max_radius = max(self.max_radius, float(radius))

    def standing(self, frame: int, ignore_owner: int | None = None):
        """(xz (M, 2), radius (M,)) of the holds that last from ``frame`` to the end: the
        characters who stand still there (not planned yet)."""
        h = self._active & (self._holds[:, 4] >= self.n_frames) & (self._holds[:, 5] <= frame)
        if ignore_owner is not None:
            h &= self._holds[:, 3] != ignore_owner
        return self._holds[h, :2], self._holds[h, 2]

    def still(self, frame: int, ignore_owner: int | None = None, tol: float = 0.02):
        """(xz (M, 2), radius (M,)): every disc that stays put from ``frame`` to the scenario's
        end -- the :meth:`standing` holds and the stored characters who do not move (by more
        than ``tol`` m) from ``frame`` on, each with its largest radius over those frames."""
        xz, r = self.standing(frame, ignore_owner)
        if len(self._xzr) and 0 <= frame < self.n_frames:
            tail = self._xzr[:, frame:]
            ok = np.isfinite(tail[:, :, 2]).all(axis=1)
            if ignore_owner is not None and ignore_owner < len(ok):
                ok[ignore_owner] = False
            rows = np.flatnonzero(ok)
            if len(rows):
                t = tail[rows].astype(np.float64)
                end = t[:, -1, :2]
                put = (np.hypot(t[:, :, 0] - end[:, None, 0], t[:, :, 1] - end[:, None, 1]) <= tol).all(axis=1)
                xz = np.concatenate([xz, end[put]])
                r = np.concatenate([r, t[put, :, 2].max(axis=1)])
        return xz, r

    def release_hold(self, owner: int, kind: str | None = "start") -> None:
        """Drop ``owner``'s hold of ``kind`` (None: every kind), if any."""
        for kd in (("start", "goal") if kind is None else (kind,)):
            k = self._hold_of.get((int(owner), kd))
            if k is not None:
                self._active[k] = False

    def _hold_grid(self):
        if self._grid is None:
            xz = self._holds[:, :2]
            o = xz.min(0) - self.cell
            ij = np.floor((xz - o) / self.cell).astype(np.int64)
            nx, nz = int(ij[:, 0].max()) + 2, int(ij[:, 1].max()) + 2
            c = ij[:, 0] * nz + ij[:, 1]
            items = np.argsort(c, kind="stable").astype(np.int64)
            start = np.searchsorted(c[items], np.arange(nx * nz + 1)).astype(np.int64)
            self._grid = (float(o[0]), float(o[1]), nx, nz, start, items)
        return self._grid

    @staticmethod
    def _query(frames, xz, radius):
        """A query's arrays as the kernels take them: frames int64, xz and radius float64 and
        contiguous, one radius per sample."""
        frames = np.asarray(frames, dtype=np.int64)
        xz = np.ascontiguousarray(xz, dtype=np.float64)
        radius = np.ascontiguousarray(np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape))
        return frames, xz, radius

    def _hold_hits(self, frames, xz, radius, margin, ignore_owner, first_only):
        """(sample, owner) pairs of a query (:meth:`_query`'s arrays) against the active holds."""
        if not self._active.any():
            return np.zeros(0, np.int64), np.zeros(0)
        ig = -1 if ignore_owner is None else int(ignore_owner)
        from . import spacetime
        if _nb is not None and spacetime.ENABLED:
            ox, oz, nx, nz, start, items = self._hold_grid()
            return _hold_hits_compiled(frames, xz, radius, float(margin), ig, bool(first_only), self._holds,
                                       self._active, self.cell, ox, oz, nx, nz, start, items)
        return _hold_hits_numpy(frames, xz, radius, margin, ig, first_only, self._holds, self._active)

    # -- the index's queries, holds included ---------------------------------------------------
    def _hits(self, frames, xz, radius, margin, ignore_owner, first_only=False, compiled=None):
        frames, xz, radius = self._query(frames, xz, radius)
        q, o = super()._hits(frames, xz, radius, margin, ignore_owner, first_only, compiled)
        if len(self._holds) == 0 or len(frames) == 0:
            return q, o
        qh, oh = self._hold_hits(frames, xz, radius, margin, ignore_owner, first_only)
        if len(qh) == 0:
            return q, o
        if len(q) == 0:
            return qh, oh
        return np.concatenate([q, qh]), np.concatenate([o, oh])

    def any_overlap_runs(self, frames, xz, radius, counts, margin: float = 0.0, ignore_owner=None) -> np.ndarray:
        out = super().any_overlap_runs(frames, xz, radius, counts, margin, ignore_owner)
        if len(np.asarray(frames)) and self._active.any():
            counts = np.asarray(counts, dtype=np.int64)
            q, _ = self._hold_hits(*self._query(frames, xz, radius), margin, ignore_owner, False)
            if len(q):
                run = np.searchsorted(np.cumsum(counts), q, side="right")
                out[run] = True
        return out

    # -- dense rows ---------------------------------------------------------------------------
    def insert(self, owner: int, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray) -> None:
        super().insert(owner, frames, xz, radius)
        if owner >= len(self._xzr):
            grow = np.full((max(owner + 1, 2 * len(self._xzr)) - len(self._xzr), self.n_frames, 3), np.nan,
                           dtype=np.float32)
            self._xzr = np.concatenate([self._xzr, grow])
        frames = np.asarray(frames, dtype=np.int64)
        ok = (frames >= 0) & (frames < self.n_frames)
        f = frames[ok]
        self._xzr[owner, f, :2] = np.asarray(xz, dtype=np.float64)[ok]
        self._xzr[owner, f, 2] = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)[ok]

    def remove_owner(self, owner: int) -> None:
        super().remove_owner(owner)
        self.release_hold(owner, None)
        if owner < len(self._xzr):
            self._xzr[owner] = np.nan

    def at_frame(self, frame: int, ignore_owner: int | None = None):
        """(xz (M, 2), radius (M,)) of every stored cylinder and hold at ``frame``."""
        if not (0 <= frame < self.n_frames):
            return np.zeros((0, 2)), np.zeros(0)
        xz, r = np.zeros((0, 2)), np.zeros(0)
        if len(self._xzr):
            row = self._xzr[:, frame]
            ok = np.isfinite(row[:, 2])
            if ignore_owner is not None and ignore_owner < len(ok):
                ok[ignore_owner] = False
            xz, r = row[ok, :2].astype(np.float64), row[ok, 2].astype(np.float64)
        if self._active.any():
            h = self._active & (self._holds[:, 4] > frame) & (self._holds[:, 5] <= frame)
            if ignore_owner is not None:
                h &= self._holds[:, 3] != ignore_owner
            xz = np.concatenate([xz, self._holds[h, :2]])
            r = np.concatenate([r, self._holds[h, 2]])
        return xz, r
