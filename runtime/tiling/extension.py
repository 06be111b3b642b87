"""Extending one character of an interactive tiling by one patch instance at its tail (Kim,
Hwang, Hyun and Lee 2012, section 5.3).

* candidates are the library patches with an entry of the tail's pose class, aligned on the
  tail (Eq. 1-3 hold exactly, nothing deforms) -- or, for multi-character patches, fitted
  rigidly to the tails of the other characters their other entries match (two-point fit), then
  deformed so every entry lands on its tail (only the new patch deforms: the past is pinned);
* they are ordered by the preference function Eq. 7 used as a sampling distribution (Gumbel
  top-k at ``temperature``, i.e. ``F^(1/temperature)`` normalised): ``f1`` the squared distance
  from where the patch leaves the character to its team's target, ``f2`` the squared angle
  between the exit heading and the direction to the target, ``f4`` label costs (e.g. a bonus
  for interaction labels);
* the first valid one (deformation within limits, no box overlap with any committed instance,
  reservation or obstacle in the space-time index) with room to stop after it, and that cannot
  corner anyone (:mod:`.cornering`), is committed. Single-character candidates are queried in
  growing batches (same choice, less work).

When nothing is valid the character's own unplayed last patch is taken back, or the others'
unplayed patches in the way yield, or a few jittered placements are tried, or any patch of its
pose class that overlaps no committed motion and no obstacle is taken (standing idle at the tail
first: the character stays where it is); only when there is none is the least overlapping patch
forced (``stats["forced"]``: the checker will report the overlap).

An extension is a generator (:meth:`Extender.steps`) that yields between its costly steps
(candidate batches, look-aheads, interaction fits), so the tick can pause it and resume it on
the next one (time slicing); if anything was committed or taken back meanwhile, it starts again
in one go before committing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..motion.planar import rotate_xz_scalar, wrap_angle

__all__ = ["Extender", "SearchSettings"]


@dataclass
class SearchSettings:
    """The candidate search of an extension (see :class:`~runtime.tiling.interactive.
    InteractiveTiling` for each field)."""
    horizon: float
    sigma_pos: float
    sigma_dir: float
    top_k: int
    jitter_tries: int
    partner_radius: float
    partner_time: float
    partner_dir: float
    max_singles: int
    clearance: float
    max_retract: int
    max_yields: int
    temperature: float
    first_batch: int


class Extender:
    """Extends characters of an interactive tiling, one patch instance at a time.

    Args:
        state: the :class:`~runtime.tiling.state.TilingState` (its ``rng`` draws everything).
        entries: the :class:`~runtime.tiling.entries.EntryTables`.
        roster: the :class:`~runtime.tiling.roster.Roster`.
        playback: the :class:`~runtime.tiling.playback.Playback` (committed fragments go in).
        cornering: the :class:`~runtime.tiling.cornering.Cornering`.
        tick: the shared :class:`~runtime.tiling.tick.TickState`.
        stats: the tiling's counters (updated in place).
        settings: the :class:`SearchSettings`.
    """

    def __init__(self, state, entries, roster, playback, cornering, tick, stats: dict, settings: SearchSettings):
        self.state = state
        self.lib = state.lib
        self.rng = state.rng
        self.fps = state.fps
        self.entries = entries
        self.roster = roster
        self.playback = playback
        self.cornering = cornering
        self.tick = tick
        self.stats = stats
        self.s = settings

    # -- commit and take back -------------------------------------------------------------------
    def commit(self, cand, chars_by_key: dict) -> None:
        """Commit ``cand``; the characters whose tails it stitches play it."""
        st = self.state
        ro = self.roster
        self.tick.work += 1.5
        self.tick.epoch += 1
        iid = st.commit(cand)
        for j, key in cand.conns:
            cid = chars_by_key.get(key)
            if cid is not None:
                ro.ban[cid] = set()
        for j, key in cand.conns:
            cid = chars_by_key.get(key)
            if cid is None:
                continue
            k = j // 2
            ro.tail[cid] = (iid, 2 * k + 1)
            ro.tail_time[cid] = st.inst[iid].time[st.lib.patches[cand.p].port_frame[2 * k + 1]]
            self.playback.write(cid, iid, cand.p, k, st.occupancy.samples(st.inst[iid]))
            self.cornering.reserve(cid)
        self.stats["extensions"] += 1
        if self.lib.patches[cand.p].K > 1:
            self.stats["multi"] += 1
            self.cornering.multi.add(iid)

    def retract(self, cid: int) -> bool:
        """Take back the character's last instance if it is single-character and has not started
        playing yet (it is in the future, so nothing visible changes); its tail goes back to the
        previous exit and the patch is banned there for the next try."""
        st = self.state
        ro = self.roster
        iid, port = ro.tail[cid]
        inst = st.inst.get(iid)
        if inst is None or len(self.playback.seg[cid]) < 2 or self.lib.patches[inst.p].K != 1 or inst.fixed:
            return False
        if inst.time[0] * self.fps <= self.tick.frame + 2:
            return False
        prev = inst.links[0]
        if prev is None:
            return False
        self.playback.take_back(cid, iid)
        st.remove(iid)
        st.history.pop(prev, None)
        ro.tail[cid] = prev
        ro.tail_time[cid] = st.dang.row(prev)[3]
        ro.ban[cid] = {inst.p}
        self.cornering.reserve(cid)
        self.tick.epoch += 1
        self.stats["retracted"] += 1
        return True

    # -- the extension ----------------------------------------------------------------------------
    def extend(self, cid: int, depth: int = 0) -> None:
        """Extend character ``cid`` by one patch instance, in one go."""
        for _ in self.steps(cid, depth, sync=True):
            pass

    def _ranked(self, cid, c, row):
        """Entries of table ``c`` in preference order (Eq. 7 with Gumbel noise), banned
        patches left out."""
        s = self.s
        th = row[2] - c["pdir"]
        cs, sn = np.cos(th), np.sin(th)
        dv = c["exz"] - c["pxz"]
        ex = row[0] + cs * dv[:, 0] + sn * dv[:, 1]
        ez = row[1] - sn * dv[:, 0] + cs * dv[:, 1]
        logf = c["label"].copy()
        tgt = self.roster.target_of(cid)
        if tgt is not None:
            d2 = (ex - tgt[0]) ** 2 + (ez - tgt[1]) ** 2
            want = np.arctan2(tgt[0] - ex, tgt[1] - ez)
            da = wrap_angle(c["edir"] + th - want)
            near = d2 < 0.25
            logf -= d2 / s.sigma_pos + np.where(near, 0.0, da * da / s.sigma_dir)
        logf += s.temperature * self.rng.gumbel(size=len(logf))
        if self.roster.ban[cid]:
            logf[np.isin(c["p"], list(self.roster.ban[cid]))] = -np.inf
        order = np.argsort(-logf, kind="stable")
        return order[np.isfinite(logf[order])]

    def steps(self, cid: int, depth: int = 0, sync: bool = False):
        """:meth:`extend` as a generator that yields between its costly steps unless ``sync``."""
        st = self.state
        s = self.s
        ro = self.roster
        epoch = self.tick.epoch
        if depth == 0:
            self.cornering.lookaheads_left = self.cornering.s.max_lookaheads
        key = ro.tail[cid]
        row = st.dang.row(key).copy()
        cls = int(row[7])
        c = self.entries.get(cls)
        chars_by_key = ro.by_tail()
        if c is None:
            raise RuntimeError(f"no patch enters pose class {cls}; the library cannot continue character {cid}")
        order = self._ranked(cid, c, row)
        # pass 1: single-character candidates, placed exactly on the tail (rigid), all tested in
        # one vectorized space-time query; then the multi-character ones in preference order
        single = order[~c["multi"][order]][:s.max_singles]
        multi = order[c["multi"][order]]
        if len(multi):
            # interactions first whenever partners are in place (the fit says so quickly)
            done = yield from self._try_multi(cid, depth, sync, epoch, c, multi, key, row, chars_by_key)
            if done:
                return
        px, pz, ths, _, _ = self.entries.aligned_origins(c, single, row)
        places = np.column_stack([px, pz, ths, row[3] - c["ptime"][single]])
        ps = c["p"][single]
        own = {ro.res_owner[cid]}
        conns = [[(int(c["j"][k]), key)] for k in single]
        cand, hits = yield from self._choose_single(ps, places, conns, own, sync)
        if self.tick.epoch != epoch:
            # paused, and the world moved on: the choice stands if it (and room to stop after
            # it) is still clear -- one query; else the search runs again, in one go
            if cand is not None and ro.tail[cid] == key:
                _, h1, p1 = st.occupancy.rigid_batch_free([cand.p], [cand.place], margin=st.cfg.margin + s.clearance,
                                                          probe=self.cornering.s.probe, ignore=own)
                self.tick.work += 1.2
                if h1[0] == 0 and p1[0] == 0:
                    self.commit(cand, chars_by_key)
                    return
            yield from self.steps(cid, depth, sync=True)
            return
        if cand is not None:
            self.commit(cand, chars_by_key)
            return
        yield from self._no_valid_candidate(cid, depth, c, single, ps, places, hits, key, row, own, chars_by_key)

    def _try_multi(self, cid, depth, sync, epoch, c, multi, key, row, chars_by_key):
        """The ``top_k`` preferred multi-character candidates whose other entries find partners;
        returns True once the extension is done (committed, or restarted in one go)."""
        st = self.state
        s = self.s
        for k in multi[:s.top_k]:
            p, j = int(c["p"][k]), int(c["j"][k])
            place, forced = self._fit_multi(p, j, key, row, self.entries.align(c, k, row), chars_by_key)
            if forced is None:
                continue
            cand = st.evaluate(p, place, forced=forced, match_others=False)
            self.stats["evaluated"] += 1
            self.tick.work += 2.5
            if not sync:
                yield
                if self.tick.epoch != epoch:
                    yield from self.steps(cid, depth, sync=True)
                    return True
            ign = {self.roster.res_owner[chars_by_key[k2]] for _, k2 in forced}
            if cand.limits_ok and not st.occupancy.collides(cand, margin=st.cfg.margin + s.clearance, ignore=ign) and \
                    self.cornering.multi_park_ok(cand, [chars_by_key[k2] for _, k2 in forced]):
                self.commit(cand, chars_by_key)
                return True
        return False

    def _no_valid_candidate(self, cid, depth, c, single, ps, places, hits, key, row, own, chars_by_key):
        """Nothing fits: the characters whose not-yet-played patches block the least-overlapping
        candidate yield them (bounded per tick), or this character takes back its own last one
        (a different previous patch opens other ways), or jittered placements of the preferred
        ones are tried; else any patch of its pose class that overlaps no committed motion
        (:meth:`_last_resort`); else the least-overlapping one is forced."""
        st = self.state
        s = self.s
        ro = self.roster
        fallback = None
        plans = []
        if len(single):
            b = int(np.argmin(hits))
            fallback = (int(ps[b]), tuple(places[b]), int(c["j"][single[b]]))
        for k in single[:s.top_k]:
            plans.append((int(c["p"][k]), self.entries.align(c, k, row), [(int(c["j"][k]), key)]))
        if fallback is None:
            k = int(np.flatnonzero(~c["multi"])[0])
            fallback = (int(c["p"][k]), self.entries.align(c, k, row), int(c["j"][k]))
        p, place, j = fallback
        best = cand = st.rigid_candidate(p, place, [(j, key)])
        if self.tick.yields < s.max_yields:
            owners = st.occupancy.owners_hit(cand, ignore=own)
            tail_of = {k[0]: i for i, k in enumerate(ro.tail)}
            tail_of.update({r: i for i, r in enumerate(ro.res_owner)})
            yielded = sorted({tail_of[o] for o in owners if o in tail_of and tail_of[o] != cid})
            if yielded and all(o in tail_of for o in owners) and all(self.retract(o) for o in yielded):
                self.tick.yields += len(yielded)
                self.stats["yielded"] += len(yielded)
                if not st.occupancy.collides(cand, ignore=own):
                    self.commit(cand, chars_by_key)
                    return
        if depth < s.max_retract and self.retract(cid):
            while ro.tail_time[cid] < self.tick.t + s.horizon:
                yield from self.steps(cid, depth + 1, sync=True)
            return
        # small jitters of the preferred ones (``jitter_tries`` evaluations in all)
        for n_j in range(s.jitter_tries if depth == 0 else 0):
            if not plans:
                break
            p, place, forced = plans[n_j % len(plans)]
            cand = st.evaluate(p, self._jitter(place), forced=forced, match_others=False)
            self.stats["evaluated"] += 1
            if cand.limits_ok and not st.occupancy.collides(cand, ignore={ro.res_owner[chars_by_key[k2]] for _, k2 in forced}):
                self.commit(cand, chars_by_key)
                return
        cand = self._last_resort(c, row, key, own)
        if cand is not None:
            self.commit(cand, chars_by_key)
            return
        # forced: nothing of its pose class fits anywhere; the candidate that overlaps least
        # (counted: the checker will find the overlap)
        self.stats["forced"] += 1
        self.commit(best, chars_by_key)

    def _last_resort(self, c, row, key, own):
        """Every single-character patch of the tail's pose class, rigid on the tail, standing
        idle ones first (the character stays where it is), then in table order, banned ones
        included: the first that overlaps no committed motion and no obstacle (the config's
        margin, no clearance, no room to stop required), else the first that overlaps only
        others' reservations, else None. One or two vectorized queries."""
        st = self.state
        sel = np.flatnonzero(~c["multi"])
        if not len(sel):
            return None
        sel = sel[np.argsort(~c["stand"][sel], kind="stable")]
        px, pz, ths, _, _ = self.entries.aligned_origins(c, sel, row)
        places = np.column_stack([px, pz, ths, row[3] - c["ptime"][sel]])
        ps = c["p"][sel]
        self.stats["evaluated"] += len(sel)
        self.tick.work += 2.0 + 0.2 * len(sel)
        f = st.occupancy.rigid_batch_free(ps, places, ignore=own)
        if f < 0:
            f = st.occupancy.rigid_batch_free(ps, places, ignore=own | set(self.roster.res_owner))
        if f < 0:
            return None
        return st.rigid_candidate(int(ps[f]), tuple(places[f]), [(int(c["j"][sel[f]]), key)])

    def _choose_single(self, ps, places, conns, own, sync=True):
        """The first single-character candidate (preference order) that is valid with room to
        stop after it (``probe``) and that cannot be cornered by a long multi-character
        instance (:meth:`~runtime.tiling.cornering.Cornering.park_mask`, else
        :meth:`~runtime.tiling.cornering.Cornering.exit_lookahead`); else the first valid one
        with the least obstructed stop (parkable first); else the first that only intrudes on
        others' reservations. Candidates are queried in growing batches (the first
        ``first_batch``, three times as many, then all): the choice is the same as one batch,
        the work usually less. Returns (candidate or None, per-candidate hits of the last
        query). A generator (returns that pair): it yields after each batch and look-ahead
        unless ``sync``."""
        st = self.state
        occ = st.occupancy
        cor = self.cornering
        n = len(ps)
        self.stats["evaluated"] += n
        if n == 0:
            return None, np.zeros(0, np.int64)
        m = st.cfg.margin + self.s.clearance
        park, far, stop = cor.park_mask(ps, places, extra=cor.s.near)
        done = 0
        hits = np.zeros(n, np.int64)
        ph = np.zeros(n, np.int64)
        first_batch = self.s.first_batch
        for nb in sorted({min(first_batch, n), min(3 * first_batch, n), n}):
            # each batch queries only the candidates the previous ones did not
            _, hits[done:nb], ph[done:nb] = occ.rigid_batch_free(ps[done:nb], places[done:nb], margin=m,
                                                                  probe=cor.s.probe, ignore=own)
            self.tick.work += 1.0 + 0.17 * (nb - done)
            free = np.flatnonzero((hits[done:nb] == 0) & (ph[done:nb] == 0)) + done
            for k in free:
                if far[k]:
                    return st.rigid_candidate(int(ps[k]), tuple(places[k]), conns[k]), hits
                if not stop[k]:
                    continue                            # it would stop on an interaction's way
                # near an interaction or unparkable by the quick test: is there a way on after
                # it (bounded lookahead)? A walker cannot turn on the spot, so one step of
                # clearance is not enough near the path of an interaction
                cand = yield from self._with_way_on(ps, places, conns, k, sync)
                if cand is not None:
                    return cand, hits
            done = nb
            if not sync and done < n:
                yield
        ok = np.flatnonzero(hits == 0)                      # free but no room to go on: still better than nothing
        # parkable first, then those that at least stop clear of the interactions' way, then
        # the least obstructed stop
        ok = ok[np.lexsort((ph[ok], ~stop[ok], ~park[ok]))]
        if len(ok):
            i = int(ok[0])
            if not park[i]:
                # every free one may be cornered: look further ahead (a larger, still bounded, budget)
                cor.lookaheads_left = max(cor.lookaheads_left, 3 * cor.s.max_lookaheads)
                for k in ok[:3 * cor.s.max_lookaheads]:
                    if stop[i] and not stop[k]:
                        break
                    cand = yield from self._with_way_on(ps, places, conns, k, sync)
                    if cand is not None:
                        return cand, hits
                self.stats["unparkable"] += 1
            return st.rigid_candidate(int(ps[i]), tuple(places[i]), conns[i]), hits
        f = occ.rigid_batch_free(ps, places, ignore=own)
        self.tick.work += 1.0 + 0.1 * n
        if f < 0:                                           # only others' reservations in the way
            f, hits = occ.rigid_batch_free(ps, places, ignore=set(self.roster.res_owner), counts=True)
            self.tick.work += 1.0 + 0.1 * n
        if f >= 0:
            return st.rigid_candidate(int(ps[f]), tuple(places[f]), conns[f]), hits
        return None, hits

    def _with_way_on(self, ps, places, conns, k, sync):
        """Rigid single-character candidate ``k`` if the character has a way on after it
        (:meth:`~runtime.tiling.cornering.Cornering.exit_lookahead`), else None. A generator
        (returns that): it yields after the look-ahead unless ``sync``."""
        cand = self.state.rigid_candidate(int(ps[k]), tuple(places[k]), conns[k])
        ok = self.cornering.exit_lookahead(cand)
        if not sync:
            yield
        return cand if ok else None

    def _jitter(self, place):
        """A small jitter for the interactive search (a third of Algorithm 2's first range)."""
        x, z, th, t = place
        r = 0.2 * math.sqrt(self.rng.random())
        a = self.rng.uniform(-np.pi, np.pi)
        return (x + r * math.cos(a), z + r * math.sin(a), th + self.rng.uniform(-0.087, 0.087), t + self.rng.uniform(-0.1, 0.1))

    def _fit_multi(self, p, j, key, row, place, chars_by_key):
        """Rigid two-point fit of a multi-character patch: entry ``j`` on this tail, each other
        entry on the nearest matching tail of another character. Returns (placement, forced)
        or (place, None) when some entry has no partner."""
        st = self.state
        s = self.s
        pp = self.lib.patches[p]
        ppos, pdir, ptime = st.place_ports(p, place)
        D = st.dang
        forced = [(j, key)]
        used = {key}
        src = [pp.port_xz[j]]
        dst = [row[:2]]
        dts = [row[3] - pp.port_time[j]]
        for jj in range(0, 2 * pp.K, 2):
            if jj == j or not pp.port_open[jj]:
                if jj != j:
                    return place, None
                continue
            best, bd = None, s.partner_radius
            for okey, cid in chars_by_key.items():
                if okey in used:
                    continue
                r2 = D.row(okey)
                if int(r2[7]) != int(pp.port_class[jj]):
                    continue
                d = math.hypot(r2[0] - ppos[jj, 0], r2[1] - ppos[jj, 1])
                dh = abs(wrap_angle(r2[2] - pdir[jj]))
                if d < bd and abs(r2[3] - ptime[jj]) < s.partner_time and dh < math.radians(s.partner_dir):
                    best, bd = okey, d
            if best is None:
                return place, None
            used.add(best)
            forced.append((jj, best))
            r2 = D.row(best)
            src.append(pp.port_xz[jj])
            dst.append(r2[:2])
            dts.append(r2[3] - pp.port_time[jj])
        src, dst = np.array(src), np.array(dst)
        cs_, cd = src.mean(0), dst.mean(0)
        a, b = src - cs_, dst - cd
        # heading th with rotate_xz(a, th) ~ b: maximise sum b . R a
        num = np.sum(a[:, 1] * b[:, 0] - a[:, 0] * b[:, 1])
        den = np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])
        th = math.atan2(num, den)
        # keep the heading close to the aligned one (the tail's direction must still fit)
        th = place[2] + wrap_angle(th - place[2])
        pos = cd - rotate_xz_scalar(cs_, th)
        return (float(pos[0]), float(pos[1]), float(th), float(np.mean(dts))), forced
