"""Space-time index of planned characters' bounding cylinders (paper 000, section 3.2).

Characters are planned one after another; the ones already planned are moving obstacles.
Their per-frame cylinders (x, z, radius) live in a uniform grid over (x, z, t): a cell is
``cell`` metres square and one frame long, keyed by a single int64. A query touches only the
3 x 3 cells around each of its samples at the same frame, so its cost does not grow with the
number of characters far away.

Storage is a small log-structured set of sorted runs: an insert appends a run (one
character's samples sorted by key); when there are more than ``max_runs`` runs they are
merged into one. A query does one ``searchsorted`` per run for all its keys at once.

Limits: cell size must be >= twice the largest radius plus the margin (checked), frames
are integers (the 30 Hz clock) in ``[0, 2**20)``, and |x|, |z| < 2**20 cells.
"""
from __future__ import annotations

import numpy as np

__all__ = ["SpaceTimeIndex"]

_BITS = 21
_OFF = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1


def _key(frame, ix, iz):
    return (np.asarray(frame, np.int64) << (2 * _BITS)) | (((ix + _OFF) & _MASK) << _BITS) | ((iz + _OFF) & _MASK)


class SpaceTimeIndex:
    def __init__(self, cell: float = 1.2, max_runs: int = 8):
        self.cell = float(cell)
        self.max_runs = max_runs
        self._runs: list[tuple[np.ndarray, np.ndarray]] = []   # (sorted keys, rows (n, 4): x, z, r, owner)
        self.count = 0
        self.max_radius = 0.0

    def __len__(self):
        return self.count

    def insert(self, owner: int, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray) -> None:
        """Add one character's samples: frames (n,) int, xz (n, 2), radius (n,)."""
        frames = np.asarray(frames, dtype=np.int64)
        if len(frames) == 0:
            return
        xz = np.asarray(xz, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)
        self.max_radius = max(self.max_radius, float(radius.max()))
        ij = np.floor(xz / self.cell).astype(np.int64)
        keys = _key(frames, ij[:, 0], ij[:, 1])
        order = np.argsort(keys, kind="stable")
        rows = np.column_stack([xz, radius, np.full(len(frames), float(owner))])
        self._runs.append((keys[order], rows[order]))
        self.count += len(frames)
        if len(self._runs) > self.max_runs:
            keys = np.concatenate([k for k, _ in self._runs])
            rows = np.concatenate([r for _, r in self._runs])
            o = np.argsort(keys, kind="stable")
            self._runs = [(keys[o], rows[o])]

    def remove_owner(self, owner: int) -> None:
        """Drop every sample of ``owner`` (used when a character is re-planned)."""
        runs = []
        for k, r in self._runs:
            m = r[:, 3] != owner
            if m.any():
                runs.append((k[m], r[m]))
        self._runs = runs
        self.count = sum(len(k) for k, _ in runs)

    def overlaps(self, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray, margin: float = 0.0,
                 ignore_owner: int | None = None, first_only: bool = False):
        """Which query samples overlap a stored cylinder at the same frame.

        Returns a bool array (n,) (``first_only``: stops caring after finding any, returns a
        bool scalar). Overlap means centre distance < r_query + r_stored + margin.
        """
        frames = np.asarray(frames, dtype=np.int64)
        xz = np.asarray(xz, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)
        n = len(frames)
        hit = np.zeros(n, dtype=bool)
        if n == 0 or not self._runs:
            return bool(hit.any()) if first_only else hit
        if self.cell < 2 * max(self.max_radius, float(radius.max())) + margin:
            raise ValueError(f"space-time cell {self.cell} m is smaller than twice the largest radius plus margin")
        ij = np.floor(xz / self.cell).astype(np.int64)
        di = np.array([-1, -1, -1, 0, 0, 0, 1, 1, 1])
        dj = np.array([-1, 0, 1, -1, 0, 1, -1, 0, 1])
        qk = _key(frames[:, None], ij[:, :1] + di[None], ij[:, 1:] + dj[None]).reshape(-1)
        qs = np.repeat(np.arange(n), 9)
        for keys, rows in self._runs:
            lo = np.searchsorted(keys, qk, side="left")
            hi = np.searchsorted(keys, qk, side="right")
            cnt = hi - lo
            tot = int(cnt.sum())
            if tot == 0:
                continue
            # expand the ranges [lo, hi) without a Python loop
            q = np.repeat(qs, cnt)
            start = np.repeat(lo - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt)
            idx = start + np.arange(tot)
            other = rows[idx]
            d = np.hypot(other[:, 0] - xz[q, 0], other[:, 1] - xz[q, 1])
            bad = d < other[:, 2] + radius[q] + margin
            if ignore_owner is not None:
                bad &= other[:, 3] != ignore_owner
            if bad.any():
                hit[q[bad]] = True
                if first_only:
                    return True
        return bool(hit.any()) if first_only else hit
