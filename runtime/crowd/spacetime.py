"""Space-time index of planned characters' bounding cylinders (Sung, Kovar and Gleicher 2005, section 3.2).

Characters are planned one after another; the ones already planned are moving obstacles.
Their per-frame cylinders (x, z, radius) live in a uniform grid over (x, z, t): a cell is
``cell`` metres square and one frame long, keyed by a single int64. A query touches only the
3 x 3 cells around each of its samples at the same frame, so its cost does not grow with the
number of characters far away.

Storage is a spatial hash with chaining, as game engines keep broad-phase grids: rows live in
append-only arrays, and ``head[hash(key)]`` / ``next[row]`` thread every row onto the chain of
its bucket. An insert appends and links its rows (vectorized: the batch is grouped by bucket);
a query walks all its keys' chains in lock step, one gather per step, so it costs a few random
reads per key, whatever the number of rows (docs/decisions.md). Removing a
character only bumps its version (O(1)); its rows stay until the arrays are full, when a
compaction drops them and the rows of frames before ``forget_before(frame)``, so a running
world never grows without bound.

The query is compiled with numba when it is installed (one loop over the query's 9 keys per
sample, walking each chain to its end; :data:`ENABLED` switches it off); without numba the numpy
walk runs. Both return the same (sample, owner) pairs, in different orders.

Limits: cell size must be >= twice the largest radius plus the margin (checked); frames are
integers (the fixed clock) in ``[0, 2**20)``; |x|, |z| < 2**20 cells; owners are small
non-negative ints (character slots). The bucket table has at least twice as many slots as the
row capacity (load <= 0.5), so chains stay a few rows long.
"""
from __future__ import annotations

import numpy as np

try:  # pragma: no cover - depends on the environment
    import numba as _nb
except Exception:
    _nb = None

__all__ = ["SpaceTimeIndex", "AVAILABLE", "ENABLED"]

AVAILABLE = _nb is not None      # numba is importable
ENABLED = AVAILABLE              # queries use the compiled kernels (set False to run the numpy walk)

_BITS = 21
_OFF = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1
_CELL = (1 << (2 * _BITS)) - 1       # the (x, z) cell bits of a key; the frame is above them


def _key(frame, ix, iz):
    return (np.asarray(frame, np.int64) << (2 * _BITS)) | (((ix + _OFF) & _MASK) << _BITS) | ((iz + _OFF) & _MASK)


_DI = np.array([-1, -1, -1, 0, 0, 0, 1, 1, 1])
_DJ = np.array([-1, 0, 1, -1, 0, 1, -1, 0, 1])

