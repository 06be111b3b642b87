"""Interactive tiling (paper 003, section 5.3): a runtime system that keeps a time horizon of
stitched patches ahead of the clock for a small number of characters steered by user targets.

Every character has a *tail*: the dangling exit of the last patch instance it plays. Each
:meth:`InteractiveTiling.step` advances the clock and, for the characters whose tail is less than
``horizon`` seconds ahead (most urgent first), samples a new patch instance at the tail. The
per-tick work is bounded deterministically, so runs are reproducible: at most ``max_per_tick``
extensions, and after the first only while the tick's estimated work (counted in candidate
queries, deformations, lookaheads and commits, about a millisecond each on a quiet machine)
stays within ``work_budget`` -- unless a tail is about to be reached; ``budget_ms`` adds a
wall-clock budget, at the price of reproducibility. A long extension is *time sliced*: it is a
generator that yields between its costly steps (candidate batches, look-aheads, interaction
fits); once the tick's work is spent it pauses (``stats["paused"]``) and goes on first thing
next tick, so no single tick carries a whole 24-candidate search. If anything was committed or
taken back while it was paused, it starts again in one go before committing (its candidates
were tested against a world that has changed). Characters about to run out of motion are
always served at once.

* candidates are the library patches with an entry of the tail's pose class, aligned on the
  tail (Eq. 1-3 hold exactly, nothing deforms) -- or, for multi-character patches, fitted
  rigidly to the tails of the other characters their other entries match (two-point fit), then
  deformed so every entry lands on its tail (only the new patch deforms: the past is pinned);
* they are ordered by the preference function Eq. 7 used as a sampling distribution (Gumbel
  top-k at ``temperature``, i.e. ``F^(1/temperature)`` normalised): ``f1`` the squared distance from where the patch leaves the character to its team's
  target, ``f2`` the squared angle between the exit heading and the direction to the target,
  ``f4`` label costs (e.g. a bonus for interaction labels);
* the first valid one (deformation within limits, no box overlap with any committed instance,
  reservation or obstacle in the space-time index) with room to stop after it is committed.
  Single-character candidates are queried in growing batches (same choice, less work).

Nobody may be cornered. A multi-character instance lasts several seconds, far beyond everyone's
horizon, so (a) it is only committed if it keeps clear of the park box of every character it does
not carry (where that one would stop: for good if it stands, else that walker must still have a
way on that never crosses the instance's future path, a one-patch lookahead), and (b) a
single-character candidate is preferred only if neither its path (sampled) nor its exit nor its
park box lies on a spot a live interaction passes later (``berth``; ``near`` more, or the
lookahead from its exit, near an interaction). When nothing is valid the character's own
unplayed last patch is taken back, or the others' unplayed patches in the way yield, or a few
jittered placements are tried; only then the least overlapping patch is forced
(``stats["forced"]``; in the benchmark scenarios such a patch overlaps at most a reservation).

Playback is vectorized: committed samples are written into per-character ring buffers indexed
by clock frame, so :meth:`root_states` / :meth:`pose_refs` / :meth:`poses` are array gathers over
all characters (no per-agent Python per tick). Python runs per character only when its tail
needs a new patch (about once a second per character).

Tracks for a bake or the viewer (identity continuous across stitched patches): with
``record=True`` every committed sample is kept, and :meth:`tracks` returns one
:class:`~runtime.tiling.result.CharacterTrack` per character (library flat-table frame indices,
root x/z/heading), usable with ``runtime.crowd.tracks.evaluate_poses(library, ...)``.
"""
from __future__ import annotations

import math
import time as _time

import numpy as np

from .patch import PatchLibrary
from .result import CharacterTrack
from .boxindex import box_samples, obb_overlap
from .tiler import Candidate, PreparedLibrary, Region, TilerConfig, TilingState, _rot, braking

__all__ = ["InteractiveTiling"]

RING = 2048   # frames of playback buffered per character (> horizon + longest fragment)


