"""Space-time index of per-frame oriented boxes (Kim, Hwang, Hyun and Lee 2012, section 5.1: "a
simple bounding box test on individual frames").

Every placed patch instance contributes, for each clock frame it covers, one box per character:
the root-relative box of :mod:`runtime.tiling.patch` placed at the root (centre, the box's lateral
and forward axes in the world, half extents, height range). Boxes live in a uniform grid over
(x, z, frame) keyed by one int64, stored as log-structured sorted runs merged like a binary
counter (at most ``max_runs`` runs, so a query does few binary searches, :func:`key_matches`);
removal bumps an owner's version in O(1), merges drop stale rows. A query touches the 3 x 3
cells around each of its boxes at the same frame (the cell is at least twice the largest box
half-diagonal plus the margin), then runs an exact 2-D separating-axis test on the oriented
boxes and an interval test on the heights, all vectorized.

Before any of that, :meth:`coarse_candidates` rejects on the whole-instance box
(x, z and frame ranges of every owner), so a query far from everything costs one comparison
per owner.

Wrap-around (repeating tiles): with ``period_x``/``period_z`` the grid has an integer number of
cells per period, neighbour cells wrap and centre offsets use the minimum image; with
``period_t`` frames wrap modulo the period.
"""
from __future__ import annotations

import math

import numpy as np

from .region import minimum_image

__all__ = ["BoxIndex", "obb_overlap", "box_samples"]


def key_matches(keys: np.ndarray, qk: np.ndarray, qs: np.ndarray):
    """Every stored row whose key equals a query key, for a sorted run ``keys``: returns
    (query sample ``qs[k]`` of each match, row index), the ranges [lo, hi) of equal keys
    expanded without a Python loop."""
    lo = np.searchsorted(keys, qk, side="left")
    hi = np.searchsorted(keys, qk, side="right")
    cnt = hi - lo
    tot = int(cnt.sum())
    if tot == 0:
        return qs[:0], lo[:0]
    q = np.repeat(qs, cnt)
    idx = np.repeat(lo - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt) + np.arange(tot)
    return q, idx


_BITS = 21
_OFF = 1 << (_BITS - 1)
_MASK = (1 << _BITS) - 1
# row columns
CX, CZ, AX, AZ, HX, HZ, YLO, YHI, OWN, VER = range(10)


def obb_overlap(ca, axa, hxa, hza, cb, axb, hxb, hzb, margin=0.0):
    """Vectorized 2-D oriented-box overlap (separating axes): centres (n, 2), unit lateral axes
    (n, 2) = (cos h, -sin h) (the forward axis is (sin h, cos h) = (-lat_z, lat_x)), half
    extents along them (n,). True where the boxes overlap or are closer than ``margin``."""
    ax, az = axa[:, 0], axa[:, 1]           # a lateral; a forward = (-az, ax)
    bx, bz = axb[:, 0], axb[:, 1]
    dx = cb[:, 0] - ca[:, 0]
    dz = cb[:, 1] - ca[:, 1]
    # |a_lat . b_lat| = |ax bx + az bz| (= |a_fwd . b_fwd|), |a_lat . b_fwd| = |az bx - ax bz| (= |a_fwd . b_lat|)
    cc = np.abs(ax * bx + az * bz)
    cs = np.abs(az * bx - ax * bz)
    rb_on_alat = hxb * cc + hzb * cs
    rb_on_afwd = hxb * cs + hzb * cc
    ra_on_blat = hxa * cc + hza * cs
    ra_on_bfwd = hxa * cs + hza * cc
    sep = np.abs(dx * ax + dz * az) >= hxa + rb_on_alat + margin
    sep |= np.abs(-dx * az + dz * ax) >= hza + rb_on_afwd + margin
    sep |= np.abs(dx * bx + dz * bz) >= hxb + ra_on_blat + margin
    sep |= np.abs(-dx * bz + dz * bx) >= hzb + ra_on_bfwd + margin
    return ~sep


def box_samples(xz, heading, box):
    """World boxes for root positions (n, 2), headings (n,) and root-relative boxes (n, 6).
    Returns (centre (n, 2), lateral axis (n, 2), hx (n,), hz (n,), ylo (n,), yhi (n,))."""
    c = np.cos(heading)
    s = np.sin(heading)
    lx = 0.5 * (box[:, 0] + box[:, 3])
    lz = 0.5 * (box[:, 2] + box[:, 5])
    # rotate_xz((lx, lz), h) = (c lx + s lz, -s lx + c lz)
    cen = np.stack([xz[:, 0] + c * lx + s * lz, xz[:, 1] - s * lx + c * lz], 1)
    lat = np.stack([c, -s], 1)
    return cen, lat, 0.5 * (box[:, 3] - box[:, 0]), 0.5 * (box[:, 5] - box[:, 2]), box[:, 1], box[:, 4]


