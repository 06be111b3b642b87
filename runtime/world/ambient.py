"""Ambient life: a World system that keeps a crowd of people going about their day.

:class:`AmbientLife` spawns ``count`` people on free ground and keeps giving them goals through
the public World API only (``go_to`` with an arrival window, ``sit`` / ``stand``, ``pick_up`` /
``put_down``, ``meet``): they stroll about and walk to points of interest (free spots of the
square) and linger there, sit on free benches for a while then stand and leave, carry boxes from
where one lies to beside another's first place, and meet in pairs and threes.

Per tick the work is bounded: the people due for a decision are found with one vectorized
comparison over their timers, and at most ``per_tick`` of them (fewer when the World's planning
queue already holds ``max_queue`` characters, so planning latency stays bounded) get a new
activity. Everything else reacts to the World's events (an arrival, a seat taken, a plan not
used), one callback per event. Characters the planner cannot place wait where they stand (the
planner's ladder), and the driver gives them something else to do a little later.

Every choice draws from one seeded random stream, so a seed gives the same day (decisions
depend on the order of events, which the World makes deterministic).

Figures (:attr:`AmbientLife.stats`): goals given, met (arrived inside the window given), late
(arrived after it, or the World reported ``late``), failed (the plan was not used), and
``on_time`` = met / (met + late + failed).
"""
from __future__ import annotations

import math

import numpy as np

from ..crowd.scenario import BOX_REACH

__all__ = ["AmbientLife", "free_spots", "AMBIENT_BUDGET_MS", "AMBIENT_JOB_SLICE"]

AMBIENT_BUDGET_MS = 12.0              # planning budget per tick for a World with ambient people
#                                       (docs/decisions.md: at 4 ms the queue plans about one step a tick)
AMBIENT_JOB_SLICE = 30                # planner steps a goal runs before giving way (World job_slice):
#                                       a named character's long ladder no longer holds up the strolls

# phases of one person
READY, WALK, SIT, SEATED, STAND, FETCH, CARRY, MEET, LINGER = range(9)
BUSY = (WALK, SIT, STAND, FETCH, CARRY, MEET)       # waiting for an event of the World

WALK_FAST, WALK_SLOW = 1.7, 0.8       # m/s: the arrival window of a walk of d metres is
WINDOW_LEAD, WINDOW_SLACK = 2.0, 12.0  # [now + lead + d / fast, now + lead + slack + d / slow], the lead
#                                        grown by the planning latency strolls have seen (LATENCY_RATE)
WALK_PACE = 1.2                       # m/s a stroll is assumed to take, for that latency
LATENCY_RATE = 0.2
SEARCH_LATENCY = 2.0                  # a timed goal needs a search: it waits about this many times longer
TIMEOUT = 45.0                        # s without an event for a busy person: given up, ready again
CLEARANCE = 0.9                       # m from obstacles of a spot someone stands on
SDF_RESOLUTION = 0.2                  # m: the distance grid the clearance tests sample
PERSONAL = 1.3                        # m a stroll's end keeps from where anyone is now
# strolls: (distance m, bearing rad relative to the facing) -- a few repeated tasks, so the World's
# motion cache (Sung, Kovar and Gleicher 2005 crowds repeat tasks) places one searched motion for
# many people; forward moves first, turns back only when nothing ahead is free
STROLLS = np.array([(d, math.radians(b)) for d in (5.0, 9.0) for b in (0.0, -30.0, 30.0)]
                   + [(4.0, math.radians(b)) for b in (-100.0, 100.0, 180.0)])
STROLL_WEIGHT = np.where(np.arange(len(STROLLS)) < 6, 4.0, 1.0)
STROLL_WEIGHT[0] = 12.0               # straight ahead most of all: the first searched motion serves many
KNOWN_STROLL = 8.0                    # weight factor of a stroll somebody has finished (its motion is stored)
STROLL_LINGER = (4.0, 14.0)           # s standing after a stroll
STROLL_SHARE = 0.5                    # of the decisions when a timed goal could be given


