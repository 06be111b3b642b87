"""Space-time index of planned characters' bounding cylinders (paper 000, section 3.2).

Characters are planned one after another; the ones already planned are moving obstacles.
Their per-frame cylinders (x, z, radius) live in a uniform grid over (x, z, t): a cell is
``cell`` metres square and one frame long, keyed by a single int64. A query touches only the
3 x 3 cells around each of its samples at the same frame, so its cost does not grow with the
number of characters far away.

Storage is a log-structured set of sorted runs: an insert appends a run (one character's
samples sorted by key), and runs are merged like a binary counter (the newest run is merged
into the one before it while that one is at most twice as large), so an insert costs
O(log n) amortised and a query does one ``searchsorted`` per run (O(log n) runs) for all its
keys at once. Removing a character only bumps its version (O(1)); its rows stay until a merge
drops them, and queries ignore rows of an old version. ``forget_before(frame)`` lets merges
drop rows of frames already played, so a running world never needs a full rebuild.

Limits: cell size must be >= twice the largest radius plus the margin (checked); frames are
integers (the fixed clock) in ``[0, 2**20)``; |x|, |z| < 2**20 cells; owners are small
non-negative ints (character slots).
"""
from __future__ import annotations

import numpy as np

__all__ = ["SpaceTimeIndex", "key_matches"]

_BITS = 21
_OFF = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1


def _key(frame, ix, iz):
    return (np.asarray(frame, np.int64) << (2 * _BITS)) | (((ix + _OFF) & _MASK) << _BITS) | ((iz + _OFF) & _MASK)



def key_matches(keys: np.ndarray, qk: np.ndarray, qs: np.ndarray):
    """Every stored row whose key equals a query key, for a sorted run ``keys``: returns
    (query sample ``qs[k]`` of each match, row index), the ranges [lo, hi) of equal keys
    expanded without a Python loop. Shared by the space-time indexes (this one and
    :class:`runtime.tiling.boxindex.BoxIndex`)."""
    lo = np.searchsorted(keys, qk, side="left")
    hi = np.searchsorted(keys, qk, side="right")
    cnt = hi - lo
    tot = int(cnt.sum())
    if tot == 0:
        return qs[:0], lo[:0]
    q = np.repeat(qs, cnt)
    idx = np.repeat(lo - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt) + np.arange(tot)
    return q, idx

class SpaceTimeIndex:
    def __init__(self, cell: float = 1.2):
        self.cell = float(cell)
        self._runs: list[tuple[np.ndarray, np.ndarray]] = []   # (sorted keys, rows (n, 5): x, z, r, owner, version)
        self._version = np.zeros(64, dtype=np.float64)
        self._floor = -1
        self.max_radius = 0.0

    @property
    def count(self) -> int:
        """Rows stored (stale rows included until merged away)."""
        return sum(len(k) for k, _ in self._runs)

    def __len__(self):
        return self.count

    def _versions(self, owners: np.ndarray) -> np.ndarray:
        return self._version[owners.astype(np.int64)]

    def insert(self, owner: int, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray) -> None:
        """Add one character's samples: frames (n,) int, xz (n, 2), radius (n,)."""
        frames = np.asarray(frames, dtype=np.int64)
        if len(frames) == 0:
            return
        owner = int(owner)
        if owner >= len(self._version):
            self._version = np.concatenate([self._version, np.zeros(max(owner + 1, 2 * len(self._version)) - len(self._version))])
        xz = np.asarray(xz, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)
        self.max_radius = max(self.max_radius, float(radius.max()))
        ij = np.floor(xz / self.cell).astype(np.int64)
        keys = _key(frames, ij[:, 0], ij[:, 1])
        order = np.argsort(keys, kind="stable")
        rows = np.column_stack([xz, radius, np.full(len(frames), float(owner)),
                                np.full(len(frames), self._version[owner])])
        self._runs.append((keys[order], rows[order]))
        while len(self._runs) > 1 and len(self._runs[-2][0]) <= 2 * len(self._runs[-1][0]):
            (k1, r1), (k2, r2) = self._runs[-2], self._runs[-1]
            keys = np.concatenate([k1, k2])
            rows = np.concatenate([r1, r2])
            live = rows[:, 4] == self._versions(rows[:, 3])
            if self._floor >= 0:
                live &= (keys >> (2 * _BITS)) >= self._floor
            keys, rows = keys[live], rows[live]
            o = np.argsort(keys, kind="stable")
            self._runs[-2:] = [(keys[o], rows[o])] if len(keys) else []

    def remove_owner(self, owner: int) -> None:
        """Forget every sample of ``owner`` (O(1): its rows become stale)."""
        if int(owner) < len(self._version):
            self._version[int(owner)] += 1

    def forget_before(self, frame: int) -> None:
        """Rows of frames before ``frame`` may be dropped (at the next merges)."""
        self._floor = int(frame)

    def overlaps(self, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray, margin: float = 0.0,
                 ignore_owner: int | None = None, first_only: bool = False):
        """Which query samples overlap a stored cylinder at the same frame.

        Returns a bool array (n,) (``first_only``: a bool, True as soon as one overlaps).
        Overlap means centre distance < r_query + r_stored + margin.
        """
        n = len(np.asarray(frames))
        hit = np.zeros(n, dtype=bool)
        for q, owners in self._hits(frames, xz, radius, margin, ignore_owner):
            hit[q] = True
            if first_only:
                return True
        return bool(hit.any()) if first_only else hit

    def overlapping_owners(self, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray,
                           margin: float = 0.0) -> dict:
        """The stored characters the query samples overlap: {owner: samples overlapping it}."""
        out: dict[int, int] = {}
        for q, owners in self._hits(frames, xz, radius, margin, None):
            for o, k in zip(*np.unique(owners.astype(np.int64), return_counts=True)):
                out[int(o)] = out.get(int(o), 0) + int(k)
        return out

    def _hits(self, frames, xz, radius, margin, ignore_owner):
        """Per run of stored rows: (query sample indices, stored owners) of the overlapping
        (query, stored) pairs (generator)."""
        frames = np.asarray(frames, dtype=np.int64)
        xz = np.asarray(xz, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)
        n = len(frames)
        if n == 0 or not self._runs:
            return
        if self.cell < 2 * max(self.max_radius, float(radius.max())) + margin:
            raise ValueError(f"space-time cell {self.cell} m is smaller than twice the largest radius plus margin")
        ij = np.floor(xz / self.cell).astype(np.int64)
        di = np.array([-1, -1, -1, 0, 0, 0, 1, 1, 1])
        dj = np.array([-1, 0, 1, -1, 0, 1, -1, 0, 1])
        qk = _key(frames[:, None], ij[:, :1] + di[None], ij[:, 1:] + dj[None]).reshape(-1)
        qs = np.repeat(np.arange(n), 9)
        for keys, rows in self._runs:
            q, idx = key_matches(keys, qk, qs)
            if len(q) == 0:
                continue
            other = rows[idx]
            d = np.hypot(other[:, 0] - xz[q, 0], other[:, 1] - xz[q, 1])
            bad = (d < other[:, 2] + radius[q] + margin) & (other[:, 4] == self._versions(other[:, 3]))
            if ignore_owner is not None:
                bad &= other[:, 3] != ignore_owner
            if bad.any():
                yield q[bad], other[bad, 3]