class BoxIndex:
    def __init__(self, cell: float = 2.0, origin=(0.0, 0.0), period_x: float | None = None,
                 period_z: float | None = None, period_t: int | None = None, max_half_diag: float = 0.95,
                 max_runs: int = 3):
        self.origin = np.asarray(origin, dtype=np.float64)
        self.period = [period_x, period_z]
        self.nx = self.nz = None
        cx = cz = float(cell)
        if period_x:
            self.nx = int(math.floor(period_x / cell))
            cx = period_x / self.nx
        if period_z:
            self.nz = int(math.floor(period_z / cell))
            cz = period_z / self.nz
        if (self.nx is not None and self.nx < 3) or (self.nz is not None and self.nz < 3):
            raise ValueError(f"a wrapped period must hold at least 3 cells of {cell} m")
        self.cell = np.array([cx, cz])
        self.period_t = int(period_t) if period_t else None
        self.max_half_diag = float(max_half_diag)
        self.max_runs = int(max_runs)
        self._runs: list[tuple[np.ndarray, np.ndarray]] = []
        self._version = np.zeros(64)
        # coarse whole-owner boxes: xmin, xmax, zmin, zmax, fmin, fmax
        self._coarse = np.full((64, 6), np.nan)
        self._live = np.zeros(64, bool)
        self.stats = {"coarse_rejects": 0, "queries": 0, "pairs": 0}

    # -- internals ---------------------------------------------------------------------------------
    def _cells(self, xz):
        ij = np.floor((xz - self.origin) / self.cell).astype(np.int64)
        if self.nx:
            ij[:, 0] %= self.nx
        if self.nz:
            ij[:, 1] %= self.nz
        return ij

    def _frames(self, f):
        f = np.asarray(f, np.int64)
        return f % self.period_t if self.period_t else f

    @staticmethod
    def _key(frame, ix, iz):
        return (np.asarray(frame, np.int64) << (2 * _BITS)) | (((ix + _OFF) & _MASK) << _BITS) | ((iz + _OFF) & _MASK)

    def _grow(self, owner):
        if owner >= len(self._version):
            n = max(owner + 1, 2 * len(self._version))
            self._version = np.concatenate([self._version, np.zeros(n - len(self._version))])
            self._coarse = np.concatenate([self._coarse, np.full((n - len(self._coarse), 6), np.nan)])
            self._live = np.concatenate([self._live, np.zeros(n - len(self._live), bool)])

    def _wrap_delta(self, d):
        for k in (0, 1):
            p = self.period[k]
            if p:
                d[:, k] = minimum_image(d[:, k], p)
        return d

    # -- updates ---------------------------------------------------------------------------------
    def insert(self, owner: int, frames, cen, lat, hx, hz, ylo, yhi) -> None:
        frames = self._frames(frames)
        n = len(frames)
        owner = int(owner)
        self._grow(owner)
        self._live[owner] = True
        if n == 0:
            self._coarse[owner] = np.nan
            return
        hd = float(np.sqrt(np.max(hx * hx + hz * hz)))
        if hd > self.max_half_diag:
            raise ValueError(f"box half-diagonal {hd:.2f} m exceeds the index limit {self.max_half_diag} m")
        r = np.sqrt(hx * hx + hz * hz)
        self._coarse[owner] = [np.min(cen[:, 0] - r), np.max(cen[:, 0] + r), np.min(cen[:, 1] - r),
                               np.max(cen[:, 1] + r), frames.min(), frames.max()]
        ij = self._cells(cen)
        keys = self._key(frames, ij[:, 0], ij[:, 1])
        order = np.argsort(keys, kind="stable")
        rows = np.column_stack([cen, lat, hx, hz, ylo, yhi, np.full(n, float(owner)), np.full(n, self._version[owner])])
        self._runs.append((keys[order], rows[order]))
        while len(self._runs) > 1 and (len(self._runs[-2][0]) <= 2 * len(self._runs[-1][0]) or len(self._runs) > self.max_runs):
            (k1, r1), (k2, r2) = self._runs[-2], self._runs[-1]
            keys = np.concatenate([k1, k2])
            rows = np.concatenate([r1, r2])
            live = rows[:, VER] == self._version[rows[:, OWN].astype(np.int64)]
            keys, rows = keys[live], rows[live]
            o = np.argsort(keys, kind="stable")
            self._runs[-2:] = [(keys[o], rows[o])] if len(keys) else []

    def remove_owner(self, owner: int) -> None:
        owner = int(owner)
        if owner < len(self._version):
            self._version[owner] += 1
            self._live[owner] = False
            self._coarse[owner] = np.nan

    # -- queries ---------------------------------------------------------------------------------
    def owner_extents(self, owners) -> np.ndarray:
        """Whole-instance boxes (xmin, xmax, zmin, zmax, frame min, frame max) of ``owners``
        (rows of NaN for owners removed or never inserted)."""
        return self._coarse[owners]

    def coarse_candidates(self, cen, hx, hz, frames, margin=0.0):
        """Owners whose whole-instance box overlaps the query's (no wrap: all live owners
        when wrapping, since the coarse box would need images)."""
        live = np.flatnonzero(self._live)
        if len(cen) == 0 or len(live) == 0:
            return live[:0]
        if self.nx or self.nz or self.period_t:
            return live
        r = np.sqrt(hx * hx + hz * hz)
        q = (np.min(cen[:, 0] - r) - margin, np.max(cen[:, 0] + r) + margin, np.min(cen[:, 1] - r) - margin,
             np.max(cen[:, 1] + r) + margin, frames.min(), frames.max())
        c = self._coarse[live]
        ok = (c[:, 0] <= q[1]) & (c[:, 1] >= q[0]) & (c[:, 2] <= q[3]) & (c[:, 3] >= q[2]) & (c[:, 4] <= q[5]) & (c[:, 5] >= q[4])
        return live[ok]

    def query(self, frames, cen, lat, hx, hz, ylo, yhi, margin=0.0, ignore=None, first_only=True,
              return_owners=False):
        """Do the query boxes overlap stored boxes at the same frame?

        ``first_only``: return a bool as soon as one pair overlaps; else a bool per query box
        (and with ``return_owners`` the set of owners hit). ``ignore``: owner ids to skip.
        """
        frames = self._frames(frames)
        n = len(frames)
        self.stats["queries"] += 1
        empty = False if first_only else np.zeros(n, bool)
        if n == 0 or not self._runs:
            return (empty, set()) if return_owners else empty
        cand = self.coarse_candidates(cen, hx, hz, frames, margin)
        candset = np.zeros(len(self._version), bool)
        candset[cand] = True
        if ignore is not None and len(cand):
            ig = np.fromiter(ignore, np.int64, len(ignore)) if isinstance(ignore, (set, frozenset, list, tuple)) \
                else np.asarray(ignore, np.int64).reshape(-1)
            candset[ig[ig < len(candset)]] = False
            cand = cand[candset[cand]]
        if len(cand) == 0:
            self.stats["coarse_rejects"] += 1
            return (empty, set()) if return_owners else empty
        if np.min(self.cell) < 2 * self.max_half_diag + margin:
            raise ValueError(f"box index cell {self.cell.min():.2f} m is smaller than twice the largest half-diagonal plus margin")
        ij = self._cells(cen)
        di = np.array([-1, -1, -1, 0, 0, 0, 1, 1, 1])
        dj = np.array([-1, 0, 1, -1, 0, 1, -1, 0, 1])
        ci = ij[:, :1] + di[None]
        cj = ij[:, 1:] + dj[None]
        if self.nx:
            ci %= self.nx
        if self.nz:
            cj %= self.nz
        qk = self._key(frames[:, None], ci, cj).reshape(-1)
        qs = np.repeat(np.arange(n), 9)
        hit = np.zeros(n, bool)
        owners = set()
        for keys, rows in self._runs:
            # (binary searches of all 9 n keys cost less than de-duplicating them first)
            q, idx = key_matches(keys, qk, qs)
            if len(q) == 0:
                continue
            other = rows[idx]
            own = other[:, OWN].astype(np.int64)
            ok = (other[:, VER] == self._version[own]) & candset[own]
            if not ok.any():
                continue
            q, other, own = q[ok], other[ok], own[ok]
            ok = (other[:, YLO] < yhi[q]) & (ylo[q] < other[:, YHI])
            q, other, own = q[ok], other[ok], own[ok]
            if len(q) == 0:
                continue
            self.stats["pairs"] += len(q)
            d = self._wrap_delta(other[:, [CX, CZ]] - cen[q])
            bad = obb_overlap(np.zeros_like(d), lat[q], hx[q], hz[q], d, other[:, [AX, AZ]], other[:, HX], other[:, HZ], margin)
            if bad.any():
                if first_only and not return_owners:
                    return True
                hit[q[bad]] = True
                owners.update(int(o) for o in np.unique(own[bad]))
        if first_only:
            res = bool(hit.any())
        else:
            res = hit
        return (res, owners) if return_owners else res
