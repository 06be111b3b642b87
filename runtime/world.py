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
resumes on the next tick. Each ``next()`` is a *step* whose kind is where the generator is
suspended; a step starts only when its predicted duration (:class:`StepCosts`) fits in what
is left of the budget, and the first step of a tick always runs. When the plan is finished,
it replaces the buffer after the hand-off; if the hand-off has already played but the
character idled in place since, the same motion starts at a later idle-loop end (tested
again for collisions), else it is planned again.

**Collisions.** A plan is tested against every other character's buffered future: planned
motion lives in a space-time index of bounding cylinders, idling in :class:`IdleStretches`
(a disc per stretch of idle clips), and beyond its buffer every character counts as standing
where it ends (it may never be planned again). A goal where someone stands waits behind the
rest of the queue a few times; a plan whose end would stand in someone's way is not used.
A plan that is not within the adjustment tolerance or collides is not played: the character
gets a ``warning`` event and keeps idling (a collided plan is tried once more when the queue
is short). Nothing a character does can make :meth:`World.step` raise.

Limits: ``MAX_BUFFER`` frames (60 s) per character, minus one kept for interpolation.
"""
from __future__ import annotations

import heapq
import inspect
import math
import time
from collections import deque
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from .crowd.scenario import BOX_REACH
from .crowd.motion_cache import MotionCache
from .crowd.scheduler import idle_track, still_nodes
from .crowd.spacetime import SpaceTimeIndex
from .crowd.synthesis import Config, Goal, MotionLibrary, SegmentPlanner, SynthesisParams, compose
from .crowd.tracks import Track, evaluate_poses
from .motion.fk import forward_kinematics
from .motion.graph import MotionGraph
from .pose import PoseBatch, PoseState

__all__ = ["World", "CharacterState", "Event", "StepCosts", "IdleStretches", "MAX_BUFFER"]

MAX_BUFFER = 1800          # frames of future per character (60 s at 30 Hz)
REFILL_BELOW = 45          # frames: append idle when fewer than this remain
REFILL_URGENT = 10         # frames: ... and always on this tick when fewer than this remain
REFILL_PER_TICK = 6        # characters refilled per tick at least (more when many run low)
IDLE_SECONDS = 4.0         # idle appended per refill
MAX_DEFER = 3              # times a goal on a spot where someone stands waits for later planning
MAX_RETRY = 1              # times a plan that collided with other characters is tried again later
RETRY_QUEUE = 8            # ... when fewer than this many characters wait for the planner
LATENCY = 12               # frames between "now" and the earliest hand-off


_FINISH = ("use the finished plan",)


def _step_kind(job):
    """Where a planner generator is suspended: (function, line) of the innermost generator
    of its ``yield from`` chain — the kind of the step its next ``next()`` runs."""
    g = job
    while getattr(g, "gi_yieldfrom", None) is not None and hasattr(g.gi_yieldfrom, "gi_frame"):
        g = g.gi_yieldfrom
    f = g.gi_frame
    if f is None:
        return ("finished",)
    if g is job and inspect.getgeneratorstate(g) == inspect.GEN_CREATED:
        return ("created",)
    return (g.gi_code.co_name, f.f_lineno)


class StepCosts:
    """Predicted duration of a planner step, per kind: running averages (rate ``rate``) of
    the duration and of its absolute deviation from the average, ``mean + k * deviation``, and
    at least a decaying maximum (each new duration of the kind multiplies it by ``decay``): some
    kinds are usually short and now and then long (a seed's last edge, a splice that is also
    collision-tested), and such a kind should not start late in a tick. Unknown kinds are
    predicted as the largest known prediction (or ``default`` s)."""

    def __init__(self, k: float = 3.0, rate: float = 0.2, decay: float = 0.97, default: float = 0.002):
        self.k, self.rate, self.decay, self.default = k, rate, decay, default
        self._m: dict = {}

    def predict(self, kind) -> float:
        m = self._m.get(kind)
        if m is None:
            return max((max(a + self.k * d, x) for a, d, x in self._m.values()), default=self.default)
        return max(m[0] + self.k * m[1], m[2])

    def record(self, kind, seconds: float) -> None:
        m = self._m.get(kind)
        if m is None:
            self._m[kind] = [seconds, 0.5 * seconds, seconds]
            return
        m[1] += self.rate * (abs(seconds - m[0]) - m[1])
        m[0] += self.rate * (seconds - m[0])
        m[2] = max(seconds, m[2] * self.decay)


class IdleStretches:
    """Where characters stand idling, as discs over frame intervals: rows (owner, first frame,
    last frame, x, z, radius). Idle clips are appended to every character all the time; kept
    out of the space-time index (which then holds only planned motion), they cost one row per
    stretch instead of one sample per frame. The radius covers the idle loop's bounding
    cylinders and its root's excursion (:meth:`World._stay_radii`). Queries are vectorized over
    samples and the rows near them."""

    def __init__(self):
        self.rows = np.zeros((0, 6))

    def add(self, owner, f0, f1, x, z, r) -> None:
        rows = self.rows
        own = np.flatnonzero(rows[:, 0] == owner)
        if len(own):
            last = own[np.argmax(rows[own, 2])]
            if rows[last, 2] >= f0 - 1 and abs(rows[last, 3] - x) < 1e-6 and abs(rows[last, 4] - z) < 1e-6:
                rows[last, 2] = max(rows[last, 2], f1)        # the same spot: extend
                rows[last, 5] = max(rows[last, 5], r)
                return
        self.rows = np.vstack([rows, [[owner, f0, f1, x, z, r]]])

    def cut(self, owner, frame) -> None:
        """Forget ``owner``'s stretches from ``frame`` on (its buffer is replaced there)."""
        rows = self.rows
        mine = rows[:, 0] == owner
        rows[mine & (rows[:, 2] >= frame), 2] = frame - 1
        self.rows = rows[~mine | (rows[:, 2] >= rows[:, 1])]

    def remove(self, owner) -> None:
        self.rows = self.rows[self.rows[:, 0] != owner]

    def forget_before(self, frame) -> None:
        self.rows = self.rows[self.rows[:, 2] >= frame]

    def overlaps(self, frames, xz, radius, ignore_owner=None) -> np.ndarray:
        n = len(frames)
        hit = np.zeros(n, dtype=bool)
        rows = self.rows
        if n == 0 or len(rows) == 0:
            return hit
        reach = float(np.max(radius)) + (rows[:, 5].max() if len(rows) else 0.0)
        lo, hi = xz.min(axis=0) - reach, xz.max(axis=0) + reach
        m = ((rows[:, 3] > lo[0]) & (rows[:, 3] < hi[0]) & (rows[:, 4] > lo[1]) & (rows[:, 4] < hi[1])
             & (rows[:, 2] >= frames.min()) & (rows[:, 1] <= frames.max()))
        if ignore_owner is not None:
            m &= rows[:, 0] != ignore_owner
        if not m.any():
            return hit
        r = rows[m]
        inside = (frames[:, None] >= r[None, :, 1]) & (frames[:, None] <= r[None, :, 2])
        d = np.hypot(xz[:, None, 0] - r[None, :, 3], xz[:, None, 1] - r[None, :, 4])
        return np.any(inside & (d < radius[:, None] + r[None, :, 5]), axis=1)


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
    start_frame: int = -1   # clock frame where its planned segment starts (set when planned)
    defers: int = 0         # times it waited because someone stood on the goal
    retries: int = 0        # times it was planned again after colliding with others


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
    job_window: tuple | None = None
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
        # that cannot be planned must not hold the queue for seconds (N_max 60 instead of 150
        # halved the planning time per used plan in bench/runtime_load.py, losing ~10% of the
        # plans), and each step is kept small (n_m perturbations per iteration) so that one
        # step fits well inside the per-tick budget
        self.params = params or SynthesisParams(fps=self.fps, n_max=60, n_m=48, k_m=16, sweep=24, backward_idle=True)
        self.lib = MotionLibrary(self.graph, self.params)
        # motions found for one character's task, tried first for the next with the same task
        self._motion_cache = MotionCache() if self.params.reuse_motions else None
        self.rng = np.random.default_rng(seed)
        self.frame = 0
        self.accumulator = 0.0
        self.flocks: list = []            # FlockSystems (one per DDG), stepped every tick
        self.tilings: list = []           # TilingZones (interactive patch tiling), stepped every tick
        self._zone_batches: dict = {}     # zone name -> (PoseBatch, frame pushed)
        self.systems: list = []           # extra per-tick systems: callables (world) -> None
        self._listeners: dict = {}
        self.events: list[Event] = []
        self._commands: deque = deque()
        self._chars: dict[str, _Char] = {}
        self._slots: list = []
        self._plan_queue: deque = deque()
        self._active: _Char | None = None
        self.stretches = IdleStretches()  # where characters stand idling (kept out of the index)
        self.index = SpaceTimeIndex(cell=max(1.2, 2 * self.lib.max_radius + 2 * (self.lib.params.margin + self.lib.params.seed_margin) + 0.1))
        self.stats = {"tick_ms": 0.0, "plan_ms": 0.0, "plan_cpu_ms": 0.0, "plan_steps": 0, "characters": 0,
                      "queue": 0, "ticks": 0, "plans_done": 0, "plans_failed": 0,
                      "plans_shifted": 0, "plans_redone": 0, "plans_retried": 0}
        self.selected = None
        self._steps = StepCosts()        # predicted duration of the planner's next step, per kind
        self._done = None                # (character, result) of a finished plan, applied as its own step
        self._idle_cache: dict = {}
        self._due: list = []             # heap of (arrival frame, sequence, character)
        self._seq = 0
        self._loop_cache: dict = {}
        self._box_place: dict = {}     # boxes put down somewhere else: path -> (x, z, heading)
        self._pose_batch = None          # render-side poses (joint_positions)
        self._pose_at = None
        self._pose_slots = None
        self._static = None
        if self.env is not None and (len(self.env.polygons) or len(self.env.circles)):
            sdf = self.env.sdf(resolution=0.05, margin=2.0)
            self._static = lambda xz: sdf.sample(xz) - sdf.max_error
        self._alloc(capacity)
        self._stay_r = self._stay_radii()
        self._still = self._still_nodes()

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
        self._indexed = np.zeros(cap, dtype=bool)         # the slot's frames are in the space-time index
        self.buf_idle = np.zeros((cap, MAX_BUFFER), dtype=bool)   # frame written as idle (not indexed)
        self._slots = [None] * cap

    def _grow(self):
        old = (self.active, self.head, self.tail, self.buf_a, self.buf_b, self.buf_t, self.buf_root, self.tail_node,
               self._slots, self._indexed, self.buf_idle)
        n = self.cap
        self._alloc(n * 2)
        self.active[:n], self.head[:n], self.tail[:n] = old[0], old[1], old[2]
        self.buf_a[:n], self.buf_b[:n], self.buf_t[:n], self.buf_root[:n] = old[3], old[4], old[5], old[6]
        self.tail_node[:n] = old[7]
        self._slots[:n] = old[8]
        self._indexed[:n] = old[9]
        self.buf_idle[:n] = old[10]

    def _write(self, c: _Char, track: Track, from_frame: int, idle_radius: float | None = None):
        """Replace the buffer of ``c`` from absolute frame ``from_frame`` with ``track`` (whose
        first frame is at ``from_frame``). Planned motion goes into the space-time index (the
        whole buffered future is re-indexed); idle clips (``idle_radius`` given: they stand on
        the track's first root position) become one idle stretch."""
        s = c.slot
        n = len(track)
        if from_frame + n - 1 - self.head[s] >= MAX_BUFFER - 1:
            # the ring keeps the previous frame (head - 1) too, for render interpolation
            n = int(MAX_BUFFER - 1 - (from_frame - self.head[s]))
            track = track.slice(0, n)
        idx = (from_frame + np.arange(n)) % MAX_BUFFER
        root = track.root
        if self._indexed[s]:
            # headings stay continuous across what is replaced (a plan may be wound 2 pi away)
            turns = np.round((self.buf_root[s, idx[0], 2] - root[0, 2]) / (2 * math.pi))
            if turns:
                root = root.copy()
                root[:, 2] += 2 * math.pi * turns
        append = from_frame == self.tail[s] and self._indexed[s]
        self.buf_a[s, idx] = track.frames_a
        self.buf_b[s, idx] = track.frames_b
        self.buf_t[s, idx] = track.frames_t
        self.buf_root[s, idx] = root
        self.buf_idle[s, idx] = idle_radius is not None
        self.tail[s] = from_frame + n - 1
        c.boundaries = [(f, cfg) for f, cfg in c.boundaries if self.head[s] <= f < from_frame]
        if not append:
            self.stretches.cut(s, from_frame)
        if idle_radius is not None:
            self.stretches.add(s, from_frame, self.tail[s], float(root[0, 0]), float(root[0, 1]), idle_radius)
            if append:
                self._indexed[s] = True
                return
        elif append:
            self._indexed[s] = True
            frames = np.arange(from_frame + 1, self.tail[s] + 1)   # the shared first frame is indexed
            self._index_frames(s, frames)
            return
        # the space-time index holds every character's buffered planned motion
        self.index.remove_owner(s)
        frames = np.arange(max(int(self.head[s]), 0), self.tail[s] + 1)
        self._index_frames(s, frames[~self.buf_idle[s, frames % MAX_BUFFER]])
        self._indexed[s] = True

    def _index_frames(self, s, frames):
        if len(frames) == 0:
            return
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
        self._write(c, self._idle(cfg, n), cfg.frame, idle_radius=self._stay_r[cfg.node])
        step = loop if loop else n - 1
        for k in range(step, n, step):
            c.boundaries.append((cfg.frame + k, Config(cfg.node, cfg.x, cfg.z, cfg.heading, cfg.frame + k)))

    def _idle(self, cfg: Config, n: int) -> Track:
        """:func:`~runtime.crowd.scheduler.idle_track` at ``cfg``: the track at the origin is
        cached per (node, length) and placed by one composition (the same arithmetic)."""
        key = (cfg.node, n)
        base = self._idle_cache.get(key)
        if base is None:
            base = idle_track(self.lib, Config(cfg.node, 0.0, 0.0, 0.0, 0), n)
            self._idle_cache[key] = base
        root = compose(np.array([cfg.x, cfg.z, cfg.heading])[None], base.root)
        return Track(base.frames_a, base.frames_b, base.frames_t, root, cfg.frame)

    def _loop_len(self, node):
        node = int(node)
        if node not in self._loop_cache:
            g = self.graph
            loops = np.flatnonzero((g.edge_src == node) & (g.edge_dst == node))
            if len(loops) == 0:
                self._loop_cache[node] = 0
            else:
                drift = np.hypot(g.edge_disp[loops, 0], g.edge_disp[loops, 1]) + 0.3 * np.abs(g.edge_disp[loops, 2])
                e = int(loops[np.argmin(drift)])
                self._loop_cache[node] = int(g.edge_frames[e] - 1)
        return self._loop_cache[node]

    # ------------------------------------------------------------------ characters
    @property
    def names(self) -> list[str]:
        return [self._slots[i].name for i in np.flatnonzero(self.active)]

    def spawn(self, name: str, position, heading: float = 0.0, pose: str = "stand") -> int:
        """Add a character standing (or seated: pose "sit") at ``position`` (x, z), facing
        ``heading`` (radians, 0 = +Z). Returns its slot."""
        if name in self._chars:
            raise ValueError(f"a character named {name!r} already exists")
        if len(self.graph.nodes_with_label(pose)) == 0:
            raise ValueError(f"pose {pose!r} is not a node label of the library ({self.graph.node_labels_all()})")
        nodes = self.pose_nodes(pose)
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
        first = self.graph.edge_start[self.graph.out_edges(node)[0]] if len(self.graph.out_edges(node)) else 0
        for f in (self.frame - 1, self.frame):     # the previous frame too: interpolation before the first tick
            self.buf_root[s, f % MAX_BUFFER] = (position[0], position[1], heading)
            self.buf_a[s, f % MAX_BUFFER] = first
            self.buf_b[s, f % MAX_BUFFER] = first
            self.buf_t[s, f % MAX_BUFFER] = 0.0
        c.boundaries.append((self.frame, Config(node, float(position[0]), float(position[1]), float(heading), self.frame)))
        # characters spawned together get idle futures of different lengths, so that their
        # refills spread over many ticks
        loop = self._loop_len(node) or 1
        self._append_idle(c, 3.0 + (s % 7) * loop / self.fps)
        return s

    def remove(self, name: str) -> None:
        c = self._chars.pop(name)
        self.active[c.slot] = False
        self._slots[c.slot] = None
        self.index.remove_owner(c.slot)
        self.stretches.remove(c.slot)
        self._indexed[c.slot] = False
        if self._active is c:
            self._active = None
        if self._done is not None and self._done[0] is c:
            self._done = None
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
            if kind == "go_to":
                # arrive standing where the character can wait still (not on a walking hub,
                # whose self loops are walk cycles)
                goal = Goal(pos, heading, self.pose_nodes("stand"), tuple(arrive) if arrive else None, label="go_to")
                pend = _Pending(goal, "go_to")
                if not marker:      # replace: drop goals nobody has started planning (queue=False)
                    keep = 1 if c.state is CharacterState.PLANNING and c.goals else 0
                    while len(c.goals) > keep:
                        c.goals.pop()
            elif kind == "sit":
                m = self._marker(marker, "seat")
                pend = _Pending(Goal(m.position.copy(), m.heading, self.pose_nodes("sit")), "sit", marker)
            elif kind == "stand":
                r = self.buf_root[c.slot, self.tail[c.slot] % MAX_BUFFER]
                fwd = np.array([math.sin(r[2]), math.cos(r[2])])
                pend = _Pending(Goal(r[:2] + 0.45 * fwd, float(r[2]), self.pose_nodes("stand")), "stand")
            elif kind == "pick_up":
                m = self._marker(marker, "box")
                fwd = np.array([math.sin(m.heading), math.cos(m.heading)])
                pend = _Pending(Goal(m.position + BOX_REACH * fwd, m.heading + math.pi, self.pose_nodes("carry")),
                                "pick_up", marker)
            elif kind == "put_down":
                pend = _Pending(Goal(pos, heading, self.pose_nodes("stand")), "put_down")
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
        planner.cache = self._motion_cache
        goal = pend.goal
        if goal.window is not None and goal.window[1] < (start.frame + 1) / self.fps:
            self._emit("late", c.name, window=goal.window, message="the arrival window has passed; planning without it")
            goal = Goal(goal.position, goal.heading, goal.nodes, None, goal.label)
        c.job = planner.run(start, goal, self.rng, owner=c.slot, name=c.name)
        c.job_goal = pend
        c.job_handoff = start
        c.job_window = goal.window
        c.state = CharacterState.PLANNING

    def _collide(self, frames, xz, radius, owner):
        """Samples that hit another character: its buffered future (space-time index), and,
        beyond its last buffered frame, the place where it stands idling. Every character
        counts as standing there, also one with goals still to plan: its plan may fail or wait
        long in the queue, and then it keeps idling there. (A goal on such a spot waits, see
        :meth:`_next_job`.) Vectorized over samples and nearby characters."""
        hit = self._occupied(frames, xz, radius, owner)
        if len(frames) == 0:
            return hit
        others = self.active & (self.tail < frames.max())
        if 0 <= owner < self.cap:
            others[owner] = False
        s = np.flatnonzero(others)
        if len(s) == 0:
            return hit
        txz = self.buf_root[s, self.tail[s] % MAX_BUFFER, :2]
        reach = float(radius.max()) + self._stay_r.max()
        lo, hi = xz.min(axis=0) - reach, xz.max(axis=0) + reach
        m = (txz[:, 0] > lo[0]) & (txz[:, 0] < hi[0]) & (txz[:, 1] > lo[1]) & (txz[:, 1] < hi[1])
        if not m.any():
            return hit
        s, txz = s[m], txz[m]
        sr = self._stay_r[self.tail_node[s]]
        late = frames[:, None] > self.tail[s][None, :]
        d = np.hypot(xz[:, None, 0] - txz[None, :, 0], xz[:, None, 1] - txz[None, :, 1])
        hit |= np.any(late & (d < radius[:, None] + sr[None, :]), axis=1)
        return hit

    def _stay_radii(self) -> np.ndarray:
        """Per node: the largest bounding radius while idling on it (its idle loop's frames,
        or the node's pose when it has none), plus how far the idle loop's root strays from
        the node's spot."""
        g = self.graph
        r = np.zeros(g.num_nodes)
        for n in range(g.num_nodes):
            tr = self._idle(Config(n, 0.0, 0.0, 0.0, 0), max(self._loop_len(n), 1) + 1)
            r[n] = (max(g.frame_radius[tr.frames_a].max(), g.frame_radius[tr.frames_b].max())
                    + np.hypot(tr.root[:, 0], tr.root[:, 1]).max())
        return r + self.params.margin

    def _still_nodes(self) -> np.ndarray:
        """Per node: whether idling on it stands still (:func:`runtime.crowd.scheduler.still_nodes`)."""
        return still_nodes(self.graph, self.params.eps, self.fps)

    def pose_nodes(self, label: str) -> np.ndarray:
        """Nodes carrying the pose ``label`` where a character can wait standing still (all
        nodes with the label when none of them can)."""
        nodes = self.graph.nodes_with_label(label)
        still = nodes[self._still[nodes]]
        return still if len(still) else nodes

    def _end_blocked(self, c: _Char, end: Config) -> bool:
        """Would the character, standing at ``end`` after it arrives, be in the way of another
        character's buffered future? (The planner tests the segment's frames; the idling
        after them is tested here.)"""
        act = self.active.copy()
        act[c.slot] = False
        if not act.any():
            return False
        last = int(min(self.tail[act].max(), end.frame + MAX_BUFFER))
        if last <= end.frame:
            return False
        frames = np.arange(end.frame + 1, last + 1)
        xz = np.broadcast_to(np.array([end.x, end.z]), (len(frames), 2))
        r = np.full(len(frames), self._stay_r[end.node])
        return bool(self._occupied(frames, xz, r, c.slot).any())

    def _occupied(self, frames, xz, radius, owner):
        """Samples that overlap another character's buffered future: its planned motion (the
        space-time index) or its idling (the idle stretches)."""
        frames = np.asarray(frames, dtype=np.int64)
        xz = np.asarray(xz, dtype=np.float64)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), frames.shape)
        hit = self.index.overlaps(frames, xz, radius, ignore_owner=owner)
        return hit | self.stretches.overlaps(frames, xz, radius, ignore_owner=owner)

    def _shifted(self, c: _Char, res, tries: int = 2):
        """A plan whose hand-off has already played, moved later in time: when the character
        has been idling in place since the hand-off, every later idle-loop end is the same
        configuration, so the same motion can start there. The moved motion is tested again
        against the other characters (the environment does not move) and against the goal's
        arrival window. Returns the new start frame or None."""
        s0 = c.job_handoff
        g = self.graph
        rad = np.maximum(g.frame_radius[res.frames_a], g.frame_radius[res.frames_b]).astype(np.float64) + self.params.margin
        for f, cfg in c.boundaries:
            if f <= self.frame or cfg.node != s0.node or abs(cfg.x - s0.x) > 1e-6 or abs(cfg.z - s0.z) > 1e-6 \
                    or abs((cfg.heading - s0.heading + math.pi) % (2 * math.pi) - math.pi) > 1e-6:
                continue
            dt = f - s0.frame
            win = c.job_window
            if win is not None and not (win[0] - 1e-9 <= (res.end.frame + dt) / self.fps <= win[1] + 1e-9):
                return None
            frames = f + np.arange(len(res.root))
            if not self._collide(frames, res.root[:, :2], rad, c.slot).any():
                return f
            tries -= 1
            if tries <= 0:
                return None
        return None

    def _finish_job(self, c: _Char, res):
        pend = c.goals.popleft()
        c.job = None
        start_frame = c.job_handoff.frame
        if start_frame < self.frame and res.ok:
            f = self._shifted(c, res)
            if f is not None:
                self.stats["plans_shifted"] += 1
                start_frame = f
        if start_frame < self.frame and res.ok:
            # the hand-off has already played and the plan cannot be moved: plan again
            c.goals.appendleft(pend)
            c.state = CharacterState.QUEUED
            self._plan_queue.append(c)
            self.stats["plans_redone"] += 1
            return
        dt = start_frame - res.start_frame
        end = Config(res.end.node, res.end.x, res.end.z, res.end.heading, res.end.frame + dt)
        problem = None
        if not res.ok:
            problem = res.warning or "no motion within the tolerance"
        elif start_frame < self.frame:
            problem = "planned too late"      # (not reached: handled above)
        elif self._end_blocked(c, end):
            problem = "standing at the goal would block a character already on its way there"
        if problem and pend.retries < MAX_RETRY and (res.collided or res.ok) and len(self._plan_queue) < RETRY_QUEUE:
            # blocked by other characters: try once more after the rest of the queue (they
            # will have moved on by then) unless many others are waiting for the planner
            pend.retries += 1
            pend.defers = 0
            c.goals.append(pend) if c.goals else c.goals.appendleft(pend)
            self.stats["plans_retried"] += 1
            c.state = CharacterState.IDLE
        elif problem:
            # a failed plan is not played: the character keeps idling where it is
            self.stats["plans_failed"] += 1
            self._emit("warning", c.name, message=f"{pend.kind}: plan not used ({problem}); keeps idling",
                       goal=[float(v) for v in pend.goal.position])
            c.state = CharacterState.IDLE
        else:
            self.stats["plans_done"] += 1
            tr = Track(res.frames_a, res.frames_b, res.frames_t, res.root, start_frame)
            self._write(c, tr, start_frame)
            self.tail_node[c.slot] = end.node
            c.boundaries.append((end.frame, end))
            c.arrivals.append((end.frame, pend))
            pend.start_frame = start_frame
            self._seq += 1
            heapq.heappush(self._due, (end.frame, self._seq, c))
            c.state = CharacterState.MOVING
            self._append_idle(c)
        if c.goals:
            c.state = CharacterState.QUEUED
            self._plan_queue.append(c)

    def _goal_taken(self, c: _Char) -> bool:
        """Does another character stand (where its buffered motion ends) on ``c``'s next goal?"""
        goal = c.goals[0].goal
        others = self.active.copy()
        others[c.slot] = False
        s = np.flatnonzero(others)
        if len(s) == 0:
            return False
        xz = self.buf_root[s, self.tail[s] % MAX_BUFFER, :2]
        d = np.hypot(xz[:, 0] - goal.position[0], xz[:, 1] - goal.position[1])
        r_goal = self._stay_r[goal.nodes].max() if goal.nodes is not None else self._stay_r.max()
        return bool(np.any(d < self._stay_r[self.tail_node[s]] + r_goal))

    def _next_job(self) -> bool:
        """Make the first queued character with a goal the active job; False when none. A goal
        where another character stands waits behind the rest of the queue (up to
        ``MAX_DEFER`` times): the other one may be about to leave, and the plan would fail."""
        tries = len(self._plan_queue)
        while self._plan_queue and self._active is None and tries > 0:
            tries -= 1
            c = self._plan_queue.popleft()
            if c.name in self._chars and c.goals:
                if c.goals[0].defers < MAX_DEFER and self._goal_taken(c):
                    c.goals[0].defers += 1
                    self._plan_queue.append(c)
                    continue
                try:
                    self._start_job(c)
                    self._active = c
                except Exception as e:
                    c.goals.popleft()
                    c.state = CharacterState.IDLE
                    self._emit("warning", c.name, message=f"planning failed to start: {e}")
        return self._active is not None

    def _advance_job(self) -> None:
        c = self._active
        try:
            next(c.job)
        except StopIteration as stop:
            self._active = None
            self._done = (c, stop.value)
        except Exception as e:
            self._active = None
            c.job = None
            if c.goals:
                c.goals.popleft()
            c.state = CharacterState.IDLE
            self._emit("warning", c.name, message=f"planning failed: {type(e).__name__}: {e}")

    def _use_result(self) -> None:
        c, res = self._done
        self._done = None
        try:
            self._finish_job(c, res)
        except Exception as e:
            c.state = CharacterState.IDLE
            self._emit("warning", c.name, message=f"could not use the plan: {e}")

    def _plan(self):
        """Planner steps under the per-tick budget. A step is one ``next()`` of the active
        planner generator, or using a finished plan (writing it into the buffer). Each step
        has a kind — the point where the generator is suspended — and a predicted duration
        for that kind (:class:`StepCosts`, a high estimate); a step starts only when its
        prediction fits in what is left of the budget. The first step of a tick always runs,
        so planning progresses even when a single step is longer than the budget."""
        t0 = time.perf_counter()
        c0 = time.thread_time()
        steps = 0
        while True:
            if self._done is not None:
                kind, run = _FINISH, self._use_result
            elif self._active is not None or self._next_job():
                kind, run = _step_kind(self._active.job), self._advance_job
            else:
                break
            if steps and (time.perf_counter() - t0) + self._steps.predict(kind) > self.budget:
                break
            ts = time.perf_counter()
            run()
            self._steps.record(kind, time.perf_counter() - ts)
            steps += 1
        self.stats["plan_cpu_ms"] = (time.thread_time() - c0) * 1000
        self.stats["plan_steps"] = steps

    # ------------------------------------------------------------------ the tick
    def tick(self) -> None:
        t0 = time.perf_counter()
        while self._commands:
            self._apply(self._commands.popleft())
        tp = time.perf_counter()
        self._plan()
        plan_ms = (time.perf_counter() - tp) * 1000
        self._step_flocks()               # flocks, then tiling and user systems, in that order
        self._step_tilings()
        for system in self.systems:
            system(self)
        # clocks: all read heads advance together
        self.frame += 1
        act = self.active
        self.head[act] = self.frame
        # never run dry: idle clips after the buffered future; the most urgent first and only
        # a few per tick (characters spawned together would otherwise all refill on one tick)
        left = self.tail - self.head
        low = np.flatnonzero(act & (left < REFILL_BELOW))
        if len(low):
            low = low[np.argsort(left[low], kind="stable")]
            n = max(REFILL_PER_TICK, int(np.sum(left[low] < REFILL_URGENT)),
                    -(-len(low) // (REFILL_BELOW - REFILL_URGENT)))
            for s in low[:n]:
                c = self._slots[s]
                self._append_idle(c, IDLE_SECONDS if c.state is not CharacterState.PLANNING else 1.0)
        self._announce()
        self.index.forget_before(self.frame)
        if self.frame % 30 == 0:
            self.stretches.forget_before(self.frame)
        self.stats.update(tick_ms=(time.perf_counter() - t0) * 1000, plan_ms=plan_ms,
                          characters=int(act.sum()), queue=len(self._plan_queue) + (self._active is not None) + (self._done is not None),
                          ticks=self.stats["ticks"] + 1)

    def _announce(self):
        # characters with an arrival due: a heap of (frame, sequence, character)
        due = []
        while self._due and self._due[0][0] <= self.frame:
            c = heapq.heappop(self._due)[2]
            if c.name in self._chars and c not in due:
                due.append(c)
        for c in due:
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
                           marker=pend.marker, frame=f, start_frame=pend.start_frame)
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
        """What the viewer draws: :meth:`poses` through the table evaluator of
        :mod:`runtime.pose` (a :class:`~runtime.pose.PoseBatch` pushed once per tick, interpolated
        per frame; float32, within a few mm of the exact path)."""
        s = np.flatnonzero(self.active)
        if self._pose_batch is None:
            self._pose_batch = PoseBatch(self.graph)
        if self._pose_at != self.frame or not np.array_equal(s, self._pose_slots):
            if self._pose_at != self.frame - 1 or not np.array_equal(s, self._pose_slots):
                self._pose_batch.reset()
                self._pose_batch.push(PoseState(*self._gather(-1)[1:]))
            self._pose_batch.push(PoseState(*self._gather(0)[1:]))
            self._pose_at, self._pose_slots = self.frame, s
        pos = self._pose_batch.positions(self.alpha)
        if not self.tilings:
            return pos
        return np.concatenate([pos] + [self._zone_positions(z) for z in self.tilings])

    def _zone_positions(self, zone):
        """Joint world positions of a tiling zone's characters at the render time (their own
        PoseBatch over the patch library's pose tables, pushed once per tick)."""
        f = zone.frame_at(self.time)
        batch, at = self._zone_batches.get(zone.name, (None, None))
        if batch is None or len(batch) != len(zone):
            batch, at = PoseBatch(zone.library), None
        if at != f:
            if at != f - 1:
                batch.reset()
                batch.push(zone.pose_state(f - 1 if f > 0 else f))
            batch.push(zone.pose_state(f))
        self._zone_batches[zone.name] = (batch, f)
        return batch.positions(self.alpha)

    def hud_stats(self) -> dict:
        out = {"tick ms": round(self.stats["tick_ms"], 2), "synthesis ms": round(self.stats["plan_ms"], 2),
               "characters": self.stats["characters"], "queue": self.stats["queue"]}
        if self.tilings:
            out["tiled"] = sum(len(z) for z in self.tilings)
            out["tiling ms"] = round(self.stats.get("tiling_ms", 0.0), 2)
        if self.flocks:
            out["flock agents"] = int(sum(f.positions().reshape(-1, 3).shape[0] for f in self.flocks))
        out["time s"] = round(self.time, 1)
        return out

    def select(self, i) -> None:
        self.selected = i

    def command_go_to(self, i: int, xz) -> None:
        """Viewer right-click: a crowd character goes to ``xz``; a tiled character's team is
        steered there (its zone clamps the spot inside the zone)."""
        names = self.names
        if i is None:
            return
        if 0 <= i < len(names):
            self.go_to(names[i], np.asarray(xz, float))
            return
        k = i - len(names)
        for z in self.tilings:
            if k < len(z):
                z.set_target(z.team_of(k), np.asarray(xz, float))
                return
            k -= len(z)

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

    # ------------------------------------------------------------------ tiling (paper 003)
    def add_tiling(self, zone):
        """Register a :class:`runtime.tiling.zone.TilingZone` (interactive motion-patch tiling
        of its teams): stepped every tick after the flocks, drawn with the crowd (its
        characters follow the crowd's rows in :meth:`joint_positions`)."""
        if any(z.name == zone.name for z in self.tilings):
            raise ValueError(f"a tiling zone named {zone.name!r} is already in the world")
        self.tilings.append(zone)
        return zone

    def _step_tilings(self):
        t = (self.frame + 1) * self.dt
        ms = 0.0
        for z in list(self.tilings):
            try:
                z.step(t)
                ms += z.step_ms
            except Exception as e:      # a failing zone never stops the loop: it stops, with an event
                self.tilings.remove(z)
                self._zone_batches.pop(z.name, None)
                self._emit("warning", z.name, message=f"tiling zone stopped: {type(e).__name__}: {e}")
        self.stats["tiling_ms"] = ms

    def add_scenario_tiling(self, sc, libraries: dict | None = None) -> None:
        """Start the ``[[tiling]]`` zones of a scenario. ``libraries`` maps a spec's ``patches``
        to a :class:`~runtime.tiling.patch.PatchLibrary`; ``"synthetic"`` (the default) is built
        from this world's motion graph (:func:`runtime.tiling.synthetic.synthetic_library`)."""
        from .tiling.patch import PatchLibrary
        from .tiling.synthetic import synthetic_library
        from .tiling.zone import TilingZone, environment_obstacles
        libraries = dict(libraries or {})
        for spec in sc.tilings:
            lib = libraries.get(spec.patches)
            if lib is None:
                lib = synthetic_library(self.graph, meets=4) if spec.patches == "synthetic" else PatchLibrary.load(spec.patches)
                libraries[spec.patches] = lib
            zone = TilingZone(spec.name, lib, spec.bounds, spec.teams, period=spec.period, horizon=spec.horizon,
                              seed=spec.seed, obstacles=environment_obstacles(self.env, spec.bounds),
                              start_time=self.time)
            self.add_tiling(zone)

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