def free_spots(env, area, spacing: float, seed: int = 0, exclude=(), clearance: float = CLEARANCE,
               sdf=None) -> np.ndarray:
    """Points (K, 2) of a jittered grid over ``area`` = (x0, z0, x1, z1), ``spacing`` metres
    apart, at least ``clearance`` from every obstacle of ``env`` (through ``sdf``, its signed
    distance grid, when given) and outside every rectangle of ``exclude``; in a seeded random
    order."""
    x0, z0, x1, z1 = area
    rng = np.random.default_rng(seed)
    gx, gz = np.meshgrid(np.arange(x0 + spacing / 2, x1, spacing), np.arange(z0 + spacing / 2, z1, spacing))
    pts = np.stack([gx.ravel(), gz.ravel()], 1)
    pts = pts + rng.uniform(-0.2, 0.2, pts.shape) * spacing
    ok = (pts[:, 0] > x0) & (pts[:, 0] < x1) & (pts[:, 1] > z0) & (pts[:, 1] < z1)
    for ex0, ez0, ex1, ez1 in exclude:
        ok &= ~((pts[:, 0] > ex0) & (pts[:, 0] < ex1) & (pts[:, 1] > ez0) & (pts[:, 1] < ez1))
    if env is not None and env.num_obstacles:
        ok[ok] = (sdf if sdf is not None else env.sdf(SDF_RESOLUTION, 2.0)).sample(pts[ok]) > clearance
    pts = pts[ok]
    return pts[rng.permutation(len(pts))]