if _nb is not None:
    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _bucket1(k, golden, shift, nb):  # pragma: no cover - compiled
        """:meth:`SpaceTimeIndex._bucket` of one key (``nb`` buckets)."""
        return (np.int64((np.uint64(k & _CELL) * golden) >> shift) + (k >> (2 * _BITS))) & (nb - 1)

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def push_hit(out_q, out_o, m, s, o):  # pragma: no cover - compiled
        """Store the overlapping pair (query sample ``s``, owner ``o``) at ``m`` in the output
        buffers, doubling them when full; returns the buffers."""
        if m == len(out_q):
            q2 = np.empty(2 * m, np.int64)
            o2 = np.empty(2 * m)
            q2[:m] = out_q[:m]
            o2[:m] = out_o[:m]
            out_q, out_o = q2, o2
        out_q[m] = s
        out_o[m] = o
        return out_q, out_o

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _hits_compiled(frames, xz, radius, margin, ignore_owner, first_only, cell, keys, rows, nxt, head,
                       version, shift, golden):  # pragma: no cover - compiled
        """(query sample indices, stored owners) of the overlapping pairs; ``first_only``
        stops at the first. Same keys, hash and test as the numpy walk."""
        n = len(frames)
        out_q = np.empty(64, np.int64)
        out_o = np.empty(64)
        m = 0
        for s in range(n):
            ix = np.int64(np.floor(xz[s, 0] / cell))
            iz = np.int64(np.floor(xz[s, 1] / cell))
            for di in range(-1, 2):
                for dj in range(-1, 2):
                    k = (frames[s] << (2 * _BITS)) | (((ix + di + _OFF) & _MASK) << _BITS) | ((iz + dj + _OFF) & _MASK)
                    b = _bucket1(k, golden, shift, len(head))
                    r = head[b]
                    while r >= 0:
                        if keys[r] == k:
                            o = rows[r, 3]
                            if rows[r, 4] == version[np.int64(o)] and np.int64(o) != ignore_owner:
                                d = np.hypot(rows[r, 0] - xz[s, 0], rows[r, 1] - xz[s, 1])
                                if d < rows[r, 2] + radius[s] + margin:
                                    out_q, out_o = push_hit(out_q, out_o, m, s, o)
                                    m += 1
                                    if first_only:
                                        return out_q[:m], out_o[:m]
                        r = nxt[r]
        return out_q[:m], out_o[:m]

    @_nb.njit(cache=True, boundscheck=False, nogil=True)
    def _runs_hit_compiled(frames, xz, radius, margin, ignore_owner, counts, cell, keys, rows, nxt, head, version,
                           shift, golden, out):  # pragma: no cover - compiled
        """Per run of consecutive query samples (``counts`` long each): whether any overlaps;
        each run stops at its first hit. Same keys, hash and test as :func:`_hits_compiled`."""
        s0 = 0
        for q in range(len(counts)):
            out[q] = False
            for s in range(s0, s0 + counts[q]):
                ix = np.int64(np.floor(xz[s, 0] / cell))
                iz = np.int64(np.floor(xz[s, 1] / cell))
                for di in range(-1, 2):
                    for dj in range(-1, 2):
                        k = (frames[s] << (2 * _BITS)) | (((ix + di + _OFF) & _MASK) << _BITS) | ((iz + dj + _OFF) & _MASK)
                        r = head[_bucket1(k, golden, shift, len(head))]
                        while r >= 0 and not out[q]:
                            if keys[r] == k:
                                o = np.int64(rows[r, 3])
                                if rows[r, 4] == version[o] and o != ignore_owner and \
                                        np.hypot(rows[r, 0] - xz[s, 0], rows[r, 1] - xz[s, 1]) < rows[r, 2] + radius[s] + margin:
                                    out[q] = True
                            r = nxt[r]
                        if out[q]:
                            break
                    if out[q]:
                        break
                if out[q]:
                    break
            s0 += counts[q]


