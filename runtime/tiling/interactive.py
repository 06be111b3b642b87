"""Interactive tiling (Kim, Hwang, Hyun and Lee 2012, section 5.3): a runtime system that keeps
a time horizon of stitched patches ahead of the clock for a small number of characters steered
by user targets.

Every character has a *tail*: the dangling exit of the last patch instance it plays. Each
:meth:`InteractiveTiling.step` advances the clock and, for the characters whose tail is less than
``horizon`` seconds ahead (most urgent first), extends it by one patch instance
(:mod:`.extension`; not cornering anyone: :mod:`.cornering`). The per-tick work is bounded
deterministically, so runs are reproducible: at most ``max_per_tick`` extensions, and after the
first only while the tick's estimated work (:class:`~runtime.tiling.tick.TickState`) stays
within ``work_budget`` -- unless a tail is about to be reached; ``budget_ms`` adds a wall-clock
budget, at the price of reproducibility. A long extension is *time sliced*: once the tick's work
is spent it pauses (``stats["paused"]``) and goes on first thing next tick, so no single tick
carries a whole candidate search. Characters about to run out of motion are always served at
once.

The parts: :class:`~runtime.tiling.state.TilingState` (the instances and their space-time
boxes), :class:`~runtime.tiling.entries.EntryTables` (candidates by entry pose class),
:class:`~runtime.tiling.roster.Roster` (characters, tails, targets),
:class:`~runtime.tiling.playback.Playback` (ring buffers), :class:`~runtime.tiling.cornering.
Cornering` (reservations, park boxes, look-aheads) and :class:`~runtime.tiling.extension.
Extender` (the candidate search).

Playback is vectorized: committed samples are written into per-character ring buffers indexed
by clock frame, so :meth:`~InteractiveTiling.root_states` / :meth:`~InteractiveTiling.pose_refs` /
:meth:`~InteractiveTiling.poses` are array gathers over all characters. Python runs per
character only when its tail needs a new patch (about once a second per character).

Tracks for a bake or the viewer (identity continuous across stitched patches): with
``record=True`` every committed sample is kept, and :meth:`~InteractiveTiling.tracks` returns one
:class:`~runtime.tiling.result.CharacterTrack` per character (library flat-table frame indices,
root x/z/heading), usable with ``runtime.crowd.tracks.evaluate_poses(library, ...)``.
"""
from __future__ import annotations

import time as _time
from dataclasses import replace

import numpy as np

from .config import TilerConfig
from .cornering import Cornering, CorneringSettings
from .entries import EntryTables
from .extension import Extender, SearchSettings
from .patch import PatchLibrary
from .playback import Playback
from .prepared import PreparedLibrary
from .region import Region
from .result import CharacterTrack, TilingResult
from .roster import Roster
from .state import TilingState, result_of
from .tick import TickState

__all__ = ["InteractiveTiling"]