class AmbientLife:
    """People going about their day on a World (a system: ``world.add_system(life)``).

    Args:
        world: the World (its environment gives seats, boxes and spawn markers).
        count: people to spawn (named ``prefix`` + number).
        seed: the random stream of every choice.
        area: (x0, z0, x1, z1) where people spawn and walk (default: the environment's bounds).
        exclude: rectangles (x0, z0, x1, z1) nobody is sent into (e.g. tiling zones).
        seats, boxes: marker paths the driver may use (default: all of the world's; leave out
            the ones a scenario's characters use).
        linger: (min, max) seconds spent at a spot, on a bench, or in a conversation.
        per_tick: decisions per tick at most; max_queue: no new goal while the World's
            planning queue holds this many characters; max_planned: goals that need a search
            (all but strolls) in flight at most.
        start_within: seconds over which the first goals are spread.
        keep_clear: ((x0, z0, x1, z1), until) pairs: nobody spawns there, and nobody is sent
            there before world time ``until`` s (room for a scenario's own characters).
    """

    name = "ambient"

    def __init__(self, world, count: int, seed: int = 0, area=None, exclude=(), seats=None, boxes=None,
                 linger=(10.0, 40.0), per_tick: int = 3, max_queue: int = 16, start_within: float = 15.0,
                 keep_clear=(), max_planned: int = 3, prefix: str = "amb"):
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
            raise ValueError(f"count must be a non-negative integer, got {count!r}")
        env = world.env
        self.world, self.env = world, env
        self.sdf = env.sdf(SDF_RESOLUTION, 2.0) if env is not None and env.num_obstacles else None
        self.rng = np.random.default_rng(seed)
        self.area = tuple(float(v) for v in (area if area is not None else
                                             (env.bounds(0.0) if env is not None else (-20, -20, 20, 20))))
        self.exclude = [tuple(float(v) for v in r) for r in exclude]
        self.keep_clear = [(tuple(float(v) for v in r), float(until)) for r, until in keep_clear]
        self.linger = (float(linger[0]), float(linger[1]))
        self.per_tick, self.max_queue, self.max_planned = int(per_tick), int(max_queue), int(max_planned)
        markers = env.markers if env is not None else {}
        seat_paths = sorted(p for p, m in markers.items() if m.role == "seat") if seats is None else list(seats)
        box_paths = sorted(p for p, m in markers.items() if m.role == "box") if boxes is None else list(boxes)
        self.seats = seat_paths
        self.seat_xz = np.array([markers[p].position for p in seat_paths], float).reshape(-1, 2)
        self.boxes = box_paths
        self.box_xz = np.array([markers[p].position for p in box_paths], float).reshape(-1, 2)
        self.box_taken = np.zeros(len(box_paths), bool)
        self.box_home = self.box_xz.copy()
        # points of interest: spots in the open, and people-sized places by the markers
        spots = free_spots(env, self.area, 2.0, seed, self.exclude, sdf=self.sdf)
        self.spots = spots
        self.spot_taken = np.zeros(len(spots), bool)
        # spawn on a coarser grid of the same free ground, clear of everyone there already
        starts = free_spots(env, self.area, 1.9, seed + 1, self.exclude + [r for r, _ in self.keep_clear],
                            clearance=1.0, sdf=self.sdf)
        others = world.root_states()[:, :2] if len(world.names) else np.zeros((0, 2))
        if len(others):
            d = np.linalg.norm(starts[:, None] - others[None], axis=-1).min(1)
            starts = starts[d > 1.6]
        self.names = [f"{prefix}{i:03d}" for i in range(count)]
        self.index = {n: i for i, n in enumerate(self.names)}
        self.seat_taken = np.zeros(len(seat_paths), bool)
        self.seat_of = np.full(count, -1, np.int64)
        pos, heading, seated, grouped = self._layout(starts, count, markers)
        for i, n in enumerate(self.names):
            world.spawn(n, pos[i], float(heading[i]), "sit" if seated[i] else "stand")
        self.slots = np.array([world.slot(n) for n in self.names], np.int64)
        # the day is under way: some sit on benches, some stand talking in small groups; the
        # rest make up their minds over the first ``start_within`` seconds
        self.phase = np.where(seated, SEATED, np.where(grouped, LINGER, READY)).astype(np.int8)
        self.next_t = world.time + np.where(seated | grouped, self.rng.uniform(*self.linger, count),
                                            self.rng.uniform(0.0, start_within, count))
        self.deadline = np.full(count, np.inf)
        self.window = np.full((count, 2), np.nan)       # arrival window of the pending timed goal
        self.spot_of = np.full(count, -1, np.int64)     # spot (or seat / box) each person holds
        self.box_of = np.full(count, -1, np.int64)
        self.holding = np.zeros(count, bool)            # carries box_of[i]
        self.short = np.zeros(count, bool)              # the pending walk is a stroll
        self.stroll_of = np.full(count, -1, np.int64)    # which of STROLLS it is
        self.stroll_known = np.zeros(len(STROLLS), bool)  # strolls somebody has finished
        self.goals_had = np.zeros(count, np.int64)
        self.issued = np.zeros(count)                   # world time the pending goal was given
        self.latency = 0.0      # s from giving a stroll to its start, a running average over arrivals
        self.stats = {"people": count, "goals": 0, "met": 0, "late": 0, "failed": 0, "timeouts": 0,
                      "arrived": 0, "strolls": 0, "walks": 0, "sits": 0, "carries": 0, "meetings": 0}
        self.world = world
        for kind in ("arrived", "sat", "stood", "picked_up", "put_down", "late", "warning"):
            world.on(kind, self._event)

    def _layout(self, starts, count: int, markers):
        """Where the people start: one in twenty on free benches (seated; half the seats stay
        free), a quarter in groups of
        two or three facing each other, the rest standing at free spots. Returns positions
        (count, 2), headings, and the seated and grouped masks."""
        rng = self.rng
        seated = np.zeros(count, bool)
        grouped = np.zeros(count, bool)
        pos = np.zeros((count, 2))
        heading = rng.uniform(-math.pi, math.pi, count)
        open_seats = np.flatnonzero(self._unreserved(self.seat_xz))
        n_seat = min(count // 20, len(open_seats) // 2)
        for k, j in enumerate(rng.permutation(open_seats)[:n_seat]):
            m = markers[self.seats[j]]
            pos[k], heading[k], seated[k] = m.position, m.heading, True
            self.seat_taken[j], self.seat_of[k] = True, j
        if len(starts) and n_seat:    # nobody starts next to a bench someone sits on
            starts = starts[np.linalg.norm(starts[:, None] - pos[None, :n_seat], axis=-1).min(1) > 1.6]
        i, used = n_seat, np.zeros(len(starts), bool)
        for c in range(len(starts)):            # groups round every few start spots
            if i >= n_seat + count // 4 or count - i < 3:
                break
            if used[c] or c % 3:
                continue
            n = int(rng.integers(2, 4))
            around = np.linalg.norm(starts - starts[c], axis=1) < 2.7
            if used[around].any():
                continue
            used |= around
            a0 = rng.uniform(0, 2 * math.pi)
            for k in range(n):
                a = a0 + 2 * math.pi * k / n
                pos[i] = starts[c] + 0.6 * np.array([math.sin(a), math.cos(a)])
                heading[i] = a + math.pi          # facing the group's centre
                grouped[i] = True
                i += 1
        rest = starts[~used]
        if len(rest) < count - i:
            raise ValueError(f"ambient: room for {i + len(rest)} people in area {self.area}, {count} asked for")
        pos[i:] = rest[:count - i]
        return pos, heading, seated, grouped

    # -- what the HUD and the command line show ---------------------------------------------------------
    @property
    def on_time(self) -> float:
        """Fraction of finished timed goals that arrived inside their window."""
        s = self.stats
        done = s["met"] + s["late"] + s["failed"]
        return s["met"] / done if done else 1.0

    def busiest(self, cell: float = 16.0) -> tuple:
        """(x, 0, z, radius) round the densest ``cell``-metre square of people now: where a
        camera shows most of them at a person's scale."""
        pos = self._positions()
        if not len(pos):
            x0, z0, x1, z1 = self.area
            return (0.5 * (x0 + x1), 0.0, 0.5 * (z0 + z1), 0.5 * cell)
        x0, z0, _, _ = self.area
        # counts in cell squares on a grid offset by half a cell too, so a cluster on a line counts once
        best, centre = -1, pos.mean(0)
        for off in (0.0, 0.5 * cell):
            ij = np.floor((pos - (x0 - off, z0 - off)) / cell).astype(np.int64)
            keys, inv, counts = np.unique(ij, axis=0, return_inverse=True, return_counts=True)
            k = int(np.argmax(counts))
            if counts[k] > best:
                best, centre = int(counts[k]), pos[inv.ravel() == k].mean(0)
        return (float(centre[0]), 0.0, float(centre[1]), 0.5 * cell)

    def hud_stats(self) -> dict:
        s = self.stats
        done = s["met"] + s["late"] + s["failed"]
        return {"ambient": len(self.names), "with a goal": int(np.isin(self.phase, BUSY).sum()),
                "goals met on time": f"{s['met']}/{done}" + (f" ({100 * s['met'] / done:.0f}%)" if done else "")}

    # -- the tick ---------------------------------------------------------------------------------------
    def tick(self, world) -> None:
        now = world.time
        stuck = np.flatnonzero(self.deadline < now)
        for i in stuck[:self.per_tick]:          # no event for too long: free it
            self.stats["timeouts"] += 1
            self._release(i)
            self.phase[i] = READY
            self.deadline[i] = np.inf
            self.next_t[i] = now
        room = min(self.per_tick, self.max_queue - int(world.stats.get("queue", 0)))
        if room <= 0:
            return
        due = np.flatnonzero((self.next_t <= now) & ~np.isin(self.phase, BUSY))
        if not len(due):
            return
        due = due[np.argsort(self.next_t[due], kind="stable")][:room]
        pos = self._positions(heading=True)
        for i in due:
            self._decide(int(i), now, pos)

    def _positions(self, heading: bool = False) -> np.ndarray:
        """(x, z) -- or (x, z, heading) -- now of every person (one gather over the World's
        playback)."""
        s, *_, root = self.world.playback.gather(0)
        rows = np.searchsorted(s, self.slots)
        return root[np.clip(rows, 0, len(s) - 1), :3 if heading else 2]

    def _unreserved(self, pts) -> np.ndarray:
        """Which points (K, 2) lie outside every ``keep_clear`` rectangle still in force."""
        ok = np.ones(len(pts), bool)
        now = self.world.time
        for (x0, z0, x1, z1), until in self.keep_clear:
            if now < until:
                ok &= ~((pts[:, 0] > x0) & (pts[:, 0] < x1) & (pts[:, 1] > z0) & (pts[:, 1] < z1))
        return ok

    def _free(self, pts) -> np.ndarray:
        """Which points (K, 2) are inside the area, outside the excluded rectangles and at
        least ``CLEARANCE`` from obstacles."""
        x0, z0, x1, z1 = self.area
        ok = (pts[:, 0] > x0) & (pts[:, 0] < x1) & (pts[:, 1] > z0) & (pts[:, 1] < z1)
        now = self.world.time
        for ex0, ez0, ex1, ez1 in self.exclude + [r for r, until in self.keep_clear if now < until]:
            ok &= ~((pts[:, 0] > ex0) & (pts[:, 0] < ex1) & (pts[:, 1] > ez0) & (pts[:, 1] < ez1))
        if self.sdf is not None and ok.any():
            ok[ok] = self.sdf.sample(pts[ok]) > CLEARANCE
        return ok

    def _decide(self, i: int, now: float, pos) -> None:
        w, name = self.world, self.names[i]
        ph = self.phase[i]
        if ph == SEATED:
            self._release(i)
            w.stand(name)
            self._busy(i, STAND, now)
            return
        self._release(i)
        if self.holding[i]:                      # a box still in the hands: put it down somewhere
            dest = self._drop_spot(int(self.box_of[i]), pos[i, :2])
            self.world.put_down(name, dest[:2], dest[2])
            self._busy(i, CARRY, now)
            return
        expensive = int(np.isin(self.phase, (SIT, FETCH, CARRY, MEET)).sum() + (self.phase == WALK).sum()
                        - self.short[self.phase == WALK].sum())
        r = self.rng.random()
        if expensive >= self.max_planned or r < STROLL_SHARE:   # mostly strolls: their motions are reused
            if not self._stroll(i, now, pos):
                self.next_t[i] = now + 3.0
            return
        r = self.rng.random()
        done = (r < 0.3 and self._try_sit(i, now, pos)) or (r < 0.45 and self._try_carry(i, now, pos)) \
            or (r < 0.65 and self._try_meet(i, now, pos)) or self._walk(i, now, pos) or self._stroll(i, now, pos)
        if not done:
            self.next_t[i] = now + 3.0

    def _stroll(self, i: int, now: float, pos) -> bool:
        """An untimed walk of one of the :data:`STROLLS` from where person ``i`` stands to a
        free spot with a clear straight line; False when none is. The walk is relative to the
        configuration the person's idling returns to (its last buffered boundary: where the
        World hands over to a new plan), so the same stroll is the same task for the World's
        motion cache whoever walks it."""
        bounds = self.world.playback.boundaries[self.slots[i]]
        if bounds:
            cfg = bounds[-1][1]
            p, h = np.array([cfg.x, cfg.z]), float(cfg.heading)
        else:
            p, h = pos[i, :2], pos[i, 2]
        ang = h + STROLLS[:, 1]
        tgt = p + STROLLS[:, :1] * np.stack([np.sin(ang), np.cos(ang)], 1)
        ok = self._free(tgt)
        if ok.any() and self.env is not None and self.env.num_obstacles:
            ok[ok] = self.env.segment_clear(np.broadcast_to(p, (int(ok.sum()), 2)), tgt[ok], 0.5)
        if ok.any():          # the walk's line keeps PERSONAL metres from where everyone else is now
            a, b = p, tgt[ok]
            ab = b - a
            q = np.delete(pos[:, :2], i, axis=0) - a
            t = np.clip((q @ ab.T) / np.maximum((ab * ab).sum(1), 1e-12), 0.0, 1.0)      # (people, K)
            gap = np.linalg.norm(q[:, None, :] - t[..., None] * ab[None], axis=-1).min(0)
            ok[ok] = gap > PERSONAL
        cand = np.flatnonzero(ok)
        if not len(cand):
            return False
        wgt = STROLL_WEIGHT[cand] * np.where(self.stroll_known[cand], KNOWN_STROLL, 1.0)
        k = int(self.rng.choice(cand, p=wgt / wgt.sum()))
        self.world.go_to(self.names[i], tgt[k])
        self.stats["strolls"] += 1
        self._busy(i, WALK, now)
        self.short[i], self.stroll_of[i] = True, k
        return True

    def _busy(self, i: int, phase: int, now: float, window=None) -> None:
        self.phase[i] = phase
        self.issued[i] = now
        self.short[i] = False
        self.deadline[i] = now + TIMEOUT + (0.0 if window is None else window[1] - now)
        self.window[i] = (np.nan, np.nan) if window is None else window
        self.goals_had[i] += 1
        self.stats["goals"] += window is not None

    def _window(self, now: float, d: float):
        """The arrival window promised for a walk of ``d`` metres given now: the planning
        latency the strolls have been seeing, then the walk at a brisk to a slow pace."""
        lead = WINDOW_LEAD + SEARCH_LATENCY * self.latency
        return (now + lead + d / WALK_FAST, now + lead + WINDOW_SLACK + d / WALK_SLOW)

    def _pick_spot(self, p, lo: float = 5.0, hi: float = 18.0) -> int:
        d = np.linalg.norm(self.spots - p[:2], axis=1)
        open_ = ~self.spot_taken & self._free(self.spots)
        cand = np.flatnonzero(open_ & (d > lo) & (d < hi))
        if not len(cand):
            cand = np.flatnonzero(open_)
        return int(self.rng.choice(cand)) if len(cand) else -1

    def _walk(self, i: int, now: float, pos) -> bool:
        k = self._pick_spot(pos[i])
        if k < 0:
            return False
        self.spot_taken[k] = True
        self.spot_of[i] = k
        d = float(np.linalg.norm(self.spots[k] - pos[i, :2]))
        win = self._window(now, d)
        self.world.go_to(self.names[i], self.spots[k], arrive=win)
        self.stats["walks"] += 1
        self._busy(i, WALK, now, win)
        return True

    def _nearest(self, xz, taken, p) -> int:
        """The nearest marker of ``xz`` (K, 2) not ``taken``, outside the kept-clear rectangles
        and within 25 m of ``p``; -1 when there is none."""
        if not len(xz):
            return -1
        d = np.linalg.norm(xz - p, axis=1)
        cand = np.flatnonzero(~taken & (d < 25.0) & self._unreserved(xz))
        return int(cand[np.argmin(d[cand])]) if len(cand) else -1

    def _try_sit(self, i: int, now: float, pos) -> bool:
        """Sit on the nearest free bench seat (False when none is in reach)."""
        return self._claim(i, now, pos, "sits")

    def _try_carry(self, i: int, now: float, pos) -> bool:
        """Pick up the nearest free box (its carrying on is the picked_up event's)."""
        return len(self.boxes) >= 2 and self._claim(i, now, pos, "carries")

    def _claim(self, i: int, now: float, pos, what: str) -> bool:
        if what == "sits":
            xz, taken, held, paths, command, phase = (self.seat_xz, self.seat_taken, self.seat_of, self.seats,
                                                      self.world.sit, SIT)
        else:
            xz, taken, held, paths, command, phase = (self.box_xz, self.box_taken, self.box_of, self.boxes,
                                                      self.world.pick_up, FETCH)
        k = self._nearest(xz, taken, pos[i, :2])
        if k < 0:
            return False
        taken[k], held[i] = True, k
        command(self.names[i], paths[k])
        self.stats[what] += 1
        self._busy(i, phase, now)
        return True

    def _try_meet(self, i: int, now: float, pos) -> bool:
        free = (self.phase == READY) | (self.phase == LINGER)
        free[i] = False
        pos = pos[:, :2]
        d = np.linalg.norm(pos - pos[i], axis=1)
        cand = np.flatnonzero(free & (d < 12.0) & (self.next_t <= now + 10.0))
        if not len(cand):
            return False
        group = [i] + [int(j) for j in cand[np.argsort(d[cand])][:int(self.rng.integers(1, 3))]]
        centre = pos[group].mean(0)
        dist = np.linalg.norm(self.spots - centre, axis=1)
        ok = np.flatnonzero(~self.spot_taken & self._free(self.spots))
        if not len(ok):
            return False
        k = int(ok[np.argmin(dist[ok])])
        for j in group:
            self._release(j)
        self.spot_taken[k] = True
        self.spot_of[i] = k
        far = float(np.linalg.norm(pos[group] - self.spots[k], axis=1).max())
        t = now + WINDOW_LEAD + SEARCH_LATENCY * self.latency + WINDOW_SLACK + far / WALK_SLOW
        self.world.meet([self.names[j] for j in group], self.spots[k], t)
        self.stats["meetings"] += 1
        for j in group:
            self._busy(j, MEET, now, (t, t + 0.5))
        return True

    def _release(self, i: int) -> None:
        """Free the spot and seat person ``i`` holds."""
        for held, taken in ((self.spot_of, self.spot_taken), (self.seat_of, self.seat_taken)):
            if held[i] >= 0:
                taken[held[i]] = False
                held[i] = -1

    # -- events -----------------------------------------------------------------------------------------
    def _event(self, e) -> None:
        i = self.index.get(e.character)
        if i is None:
            return
        now, ph = e.time, self.phase[i]
        if e.kind == "late":
            if not np.isnan(self.window[i, 0]):
                self.stats["late"] += 1
                self.window[i] = np.nan
            return
        if e.kind == "warning":
            msg = str(e.data.get("message", ""))
            if "plan not used" in msg or "planning failed" in msg or "could not use" in msg \
                    or "no character" in msg or "no seat" in msg or "no box" in msg:
                self._failed(i, now)
            return
        if ph not in BUSY:
            return
        if not np.isnan(self.window[i, 0]):
            t0, t1 = self.window[i]
            self.stats["met" if t0 - 1e-6 <= now <= t1 + 1e-6 else "late"] += 1
            self.window[i] = np.nan
        self.deadline[i] = np.inf
        lo, hi = self.linger
        if e.kind == "sat":
            self.phase[i], self.next_t[i] = SEATED, now + self.rng.uniform(lo, hi)
        elif e.kind == "picked_up":
            k = self.box_of[i]
            self.holding[i] = True
            dest = self._drop_spot(k, e.data.get("position"))
            self.world.put_down(self.names[i], dest[:2], dest[2])
            self._busy(i, CARRY, now)
        elif e.kind == "put_down":
            k = self.box_of[i]
            if k >= 0:
                h = float(e.data.get("heading", 0.0))
                p = np.asarray(e.data.get("position", self.box_xz[k]), float)
                self.box_xz[k] = p + BOX_REACH * np.array([math.sin(h), math.cos(h)])
                self.box_taken[k] = False
                self.box_of[i] = -1
            self.holding[i] = False
            self.phase[i], self.next_t[i] = LINGER, now + self.rng.uniform(2.0, 6.0)
        elif e.kind == "stood":
            self.phase[i], self.next_t[i] = READY, now + 0.5
        else:                                     # arrived: linger at the spot
            self.stats["arrived"] += 1
            if self.short[i]:
                lo, hi = STROLL_LINGER
                self.stroll_known[self.stroll_of[i]] = True
                took = now - self.issued[i] - STROLLS[self.stroll_of[i], 0] / WALK_PACE
                self.latency += LATENCY_RATE * (float(np.clip(took, 0.0, 60.0)) - self.latency)
            self.phase[i], self.next_t[i] = LINGER, now + self.rng.uniform(lo, hi)

    def _drop_spot(self, k: int, at) -> np.ndarray:
        """(x, z, heading) where a box picked up near ``at`` is put down: in front of another
        box's home stall, facing it."""
        at = np.asarray(at if at is not None else self.box_home[k], float)
        d = np.linalg.norm(self.box_home - at, axis=1)
        cand = np.flatnonzero((d > 6.0) & self._unreserved(self.box_home))
        j = int(self.rng.choice(cand)) if len(cand) else k
        m = self.world.env.markers[self.boxes[j]]
        h = float(m.heading)
        side = self.rng.uniform(-1.2, 1.2)
        fwd, right = np.array([math.sin(h), math.cos(h)]), np.array([math.cos(h), -math.sin(h)])
        p = self.box_home[j] + 1.3 * fwd + side * right
        return np.array([p[0], p[1], h + math.pi])

    def _failed(self, i: int, now: float) -> None:
        if not np.isnan(self.window[i, 0]):
            self.stats["failed"] += 1
            self.window[i] = np.nan
        if self.phase[i] in BUSY:
            if self.phase[i] == FETCH and self.box_of[i] >= 0:      # a box not reached is free again
                self.box_taken[self.box_of[i]] = False
                self.box_of[i] = -1
            if self.phase[i] == STAND:                                # still seated: try standing later
                self.phase[i] = SEATED
            else:
                self._release(i)
                self.phase[i] = READY
            self.deadline[i] = np.inf
            self.next_t[i] = now + self.rng.uniform(3.0, 8.0)