class SpaceTimeIndex:
    _GOLDEN = np.uint64(0x9E3779B97F4A7C15)    # Fibonacci hashing multiplier
    MIN_CAPACITY = 1024

    MAX_PRESIZE = 1 << 21        # rows a capacity hint may allocate up front (about 150 MB with the bucket table)

    def __init__(self, cell: float = 1.2, capacity: int = 0):
        """``capacity``: rows expected (e.g. characters x frames), allocated up front (at most
        ``MAX_PRESIZE``) so that filling the index does not grow and relink it again and again."""
        self.cell = float(cell)
        self._n = 0                                        # rows used (stale ones included)
        cap = min(int(capacity), self.MAX_PRESIZE)
        cap = max(self.MIN_CAPACITY, cap) if cap > 0 else 0
        self._keys = np.empty(cap, dtype=np.int64)
        self._rows = np.empty((cap, 5), dtype=np.float64)  # x, z, r, owner, version
        self._next = np.empty(cap, dtype=np.int64)
        self._head = np.full(1 << int(2 * cap - 1).bit_length() if cap else 2, -1, dtype=np.int64)
        self._version = np.zeros(64, dtype=np.float64)
        self._floor = -1
        self.max_radius = 0.0

    @property
    def count(self) -> int:
        """Rows stored (stale rows included until a compaction drops them)."""
        return self._n

    def __len__(self):
        return self.count

    def _versions(self, owners: np.ndarray) -> np.ndarray:
        return self._version[owners.astype(np.int64)]

    def _bucket(self, keys: np.ndarray) -> np.ndarray:
        """Bucket of each key: a Fibonacci hash of its (x, z) cell plus its frame, so one
        cell's consecutive frames sit in consecutive buckets -- a query walks a motion frame
        by frame and then reads the bucket table in 9 sequential streams, not at random
        (grid500 profiled: the final tests' query kernel 2.23 s -> 1.18 s)."""
        shift = np.uint64(64 - (len(self._head).bit_length() - 1))
        cell = ((keys & _CELL).view(np.uint64) * self._GOLDEN) >> shift
        return (cell.astype(np.int64) + (keys >> (2 * _BITS))) & (len(self._head) - 1)

    def _link(self, start: int, stop: int) -> None:
        """Thread rows [start, stop) onto their buckets' chains (newest first)."""
        rows = np.arange(start, stop)
        h = self._bucket(self._keys[start:stop])
        o = np.argsort(h, kind="stable")
        h, rows = h[o], rows[o]
        new = np.ones(len(h), dtype=bool)
        new[1:] = h[1:] != h[:-1]                # first row of each bucket in the batch
        nxt = np.empty_like(rows)
        nxt[1:] = rows[:-1]
        nxt[new] = self._head[h[new]]
        self._next[rows] = nxt
        last = np.ones(len(h), dtype=bool)
        last[:-1] = new[1:]
        self._head[h[last]] = rows[last]

    def _reserve(self, m: int) -> None:
        """Room for ``m`` more rows: compact (drop stale and forgotten rows) and grow as needed."""
        if self._n + m <= len(self._keys):
            return
        keys, rows = self._keys[:self._n], self._rows[:self._n]
        live = rows[:, 4] == self._versions(rows[:, 3])
        if self._floor >= 0:
            live &= (keys >> (2 * _BITS)) >= self._floor
        keys, rows = keys[live], rows[live]
        n = len(keys)
        cap = max(self.MIN_CAPACITY, 2 * (n + m))
        self._keys = np.empty(cap, dtype=np.int64)
        self._rows = np.empty((cap, 5), dtype=np.float64)
        self._next = np.empty(cap, dtype=np.int64)
        self._keys[:n], self._rows[:n] = keys, rows
        self._head = np.full(1 << int(2 * cap - 1).bit_length(), -1, dtype=np.int64)
        self._n = n
        if n:
            self._link(0, n)

    def insert(self, owner: int, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray) -> None:
        """Add one character's samples: frames (n,) int, xz (n, 2), radius (n,)."""
        frames = np.asarray(frames, dtype=np.int64)
        m = len(frames)
        if m == 0:
            return
        owner = int(owner)
        if owner >= len(self._version):
            self._version = np.concatenate([self._version, np.zeros(max(owner + 1, 2 * len(self._version)) - len(self._version))])
        xz = np.asarray(xz, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)
        self.max_radius = max(self.max_radius, float(radius.max()))
        ij = np.floor(xz / self.cell).astype(np.int64)
        self._reserve(m)
        a, b = self._n, self._n + m
        self._keys[a:b] = _key(frames, ij[:, 0], ij[:, 1])
        self._rows[a:b, :2] = xz
        self._rows[a:b, 2] = radius
        self._rows[a:b, 3] = owner
        self._rows[a:b, 4] = self._version[owner]
        self._n = b
        self._link(a, b)

    def remove_owner(self, owner: int) -> None:
        """Forget every sample of ``owner`` (O(1): its rows become stale)."""
        if int(owner) < len(self._version):
            self._version[int(owner)] += 1

    def forget_before(self, frame: int) -> None:
        """Rows of frames before ``frame`` may be dropped (at the next compaction)."""
        self._floor = int(frame)

    def overlaps(self, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray, margin: float = 0.0,
                 ignore_owner: int | None = None, first_only: bool = False):
        """Which query samples overlap a stored cylinder at the same frame.

        Returns a bool array (n,) (``first_only``: a bool, True as soon as one overlaps).
        Overlap means centre distance < r_query + r_stored + margin.
        """
        n = len(np.asarray(frames))
        hit = np.zeros(n, dtype=bool)
        q, owners = self._hits(frames, xz, radius, margin, ignore_owner, first_only)
        if first_only:
            return bool(len(q))
        hit[q] = True
        return hit

    def first_overlap(self, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray, margin: float = 0.0,
                      ignore_owner: int | None = None) -> int:
        """The index of the first query sample that overlaps a stored cylinder, or -1 (the
        compiled query stops there: a motion that collides early costs a few samples)."""
        q, _ = self._hits(frames, xz, radius, margin, ignore_owner, first_only=True)
        return int(q.min()) if len(q) else -1

    def any_overlap_runs(self, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray, counts: np.ndarray,
                         margin: float = 0.0, ignore_owner: int | None = None) -> np.ndarray:
        """Per run of consecutive query samples (``counts`` samples each, in order): whether
        any of its samples overlaps a stored cylinder -- the seed planner's test of many
        candidate clips at once. Compiled, each run stops at its first hit."""
        counts = np.asarray(counts, dtype=np.int64)
        frames = np.asarray(frames, dtype=np.int64)
        xz = np.asarray(xz, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)
        out = np.zeros(len(counts), dtype=bool)
        if len(frames) == 0 or self._n == 0:
            return out
        if not ENABLED:
            hit = self.overlaps(frames, xz, radius, margin, ignore_owner)
            nz = counts > 0
            out[nz] = np.logical_or.reduceat(hit, (np.cumsum(counts) - counts)[nz])
            return out
        self._check_cell(radius, margin)
        shift = np.uint64(64 - (len(self._head).bit_length() - 1))
        _runs_hit_compiled(frames, np.ascontiguousarray(xz), np.ascontiguousarray(radius), float(margin),
                           -1 if ignore_owner is None else int(ignore_owner), counts, self.cell, self._keys,
                           self._rows, self._next, self._head, self._version, shift, self._GOLDEN, out)
        return out

    def _check_cell(self, radius, margin):
        if self.cell < 2 * max(self.max_radius, float(radius.max())) + margin:
            raise ValueError(f"space-time cell {self.cell} m is smaller than twice the largest radius plus margin")

    def overlapping_owners(self, frames: np.ndarray, xz: np.ndarray, radius: np.ndarray,
                           margin: float = 0.0) -> dict:
        """The stored characters the query samples overlap: {owner: samples overlapping it}."""
        q, owners = self._hits(frames, xz, radius, margin, None)
        o, k = np.unique(owners.astype(np.int64), return_counts=True)
        return {int(a): int(b) for a, b in zip(o, k)}

    def _matches(self, qk: np.ndarray):
        """(query index, row) of every stored row whose key equals ``qk[i]``: all the keys'
        chains walked in lock step."""
        cur = self._head[self._bucket(qk)]
        qi = np.flatnonzero(cur >= 0)
        cur = cur[qi]
        found_q, found_r = [], []
        while len(cur):
            eq = self._keys[cur] == qk[qi]
            found_q.append(qi[eq])
            found_r.append(cur[eq])
            cur = self._next[cur]
            more = cur >= 0
            qi, cur = qi[more], cur[more]
        if not found_q:
            return qi, cur
        return np.concatenate(found_q), np.concatenate(found_r)

    def _hits(self, frames, xz, radius, margin, ignore_owner, first_only=False, compiled=None):
        """(query sample indices, stored owners) of the overlapping (query, stored) pairs
        (``first_only``: at least the first, when there is one). ``compiled`` None: the numba
        kernel when :data:`ENABLED`."""
        frames = np.asarray(frames, dtype=np.int64)
        xz = np.asarray(xz, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)
        n = len(frames)
        if n == 0 or self._n == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        self._check_cell(radius, margin)
        if ENABLED if compiled is None else compiled:
            shift = np.uint64(64 - (len(self._head).bit_length() - 1))
            return _hits_compiled(frames, np.ascontiguousarray(xz), np.ascontiguousarray(radius), float(margin),
                                  -1 if ignore_owner is None else int(ignore_owner), bool(first_only), self.cell,
                                  self._keys, self._rows, self._next, self._head, self._version, shift, self._GOLDEN)
        ij = np.floor(xz / self.cell).astype(np.int64)
        qk = _key(frames[:, None], ij[:, :1] + _DI[None], ij[:, 1:] + _DJ[None]).reshape(-1)
        k, row = self._matches(qk)
        q = k // 9
        other = self._rows[row]
        d = np.hypot(other[:, 0] - xz[q, 0], other[:, 1] - xz[q, 1])
        bad = (d < other[:, 2] + radius[q] + margin) & (other[:, 4] == self._versions(other[:, 3]))
        if ignore_owner is not None:
            bad &= other[:, 3] != ignore_owner
        return q[bad], other[bad, 3]