class InteractiveTiling:
    """Interactive tiling of a few characters steered by team targets.

    New characters come with :meth:`add_character`, targets with :meth:`set_target`.

    Args:
        library: a :class:`~runtime.tiling.patch.PatchLibrary` or a prepared one.
        horizon: seconds of motion kept committed ahead of the clock.
        seed: of the one random generator.
        config: the :class:`~runtime.tiling.config.TilerConfig` (margin, limits, fps).
        obstacles: :class:`~runtime.tiling.region.Obstacle` s.
        max_per_tick, work_budget, budget_ms: work per tick: extensions, estimated work units
            (about a millisecond each on a quiet machine; None: no work budget), wall clock (not
            reproducible).
        record: keep every committed sample (for :meth:`tracks` and :meth:`result`).
        bounds: (x0, z0, x1, z1) characters never leave.
        spawn_class: pose class new characters stand in.
        interaction_labels, interaction_bonus, label_cost: Eq. 7 label costs (``f4``); the
            interaction labels get a bonus.
        sigma_pos, sigma_dir, temperature: Eq. 7 towards the team's target, and the Gumbel
            top-k temperature.
        first_batch, max_singles, top_k, jitter_tries: the search (single-character candidates
            queried first, at most in all; multi-character tries; jitter tries).
        partner_radius, partner_time, partner_dir: how near (m, s, deg) another character's tail
            must be to a multi-character patch's entry to play it.
        formation_spacing: default spacing of a team's target grid (m).
        clearance: metres kept from other characters' boxes beyond the config's margin.
        max_retract, max_yields: own patches taken back per extension, others' per tick.
        probe, hold: seconds of braking after a candidate that must be free; seconds more a
            reservation holds the braked box.
        park, berth, near, max_lookaheads: not being cornered by interactions
            (:mod:`.cornering`): berth and near in metres, look-aheads per extension.
    """

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
        prepared = library if isinstance(library, PreparedLibrary) else PreparedLibrary(library)
        self.lib = prepared
        self.library: PatchLibrary = prepared.library
        cfg = config or TilerConfig()
        if cfg.max_query_margin < cfg.margin + clearance:
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
        self.work_budget = None if work_budget is None else float(work_budget)
        self.tick = TickState()
        self._pending = None       # (character, paused extension generator) carried to the next tick
        self._ticks = 0
        self.archive: list = []    # instances forgotten from the index (record=True)
        lc = dict(label_cost or {})
        for l in interaction_labels:
            lc[l] = lc.get(l, 0.0) - interaction_bonus
        self.entries = EntryTables(prepared, lc)
        self.roster = Roster(formation_spacing)
        self.playback = Playback(prepared, record)
        self.cornering = Cornering(self.state, self.entries, self.roster, self.tick, CorneringSettings(
            int(round(probe * self.fps)), int(round(hold * self.fps)), clearance, bool(park), float(berth), float(near),
            int(max_lookaheads)))
        self.stats = {"extensions": 0, "multi": 0, "forced": 0, "evaluated": 0, "pruned": 0, "deferred": 0,
                      "retracted": 0, "yielded": 0, "paused": 0, "unparkable": 0}
        settings = SearchSettings(self.horizon, sigma_pos, sigma_dir, top_k, jitter_tries, partner_radius, partner_time,
                                  partner_dir, max_singles, clearance, max_retract, max_yields, float(temperature),
                                  max(1, int(first_batch)))
        self.extender = Extender(self.state, self.entries, self.roster, self.playback, self.cornering, self.tick,
                                 self.stats, settings)
        self.last_tick_ms = 0.0

    # -- the clock and the characters -------------------------------------------------------------
    t = property(lambda self: self.tick.t, doc="The clock (s).")
    frame = property(lambda self: self.tick.frame, doc="The clock frame.")
    n = property(lambda self: self.roster.n, doc="Number of characters.")
    team = property(lambda self: self.roster.team, doc="Per character, its team.")
    tail_time = property(lambda self: self.roster.tail_time,
                         doc="Per character, the time its committed motion reaches.")
    targets = property(lambda self: self.roster.targets, doc="Team -> (target position, formation spacing).")

    def set_target(self, team: int, position, spacing: float | None = None) -> None:
        """Steer a team: candidates that leave its characters nearer their spot are preferred.
        The spots form a square grid of ``spacing`` metres (default ``formation_spacing``)
        centred on ``position``, in the order the members were added."""
        self.roster.set_target(team, position, spacing)

    def target_of(self, cid: int):
        """Character ``cid``'s spot, or None if its team has no target."""
        return self.roster.target_of(cid)

    def add_character(self, position, heading: float = 0.0, team: int = 0) -> int:
        """Start a character standing at ``position`` facing ``heading`` at the current time."""
        st = self.state
        c = self.entries.get(self.spawn_class)
        if c is None:
            raise ValueError(f"the library has no patch entering pose class {self.spawn_class}")
        order = np.flatnonzero(c["stand"]) if c["stand"].any() else np.flatnonzero(~c["multi"])
        row = np.array([position[0], position[1], heading, self.t, 0.0, 0.0, 1, self.spawn_class, 1, 0])
        best = None
        for k in order[self.rng.permutation(len(order))]:
            p = int(c["p"][k])
            cand = st.evaluate(p, self.entries.align(c, k, row), match_others=False)
            if best is None:
                best = cand
            if not st.occupancy.collides(cand):
                best = cand
                break
        iid = st.commit(best)
        st.dang.remove((iid, 0))                  # the entry is a source: not dangling
        cid = self.roster.add(team, (iid, 1), st.inst[iid].time[-1], st.next_id)
        st.next_id += 1
        self.playback.add_character()
        self.cornering.add_character()
        self.playback.write(cid, iid, best.p, 0, st.occupancy.samples(st.inst[iid]))
        self.cornering.reserve(cid)
        return cid

    # -- the tick ---------------------------------------------------------------------------------
    def _over_budget(self, done: int, t0: float) -> bool:
        """Whether the tick may extend no further non-urgent character."""
        return done >= self.max_per_tick or (
            self.work_budget is not None and done and self.tick.work + 2.5 > self.work_budget) or (
            self.budget is not None and done and _time.perf_counter() - t0 > self.budget)

    def step(self, t: float | None = None, dt: float | None = None) -> None:
        """Advance the clock to ``t`` (or by ``dt``; default one frame) and fill the horizon."""
        tick = self.tick
        if t is None:
            t = tick.t + (dt if dt is not None else 1.0 / self.fps)
        tick.t = float(t)
        tick.frame = int(round(tick.t * self.fps))
        t0 = _time.perf_counter()
        tick.yields = 0
        tick.work = 0.0
        if self.n:
            ext = self.extender
            need = self.tail_time < tick.t + self.horizon
            urgent_t = tick.t + 3.0 / self.fps
            done = 0
            per = np.zeros(self.n, np.int64)
            while need.any() or self._pending is not None:
                if self._pending is not None:           # the extension paused last tick goes on first
                    cid, gen = self._pending
                    self._pending = None
                else:
                    cid = int(np.flatnonzero(need)[np.argmin(self.tail_time[need])])
                    if self.tail_time[cid] >= urgent_t and self._over_budget(done, t0):
                        self.stats["deferred"] += 1
                        break
                    gen = ext.steps(cid, sync=self.work_budget is None)
                urgent = self.tail_time[cid] < urgent_t
                paused = False
                for _ in gen:
                    # time slicing: a long extension pauses between its steps once the tick's
                    # work is spent, and goes on next tick (a tail far enough ahead can wait)
                    if not urgent and self.work_budget is not None and tick.work > self.work_budget:
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
                            ext.extend(int(u))
                    break
                done += 1
                per[cid] += 1
                # a character retracted by others' yields comes back next tick unless urgent
                need = (self.tail_time < tick.t + self.horizon) & ((per < 3) | (self.tail_time < urgent_t))
        self.last_tick_ms = 1000.0 * (_time.perf_counter() - t0)
        self._ticks += 1
        if self._ticks % 30 == 0:
            self._forget_old()

    def _forget_old(self):
        """Drop instances whose motion is entirely in the past from the index and tables."""
        st = self.state
        tails = {k[0] for k in self.roster.tail}
        old = [iid for iid, inst in st.inst.items() if iid not in tails and inst.time.max() * self.fps < self.frame - 2]
        for iid in old:
            inst = st.inst.pop(iid)
            st.occupancy.index.remove_owner(iid)
            self.cornering.multi.discard(iid)
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
            self.stats["pruned"] += 1

    # -- playback (vectorized over characters) ----------------------------------------------------
    def _frame(self, frame) -> int:
        return self.frame if frame is None else int(frame)

    def root_states(self, frame=None) -> np.ndarray:
        """(C, 3) x, z, heading of every character at the clock frame (NaN if not buffered)."""
        return self.playback.root_states(self._frame(frame))

    def pose_refs(self, frame=None):
        """(frames_a (C,), frames_b (C,), blend (C,), root (C, 3)) into the library's flat pose
        tables (``library.frame_rotations`` / ``frame_height``)."""
        return self.playback.pose_refs(self._frame(frame))

    def poses(self, frame=None):
        """Root positions (C, 3) and local rotations (C, J, 4) (entry 0 = root world rotation)."""
        return self.playback.poses(self._frame(frame))

    def result(self) -> TilingResult:
        """Everything committed so far as a :class:`~runtime.tiling.result.TilingResult` (region:
        the box around all motion plus 1 m, time 0 .. now) for the checker or a bake
        (``record=True``)."""
        if not self.record:
            raise RuntimeError("InteractiveTiling(record=False) keeps no history")
        insts = sorted(self.archive + list(self.state.inst.values()), key=lambda i: i.id)
        allxz = np.concatenate([i.xz for i in insts]) if insts else np.zeros((1, 2))
        lo, hi = np.floor(allxz.min(0)) - 1.0, np.ceil(allxz.max(0)) + 1.0
        reg = Region(float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]), 0.0, self.t)
        return result_of(self.library, reg, insts, self.state.obstacles, [], self.fps, {"stats": dict(self.stats)})

    def tracks(self) -> list[CharacterTrack]:
        """One track per character from its first frame to the last committed one (``record``)."""
        return self.playback.tracks()
