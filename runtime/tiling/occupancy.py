"""What a tiling occupies in space-time, and the collision queries of ``IsValid`` (Kim, Hwang,
Hyun and Lee 2012, section 5.1: a bounding box test on individual frames).

A patch instance (or candidate) is resampled on the clock (``fps``) into one oriented box per
character per frame (:meth:`Occupancy.samples`). The committed boxes live in a
:class:`~runtime.tiling.boxindex.BoxIndex`; obstacles are tested directly. Queries:
:meth:`Occupancy.collides` (one candidate), :meth:`Occupancy.first_free` (the first free one of
a list, one batched query) and :meth:`Occupancy.rigid_batch_free` (rigidly placed
single-fragment patches, every sample built in one vectorized pass, optionally with a braking
look-ahead after each).
"""
from __future__ import annotations

import math

import numpy as np

from .boxindex import BoxIndex, box_samples, obb_overlap
from .region import minimum_image

__all__ = ["Occupancy", "braking"]


def braking(k, n):
    """Distance (in frames of the last velocity) covered ``k`` frames into a stop that takes
    ``n`` frames with constant deceleration."""
    k = np.minimum(np.asarray(k, np.float64), n)
    return k - 0.5 * k * k / n


class Occupancy:
    """The space-time boxes of a tiling in ``region`` with ``obstacles``.

    Args:
        prepared: the :class:`~runtime.tiling.prepared.PreparedLibrary`.
        region: the :class:`~runtime.tiling.region.Region` (clock frames ``F0..F1``; wrapping).
        obstacles: :class:`~runtime.tiling.region.Obstacle` s.
        config: the :class:`~runtime.tiling.config.TilerConfig` (``fps``, ``margin``, ``cell``,
            ``max_query_margin``).
    """

    def __init__(self, prepared, region, obstacles, config):
        self.lib = prepared
        self.region = region
        self.obstacles = list(obstacles)
        self.margin = config.margin
        self.fps = config.fps
        self.F0 = int(round(region.t0 * self.fps))
        self.F1 = int(round(region.t1 * self.fps))
        w, h = region.size
        self.period = np.array([w, h]) if region.wrap_space else None
        hd = max(pp.half_diag for pp in prepared.patches)
        cell = config.cell or (2 * hd + max(config.margin, config.max_query_margin) + 0.05)
        self.index = BoxIndex(cell, origin=(region.x0, region.z0), max_half_diag=hd + 1e-6,
                              period_x=w if region.wrap_space else None, period_z=h if region.wrap_space else None,
                              period_t=(self.F1 - self.F0) if region.wrap_time else None)

    def samples(self, c):
        """Clock-frame samples of a candidate or instance ``c`` (cached on it): (frames, frag,
        source index (float), xz, heading, box centre, lateral axis, hx, hz, ylo, yhi); frames
        inside the scene only (or wrapped)."""
        if c.samples is not None:
            return c.samples
        pp = self.lib.patches[c.p]
        fs = pp.frag_start
        fr, fg, si = [], [], []
        for k in range(pp.K):
            a, b = fs[k], fs[k + 1]
            tau = c.time[a:b]
            q0 = math.ceil(tau[0] * self.fps - 1e-6)
            q1 = math.ceil(tau[-1] * self.fps - 1e-6)
            if not self.region.wrap_time:
                q0, q1 = max(q0, self.F0), min(q1, self.F1 + 1)
            if q1 <= q0:
                continue
            q = np.arange(q0, q1)
            fr.append(q)
            fg.append(np.full(len(q), k))
            si.append(a + np.interp(q / self.fps, tau, np.arange(b - a, dtype=np.float64)))
        if fr:
            frames = np.concatenate(fr)
            frag = np.concatenate(fg)
            s = np.concatenate(si)
        else:
            frames = np.zeros(0, np.int64)
            frag = np.zeros(0, np.int64)
            s = np.zeros(0)
        i0 = np.floor(s).astype(np.int64)
        i1 = np.minimum(i0 + 1, pp.N - 1)
        w = (s - i0)[:, None]
        xz = c.xz[i0] * (1 - w) + c.xz[i1] * w
        hd = c.heading[i0] * (1 - w[:, 0]) + c.heading[i1] * w[:, 0]
        box = pp.box[np.rint(s).astype(np.int64)]
        c.samples = (frames, frag, s, xz, hd) + box_samples(xz, hd, box)
        return c.samples

    def obstacle_hits(self, frames, cen, lat, hx, hz, ylo, margin):
        """Per obstacle, a bool per box sample: does it overlap that obstacle (footprint within
        ``margin``, and the box's bottom below the obstacle's top)?"""
        n = len(frames)
        for ob in self.obstacles:
            oc, oh = ob.at(frames - self.F0)
            d = minimum_image(oc - cen, self.period)
            olat = np.stack([np.cos(oh), -np.sin(oh)], 1)
            yield obb_overlap(np.zeros_like(d), lat, hx, hz, d, olat, np.full(n, ob.half[0]),
                              np.full(n, ob.half[1]), margin) & (ylo < ob.height)

    def _bad_counts(self, owner, frames, cen, lat, hx, hz, ylo, yhi, margin, nb, ignore=None):
        """Colliding samples per owner (``nb`` owners): obstacles, then one index query."""
        bad = np.zeros(nb, np.int64)
        for hit in self.obstacle_hits(frames, cen, lat, hx, hz, ylo, margin):
            bad += np.bincount(owner[hit], minlength=nb)
        if len(frames):
            hit = self.index.query(frames, cen, lat, hx, hz, ylo, yhi, margin=margin, first_only=False, ignore=ignore)
            bad += np.bincount(owner[hit], minlength=nb)
        return bad

    def rigid_batch_free(self, ps, places, margin: float | None = None, counts: bool = False, probe: int = 0,
                         ignore=None):
        """:meth:`first_free` for rigidly placed *single-fragment* patches, with every
        candidate's clock samples built in one vectorized pass (no per-candidate Python).

        ``probe`` > 0 also extrapolates each candidate ``probe`` frames past its end (braking to
        a stop from its last velocity, last box) and returns ``(first free, main hits, probe
        hits)``: a look-ahead for room to stop safely after the patch."""
        ps = np.asarray(ps, np.int64)
        pl = np.asarray(places, np.float64).reshape(-1, 4)
        n = len(ps)
        if n == 0:
            return (-1, np.zeros(0, np.int64)) if counts else -1
        rxz, rh, rbox, start, t0 = self.lib.rest
        fps = self.fps
        ta = (pl[:, 3] + t0[ps]) * fps                     # source frame 0 on the clock (frames)
        Nf = start[ps + 1] - start[ps]
        q0 = np.ceil(ta - 1e-6).astype(np.int64)
        q1 = np.ceil(ta + (Nf - 1) - 1e-6).astype(np.int64)
        if not self.region.wrap_time:
            q0 = np.maximum(q0, self.F0)
            q1 = np.minimum(q1, self.F1 + 1)
        cnt = np.maximum(q1 - q0, 0)
        tot = int(cnt.sum())
        owner = np.repeat(np.arange(n), cnt)
        q = np.repeat(q0 - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt) + np.arange(tot)
        s = q - ta[owner]
        i0 = np.floor(s).astype(np.int64)
        w = s - i0
        i1 = np.minimum(i0 + 1, Nf[owner] - 1)
        g0 = start[ps][owner] + i0
        g1 = start[ps][owner] + i1
        lxz = rxz[g0] * (1 - w)[:, None] + rxz[g1] * w[:, None]
        th = pl[owner, 2]
        c, sn = np.cos(th), np.sin(th)
        xz = np.stack([c * lxz[:, 0] + sn * lxz[:, 1] + pl[owner, 0], c * lxz[:, 1] - sn * lxz[:, 0] + pl[owner, 1]], 1)
        hd = rh[g0] * (1 - w) + rh[g1] * w + th
        box = rbox[start[ps][owner] + np.rint(s).astype(np.int64)]
        if probe and tot:
            last = np.cumsum(cnt) - 1
            has = cnt >= 2
            li = last[has]
            v = xz[li] - xz[li - 1]
            k = np.tile(np.arange(1, probe + 1), len(li))
            rep = np.repeat(np.arange(len(li)), probe)
            q = np.concatenate([q, q[li][rep] + k])
            xz = np.concatenate([xz, xz[li][rep] + v[rep] * braking(k, probe)[:, None]])
            hd = np.concatenate([hd, hd[li][rep]])
            box = np.concatenate([box, box[li][rep]])
            owner = np.concatenate([owner, n + np.flatnonzero(has)[rep]])
        cen, lat, hx, hz, ylo, yhi = box_samples(xz, hd, box)
        m = self.margin if margin is None else margin
        bad = self._bad_counts(owner, q, cen, lat, hx, hz, ylo, yhi, m, 2 * n if probe else n, ignore)
        if probe:
            main, pr = bad[:n], bad[n:]
            free = np.flatnonzero((main == 0) & (pr == 0))
            return (int(free[0]) if len(free) else -1), main, pr
        free = np.flatnonzero(bad == 0)
        f = int(free[0]) if len(free) else -1
        return (f, bad) if counts else f

    def first_free(self, cands, margin: float | None = None, counts: bool = False):
        """Index of the first candidate (in order) that collides with nothing, -1 if none: one
        batched space-time query for all of them. ``counts``: also return the number of
        colliding samples per candidate."""
        if not cands:
            return (-1, np.zeros(0, np.int64)) if counts else -1
        parts = [self.samples(c) for c in cands]
        owner = np.concatenate([np.full(len(s[0]), k) for k, s in enumerate(parts)])
        cols = [np.concatenate([s[i] for s in parts]) for i in range(11)]
        fr, _, _, _, _, cen, lat, hx, hz, ylo, yhi = cols
        m = self.margin if margin is None else margin
        bad = self._bad_counts(owner, fr, cen, lat, hx, hz, ylo, yhi, m, len(cands))
        free = np.flatnonzero(bad == 0)
        f = int(free[0]) if len(free) else -1
        return (f, bad) if counts else f

    def collides(self, cand, ignore=None, margin: float | None = None) -> bool:
        """Does ``cand`` overlap an obstacle or a box in the index (owners in ``ignore``
        aside)?"""
        fr, _, _, _, _, cen, lat, hx, hz, ylo, yhi = self.samples(cand)
        if len(fr) == 0:
            return False
        m = self.margin if margin is None else margin
        if any(hit.any() for hit in self.obstacle_hits(fr, cen, lat, hx, hz, ylo, m)):
            return True
        return bool(self.index.query(fr, cen, lat, hx, hz, ylo, yhi, margin=m, ignore=ignore))

    def owners_hit(self, cand, ignore=None) -> set:
        """The index owners whose boxes ``cand`` overlaps (margin: the config's)."""
        fr, _, _, _, _, cen, lat, hx, hz, ylo, yhi = self.samples(cand)
        _, owners = self.index.query(fr, cen, lat, hx, hz, ylo, yhi, margin=self.margin, first_only=False,
                                     return_owners=True, ignore=ignore)
        return owners

    def insert(self, owner: int, c) -> None:
        """Put the boxes of committed instance ``c`` into the index under ``owner``."""
        fr, _, _, _, _, cen, lat, hx, hz, ylo, yhi = self.samples(c)
        self.index.insert(owner, fr, cen, lat, hx, hz, ylo, yhi)

    def reserve(self, owner: int, frames, xz, heading, box) -> None:
        """(Re)place extra boxes owned by ``owner`` (not an instance): e.g. where a character is
        expected to be just after its last committed frame."""
        self.index.remove_owner(owner)
        cen, lat, hx, hz, ylo, yhi = box_samples(np.asarray(xz, np.float64), np.asarray(heading, np.float64), box)
        self.index.insert(owner, frames, cen, lat, hx, hz, ylo, yhi)

