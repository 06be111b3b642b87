"""Nobody may be cornered (interactive tiling, Kim, Hwang, Hyun and Lee 2012, section 5.3).

A multi-character instance lasts several seconds, far beyond everyone's horizon, so (a) it is
only committed if it keeps clear of the park box of every character it does not carry (where
that one would stop: for good if it stands, else that walker must still have a way on that
never crosses the instance's future path, a one-patch look-ahead), and (b) a single-character
candidate is preferred only if neither its path (sampled) nor its exit nor its park box lies on
a spot a live interaction passes later (``berth``; ``near`` more, or the look-ahead from its
exit, near an interaction); one that is not parkable is taken only if it stops clear (its exit
and park box keep the berth: walking through a spot an interaction passes later is fine,
stopping there is not) while any such candidate exists.

Every character also *reserves* where it will be just after its tail (its last box carried on
at the last velocity, braking to a stop over ``probe`` frames, then held ``hold`` frames), so
others keep out of the way it must go on; the stopped box is its *park box*.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .boxindex import box_samples, obb_overlap
from .occupancy import braking

__all__ = ["Cornering", "CorneringSettings"]


@dataclass
class CorneringSettings:
    """``probe``: frames of braking after a candidate that must be free; ``hold``: frames a
    reservation holds the stopped box; ``clearance``: metres kept from other characters' boxes
    beyond the config's margin; ``park``: whether to guard against being cornered at all;
    ``berth``: metres more kept from live interactions; ``near``: metres more still for a
    candidate to need no look-ahead; ``max_lookaheads``: look-aheads per extension."""
    probe: int
    hold: int
    clearance: float
    park: bool
    berth: float
    near: float
    max_lookaheads: int


class Cornering:
    """Reservations, park boxes and the look-aheads against live multi-character instances.

    Args:
        state: the :class:`~runtime.tiling.state.TilingState`.
        entries: the :class:`~runtime.tiling.entries.EntryTables`.
        roster: the :class:`~runtime.tiling.roster.Roster`.
        tick: the shared :class:`~runtime.tiling.tick.TickState` (work accounting).
        settings: the :class:`CorneringSettings`.
    """

    def __init__(self, state, entries, roster, tick, settings: CorneringSettings):
        self.s = settings
        self.state, self.lib, self.fps = state, state.lib, state.fps
        self.entries, self.roster, self.tick = entries, roster, tick
        self.lookaheads_left = settings.max_lookaheads
        self.multi: set = set()                  # live multi-character instances (long: they outlast horizons)
        # per character: where it would stand after braking at its tail ("park" box, from frame park_q on)
        self.park_q = np.zeros(0, np.int64)
        self.park_box = np.zeros((0, 6))          # centre x, z, lateral axis x, z, hx, hz

    def add_character(self) -> None:
        self.park_q = np.append(self.park_q, 0)
        self.park_box = np.concatenate([self.park_box, np.zeros((1, 6))])

    def reserve(self, cid: int) -> None:
        """Reserve where character ``cid`` will be just after its tail (see the module
        docstring) and set its park box."""
        if not self.s.probe:
            return
        st = self.state
        iid, port = self.roster.tail[cid]
        inst = st.inst[iid]
        pp = self.lib.patches[inst.p]
        k = port // 2
        b = pp.frag_start[k + 1]
        q_end = inst.time[b - 1] * self.fps
        v = (inst.xz[b - 1] - inst.xz[b - 2]) / max((inst.time[b - 1] - inst.time[b - 2]) * self.fps, 1e-6)
        q0 = int(math.ceil(q_end - 1e-6))
        q = np.arange(q0, q0 + self.s.probe + self.s.hold)
        dt = braking(q - q_end, self.s.probe)[:, None]
        xz = inst.xz[b - 1] + v * dt
        hd = np.full(len(q), inst.heading[b - 1])
        box = np.repeat(pp.box[b - 1:b], len(q), 0)
        st.occupancy.reserve(self.roster.res_owner[cid], q, xz, hd, box)
        cen, lat, hx, hz, _, _ = box_samples(xz[-1:], hd[-1:], box[-1:])
        self.park_q[cid] = q0 + self.s.probe
        self.park_box[cid] = [cen[0, 0], cen[0, 1], lat[0, 0], lat[0, 1], hx[0], hz[0]]

    def park_mask(self, ps, places, extra: float = 0.0):
        """Per rigid single-character candidate: can the character stop after it and stand
        there? Boxes along it (start, a third, two thirds, exit: each from its frame on) and its
        park box (the exit box carried on braking for ``probe`` frames, from the stop on) must
        keep ``berth`` metres more than the clearance from the live multi-character instances
        -- the only ones reaching far beyond everyone's horizon: a character that walks onto or
        stops on a spot an interaction will pass later could be cornered there. Vectorized
        over the candidates. Returns (parkable, parkable with ``extra`` metres more berth, can
        stop clear: the exit and park box alone keep the berth -- a character that walks through
        a spot an interaction passes later but stops clear of its way is not cornered by it)."""
        n = len(ps)
        ok = np.ones(n, bool)
        far = np.ones(n, bool)
        stop = np.ones(n, bool)
        if not self.s.park or not self.multi or n == 0:
            return ok, far, stop
        st = self.state
        # whole-instance boxes first: most of the time no interaction is anywhere near
        co = st.occupancy.index.owner_extents(sorted(self.multi))
        c0 = places[:, :2].mean(0)
        r = 7.0 + self.s.berth + extra + float(np.max(np.hypot(*(places[:, :2] - c0).T)))
        if not np.any((co[:, 0] - r <= c0[0]) & (c0[0] <= co[:, 1] + r) & (co[:, 2] - r <= c0[1]) & (c0[1] <= co[:, 3] + r)
                      & (co[:, 5] >= np.min(places[:, 3]) * self.fps)):
            return ok, far, stop
        rxz, rh, rbox, start, t0 = self.lib.rest
        e = start[ps + 1] - 1
        th = places[:, 2]
        cs_, sn_ = np.cos(th), np.sin(th)

        def world(g):
            return np.stack([cs_ * rxz[g, 0] + sn_ * rxz[g, 1] + places[:, 0], cs_ * rxz[g, 1] - sn_ * rxz[g, 0] + places[:, 1]], 1)
        q_start = (places[:, 3] + t0[ps]) * self.fps
        xe, xp = world(e), world(np.maximum(e - 1, start[ps]))
        mid = xe.mean(0)
        M = self.multi_boxes(int(q_start.min()), mid, 4.0 + self.s.berth + extra + float(np.max(np.hypot(*(xe - mid).T))))
        if M is None:
            return ok, far, stop
        mf, mc, ml, mx, mz = M
        mg = st.cfg.margin + self.s.clearance + self.s.berth
        # points along the patch (its "shadow": no spot an interaction will cross later), the
        # exit, and the park spot after braking
        # the four points along every candidate in one batch (rows k * n + candidate)
        g = np.concatenate([start[ps] + np.floor(f * (e - start[ps])).astype(np.int64) for f in (0.0, 0.33, 0.67, 1.0)])
        c4, s4, p4 = np.tile(cs_, 4), np.tile(sn_, 4), np.tile(places, (4, 1))
        w4 = np.stack([c4 * rxz[g, 0] + s4 * rxz[g, 1] + p4[:, 0], c4 * rxz[g, 1] - s4 * rxz[g, 0] + p4[:, 1]], 1)
        cen, lat, hx, hz, _, _ = box_samples(w4, rh[g] + np.tile(th, 4), rbox[g])
        q0 = np.floor(np.tile(q_start, 4) + (g - np.tile(start[ps], 4)) + 1e-6)
        # and the park box (the exit box carried on braking)
        last = slice(3 * n, 4 * n)
        cen = np.concatenate([cen, cen[last] + (xe - xp) * float(braking(self.s.probe, self.s.probe))])
        lat = np.concatenate([lat, lat[last]])
        hx, hz = np.concatenate([hx, hx[last]]), np.concatenate([hz, hz[last]])
        q0 = np.concatenate([q0, q0[last] + self.s.probe])
        cand = np.tile(np.arange(n), 5)
        a, bb = np.nonzero((mf[None, :] >= q0[:, None]) & (
            np.hypot(mc[None, :, 0] - cen[:, None, 0], mc[None, :, 1] - cen[:, None, 1]) < np.hypot(hx, hz)[:, None] + np.hypot(mx, mz)[None, :] + mg + extra))
        if len(a):
            hit = obb_overlap(cen[a], lat[a], hx[a], hz[a], mc[bb], ml[bb], mx[bb], mz[bb], mg + extra)
            far[cand[a[hit]]] = False
            a, bb = a[hit], bb[hit]
            hit = obb_overlap(cen[a], lat[a], hx[a], hz[a], mc[bb], ml[bb], mx[bb], mz[bb], mg)
            ok[cand[a[hit]]] = False
            stop[cand[a[hit][a[hit] >= 3 * n]]] = False
        return ok, far & ok, stop

    def exit_lookahead(self, cand) -> bool:
        """:meth:`lookahead` from the exit of a single-character candidate against the live
        multi-character instances near it (at most ``lookaheads_left`` more this extension)."""
        if self.lookaheads_left <= 0:                   # bounded work per extension
            return False
        self.lookaheads_left -= 1
        pp = self.lib.patches[cand.p]
        f = pp.port_frame[1]
        row = np.zeros(10)
        row[:4] = cand.xz[f, 0], cand.xz[f, 1], cand.heading[f], cand.time[f]
        row[7] = pp.port_class[1]
        M = self.multi_boxes(int(math.floor(cand.time[f] * self.fps)), cand.xz[f], 4.5)
        return M is None or self.lookahead(row, M)

    def multi_park_ok(self, cand, carried) -> bool:
        """A multi-character instance outlasts everyone's horizon, so it must not corner anyone
        it does not carry: it keeps clear of the park box of every other character (where that
        one would stop and stand, from then on), unless that character walks and still has a
        way on from its tail that keeps clear of the new instance (:meth:`lookahead`)."""
        if not self.s.park:
            return True
        st = self.state
        others = np.setdiff1d(np.arange(self.roster.n), np.asarray(list(carried), np.int64))
        if not len(others):
            return True
        fr, _, _, _, _, cen, lat, hx, hz = st.occupancy.samples(cand)[:9]
        pb = self.park_box[others]
        rp = np.hypot(pb[:, 4], pb[:, 5])
        mg = st.cfg.margin + self.s.clearance
        near = (fr[:, None] >= self.park_q[others][None, :]) & (
            np.hypot(cen[:, None, 0] - pb[None, :, 0], cen[:, None, 1] - pb[None, :, 1]) < np.hypot(hx, hz)[:, None] + rp[None, :] + mg)
        a, b = np.nonzero(near)
        if not len(a):
            return True
        hit = obb_overlap(cen[a], lat[a], hx[a], hz[a], pb[b, :2], pb[b, 2:4], pb[b, 4], pb[b, 5], mg)
        o = np.argsort(fr, kind="stable")
        M = (fr[o], cen[o], lat[o], hx[o], hz[o])
        for k in np.unique(b[hit]):
            row = st.dang.row(self.roster.tail[int(others[k])])
            if not self.entries.mobile.get(int(row[7]), False) or not self.lookahead(row, M):
                return False
        return True

    def multi_boxes(self, q0, pc, reach):
        """Boxes of the live multi-character instances from clock frame ``q0`` on within
        ``reach`` of ``pc``, sorted by frame: (frames, centre, lateral axis, hx, hz) or None."""
        st = self.state
        parts = []
        for iid in sorted(self.multi):
            inst = st.inst.get(iid)
            if inst is None:
                continue
            f2, _, _, _, _, c2, l2, x2, z2 = st.occupancy.samples(inst)[:9]
            m = (f2 >= q0) & (np.hypot(c2[:, 0] - pc[0], c2[:, 1] - pc[1]) < reach)
            if m.any():
                parts.append((f2[m], c2[m], l2[m], x2[m], z2[m]))
        if not parts:
            return None
        M = [np.concatenate([p[i] for p in parts]) for i in range(5)]
        o = np.argsort(M[0], kind="stable")
        return tuple(x[o] for x in M)

    def lookahead(self, row, M, shadow: bool = True) -> bool:
        """Is there a single-character patch from the exit ``row`` (x, z, dir, time, .., class)
        whose boxes keep clear of the boxes ``M`` (sorted by frame) from their own frame on
        (never on a spot an interaction passes later; with ``shadow=False`` only on the same
        frame, every 5th), its last box held from its end on (the character could stop there)?"""
        self.tick.work += 1.5
        c = self.entries.get(int(row[7]))
        if c is None:
            return False
        sel = np.flatnonzero(~c["multi"])
        if not len(sel):
            return False
        rxz, rh, rbox, start, t0 = self.lib.rest
        ps = c["p"][sel]
        px, pz, th, cs_, sn_ = self.entries.aligned_origins(c, sel, row)
        fps = self.fps
        ta = (row[3] - c["ptime"][sel] + t0[ps]) * fps
        Nf = start[ps + 1] - start[ps]
        q0 = np.ceil(ta - 1e-6).astype(np.int64)
        q1 = np.ceil(ta + (Nf - 1) - 1e-6).astype(np.int64)
        cnt = np.maximum(q1 - q0, 1)
        n = len(ps)
        own = np.repeat(np.arange(n), cnt)
        q = np.repeat(q0 - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt) + np.arange(int(cnt.sum()))
        s_ = np.clip(q - ta[own], 0, Nf[own] - 1)
        i0 = np.floor(s_).astype(np.int64)
        w = s_ - i0
        i1 = np.minimum(i0 + 1, Nf[own] - 1)
        g0, g1 = start[ps][own] + i0, start[ps][own] + i1
        lxz = rxz[g0] * (1 - w)[:, None] + rxz[g1] * w[:, None]
        co, so = cs_[own], sn_[own]
        xz = np.stack([co * lxz[:, 0] + so * lxz[:, 1] + px[own], co * lxz[:, 1] - so * lxz[:, 0] + pz[own]], 1)
        hd = rh[g0] * (1 - w) + rh[g1] * w + th[own]
        cen, lat, hx, hz, _, _ = box_samples(xz, hd, rbox[start[ps][own] + np.rint(s_).astype(np.int64)])
        mg = self.state.cfg.margin + self.s.clearance
        mf, mc, ml, mx, mz = M
        bad = np.zeros(n, bool)
        # every 5th box and the last one of each continuation against the boxes from its frame
        # on (a spot an interaction passes later is no place to be; the last box is held)
        first = np.concatenate([[0], np.cumsum(cnt)[:-1]])
        last = np.cumsum(cnt) - 1
        sel = np.union1d(np.flatnonzero((np.arange(len(q)) - first[own]) % 5 == 0), last)
        later = (mf[None, :] >= q[sel][:, None]) if shadow else (mf[None, :] == q[sel][:, None]) | (
            np.isin(sel, last)[:, None] & (mf[None, :] > q[sel][:, None]))
        a, bb = np.nonzero(later & (
            np.hypot(mc[None, :, 0] - cen[sel, None, 0], mc[None, :, 1] - cen[sel, None, 1])
            < np.hypot(hx[sel], hz[sel])[:, None] + np.hypot(mx, mz)[None, :] + mg))
        if len(a):
            a = sel[a]
            hit = obb_overlap(cen[a], lat[a], hx[a], hz[a], mc[bb], ml[bb], mx[bb], mz[bb], mg)
            bad[own[a[hit]]] = True
        return not bad.all()
