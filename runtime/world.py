"""World: the runtime a game embeds — fixed-timestep loop, commands, staged synthesis, poses.

The tick (ARCHITECTURE.md)::

    accumulate real time; while accumulator >= dt:
        apply queued commands
        crowd scheduler: plan the next constraint segment for characters that need one, within
                         a time budget (default 4 ms); unfinished work continues next tick
        flocks, tiling: registered systems, in that order
        advance clocks; emit events (arrived, sat, stood, picked_up, put_down, late, warning)
    render: poses interpolated between the last two ticks, all characters in one pass

**Playback.** Every character owns a ring buffer of future frames (library frames a/b/t and
the root x, z, heading) on the world clock. A tick advances every read head at once; the
current pose of all characters is one gather (no per-character Python loop). When a buffer
runs low and nothing is planned, idle clips of the character's node are appended, so a
character never freezes.

**Staged synthesis** (paper 000, section 5: "the search can be broken into stages"). A goal
given at run time is planned from a *hand-off* on the character's buffered future: the first
point at least ``latency`` ahead where the character stands exactly on a graph node (the end
of an idle loop, or the end of the segment it is playing). The planner is the generator of
:class:`~runtime.crowd.synthesis.SegmentPlanner`; it runs under the per-tick budget and
resumes on the next tick. When it finishes, its segment replaces the buffer after the
hand-off. Planned characters are moving obstacles for later plans (a space-time index of
buffered frames). A plan that raises or fails emits a ``warning`` event; the character keeps
playing what it has. Nothing a character does can make :meth:`World.step` raise.

Limits: ``MAX_BUFFER`` frames (60 s) per character; a plan whose hand-off has already played
when it finishes is planned again from a later hand-off.
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from .crowd.scenario import BOX_REACH
from .crowd.scheduler import idle_track
from .crowd.spacetime import SpaceTimeIndex
from .crowd.synthesis import Config, Goal, MotionLibrary, SegmentPlanner, SynthesisParams
from .crowd.tracks import Track, evaluate_poses
from .motion.fk import forward_kinematics
from .motion.graph import MotionGraph

__all__ = ["World", "CharacterState", "Event", "MAX_BUFFER"]

MAX_BUFFER = 1800          # frames of future per character (60 s at 30 Hz)
REFILL_BELOW = 45          # frames: append idle when fewer than this remain
LATENCY = 12               # frames between "now" and the earliest hand-off


class CharacterState(Enum):
    IDLE = "idle"           # playing idle clips, no goal
    QUEUED = "queued"       # has a goal waiting for the planner
    PLANNING = "planning"   # the planner is working on its goal
    MOVING = "moving"       # playing a planned segment


@dataclass
class Event:
    kind: str               # arrived | sat | stood | picked_up | put_down | late | warning
    character: str
    time: float
    data: dict = field(default_factory=dict)


@dataclass
class _Pending:
    goal: Goal
    kind: str               # "go_to" | "sit" | "stand" | "pick_up" | "put_down"
    marker: str | None = None
    label: str = ""


@dataclass
class _Char:
    name: str
    slot: int
    goals: deque = field(default_factory=deque)
    state: CharacterState = CharacterState.IDLE
    boundaries: list = field(default_factory=list)   # (abs frame, Config) where it stands on a node
    job: object = None
    job_goal: _Pending | None = None
    job_handoff: Config | None = None
    arrivals: list = field(default_factory=list)      # (abs frame, _Pending) still to announce
    carrying: str | None = None


class World:
    def __init__(self, library="default", world=None, roadmap=None, dt: float = 1.0 / 30.0,
                 budget_ms: float = 4.0, seed: int = 0, params: SynthesisParams | None = None,
                 capacity: int = 64):
        from .library import load_library
        self.graph: MotionGraph = library if isinstance(library, MotionGraph) else load_library(library)
        if world is None or hasattr(world, "polygons"):
            self.env = world
        else:
            from usd_io.world import read_world   # only when a stage path is given
            self.env = read_world(world)
        self.roadmap = roadmap
        self.dt = float(dt)
        self.fps = 1.0 / self.dt
        self.budget = budget_ms / 1000.0
        # online planning gives up sooner than the paper's offline N_max = 1000: a character
        # that cannot be planned must not hold the queue for seconds
        # and each step is kept small (n_m perturbations per iteration) so that one step fits
        # well inside the per-tick budget
        self.params = params or SynthesisParams(fps=self.fps, n_max=150, n_m=48, k_m=16, sweep=24, backward_idle=True)
        self.lib = MotionLibrary(self.graph, self.params)
        self.rng = np.random.default_rng(seed)
        self.frame = 0
        self.accumulator = 0.0
        self.flocks: list = []            # FlockSystems (one per DDG), stepped every tick
        self.systems: list = []           # extra per-tick systems: callables (world) -> None
        self._listeners: dict = {}
        self.events: list[Event] = []
        self._commands: deque = deque()
        self._chars: dict[str, _Char] = {}
        self._slots: list = []
        self._plan_queue: deque = deque()
        self._active: _Char | None = None
        self.index = SpaceTimeIndex(cell=max(1.2, 2 * self.lib.max_radius + 2 * (self.lib.params.margin + self.lib.params.seed_margin) + 0.1))
        self.stats = {"tick_ms": 0.0, "plan_ms": 0.0, "characters": 0, "queue": 0, "ticks": 0}
        self.selected = None
        self._step_ema = 0.0005         # running average of a planner step's duration (s)
        self._box_place: dict = {}     # boxes put down somewhere else: path -> (x, z, heading)
        self._static = None
        if self.env is not None and (len(self.env.polygons) or len(self.env.circles)):
            sdf = self.env.sdf(resolution=0.05, margin=2.0)
            self._static = lambda xz: sdf.sample(xz) - sdf.max_error
        self._alloc(capacity)

    # ------------------------------------------------------------------ storage
    def _alloc(self, cap):
        self.cap = cap
        self.active = np.zeros(cap, dtype=bool)
        self.head = np.zeros(cap, dtype=np.int64)        # absolute frame of the current pose
        self.tail = np.zeros(cap, dtype=np.int64)        # absolute frame of the last buffered frame
        self.buf_a = np.zeros((cap, MAX_BUFFER), dtype=np.int64)
        self.buf_b = np.zeros((cap, MAX_BUFFER), dtype=np.int64)
        self.buf_t = np.zeros((cap, MAX_BUFFER), dtype=np.float32)
        self.buf_root = np.zeros((cap, MAX_BUFFER, 3))
        self.tail_node = np.zeros(cap, dtype=np.int64)
        self._slots = [None] * cap

    def _grow(self):
        old = (self.active, self.head, self.tail, self.buf_a, self.buf_b, self.buf_t, self.buf_root, self.tail_node, self._slots)
        n = self.cap
        self._alloc(n * 2)
        self.active[:n], self.head[:n], self.tail[:n] = old[0], old[1], old[2]
        self.buf_a[:n], self.buf_b[:n], self.buf_t[:n], self.buf_root[:n] = old[3], old[4], old[5], old[6]
        self.tail_node[:n] = old[7]
        self._slots[:n] = old[8]

    def _write(self, c: _Char, track: Track, from_frame: int):
        """Replace the buffer of ``c`` from absolute frame ``from_frame`` with ``track`` (whose
        first frame is at ``from_frame``)."""
        s = c.slot
        n = len(track)
        if from_frame + n - 1 - self.head[s] >= MAX_BUFFER:
            n = int(MAX_BUFFER - (from_frame - self.head[s]))
            track = track.slice(0, n)
        idx = (from_frame + np.arange(n)) % MAX_BUFFER
        self.buf_a[s, idx] = track.frames_a
        self.buf_b[s, idx] = track.frames_b
        self.buf_t[s, idx] = track.frames_t
        self.buf_root[s, idx] = track.root
        self.tail[s] = from_frame + n - 1
        c.boundaries = [(f, cfg) for f, cfg in c.boundaries if f < from_frame]
        # the space-time index holds every character's buffered future
        self.index.remove_owner(s)
        f0 = max(int(self.head[s]), 0)
        frames = np.arange(f0, self.tail[s] + 1)
        k = frames % MAX_BUFFER
        rad = np.maximum(self.graph.frame_radius[self.buf_a[s, k]], self.graph.frame_radius[self.buf_b[s, k]])
        self.index.insert(s, frames, self.buf_root[s, k, :2], rad)

    def _config_at_tail(self, c: _Char) -> Config:
        s = c.slot
        r = self.buf_root[s, self.tail[s] % MAX_BUFFER]
        return Config(int(self.tail_node[s]), float(r[0]), float(r[1]), float(r[2]), int(self.tail[s]))

    def _append_idle(self, c: _Char, seconds: float = 3.0):
        """Append whole idle loops (the node's self-loop clip, drift removed) after the tail;
        each loop ends exactly on the node, so each loop end is a hand-off point."""
        cfg = self._config_at_tail(c)
        loop = self._loop_len(cfg.node)
        want = max(1, int(round(seconds * self.fps)))
        n = (int(math.ceil(want / loop)) * loop if loop else want) + 1
        self._write(c, idle_track(self.lib, cfg, n), cfg.frame)
        step = loop if loop else n - 1
        for k in range(step, n, step):
            c.boundaries.append((cfg.frame + k, Config(cfg.node, cfg.x, cfg.z, cfg.heading, cfg.frame + k)))

    def _loop_len(self, node):
        g = self.graph
        loops = np.flatnonzero((g.edge_src == node) & (g.edge_dst == node))
        if len(loops) == 0:
            return 0
        drift = np.hypot(g.edge_disp[loops, 0], g.edge_disp[loops, 1]) + 0.3 * np.abs(g.edge_disp[loops, 2])
        e = int(loops[np.argmin(drift)])
        return int(g.edge_frames[e] - 1)

    # ------------------------------------------------------------------ characters
    @property
    def names(self) -> list[str]:
        return [self._slots[i].name for i in np.flatnonzero(self.active)]

    def spawn(self, name: str, position, heading: float = 0.0, pose: str = "stand") -> int:
        """Add a character standing (or seated: pose "sit") at ``position`` (x, z), facing
        ``heading`` (radians, 0 = +Z). Returns its slot."""
        if name in self._chars:
            raise ValueError(f"a character named {name!r} already exists")
        nodes = self.graph.nodes_with_label(pose)
        if len(nodes) == 0:
            raise ValueError(f"pose {pose!r} is not a node label of the library ({self.graph.node_labels_all()})")
        free = np.flatnonzero(~self.active)
        if len(free) == 0:
            self._grow()
            free = np.flatnonzero(~self.active)
        s = int(free[0])
        deg = np.bincount(self.graph.edge_src, minlength=self.graph.num_nodes)[nodes]
        node = int(nodes[np.argmax(deg)])
        c = _Char(name, s)
        self._chars[name] = c
        self._slots[s] = c
        self.active[s] = True
        self.head[s] = self.frame
        self.tail[s] = self.frame
        self.tail_node[s] = node
        self.buf_root[s, self.frame % MAX_BUFFER] = (position[0], position[1], heading)
        first = self.graph.edge_start[self.graph.out_edges(node)[0]] if len(self.graph.out_edges(node)) else 0
        self.buf_a[s, self.frame % MAX_BUFFER] = first
        self.buf_b[s, self.frame % MAX_BUFFER] = first
        self.buf_t[s, self.frame % MAX_BUFFER] = 0.0
        c.boundaries.append((self.frame, Config(node, float(position[0]), float(position[1]), float(heading), self.frame)))
        self._append_idle(c)
        return s

    def remove(self, name: str) -> None:
        c = self._chars.pop(name)
        self.active[c.slot] = False
        self._slots[c.slot] = None
        self.index.remove_owner(c.slot)
        if self._active is c:
            self._active = None
        if c in self._plan_queue:
            self._plan_queue.remove(c)

    def state(self, name: str) -> CharacterState:
        return self._chars[name].state

    def position(self, name: str) -> np.ndarray:
        c = self._chars[name]
        return self.buf_root[c.slot, self.head[c.slot] % MAX_BUFFER].copy()

    # ------------------------------------------------------------------ commands (queued)
    def go_to(self, name, position, heading=None, arrive=None, queue: bool = False):
        """Walk to ``position`` (x, z), optionally facing ``heading`` (radians) and arriving in
        the absolute time window ``arrive = (t0, t1)`` seconds. A new go_to replaces goals that
        are still waiting for the planner unless ``queue`` is True (then it comes after them)."""
        self._commands.append(("go_to", name, np.asarray(position, float), heading, arrive, queue))

    def sit(self, name, seat):
        self._commands.append(("sit", name, None, None, None, seat))

    def stand(self, name):
        self._commands.append(("stand", name, None, None, None, None))

    def pick_up(self, name, box):
        self._commands.append(("pick_up", name, None, None, None, box))

    def put_down(self, name, position, heading=None):
        self._commands.append(("put_down", name, np.asarray(position, float), heading, None, None))

    def meet(self, names, position, time_s):
        """Characters arrive together at ``time_s`` around ``position``, facing its centre."""
        n = len(names)
        r = 0.0 if n == 1 else max(0.55, 0.75 / (2 * math.sin(math.pi / n)))
        for k, name in enumerate(names):
            a = 2 * math.pi * k / n
            p = np.asarray(position, float) + r * np.array([math.sin(a), math.cos(a)])
            h = math.atan2(position[0] - p[0], position[1] - p[1]) if n > 1 else None
            self.go_to(name, p, heading=h, arrive=(time_s, time_s + 0.5))

    def on(self, kind: str, callback) -> None:
        """Call ``callback(event)`` for events of ``kind`` ("*" for all)."""
        self._listeners.setdefault(kind, []).append(callback)

    def _marker(self, path, role):
        m = self.env.markers.get(path) if self.env is not None else None
        if m is None or m.role != role:
            raise ValueError(f"no {role} marker {path!r} in the world")
        return m

    def _apply(self, cmd):
        kind, name, pos, heading, arrive, marker = cmd
        c = self._chars.get(name)
        if c is None:
            self._emit("warning", name, message=f"{kind}: no character named {name!r}")
            return
        try:
            g = self.graph
            if kind == "go_to":
                goal = Goal(pos, heading, None, tuple(arrive) if arrive else None, label="go_to")
                pend = _Pending(goal, "go_to")
                if not marker:      # replace: drop goals nobody has started planning (queue=False)
                    keep = 1 if c.state is CharacterState.PLANNING and c.goals else 0
                    while len(c.goals) > keep:
                        c.goals.pop()
            elif kind == "sit":
                m = self._marker(marker, "seat")
                pend = _Pending(Goal(m.position.copy(), m.heading, g.nodes_with_label("sit")), "sit", marker)
            elif kind == "stand":
                r = self.buf_root[c.slot, self.tail[c.slot] % MAX_BUFFER]
                fwd = np.array([math.sin(r[2]), math.cos(r[2])])
                pend = _Pending(Goal(r[:2] + 0.45 * fwd, float(r[2]), g.nodes_with_label("stand")), "stand")
            elif kind == "pick_up":
                m = self._marker(marker, "box")
                fwd = np.array([math.sin(m.heading), math.cos(m.heading)])
                pend = _Pending(Goal(m.position + BOX_REACH * fwd, m.heading + math.pi, g.nodes_with_label("carry")),
                                "pick_up", marker)
            elif kind == "put_down":
                pend = _Pending(Goal(pos, heading, g.nodes_with_label("stand")), "put_down")
            else:
                raise ValueError(f"unknown command {kind}")
        except Exception as e:   # a bad command never stops the loop
            self._emit("warning", name, message=f"{kind}: {e}")
            return
        c.goals.append(pend)
        if c.state in (CharacterState.IDLE, CharacterState.MOVING) and c not in self._plan_queue and c is not self._active:
            c.state = CharacterState.QUEUED
            self._plan_queue.append(c)

    # ------------------------------------------------------------------ planning
    def _handoff(self, c: _Char) -> Config:
        """Earliest point >= now + LATENCY where the character stands on a node."""
        earliest = self.frame + LATENCY
        for f, cfg in c.boundaries:
            if f >= earliest:
                return cfg
        # none buffered far enough: extend with idle (which creates boundaries) and retry
        self._append_idle(c)
        for f, cfg in c.boundaries:
            if f >= earliest:
                return cfg
        return self._config_at_tail(c)

    def _start_job(self, c: _Char):
        pend = c.goals[0]
        start = self._handoff(c)
        planner = SegmentPlanner(self.lib, static=self._static,
                                 collide=lambda f, xz, r, s=c.slot: self._collide(f, xz, r, s),
                                 roadmap=self.roadmap, env=self.env, params=self.params)
        goal = pend.goal
        if goal.window is not None and goal.window[1] < (start.frame + 1) / self.fps:
            self._emit("late", c.name, window=goal.window, message="the arrival window has passed; planning without it")
            goal = Goal(goal.position, goal.heading, goal.nodes, None, goal.label)
        c.job = planner.run(start, goal, self.rng, owner=c.slot, name=c.name)
        c.job_goal = pend
        c.job_handoff = start
        c.state = CharacterState.PLANNING

    def _collide(self, frames, xz, radius, owner):
        """Samples that hit another character: its buffered future (space-time index), and,
        for characters with nothing left to plan, beyond their last buffered frame the place
        where they will stand idling. (Vectorized over samples and characters.)"""
        hit = self.index.overlaps(frames, xz, radius, ignore_owner=owner)
        # characters with goals still to plan will move away: only the others stay put
        s = np.array([i for i in np.flatnonzero(self.active)
                      if i != owner and not self._slots[i].goals], dtype=np.int64)
        if len(s) == 0:
            return hit
        txz = self.buf_root[s, self.tail[s] % MAX_BUFFER, :2]
        late = frames[:, None] > self.tail[s][None, :]
        if not late.any():
            return hit
        near = (np.abs(xz[:, None, 0] - txz[None, :, 0]) < 1.5) & (np.abs(xz[:, None, 1] - txz[None, :, 1]) < 1.5) & late
        q, k = np.nonzero(near)
        if len(q):
            d = np.hypot(xz[q, 0] - txz[k, 0], xz[q, 1] - txz[k, 1])
            hit[q[d < radius[q] + 0.35]] = True
        return hit

    def _finish_job(self, c: _Char, res):
        pend = c.goals.popleft()
        c.job = None
        if res.warning:
            self._emit("warning", c.name, message=res.warning)
        start = c.job_handoff
        if start.frame < self.frame:
            # the hand-off has already played: plan again from a later one
            c.goals.appendleft(pend)
            c.state = CharacterState.QUEUED
            self._plan_queue.append(c)
            return
        tr = Track(res.frames_a, res.frames_b, res.frames_t, res.root, start.frame)
        self._write(c, tr, start.frame)
        self.tail_node[c.slot] = res.end.node
        end = res.end
        c.boundaries.append((end.frame, end))
        c.arrivals.append((end.frame, pend))
        c.state = CharacterState.MOVING
        self._append_idle(c)
        if c.goals:
            c.state = CharacterState.QUEUED
            self._plan_queue.append(c)

    def _plan(self):
        """Planner steps while the next one is expected to fit in what is left of the budget
        (a running average of step durations), and at least one step per tick, so planning
        always progresses and rarely overruns."""
        t_end = time.perf_counter() + self.budget
        first = True
        while first or time.perf_counter() + self._step_ema < t_end:
            first = False
            t_step = time.perf_counter()
            if self._active is None:
                while self._plan_queue and self._active is None:
                    c = self._plan_queue.popleft()
                    if c.name in self._chars and c.goals:
                        try:
                            self._start_job(c)
                            self._active = c
                        except Exception as e:
                            c.goals.popleft()
                            c.state = CharacterState.IDLE
                            self._emit("warning", c.name, message=f"planning failed to start: {e}")
                if self._active is None:
                    return
            c = self._active
            try:
                next(c.job)
                self._step_ema = 0.9 * self._step_ema + 0.1 * (time.perf_counter() - t_step)
            except StopIteration as stop:
                self._active = None
                try:
                    self._finish_job(c, stop.value)
                except Exception as e:
                    c.state = CharacterState.IDLE
                    self._emit("warning", c.name, message=f"could not use the plan: {e}")
            except Exception as e:
                self._active = None
                c.job = None
                if c.goals:
                    c.goals.popleft()
                c.state = CharacterState.IDLE
                self._emit("warning", c.name, message=f"planning failed: {type(e).__name__}: {e}")

    # ------------------------------------------------------------------ the tick
    def tick(self) -> None:
        t0 = time.perf_counter()
        while self._commands:
            self._apply(self._commands.popleft())
        tp = time.perf_counter()
        self._plan()
        plan_ms = (time.perf_counter() - tp) * 1000
        self._step_flocks()               # flocks, then tiling and user systems, in that order
        for system in self.systems:
            system(self)
        # clocks: all read heads advance together
        self.frame += 1
        act = self.active
        self.head[act] = self.frame
        # never run dry: idle clips after the buffered future
        low = np.flatnonzero(act & (self.tail - self.head < REFILL_BELOW))
        for s in low:
            c = self._slots[s]
            if c.state is not CharacterState.PLANNING:
                self._append_idle(c)
            else:
                self._append_idle(c, 1.0)
        self._announce()
        self.index.forget_before(self.frame)
        self.stats.update(tick_ms=(time.perf_counter() - t0) * 1000, plan_ms=plan_ms,
                          characters=int(act.sum()), queue=len(self._plan_queue) + (self._active is not None),
                          ticks=self.stats["ticks"] + 1)

    def _announce(self):
        for c in self._chars.values():
            if not c.arrivals:
                continue
            while c.arrivals and c.arrivals[0][0] <= self.frame:
                f, pend = c.arrivals.pop(0)
                kind = {"go_to": "arrived", "sit": "sat", "stand": "stood", "pick_up": "picked_up",
                        "put_down": "put_down"}[pend.kind]
                if pend.kind == "pick_up":
                    c.carrying = pend.marker
                if pend.kind == "put_down":
                    if c.carrying:
                        r0 = self.buf_root[c.slot, f % MAX_BUFFER]
                        fwd = (math.sin(r0[2]), math.cos(r0[2]))
                        self._box_place[c.carrying] = (r0[0] + BOX_REACH * fwd[0], r0[1] + BOX_REACH * fwd[1], r0[2])
                    c.carrying = None
                r = self.buf_root[c.slot, f % MAX_BUFFER]
                self._emit(kind, c.name, position=(float(r[0]), float(r[1])), heading=float(r[2]),
                           marker=pend.marker, frame=f)
                if not c.arrivals and not c.goals and c.state is CharacterState.MOVING:
                    c.state = CharacterState.IDLE

    def _emit(self, kind, name, **data):
        ev = Event(kind, name, self.frame / self.fps, data)
        self.events.append(ev)
        for cb in self._listeners.get(kind, []) + self._listeners.get("*", []):
            try:
                cb(ev)
            except Exception:      # a listener's error never stops the loop
                pass

    def step(self, real_dt: float) -> int:
        """Advance by ``real_dt`` seconds of real time; returns the ticks run (capped at 8 so a
        stall never snowballs)."""
        self.accumulator += max(0.0, float(real_dt))
        n = 0
        while self.accumulator >= self.dt and n < 8:
            self.tick()
            self.accumulator -= self.dt
            n += 1
        if n == 8:
            self.accumulator = min(self.accumulator, self.dt)
        return n

    @property
    def time(self) -> float:
        return self.frame / self.fps

    @property
    def alpha(self) -> float:
        """Fraction of a tick between the last tick and the next (for render interpolation)."""
        return min(1.0, self.accumulator / self.dt)

    # ------------------------------------------------------------------ poses
    def _gather(self, frame_offset: int):
        s = np.flatnonzero(self.active)
        k = np.clip(self.head[s] + frame_offset, self.head[s] - 1, self.tail[s]) % MAX_BUFFER
        return s, self.buf_a[s, k], self.buf_b[s, k], self.buf_t[s, k], self.buf_root[s, k]

    def root_states(self):
        """Current (x, z, heading) of every active character (N, 3), in slot order."""
        return self._gather(0)[4]

    def poses(self, alpha: float | None = None):
        """Joint world positions (N, J, 3) of all characters (slot order = :attr:`names`),
        interpolated between the previous and the current tick by ``alpha`` (default: the
        accumulator's fraction)."""
        alpha = self.alpha if alpha is None else alpha
        s, a, b, t, root = self._gather(0)
        if len(s) == 0:
            return np.zeros((0, self.graph.skeleton.num_joints, 3))
        pos, rot = evaluate_poses(self.graph, a, b, t, root)
        cur = forward_kinematics(self.graph.skeleton, pos, rot)[1]
        if alpha >= 1.0:
            return cur
        _, a0, b0, t0, root0 = self._gather(-1)
        pos0, rot0 = evaluate_poses(self.graph, a0, b0, t0, root0)
        prev = forward_kinematics(self.graph.skeleton, pos0, rot0)[1]
        return prev + (cur - prev) * alpha

    # ------------------------------------------------------------------ viewer scene protocol
    @property
    def environment(self):
        if self.env is None:
            from .crowd.environment import Environment
            self.env = Environment.open_ground()
        return self.env

    @property
    def skeleton(self):
        return self.graph.skeleton

    def joint_positions(self):
        return self.poses()

    def hud_stats(self) -> dict:
        return {"tick ms": round(self.stats["tick_ms"], 2), "synthesis ms": round(self.stats["plan_ms"], 2),
                "characters": self.stats["characters"], "queue": self.stats["queue"],
                "time s": round(self.time, 1)}

    def select(self, i) -> None:
        self.selected = i

    def command_go_to(self, i: int, xz) -> None:
        names = self.names
        if i is not None and 0 <= i < len(names):
            self.go_to(names[i], np.asarray(xz, float))

    def box_positions(self):
        """Bottom-centre (x, y, z) and heading of every box marker, carried ones in the hands."""
        if self.env is None:
            return np.zeros((0, 4))
        boxes = self.env.markers_with_role("box")
        carried = {c.carrying: c for c in self._chars.values() if c.carrying}
        out = []
        for m in boxes:
            c = carried.get(m.path)
            if c is None:
                p = self._box_place.get(m.path, (m.position[0], m.position[1], m.heading))
                out.append((p[0], 0.0, p[1], p[2]))
            else:
                r = self.buf_root[c.slot, self.head[c.slot] % MAX_BUFFER]
                fwd = np.array([math.sin(r[2]), math.cos(r[2])])
                out.append((r[0] + 0.35 * fwd[0], 0.85, r[1] + 0.35 * fwd[1], r[2]))
        return np.array(out, dtype=np.float64).reshape(-1, 4)

    # ------------------------------------------------------------------ scenarios
    def apply_scenario(self, sc) -> None:
        """Spawn a scenario's characters and queue their goals as run-time commands (staged:
        each goal is planned while the previous one plays). Seats and boxes become sit and
        pick_up; a "stand" goal while carrying becomes put_down; relative timing (``after``)
        is not used online."""
        for c in sc.characters:
            self.spawn(c.name, c.position, c.heading, c.pose)
        # (flocks: add_scenario_flocks, once their graphs are loaded)
        for c in sc.characters:
            carrying = False
            for g in c.goals:
                if g.kind == "seat":
                    self.sit(c.name, g.marker)
                elif g.kind == "box":
                    self.pick_up(c.name, g.marker)
                    carrying = True
                elif carrying and g.pose in ("stand", None):
                    self.put_down(c.name, g.position, g.heading)
                    carrying = False
                else:
                    self.go_to(c.name, g.position, g.heading, g.time, queue=True)

    # ------------------------------------------------------------------ flocks (paper 004)
    def add_flocks(self, ddg, positions, headings=None, regions=None, seed: int | None = None):
        """Start flocks walking ``ddg`` (a :class:`runtime.flock.DDG` or a pack path): their
        centroids at ``positions`` (k, 3), optionally each constrained to a region. All flocks
        of one DDG advance together in one vectorized system of the tick. Returns
        (system index, flock rows)."""
        from .flock import FlockSystem, load_ddg
        if not hasattr(ddg, "n_agents"):
            ddg = load_ddg(ddg)
        sys_i = next((i for i, f in enumerate(self.flocks) if f.ddg is ddg), None)
        if sys_i is None:
            fs = FlockSystem(ddg, seed=self.rng.integers(1 << 31) if seed is None else seed)
            self.flocks.append(fs)
            sys_i = len(self.flocks) - 1
        rows = self.flocks[sys_i].add_flocks(positions, headings, regions)
        return sys_i, rows

    def _step_flocks(self):
        for fs in self.flocks:
            fs.step(self.dt)

    def flock_positions(self):
        """All flock agents: positions (M, 3) and headings (M,) (viewer protocol)."""
        if not self.flocks:
            return np.zeros((0, 3)), np.zeros(0)
        pos = np.concatenate([f.positions().reshape(-1, 3) for f in self.flocks])
        hd = np.concatenate([f.headings().reshape(-1) for f in self.flocks])
        return pos, hd

    def _flock_region(self, spec):
        from .flock import Box, Polygon
        if spec.region is None:
            return None
        poly = self.env.markers[spec.region].polygon
        if spec.altitude is not None:
            lo, hi = poly.min(axis=0), poly.max(axis=0)
            return Box([lo[0], spec.altitude[0], lo[1]], [hi[0], spec.altitude[1], hi[1]])
        return Polygon(poly)

    def add_scenario_flocks(self, sc) -> None:
        """Start the ``[[flock]]`` entries of a scenario (their DDGs resolved into
        ``spec.loaded`` by the caller, see ``authoring.commands.bake.load_sample``)."""
        for spec in sc.flocks:
            ddg = spec.loaded
            region = self._flock_region(spec)
            if spec.positions is not None:
                pos = np.asarray(spec.positions, dtype=np.float64).reshape(-1, 3)
            else:
                pos = spread_in_region(region, spec.count, 25.0 if ddg.dim == 3 else 0.0, seed=spec.seed)
            headings = np.linspace(0.0, 2 * math.pi, len(pos), endpoint=False)
            self.add_flocks(ddg, pos, headings, [region] * len(pos), seed=spec.seed)


def spread_in_region(region, k: int, height: float = 0.0, seed: int = 0) -> np.ndarray:
    """``k`` start points well inside a region, far apart (deepest grid points, then farthest
    point sampling); deterministic."""
    if region is None:
        a = np.linspace(0, 2 * math.pi, k, endpoint=False)
        return np.stack([15 * np.sin(a), np.full(k, height), 15 * np.cos(a)], axis=1)
    if hasattr(region, "vertices"):          # polygon (2D flocks walk at ``height``)
        lo, hi = region.vertices.min(axis=0), region.vertices.max(axis=0)
        y = height
    else:                                    # box (3D flocks start at mid altitude)
        lo, hi = region.lo[[0, 2]], region.hi[[0, 2]]
        y = 0.5 * (region.lo[1] + region.hi[1])
    X, Z = np.meshgrid(np.linspace(lo[0], hi[0], 40), np.linspace(lo[1], hi[1], 40))
    pts = np.stack([X.ravel(), np.full(X.size, y), Z.ravel()], axis=1)
    depth = region.depth(pts)
    ok = depth > np.percentile(depth[depth > 0], 60) if np.any(depth > 0) else depth > -np.inf
    cand = pts[ok]
    chosen = [int(np.argmax(region.depth(cand)))]
    d = np.hypot(cand[:, 0] - cand[chosen[0], 0], cand[:, 2] - cand[chosen[0], 2])
    while len(chosen) < k:
        i = int(np.argmax(d))
        chosen.append(i)
        d = np.minimum(d, np.hypot(cand[:, 0] - cand[i, 0], cand[:, 2] - cand[i, 2]))
    return cand[chosen]