class InteractiveTiling:
    def __init__(self, library, horizon: float = 1.5, seed: int = 0, config: TilerConfig | None = None,
                 obstacles=(), max_per_tick: int = 3, budget_ms: float | None = None, record: bool = True,
                 bounds=(-1e3, -1e3, 1e3, 1e3),
                 spawn_class: int = 0, interaction_labels=(), interaction_bonus: float = 2.0,
                 sigma_pos: float = 4.0, sigma_dir: float = 1.0, top_k: int = 4, jitter_tries: int = 4,
                 partner_radius: float = 1.2, partner_time: float = 0.6, partner_dir: float = 35.0,
                 label_cost: dict | None = None,
                 formation_spacing: float = 2.0, max_singles: int = 24, clearance: float = 0.35,
                 max_retract: int = 1, max_yields: int = 4, probe: float = 1.2, temperature: float = 0.7,
                 first_batch: int = 4, hold: float = 1.0, park: bool = True, berth: float = 0.5, near: float = 0.75,
                 work_budget: float | None = 6.0, max_lookaheads: int = 2):
        """New characters come with :meth:`add_character`, targets with :meth:`set_target`.
        Work per tick: ``max_per_tick``, ``work_budget`` (estimated work units, about a
        millisecond each on a quiet machine; None: no work budget), ``budget_ms`` (wall clock,
        not reproducible). Search: ``first_batch`` (single-character candidates queried first),
        ``max_singles``, ``top_k`` multi-character tries, ``jitter_tries``. Room to go on:
        ``probe`` seconds of braking after a candidate must be free; reservations hold the
        braked box ``hold`` seconds more. Not being cornered by interactions (``park``):
        ``berth`` and ``near`` metres, ``max_lookaheads`` per extension."""
        prepared = library if isinstance(library, PreparedLibrary) else PreparedLibrary(library)
        self.lib = prepared
        self.library: PatchLibrary = prepared.library
        cfg = config or TilerConfig()
        if cfg.max_query_margin < cfg.margin + clearance:
            from dataclasses import replace
            cfg = replace(cfg, max_query_margin=cfg.margin + clearance)
        region = Region(bounds[0], bounds[1], bounds[2], bounds[3], 0.0, 8 * 3600.0)
        self.state = TilingState(prepared, region, obstacles, (), cfg, seed)
        self.rng = self.state.rng
        self.fps = cfg.fps
        self.horizon = float(horizon)
        self.max_per_tick = int(max_per_tick)
        self.budget = None if budget_ms is None else budget_ms / 1000.0
        self.record = record
        self.spawn_class = spawn_class
        self.sigma_pos, self.sigma_dir = sigma_pos, sigma_dir
        self.top_k = top_k
        self.jitter_tries = jitter_tries
        self.partner_radius = partner_radius
        self.partner_time = partner_time
        self.partner_dir = partner_dir
        self.formation_spacing = formation_spacing
        self.max_singles = max_singles
        self.max_retract = max_retract
        self.max_yields = max_yields
        self.probe = int(round(probe * self.fps))
        self.temperature = float(temperature)
        self.first_batch = max(1, int(first_batch))
        self.hold = int(round(hold * self.fps))
        self.park = bool(park)
        self.berth = float(berth)
        self.near = float(near)
        self.work_budget = None if work_budget is None else float(work_budget)
        self.max_lookaheads = int(max_lookaheads)
        self._work = 0.0
        self._epoch = 0            # bumped by every commit and retraction (a paused search restarts)
        self._pending = None       # (character, paused extension generator) carried to the next tick
        self._la_left = self.max_lookaheads
        self._yields = 0
        self.clearance = clearance
        self.t = 0.0
        self.frame = 0
        # label factor per patch (Eq. 7, f4)
        lc = dict(label_cost or {})
        for l in interaction_labels:
            lc[l] = lc.get(l, 0.0) - interaction_bonus
        self.log_label = np.array([-sum(lc.get(l, 0.0) for l in pp.patch.labels) for pp in prepared.patches])
        # candidate tables per entry class: (patch, port, fragment exit port), rest port values
        self.cands = {}
        for (kind, cls), arr in prepared.by_port.items():
            if kind != 0:
                continue
            p, j = arr[:, 0], arr[:, 1]
            pps = [prepared.patches[int(q)] for q in p]
            self.cands[cls] = {
                "p": p, "j": j, "multi": np.array([pp.K > 1 for pp in pps]),
                "pxz": np.array([pp.port_xz[jj] for pp, jj in zip(pps, j)]),
                "pdir": np.array([pp.port_dir[jj] for pp, jj in zip(pps, j)]),
                "ptime": np.array([pp.port_time[jj] for pp, jj in zip(pps, j)]),
                "exz": np.array([pp.port_xz[jj + 1] for pp, jj in zip(pps, j)]),
                "edir": np.array([pp.port_dir[jj + 1] for pp, jj in zip(pps, j)]),
                "label": self.log_label[p],
                "stand": np.array([("idle" in pp.patch.labels) and pp.K == 1 for pp in pps]),
            }
        # walking pose classes: several single patches leave them by half a metre or more
        self.mobile = {cls: int(np.count_nonzero(~c["multi"] & (np.hypot(*(c["exz"] - c["pxz"]).T) >= 0.5))) >= 3
                       for cls, c in self.cands.items()}
        # characters
        self.n = 0
        self.team = np.zeros(0, np.int64)
        self.tail: list = []                      # dangling exit key per character
        self.tail_time = np.zeros(0)
        self.ring_q = np.full((0, RING), -1, np.int64)
        self.ring_ab = np.zeros((0, RING, 2), np.int64)
        self.ring_w = np.zeros((0, RING), np.float32)
        self.ring_root = np.zeros((0, RING, 3))
        self.last_h = np.zeros(0)
        self.hist: list = []
        self.seg: list = []                       # per character: (instance, fragment, frames, previous heading)
        self.ban: list = []                       # per character: patches not to retry at the current tail
        self.archive: list = []                   # instances forgotten from the index (record=True)
        self.res_owner: list = []                 # per character: index owner of its reservation boxes
        # per character: where it would stand after braking at its tail ("park" box, from frame park_q on)
        self.park_q = np.zeros(0, np.int64)
        self.park_box = np.zeros((0, 6))          # centre x, z, lateral axis x, z, hx, hz
        self._multi: set = set()                  # live multi-character instances (long: they outlast horizons)
        self.targets: dict = {}
        self._owner_chars: dict = {}              # instance id -> characters it carries
        self.stats = {"extensions": 0, "multi": 0, "forced": 0, "evaluated": 0, "pruned": 0, "deferred": 0,
                      "retracted": 0, "yielded": 0, "paused": 0, "unparkable": 0}
        self._tick = 0

    # -- characters and control ------------------------------------------------------------------
    def set_target(self, team: int, position, spacing: float | None = None) -> None:
        """Steer a team: candidates that leave its characters nearer their spot are preferred.
        The spots form a square grid of ``spacing`` metres (default ``formation_spacing``)
        centred on ``position``, in the order the members were added."""
        self.targets[int(team)] = (np.asarray(position, np.float64).reshape(2),
                                   self.formation_spacing if spacing is None else float(spacing))

    def target_of(self, cid: int):
        tg = self.targets.get(int(self.team[cid]))
        if tg is None:
            return None
        pos, sp = tg
        members = np.flatnonzero(self.team == self.team[cid])
        n = len(members)
        k = int(np.searchsorted(members, cid))
        side = int(math.ceil(math.sqrt(n)))
        r, c = divmod(k, side)
        return pos + sp * np.array([c - 0.5 * (side - 1), r - 0.5 * (math.ceil(n / side) - 1)])

    def add_character(self, position, heading: float = 0.0, team: int = 0) -> int:
        """Start a character standing at ``position`` facing ``heading`` at the current time."""
        st = self.state
        c = self.cands.get(self.spawn_class)
        if c is None:
            raise ValueError(f"the library has no patch entering pose class {self.spawn_class}")
        order = np.flatnonzero(c["stand"]) if c["stand"].any() else np.flatnonzero(~c["multi"])
        row = np.array([position[0], position[1], heading, self.t, 0.0, 0.0, 1, self.spawn_class, 1, 0])
        best = None
        for k in order[self.rng.permutation(len(order))]:
            p = int(c["p"][k])
            place = self._align_row(k, c, row)
            cand = st.evaluate(p, place, match_others=False)
            if best is None:
                best = cand
            if not st.collides(cand):
                best = cand
                break
        iid = st.commit(best)
        st.dang.remove((iid, 0))                  # the entry is a source: not dangling
        cid = self.n
        self.n += 1
        self.team = np.append(self.team, int(team))
        self.tail.append((iid, 1))
        self.tail_time = np.append(self.tail_time, st.inst[iid].time[-1])
        self.ring_q = np.concatenate([self.ring_q, np.full((1, RING), -1, np.int64)])
        self.ring_ab = np.concatenate([self.ring_ab, np.zeros((1, RING, 2), np.int64)])
        self.ring_w = np.concatenate([self.ring_w, np.zeros((1, RING), np.float32)])
        self.ring_root = np.concatenate([self.ring_root, np.zeros((1, RING, 3))])
        self.last_h = np.append(self.last_h, np.nan)
        self.hist.append([])
        self.seg.append([])
        self.ban.append(set())
        self._owner_chars[iid] = [cid]
        self.res_owner.append(st.next_id)
        st.next_id += 1
        self.park_q = np.append(self.park_q, 0)
        self.park_box = np.concatenate([self.park_box, np.zeros((1, 6))])
        self._write(cid, iid, 0, first=True)
        self._reserve(cid)
        return cid

    # -- internals -------------------------------------------------------------------------------
    def _align_row(self, k, c, row):
        th = float(row[2] - c["pdir"][k])
        pos = row[:2] - _rot(c["pxz"][k], th)
        return (float(pos[0]), float(pos[1]), th, float(row[3] - c["ptime"][k]))

    def _write(self, cid, iid, frag, first=False):
        """Put fragment ``frag`` of instance ``iid`` into character ``cid``'s playback ring."""
        st = self.state
        inst = st.inst[iid]
        fr, fg, s, xz, hd = st.samples(inst)[:5]
        m = fg == frag
        q, s, xz, hd = fr[m], s[m], xz[m], hd[m]
        if len(q) == 0:
            return
        pp = self.lib.patches[inst.p]
        a0 = pp.frag_start[frag]
        off = self.library.fragment_offset(inst.p, frag)
        i0 = np.floor(s).astype(np.int64)
        i1 = np.minimum(i0 + 1, pp.frag_start[frag + 1] - 1)
        w = (s - i0).astype(np.float32)
        prev_h = self.last_h[cid]
        if not np.isnan(prev_h):
            hd = hd + 2 * np.pi * np.round((prev_h - hd[0]) / (2 * np.pi))
        self.last_h[cid] = hd[-1]
        self.seg[cid].append((iid, frag, q, prev_h))
        slot = q % RING
        self.ring_q[cid, slot] = q
        self.ring_ab[cid, slot, 0] = off + i0 - a0
        self.ring_ab[cid, slot, 1] = off + i1 - a0
        self.ring_w[cid, slot] = w
        self.ring_root[cid, slot, 0] = xz[:, 0]
        self.ring_root[cid, slot, 1] = xz[:, 1]
        self.ring_root[cid, slot, 2] = hd
        if self.record:
            self.hist[cid].append((q, off + i0 - a0, off + i1 - a0, w, np.column_stack([xz, hd]), iid, frag))

    def _commit(self, cand: Candidate, chars_by_key: dict) -> None:
        st = self.state
        self._work += 1.5
        self._epoch += 1
        iid = st.commit(cand)
        for j, key in cand.conns:
            cid = chars_by_key.get(key)
            if cid is not None:
                self.ban[cid] = set()
        carried = []
        for j, key in cand.conns:
            cid = chars_by_key.get(key)
            if cid is None:
                continue
            k = j // 2
            self.tail[cid] = (iid, 2 * k + 1)
            self.tail_time[cid] = st.inst[iid].time[st.lib.patches[cand.p].port_frame[2 * k + 1]]
            self._write(cid, iid, k)
            self._reserve(cid)
            carried.append(cid)
        self._owner_chars[iid] = carried
        self.stats["extensions"] += 1
        if self.lib.patches[cand.p].K > 1:
            self.stats["multi"] += 1
            self._multi.add(iid)

    def _extend(self, cid: int, depth: int = 0) -> None:
        """Extend character ``cid`` by one patch instance, in one go."""
        for _ in self._extend_g(cid, depth, sync=True):
            pass

    def _extend_g(self, cid: int, depth: int = 0, sync: bool = False):
        """:meth:`_extend` as a generator that yields between its costly steps (candidate
        batches, look-aheads, interaction fits) unless ``sync``, so the tick can pause it and
        resume it on the next one (time slicing). If anything was committed or taken back while
        it was paused, it starts again, in one go, before committing anything."""
        st = self.state
        epoch = self._epoch
        if depth == 0:
            self._la_left = self.max_lookaheads
        key = self.tail[cid]
        D = st.dang
        row = D.rows[D.where[key]].copy()
        cls = int(row[7])
        c = self.cands.get(cls)
        chars_by_key = {k: i for i, k in enumerate(self.tail)}
        if c is None:
            raise RuntimeError(f"no patch enters pose class {cls}; the library cannot continue character {cid}")
        # vectorized preference over all candidates aligned on the tail
        th = row[2] - c["pdir"]
        cs, sn = np.cos(th), np.sin(th)
        dv = c["exz"] - c["pxz"]
        ex = row[0] + cs * dv[:, 0] + sn * dv[:, 1]
        ez = row[1] - sn * dv[:, 0] + cs * dv[:, 1]
        logf = c["label"].copy()
        tgt = self.target_of(cid)
        if tgt is not None:
            d2 = (ex - tgt[0]) ** 2 + (ez - tgt[1]) ** 2
            want = np.arctan2(tgt[0] - ex, tgt[1] - ez)
            da = (c["edir"] + th - want + np.pi) % (2 * np.pi) - np.pi
            near = d2 < 0.25
            logf -= d2 / self.sigma_pos + np.where(near, 0.0, da * da / self.sigma_dir)
        logf += self.temperature * self.rng.gumbel(size=len(logf))
        if self.ban[cid]:
            logf[np.isin(c["p"], list(self.ban[cid]))] = -np.inf
        order = np.argsort(-logf, kind="stable")
        order = order[np.isfinite(logf[order])]
        fallback = None
        plans = []
        # pass 1: single-character candidates, placed exactly on the tail (rigid), all tested in
        # one vectorized space-time query; then the multi-character ones in preference order
        single = order[~c["multi"][order]][:self.max_singles]
        multi = order[c["multi"][order]]
        if len(multi):
            # interactions first whenever partners are in place (the fit says so quickly)
            for k in multi[:self.top_k]:
                p, j = int(c["p"][k]), int(c["j"][k])
                place, forced = self._fit_multi(p, j, key, row, self._align_row(k, c, row), chars_by_key)
                if forced is None:
                    continue
                cand = st.evaluate(p, place, forced=forced, match_others=False)
                self.stats["evaluated"] += 1
                self._work += 2.5
                if not sync:
                    yield
                    if self._epoch != epoch:
                        yield from self._extend_g(cid, depth, sync=True)
                        return
                ign = {self.res_owner[chars_by_key[k2]] for _, k2 in forced}
                if cand.limits_ok and not st.collides(cand, margin=st.cfg.margin + self.clearance, ignore=ign) and \
                        self._multi_park_ok(cand, [chars_by_key[k2] for _, k2 in forced]):
                    self._commit(cand, chars_by_key)
                    return
        ths = row[2] - c["pdir"][single]
        cs_, sn_ = np.cos(ths), np.sin(ths)
        pxz = c["pxz"][single]
        places = np.column_stack([row[0] - (cs_ * pxz[:, 0] + sn_ * pxz[:, 1]), row[1] - (cs_ * pxz[:, 1] - sn_ * pxz[:, 0]),
                                  ths, row[3] - c["ptime"][single]])
        ps = c["p"][single]
        own = {self.res_owner[cid]}
        conns = [[(int(c["j"][k]), key)] for k in single]
        cand, hits = yield from self._choose_single(ps, places, conns, own, sync)
        if self._epoch != epoch:
            # paused, and the world moved on: the choice stands if it (and room to stop after
            # it) is still clear -- one query; else the search runs again, in one go
            if cand is not None and self.tail[cid] == key:
                _, h1, p1 = st.rigid_batch_free([cand.p], [cand.place], margin=st.cfg.margin + self.clearance,
                                                probe=self.probe, ignore=own)
                self._work += 1.2
                if h1[0] == 0 and p1[0] == 0:
                    self._commit(cand, chars_by_key)
                    return
            yield from self._extend_g(cid, depth, sync=True)
            return
        if cand is not None:
            self._commit(cand, chars_by_key)
            return
        if len(single):
            b = int(np.argmin(hits))
            fallback = (int(ps[b]), tuple(places[b]), int(c["j"][single[b]]))
        for k in single[:self.top_k]:
            plans.append((int(c["p"][k]), self._align_row(k, c, row), [(int(c["j"][k]), key)]))
        # nothing fits: the characters whose not-yet-played patches block the least-overlapping
        # candidate yield them (bounded per tick), or this character takes back its own last one
        if fallback is None:
            k = int(np.flatnonzero(~c["multi"])[0])
            fallback = (int(c["p"][k]), self._align_row(k, c, row), int(c["j"][k]))
        p, place, j = fallback
        best = cand = st.rigid_candidate(p, place, [(j, key)])
        # the characters whose not-yet-played patches block the best candidate yield them
        if self._yields < self.max_yields:
            fr, _, _, _, _, cen, lat, hx, hz, ylo, yhi = st.samples(cand)
            _, owners = st.index.query(fr, cen, lat, hx, hz, ylo, yhi, margin=st.cfg.margin, first_only=False,
                                       return_owners=True, ignore=own)
            tail_of = {k[0]: i for i, k in enumerate(self.tail)}
            tail_of.update({r: i for i, r in enumerate(self.res_owner)})
            yielded = sorted({tail_of[o] for o in owners if o in tail_of and tail_of[o] != cid})
            if yielded and all(o in tail_of for o in owners) and all(self._retract(o) for o in yielded):
                self._yields += len(yielded)
                self.stats["yielded"] += len(yielded)
                if not st.collides(cand, ignore=own):
                    self._commit(cand, chars_by_key)
                    return
        # (a different previous patch opens other ways)
        if depth < self.max_retract and self._retract(cid):
            while self.tail_time[cid] < self.t + self.horizon:
                yield from self._extend_g(cid, depth + 1, sync=True)
            return
        # pass 2: small jitters of the preferred ones (``jitter_tries`` evaluations in all)
        for n_j in range(self.jitter_tries if depth == 0 else 0):
            if not plans:
                break
            p, place, forced = plans[n_j % len(plans)]
            cand = st.evaluate(p, self._jitter(place, n_j), forced=forced, match_others=False)
            self.stats["evaluated"] += 1
            if cand.limits_ok and not st.collides(cand, ignore={self.res_owner[chars_by_key[k2]] for _, k2 in forced}):
                self._commit(cand, chars_by_key)
                return
        # forced: the candidate that overlaps least
        self.stats["forced"] += 1
        self._commit(best, chars_by_key)

    def _choose_single(self, ps, places, conns, own, sync=True):
        """The first single-character candidate (preference order) that is valid with room to
        stop after it (``probe``) and that cannot be cornered by a long multi-character
        instance (:meth:`_park_mask`, else :meth:`_exit_lookahead`); else the first valid one
        with the least obstructed stop (parkable first); else the first that only intrudes on
        others' reservations. Candidates are queried in growing batches (the first
        ``first_batch``, three times as many, then all): the choice is the same as one batch,
        the work usually 4x less. Returns (candidate or None, per-candidate hits of the last
        query). A generator (returns that pair): it yields after each batch and look-ahead
        unless ``sync``."""
        st = self.state
        n = len(ps)
        self.stats["evaluated"] += n
        if n == 0:
            return None, np.zeros(0, np.int64)
        m = st.cfg.margin + self.clearance
        park, far = self._park_mask(ps, places, extra=self.near)
        done = 0
        hits = np.zeros(n, np.int64)
        ph = np.zeros(n, np.int64)
        for nb in sorted({min(self.first_batch, n), min(3 * self.first_batch, n), n}):
            # each batch queries only the candidates the previous ones did not
            _, hits[done:nb], ph[done:nb] = st.rigid_batch_free(ps[done:nb], places[done:nb], margin=m,
                                                                 probe=self.probe, ignore=own)
            self._work += 1.0 + 0.17 * (nb - done)
            free = np.flatnonzero((hits[done:nb] == 0) & (ph[done:nb] == 0)) + done
            for k in free:
                if far[k]:
                    return st.rigid_candidate(int(ps[k]), tuple(places[k]), conns[k]), hits
                # near an interaction or unparkable by the quick test: is there a way on after
                # it (bounded lookahead)? A walker cannot turn on the spot, so one step of
                # clearance is not enough near the path of an interaction
                cand = st.rigid_candidate(int(ps[k]), tuple(places[k]), conns[k])
                ok = self._exit_lookahead(cand)
                if not sync:
                    yield
                if ok:
                    return cand, hits
            done = nb
            if not sync and done < n:
                yield
        ok = np.flatnonzero(hits == 0)                      # free but no room to go on: still better than nothing
        ok = ok[np.lexsort((ph[ok], ~park[ok]))]             # parkable first, then the least obstructed stop
        if len(ok):
            i = int(ok[0])
            if not park[i]:
                # every free one may be cornered: look further ahead (a larger, still bounded, budget)
                self._la_left = max(self._la_left, 3 * self.max_lookaheads)
                for k in ok[:3 * self.max_lookaheads]:
                    cand = st.rigid_candidate(int(ps[k]), tuple(places[k]), conns[k])
                    la = self._exit_lookahead(cand)
                    if not sync:
                        yield
                    if la:
                        return cand, hits
                self.stats["unparkable"] += 1
            return st.rigid_candidate(int(ps[i]), tuple(places[i]), conns[i]), hits
        f = st.rigid_batch_free(ps, places, ignore=own)
        self._work += 1.0 + 0.1 * n
        if f < 0:                                           # only others' reservations in the way
            f, hits = st.rigid_batch_free(ps, places, ignore=set(self.res_owner), counts=True)
            self._work += 1.0 + 0.1 * n
        if f >= 0:
            return st.rigid_candidate(int(ps[f]), tuple(places[f]), conns[f]), hits
        return None, hits

    def _park_mask(self, ps, places, extra: float = 0.0):
        """Per rigid single-character candidate: can the character stop after it and stand
        there? Boxes along it (start, a third, two thirds, exit: each from its frame on) and its
        park box (the exit box carried on braking for ``probe`` frames, from the stop on) must
        keep ``berth`` metres more than the clearance from the live multi-character instances
        -- the only ones reaching far beyond everyone's horizon: a character that walks onto or
        stops on a spot an interaction will pass later could be cornered there. Vectorized
        over the candidates. Returns (parkable, parkable with ``extra`` metres more berth)."""
        n = len(ps)
        ok = np.ones(n, bool)
        far = np.ones(n, bool)
        if not self.park or not self._multi or n == 0:
            return ok, far
        st = self.state
        # whole-instance boxes first: most of the time no interaction is anywhere near
        co = st.index._coarse[sorted(self._multi)]
        c0 = places[:, :2].mean(0)
        r = 7.0 + self.berth + extra + float(np.max(np.hypot(*(places[:, :2] - c0).T)))
        if not np.any((co[:, 0] - r <= c0[0]) & (c0[0] <= co[:, 1] + r) & (co[:, 2] - r <= c0[1]) & (c0[1] <= co[:, 3] + r)
                      & (co[:, 5] >= np.min(places[:, 3]) * self.fps)):
            return ok, far
        lib = self.lib
        if not hasattr(lib, "_flat_rest"):
            st.rigid_batch_free(ps[:1], np.zeros((1, 4)) + [[0, 0, 0, -1e6]])   # builds the flat tables
        rxz, rh, rbox, start, t0 = lib._flat_rest
        e = start[ps + 1] - 1
        th = places[:, 2]
        cs_, sn_ = np.cos(th), np.sin(th)

        def world(g):
            return np.stack([cs_ * rxz[g, 0] + sn_ * rxz[g, 1] + places[:, 0], cs_ * rxz[g, 1] - sn_ * rxz[g, 0] + places[:, 1]], 1)
        q_start = (places[:, 3] + t0[ps]) * self.fps
        xe, xp = world(e), world(np.maximum(e - 1, start[ps]))
        mid = xe.mean(0)
        M = self._multi_boxes(int(q_start.min()), mid, 4.0 + self.berth + extra + float(np.max(np.hypot(*(xe - mid).T))))
        if M is None:
            return ok, far
        mf, mc, ml, mx, mz = M
        mg = st.cfg.margin + self.clearance + self.berth
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
        cen = np.concatenate([cen, cen[last] + (xe - xp) * float(braking(self.probe, self.probe))])
        lat = np.concatenate([lat, lat[last]])
        hx, hz = np.concatenate([hx, hx[last]]), np.concatenate([hz, hz[last]])
        q0 = np.concatenate([q0, q0[last] + self.probe])
        cand = np.tile(np.arange(n), 5)
        a, bb = np.nonzero((mf[None, :] >= q0[:, None]) & (
            np.hypot(mc[None, :, 0] - cen[:, None, 0], mc[None, :, 1] - cen[:, None, 1]) < np.hypot(hx, hz)[:, None] + np.hypot(mx, mz)[None, :] + mg + extra))
        if len(a):
            hit = obb_overlap(cen[a], lat[a], hx[a], hz[a], mc[bb], ml[bb], mx[bb], mz[bb], mg + extra)
            far[cand[a[hit]]] = False
            a, bb = a[hit], bb[hit]
            hit = obb_overlap(cen[a], lat[a], hx[a], hz[a], mc[bb], ml[bb], mx[bb], mz[bb], mg)
            ok[cand[a[hit]]] = False
        return ok, far & ok

    def _exit_lookahead(self, cand) -> bool:
        """:meth:`_lookahead` from the exit of a single-character candidate against the live
        multi-character instances near it (at most ``max_lookaheads`` per extension)."""
        if self._la_left <= 0:                          # bounded work per extension
            return False
        self._la_left -= 1
        pp = self.lib.patches[cand.p]
        f = pp.port_frame[1]
        row = np.zeros(10)
        row[:4] = cand.xz[f, 0], cand.xz[f, 1], cand.heading[f], cand.time[f]
        row[7] = pp.port_class[1]
        M = self._multi_boxes(int(math.floor(cand.time[f] * self.fps)), cand.xz[f], 4.5)
        return M is None or self._lookahead(row, M)

    def _multi_park_ok(self, cand, carried) -> bool:
        """A multi-character instance outlasts everyone's horizon, so it must not corner anyone
        it does not carry: it keeps clear of the park box of every other character (where that
        one would stop and stand, from then on), unless that character walks and still has a
        way on from its tail that keeps clear of the new instance (:meth:`_lookahead`)."""
        if not self.park:
            return True
        st = self.state
        others = np.setdiff1d(np.arange(self.n), np.asarray(list(carried), np.int64))
        if not len(others):
            return True
        fr, _, _, _, _, cen, lat, hx, hz = st.samples(cand)[:9]
        pb = self.park_box[others]
        rp = np.hypot(pb[:, 4], pb[:, 5])
        mg = st.cfg.margin + self.clearance
        near = (fr[:, None] >= self.park_q[others][None, :]) & (
            np.hypot(cen[:, None, 0] - pb[None, :, 0], cen[:, None, 1] - pb[None, :, 1]) < np.hypot(hx, hz)[:, None] + rp[None, :] + mg)
        a, b = np.nonzero(near)
        if not len(a):
            return True
        hit = obb_overlap(cen[a], lat[a], hx[a], hz[a], pb[b, :2], pb[b, 2:4], pb[b, 4], pb[b, 5], mg)
        o = np.argsort(fr, kind="stable")
        M = (fr[o], cen[o], lat[o], hx[o], hz[o])
        for k in np.unique(b[hit]):
            row = st.dang.rows[st.dang.where[self.tail[int(others[k])]]]
            if not self.mobile.get(int(row[7]), False) or not self._lookahead(row, M):
                return False
        return True

    def _multi_boxes(self, q0, pc, reach):
        """Boxes of the live multi-character instances from clock frame ``q0`` on within
        ``reach`` of ``pc``, sorted by frame: (frames, centre, lateral axis, hx, hz) or None."""
        st = self.state
        parts = []
        for iid in sorted(self._multi):
            inst = st.inst.get(iid)
            if inst is None:
                continue
            f2, _, _, _, _, c2, l2, x2, z2 = st.samples(inst)[:9]
            m = (f2 >= q0) & (np.hypot(c2[:, 0] - pc[0], c2[:, 1] - pc[1]) < reach)
            if m.any():
                parts.append((f2[m], c2[m], l2[m], x2[m], z2[m]))
        if not parts:
            return None
        M = [np.concatenate([p[i] for p in parts]) for i in range(5)]
        o = np.argsort(M[0], kind="stable")
        return tuple(x[o] for x in M)

    def _lookahead(self, row, M, shadow: bool = True) -> bool:
        """Is there a single-character patch from the exit ``row`` (x, z, dir, time, .., class)
        whose boxes keep clear of the boxes ``M`` (sorted by frame) from their own frame on
        (never on a spot an interaction passes later; with ``shadow=False`` only on the same
        frame, every 5th), its last box held from its end on (the character could stop there)?"""
        self._work += 1.5
        st = self.state
        c = self.cands.get(int(row[7]))
        if c is None:
            return False
        sel = np.flatnonzero(~c["multi"])
        if not len(sel):
            return False
        lib = self.lib
        if not hasattr(lib, "_flat_rest"):
            st.rigid_batch_free(c["p"][sel[:1]], np.zeros((1, 4)) + [[0, 0, 0, -1e6]])   # builds the flat tables
        rxz, rh, rbox, start, t0 = lib._flat_rest
        ps = c["p"][sel]
        th = row[2] - c["pdir"][sel]
        cs_, sn_ = np.cos(th), np.sin(th)
        pxz = c["pxz"][sel]
        px = row[0] - (cs_ * pxz[:, 0] + sn_ * pxz[:, 1])
        pz = row[1] - (cs_ * pxz[:, 1] - sn_ * pxz[:, 0])
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
        mg = st.cfg.margin + self.clearance
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

    def _reserve(self, cid: int) -> None:
        """Reserve where the character will be just after its tail: its last box carried on at the
        last velocity, braking to a stop over ``probe`` frames and then held ``hold`` frames, so
        others keep out of the way it must go on. The stopped box is its park box."""
        if not self.probe:
            return
        st = self.state
        iid, port = self.tail[cid]
        inst = st.inst[iid]
        pp = self.lib.patches[inst.p]
        k = port // 2
        b = pp.frag_start[k + 1]
        q_end = inst.time[b - 1] * self.fps
        v = (inst.xz[b - 1] - inst.xz[b - 2]) / max((inst.time[b - 1] - inst.time[b - 2]) * self.fps, 1e-6)
        q0 = int(math.ceil(q_end - 1e-6))
        q = np.arange(q0, q0 + self.probe + self.hold)
        dt = braking(q - q_end, self.probe)[:, None]
        xz = inst.xz[b - 1] + v * dt
        hd = np.full(len(q), inst.heading[b - 1])
        box = np.repeat(pp.box[b - 1:b], len(q), 0)
        st.reserve(self.res_owner[cid], q, xz, hd, box)
        cen, lat, hx, hz, _, _ = box_samples(xz[-1:], hd[-1:], box[-1:])
        self.park_q[cid] = q0 + self.probe
        self.park_box[cid] = [cen[0, 0], cen[0, 1], lat[0, 0], lat[0, 1], hx[0], hz[0]]

    def _retract(self, cid: int) -> bool:
        """Take back the character's last instance if it is single-character and has not started
        playing yet (it is in the future, so nothing visible changes); its tail goes back to the
        previous exit and the patch is banned there for the next try."""
        st = self.state
        iid, port = self.tail[cid]
        inst = st.inst.get(iid)
        segs = self.seg[cid]
        if inst is None or len(segs) < 2 or self.lib.patches[inst.p].K != 1 or inst.fixed:
            return False
        if inst.time[0] * self.fps <= self.frame + 2:
            return False
        prev = inst.links[0]
        if prev is None:
            return False
        _, _, q, prev_h = segs.pop()
        slot = q % RING
        stale = self.ring_q[cid, slot] == q
        self.ring_q[cid, slot[stale]] = -1
        self.last_h[cid] = prev_h
        if self.record and self.hist[cid] and self.hist[cid][-1][5] == iid:
            self.hist[cid].pop()
        st.remove(iid)
        st.history.pop(prev, None)
        self._owner_chars.pop(iid, None)
        self.tail[cid] = prev
        self.tail_time[cid] = st.dang.rows[st.dang.where[prev], 3]
        self.ban[cid] = {inst.p}
        self._reserve(cid)
        self._epoch += 1
        self.stats["retracted"] += 1
        return True

    def _jitter(self, place, i):
        """Small jitters for the interactive search (a third of Algorithm 2's first range)."""
        x, z, th, t = place
        r = 0.2 * math.sqrt(self.rng.random())
        a = self.rng.uniform(-np.pi, np.pi)
        return (x + r * math.cos(a), z + r * math.sin(a), th + self.rng.uniform(-0.087, 0.087), t + self.rng.uniform(-0.1, 0.1))

    def _fit_multi(self, p, j, key, row, place, chars_by_key):
        """Rigid two-point fit of a multi-character patch: entry ``j`` on this tail, each other
        entry on the nearest matching tail of another character. Returns (placement, forced)
        or (place, None) when some entry has no partner."""
        st = self.state
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
            best, bd = None, self.partner_radius
            for okey, cid in chars_by_key.items():
                if okey in used:
                    continue
                r2 = D.rows[D.where[okey]]
                if int(r2[7]) != int(pp.port_class[jj]):
                    continue
                d = math.hypot(r2[0] - ppos[jj, 0], r2[1] - ppos[jj, 1])
                dh = abs((r2[2] - pdir[jj] + math.pi) % (2 * math.pi) - math.pi)
                if d < bd and abs(r2[3] - ptime[jj]) < self.partner_time and dh < math.radians(self.partner_dir):
                    best, bd = okey, d
            if best is None:
                return place, None
            used.add(best)
            forced.append((jj, best))
            r2 = D.rows[D.where[best]]
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
        dth = (th - place[2] + np.pi) % (2 * np.pi) - np.pi
        th = place[2] + dth
        pos = cd - _rot(cs_, th)
        return (float(pos[0]), float(pos[1]), float(th), float(np.mean(dts))), forced

    def _forget_old(self):
        """Drop instances whose motion is entirely in the past from the index and tables."""
        st = self.state
        tails = {k[0] for k in self.tail}
        old = [iid for iid, inst in st.inst.items() if iid not in tails and inst.time.max() * self.fps < self.frame - 2]
        for iid in old:
            inst = st.inst.pop(iid)
            st.index.remove_owner(iid)
            self._multi.discard(iid)
            if self.record:
                self.archive.append(inst)
            for jj, link in enumerate(inst.links):
                if link is None:
                    if (iid, jj) in st.dang.where:
                        st.dang.remove((iid, jj))
                else:
                    oi, oj = link
                    if oi in st.inst:
                        st.inst[oi].links[oj] = None
            self._owner_chars.pop(iid, None)
            self.stats["pruned"] += 1

    # -- the tick --------------------------------------------------------------------------------
    def step(self, t: float | None = None, dt: float | None = None) -> None:
        """Advance the clock to ``t`` (or by ``dt``; default one frame) and fill the horizon."""
        if t is None:
            t = self.t + (dt if dt is not None else 1.0 / self.fps)
        self.t = float(t)
        self.frame = int(round(self.t * self.fps))
        t0 = _time.perf_counter()
        self._yields = 0
        self._work = 0.0
        if self.n:
            need = self.tail_time < self.t + self.horizon
            urgent_t = self.t + 3.0 / self.fps
            done = 0
            per = np.zeros(self.n, np.int64)
            while need.any() or self._pending is not None:
                if self._pending is not None:           # the extension paused last tick goes on first
                    cid, gen = self._pending
                    self._pending = None
                else:
                    cid = int(np.flatnonzero(need)[np.argmin(self.tail_time[need])])
                    if self.tail_time[cid] >= urgent_t and (done >= self.max_per_tick or (
                            self.work_budget is not None and done and self._work + 2.5 > self.work_budget) or (
                            self.budget is not None and done and _time.perf_counter() - t0 > self.budget)):
                        self.stats["deferred"] += 1
                        break
                    gen = self._extend_g(cid, sync=self.work_budget is None)
                urgent = self.tail_time[cid] < urgent_t
                paused = False
                for _ in gen:
                    # time slicing: a long extension pauses between its steps once the tick's
                    # work is spent, and goes on next tick (a tail far enough ahead can wait)
                    if not urgent and self.work_budget is not None and self._work > self.work_budget:
                        self._pending = (cid, gen)
                        self.stats["paused"] += 1
                        paused = True
                        break
                if paused:
                    # only characters about to run out of motion are still served this tick
                    for u in np.flatnonzero(self.tail_time < urgent_t):
                        if int(u) == cid:
                            for _ in gen:
                                pass
                            self._pending = None
                        else:
                            self._extend(int(u))
                    break
                done += 1
                per[cid] += 1
                # a character retracted by others' yields comes back next tick unless urgent
                need = (self.tail_time < self.t + self.horizon) & ((per < 3) | (self.tail_time < urgent_t))
        self.last_tick_ms = 1000.0 * (_time.perf_counter() - t0)
        self._tick += 1
        if self._tick % 30 == 0:
            self._forget_old()

    # -- playback (vectorized over characters) ---------------------------------------------------------
    def _slot(self, frame=None):
        q = self.frame if frame is None else int(frame)
        slot = q % RING
        ok = self.ring_q[:, slot] == q
        return slot, ok

    def root_states(self, frame=None) -> np.ndarray:
        """(C, 3) x, z, heading of every character at the clock frame (NaN if not buffered)."""
        slot, ok = self._slot(frame)
        out = self.ring_root[:, slot].copy()
        out[~ok] = np.nan
        return out

    def pose_refs(self, frame=None):
        """(frames_a (C,), frames_b (C,), blend (C,), root (C, 3)) into the library's flat pose
        tables (``library.frame_rotations`` / ``frame_height``)."""
        slot, ok = self._slot(frame)
        return self.ring_ab[:, slot, 0], self.ring_ab[:, slot, 1], self.ring_w[:, slot], self.ring_root[:, slot]

    def poses(self, frame=None):
        """Root positions (C, 3) and local rotations (C, J, 4) (entry 0 = root world rotation)."""
        from ..crowd.tracks import evaluate_poses
        a, b, w, root = self.pose_refs(frame)
        return evaluate_poses(self.library, a, b, w, root)

    def result(self):
        """Everything committed so far as a :class:`~runtime.tiling.result.TilingResult` (region:
        the box around all motion plus 1 m, time 0 .. now) for the checker or a bake
        (``record=True``)."""
        from .result import TilingResult
        if not self.record:
            raise RuntimeError("InteractiveTiling(record=False) keeps no history")
        insts = sorted(self.archive + list(self.state.inst.values()), key=lambda i: i.id)
        pos = {i.id: k for k, i in enumerate(insts)}
        links = []
        for k, inst in enumerate(insts):
            for j, l in enumerate(inst.links):
                if l is not None and j % 2 == 1 and l[0] in pos:
                    links.append((k, j // 2, pos[l[0]], l[1] // 2))
        allxz = np.concatenate([i.xz for i in insts]) if insts else np.zeros((1, 2))
        lo, hi = np.floor(allxz.min(0)) - 1.0, np.ceil(allxz.max(0)) + 1.0
        reg = Region(float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]), 0.0, self.t)
        return TilingResult(self.library, reg, [i.p for i in insts], [i.place for i in insts], [i.fixed for i in insts],
                            [i.xz for i in insts], [i.heading for i in insts], [i.time for i in insts],
                            np.array(links, np.int64).reshape(-1, 4), self.state.obstacles, [], self.fps,
                            {"stats": dict(self.stats)})

    def tracks(self) -> list[CharacterTrack]:
        """One track per character from its first frame to the last committed one (``record``)."""
        if not self.record:
            raise RuntimeError("InteractiveTiling(record=False) keeps no history")
        out = []
        for cid in range(self.n):
            h = self.hist[cid]
            if not h:
                continue
            q = np.concatenate([x[0] for x in h])
            order = np.argsort(q, kind="stable")
            q = q[order]
            keep = np.r_[True, q[1:] != q[:-1]]
            sel = order[keep]
            fa = np.concatenate([x[1] for x in h])[sel]
            fb = np.concatenate([x[2] for x in h])[sel]
            w = np.concatenate([x[3] for x in h])[sel]
            root = np.concatenate([x[4] for x in h])[sel]
            segs = [(x[5], x[6], int(x[0][0])) for x in h]
            out.append(CharacterTrack(fa, fb, w.astype(np.float32), root, int(q[keep][0]), segments=segs))
        return out
