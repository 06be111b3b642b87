"""Goal-directed characters in the World: commands, staged synthesis, arrivals.

A goal given at run time is planned from a *hand-off* on the character's buffered future: the
first boundary at least ``LATENCY`` frames ahead where the character stands exactly on a graph
node (the end of an idle loop, or the end of the segment it is playing). The planner runs in the
planning queue under the per-tick budget (:mod:`runtime.world.planning`). When the plan is
finished it replaces the buffer after the hand-off; if the hand-off has already played but the
character idled in place since, the same motion starts at a later idle-loop end (tested again
for collisions), else it is planned again.

A plan is tested against every other character's buffered future (:mod:`runtime.world.occupancy`).
A goal where someone stands waits behind the rest of the queue a few times; a plan whose end
would stand in someone's way is not used. A plan that is not within the adjustment tolerance or
collides is not played: the character gets a ``warning`` event and keeps idling (a collided plan
is tried once more when the queue is short). Nothing a character does can make a tick raise.
"""
from __future__ import annotations

import heapq
import math
from collections import deque
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from ..crowd.clearance import Clearance
from ..crowd.goals import SegmentLadder, with_prefix
from ..crowd.idle import still_nodes
from ..crowd.planner import (Config, CrowdPolicy, Goal, MotionCache, MotionLibrary, SearchParams, SegmentPlanner,
                             SegmentResult)
from ..crowd.scenario import BOX_REACH
from ..crowd.spacetime import SpaceTimeIndex
from ..crowd.tracks import Track
from ..motion.cylinders import blend_cylinders
from . import args
from .occupancy import Occupancy, PlanningView
from .planning import PlanningQueue
from .playback import Playback

__all__ = ["CrowdSystem", "Character", "CharacterState", "PendingGoal", "online_params", "LATENCY"]

REFILL_BELOW = 45          # frames: append idle when fewer than this remain
REFILL_URGENT = 10         # frames: ... and always on this tick when fewer than this remain
REFILL_PER_TICK = 6        # characters refilled per tick at least (more when many run low)
IDLE_SECONDS = 4.0         # idle appended per refill
MAX_DEFER = 3              # times a goal on a spot where someone stands waits for later planning
MAX_RETRY = 1              # times a plan that collided with other characters is tried again later
RETRY_QUEUE = 8            # ... when fewer than this many characters wait for the planner
LATENCY = 12               # frames between "now" and the earliest hand-off

ARRIVAL_EVENTS = {"go_to": "arrived", "sit": "sat", "stand": "stood", "pick_up": "picked_up", "put_down": "put_down"}


_NO_MOTION = SegmentResult(False, np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32),
                           np.zeros((0, 3)), 0, Config(0, 0.0, 0.0, 0.0, 0), float("inf"), (0.0, 0.0, 0.0), 0, [],
                           warning="no collision-free motion, even late or with eps relaxed", collided=True)


def online_params(fps: float) -> SearchParams:
    """The World's search parameters: online planning gives up sooner than the paper's offline
    N_max = 1000 (a character that cannot be planned must not hold the queue for seconds) and
    keeps each step small (n_m perturbations per iteration) so one step fits well inside the
    per-tick budget (see docs/decisions.md)."""
    return SearchParams(fps=fps, n_max=60, n_m=48, k_m=16, sweep=24, backward_idle=True)


class CharacterState(Enum):
    IDLE = "idle"           # playing idle clips, no goal
    QUEUED = "queued"       # has a goal waiting for the planner
    PLANNING = "planning"   # the planner is working on its goal
    MOVING = "moving"       # playing a planned segment


@dataclass
class PendingGoal:
    goal: Goal
    kind: str               # "go_to" | "sit" | "stand" | "pick_up" | "put_down"
    marker: str | None = None
    label: str = ""
    start_frame: int = -1   # clock frame where its planned segment starts (set when planned)
    defers: int = 0         # times it waited because someone stood on the goal
    retries: int = 0        # times it was planned again after colliding with others


@dataclass
class Character:
    name: str
    slot: int
    goals: deque = field(default_factory=deque)
    state: CharacterState = CharacterState.IDLE
    job: object = None
    job_handoff: Config | None = None
    job_window: tuple | None = None
    arrivals: list = field(default_factory=list)      # (abs frame, PendingGoal) still to announce
    carrying: str | None = None


class CrowdSystem:
    """The World's goal-directed characters (Sung, Kovar and Gleicher 2005, planned online).

    Args:
        world: the World (its ``frame``, ``fps`` and ``emit``).
        graph, env, roadmap: the motion graph, the environment (or None), the roadmap (or None).
        budget: seconds of planning per tick.
        rng: the random stream of the planner.
        params: search parameters (default :func:`online_params`); policy: the crowd policy.
        capacity: character slots to start with.
        job_slice: planner steps a goal's job runs before it gives way to others waiting
            (:class:`~.planning.PlanningQueue` ``slice_steps``; None: to its end).
    """

    name = "crowd"

    def __init__(self, world, graph, env, roadmap, budget: float, rng, params: SearchParams | None = None,
                 policy: CrowdPolicy | None = None, capacity: int = 64, job_slice: int | None = None):
        self.world = world
        self.graph, self.env, self.roadmap, self.rng = graph, env, roadmap, rng
        self.params = params or online_params(world.fps)
        self.policy = policy or CrowdPolicy()
        self.lib = MotionLibrary(graph, self.params)
        # motions found for one character's task, tried first for the next with the same task
        self.motion_cache = MotionCache() if self.policy.reuse_motions else None
        p = self.params
        index = SpaceTimeIndex(cell=max(1.2, 2 * self.lib.max_reach + 2 * (p.margin + p.seed_margin) + 0.1))
        self.playback = Playback(self.lib, world.fps, index, capacity)
        self.occupancy = Occupancy(self.playback, self.playback.stay_radii(p.margin))
        self.still = still_nodes(graph, p.eps, world.fps)
        self.queue = PlanningQueue(budget, self._ready, self._start_job, self._finish_job, self._job_failed,
                                   slice_steps=job_slice)
        self.static = None
        if env is not None and (len(env.polygons) or len(env.circles)):
            sdf = env.sdf(resolution=0.05, margin=2.0)
            self.static = Clearance(sdf, sdf.max_error)
        self.chars: dict[str, Character] = {}
        self.slots: list = []
        self.commands: deque = deque()
        self.due: list = []              # heap of (arrival frame, sequence, character)
        self.seq = 0
        self.box_place: dict = {}        # boxes put down somewhere else: path -> (x, z, heading)
        self.stats = world.stats         # plan_cpu_ms, plan_steps, characters, queue, plans_*

    # -- characters -----------------------------------------------------------------------------------
    @property
    def names(self) -> list[str]:
        pb = self.playback
        return [self.slots[i].name for i in np.flatnonzero(pb.active)]

    def pose_nodes(self, label: str) -> np.ndarray:
        """Nodes carrying the pose ``label`` where a character can wait standing still (all
        nodes with the label when none of them can)."""
        nodes = self.graph.nodes_with_label(label)
        still = nodes[self.still[nodes]]
        return still if len(still) else nodes

    def spawn(self, name: str, position, heading: float, pose: str) -> int:
        """Add a character (arguments checked first: TypeError / ValueError, see
        :mod:`runtime.world.args`); if anything fails, nothing of it stays registered."""
        name = args.character_name(name)
        position = args.point(position)
        heading = args.heading(heading)
        if not isinstance(pose, str):
            raise TypeError(f"pose must be a string, not {type(pose).__name__}")
        if name in self.chars:
            raise ValueError(f"a character named {name!r} already exists")
        if len(self.graph.nodes_with_label(pose)) == 0:
            raise ValueError(f"pose {pose!r} is not a node label of the library ({self.graph.node_labels_all()})")
        nodes = self.pose_nodes(pose)
        pb = self.playback
        s = pb.free_slot()
        if len(self.slots) < pb.cap:
            self.slots += [None] * (pb.cap - len(self.slots))
        deg = np.bincount(self.graph.edge_src, minlength=self.graph.num_nodes)[nodes]
        node = int(nodes[np.argmax(deg)])
        c = Character(name, s)
        self.chars[name] = c
        self.slots[s] = c
        try:
            pb.place(s, self.world.frame, position, heading, node)
            # characters spawned together get idle futures of different lengths, so that their
            # refills spread over many ticks
            loop = pb.loop_len(node) or 1
            self.append_idle(c, 3.0 + (s % 7) * loop / self.world.fps)
        except BaseException:       # transactional: no half-registered character
            del self.chars[name]
            self.slots[s] = None
            pb.release(s)
            raise
        return s

    def remove(self, name: str) -> None:
        c = self.chars.pop(name)
        self.slots[c.slot] = None
        self.playback.release(c.slot)
        self.queue.forget(c)

    def append_idle(self, c: Character, seconds: float = 3.0) -> None:
        self.playback.append_idle(c.slot, self.occupancy.stay_r, seconds)

    # -- commands ---------------------------------------------------------------------------------------
    def marker(self, path, role):
        m = self.env.markers.get(path) if self.env is not None else None
        if m is None or m.role != role:
            raise ValueError(f"no {role} marker {path!r} in the world")
        return m

    def apply(self, cmd) -> None:
        """Turn a queued command into a pending goal of its character."""
        kind, name, pos, heading, arrive, marker = cmd
        c = self.chars.get(name)
        if c is None:
            self.world.emit("warning", name, message=f"{kind}: no character named {name!r}")
            return
        try:
            pend = self._pending(c, kind, pos, heading, arrive, marker)
        except Exception as e:   # a bad command never stops the loop
            self.world.emit("warning", name, message=f"{kind}: {e}")
            return
        c.goals.append(pend)
        if c.state in (CharacterState.IDLE, CharacterState.MOVING) and c not in self.queue.queue \
                and c is not self.queue.active:
            c.state = CharacterState.QUEUED
            self.queue.push(c)

    def _pending(self, c: Character, kind, pos, heading, arrive, marker) -> PendingGoal:
        if pos is not None:            # commands queued without the World's checks are checked here
            pos = args.point(pos)
        heading = args.heading(heading, optional=True)
        arrive = args.window(arrive)
        pb = self.playback
        if kind == "go_to":
            # arrive standing where the character can wait still (not on a walking hub, whose
            # self loops are walk cycles)
            goal = Goal(pos, heading, self.pose_nodes("stand"), tuple(arrive) if arrive else None, label="go_to")
            pend = PendingGoal(goal, "go_to")
            if not marker:      # replace: drop goals nobody has started planning (queue=False)
                keep = 1 if c.state is CharacterState.PLANNING and c.goals else 0
                while len(c.goals) > keep:
                    c.goals.pop()
            return pend
        if kind == "sit":
            m = self.marker(marker, "seat")
            return PendingGoal(Goal(m.position.copy(), m.heading, self.pose_nodes("sit")), "sit", marker)
        if kind == "stand":
            r = pb.root_at(c.slot, pb.tail[c.slot])
            fwd = np.array([math.sin(r[2]), math.cos(r[2])])
            return PendingGoal(Goal(r[:2] + 0.45 * fwd, float(r[2]), self.pose_nodes("stand")), "stand")
        if kind == "pick_up":
            m = self.marker(marker, "box")
            placed = self.box_place.get(marker)
            if placed is not None:     # put down somewhere else since: stand where its carrier stood
                h = float(placed[2])
                at = np.array(placed[:2], float) - BOX_REACH * np.array([math.sin(h), math.cos(h)])
                return PendingGoal(Goal(at, h, self.pose_nodes("carry")), "pick_up", marker)
            fwd = np.array([math.sin(m.heading), math.cos(m.heading)])
            return PendingGoal(Goal(m.position + BOX_REACH * fwd, m.heading + math.pi, self.pose_nodes("carry")),
                               "pick_up", marker)
        if kind == "put_down":
            return PendingGoal(Goal(pos, heading, self.pose_nodes("stand")), "put_down")
        raise ValueError(f"unknown command {kind}")

    # -- planning -----------------------------------------------------------------------------------------
    def _handoff(self, c: Character) -> Config:
        """Earliest boundary >= now + LATENCY where the character stands on a node."""
        earliest = self.world.frame + LATENCY
        for f, cfg in self.playback.boundaries[c.slot]:
            if f >= earliest:
                return cfg
        # none buffered far enough: extend with idle (which creates boundaries) and retry
        self.append_idle(c)
        for f, cfg in self.playback.boundaries[c.slot]:
            if f >= earliest:
                return cfg
        return self.playback.config_at_tail(c.slot)

    def _ready(self, c: Character):
        """The planning queue's test: None (gone or nothing to plan), False (a goal where
        another character stands waits behind the rest of the queue, up to ``MAX_DEFER``
        times: the other one may be about to leave, and the plan would fail), True."""
        if c.name not in self.chars or not c.goals:
            return None
        if c.goals[0].defers < MAX_DEFER and self.occupancy.goal_taken(c.slot, c.goals[0].goal):
            c.goals[0].defers += 1
            return False
        return True

    def _start_job(self, c: Character):
        pend = c.goals[0]
        start = self._handoff(c)
        planner = SegmentPlanner(self.lib, static=self.static,
                                 collide=lambda f, xz, r, s=c.slot: self.occupancy.collide(f, xz, r, s),
                                 roadmap=self.roadmap, env=self.env, params=self.params)
        planner.cache = self.motion_cache
        goal = pend.goal
        fps = self.world.fps
        if goal.window is not None and goal.window[1] < (start.frame + 1) / fps:
            self.world.emit("late", c.name, window=goal.window,
                            message="the arrival window has passed; planning without it")
            goal = Goal(goal.position, goal.heading, goal.nodes, None, goal.label)
        n = self.params.n_max
        view = PlanningView(self, c.slot)
        if self.policy.bend_waypoints:
            planner.standing = view.standing
        ladder = SegmentLadder(view, planner, c.name, self.rng, n,
                               min(self.policy.retry_n_max, n))
        job = ladder.plan(start, goal, 0)
        c.job_handoff = start
        c.job_window = goal.window
        c.state = CharacterState.PLANNING
        return job

    def _job_failed(self, c: Character, message: str, pop: bool) -> None:
        c.job = None
        if pop and c.goals:
            c.goals.popleft()
        c.state = CharacterState.IDLE
        self.world.emit("warning", c.name, message=message)

    def _shifted(self, c: Character, res, tries: int = 2):
        """A plan whose hand-off has already played, moved later in time: when the character
        has been idling in place since the hand-off, every later idle-loop end is the same
        configuration, so the same motion can start there. The moved motion is tested again
        against the other characters (the environment does not move) and against the goal's
        arrival window. Returns the new start frame or None."""
        s0 = c.job_handoff
        g = self.graph
        xz, rad = blend_cylinders(g, res.frames_a, res.frames_b, res.root)
        rad = rad + self.params.margin
        for f, cfg in self.playback.boundaries[c.slot]:
            if f <= self.world.frame or cfg.node != s0.node or abs(cfg.x - s0.x) > 1e-6 or abs(cfg.z - s0.z) > 1e-6 \
                    or abs((cfg.heading - s0.heading + math.pi) % (2 * math.pi) - math.pi) > 1e-6:
                continue
            dt = f - s0.frame
            win = c.job_window
            if win is not None and not (win[0] - 1e-9 <= (res.end.frame + dt) / self.world.fps <= win[1] + 1e-9):
                return None
            frames = f + np.arange(len(res.root))
            if not self.occupancy.collide(frames, xz, rad, c.slot).any():
                return f
            tries -= 1
            if tries <= 0:
                return None
        return None

    def _finish_job(self, c: Character, out) -> None:
        """Use a finished plan: ``out`` is the ladder's (wait before, SegmentResult, LadderStep)
        or None when not even a late or relaxed motion is clear of everyone."""
        res, step = (_NO_MOTION, None) if out is None else (with_prefix(out[0], out[1]), out[2])
        pend = c.goals.popleft()
        c.job = None
        now = self.world.frame
        start_frame = c.job_handoff.frame
        if start_frame < now and res.ok:
            f = self._shifted(c, res)
            if f is not None:
                self.stats["plans_shifted"] += 1
                start_frame = f
        if start_frame < now and res.ok:
            # the hand-off has already played and the plan cannot be moved: plan again
            c.goals.appendleft(pend)
            c.state = CharacterState.QUEUED
            self.queue.push(c)
            self.stats["plans_redone"] += 1
            return
        dt = start_frame - res.start_frame
        end = Config(res.end.node, res.end.x, res.end.z, res.end.heading, res.end.frame + dt)
        problem = None
        if not res.ok or res.warning:
            problem = res.warning or "no motion within the tolerance"
        elif self.occupancy.end_blocked(c.slot, end):
            problem = "standing at the goal would block a character already on its way there"
        if problem and pend.retries < MAX_RETRY and len(self.queue.queue) < RETRY_QUEUE:
            # blocked by other characters: try once more after the rest of the queue (they will
            # have moved on by then) unless many others are waiting for the planner
            pend.retries += 1
            pend.defers = 0
            c.goals.append(pend) if c.goals else c.goals.appendleft(pend)
            self.stats["plans_retried"] += 1
            c.state = CharacterState.IDLE
        elif problem:
            # a failed plan is not played: the character keeps idling where it is
            self.stats["plans_failed"] += 1
            self.world.emit("warning", c.name, message=f"{pend.kind}: plan not used ({problem}); it waits where "
                            "it stands, clear of everyone", goal=[float(v) for v in pend.goal.position])
            c.state = CharacterState.IDLE
        else:
            self.stats["plans_done"] += 1
            tr = Track(res.frames_a, res.frames_b, res.frames_t, res.root, start_frame)
            self.playback.write(c.slot, tr, start_frame)
            self.playback.tail_node[c.slot] = end.node
            self.playback.boundaries[c.slot].append((end.frame, end))
            c.arrivals.append((end.frame, pend))
            pend.start_frame = start_frame
            self.seq += 1
            heapq.heappush(self.due, (end.frame, self.seq, c))
            c.state = CharacterState.MOVING
            self.append_idle(c)
            if step is not None and step.kind == "late":
                self.world.emit("late", c.name, delay=step.delay_s, window=c.job_window,
                                message=f"{pend.kind}: arrives {step.delay_s:.2f} s after its window ({step.reason})")
            elif step is not None and step.kind == "relaxed":
                self.world.emit("warning", c.name, eps_factor=step.eps_factor,
                                message=f"{pend.kind}: adjustment {step.eps_factor:.2f} x eps ({step.reason})")
        if c.goals:
            c.state = CharacterState.QUEUED
            self.queue.push(c)

    # -- the tick ------------------------------------------------------------------------------------------
    def tick(self, world) -> None:
        """Before the clock advances: apply queued commands."""
        while self.commands:
            self.apply(self.commands.popleft())

    def plan(self, deadline: float) -> None:
        """Planner steps until ``deadline`` (``time.perf_counter()``; the World calls this after
        every system's tick, so the budget is what the tick's other work left of it)."""
        self.queue.run(self.stats, deadline)

    def after_tick(self, world) -> None:
        """After the clock advanced: every read head moves to the new frame; buffers running low
        get idle clips (the most urgent first and only a few per tick: characters spawned
        together would otherwise all refill on one tick); arrivals are announced."""
        pb = self.playback
        frame = world.frame
        act = pb.active
        pb.head[act] = frame
        left = pb.tail - pb.head
        low = np.flatnonzero(act & (left < REFILL_BELOW))
        if len(low):
            low = low[np.argsort(left[low], kind="stable")]
            n = max(REFILL_PER_TICK, int(np.sum(left[low] < REFILL_URGENT)),
                    -(-len(low) // (REFILL_BELOW - REFILL_URGENT)))
            for s in low[:n]:
                c = self.slots[s]
                self.append_idle(c, IDLE_SECONDS if c.state is not CharacterState.PLANNING else 1.0)
        self._announce(frame)
        pb.index.forget_before(frame)
        if frame % 30 == 0:
            pb.stretches.forget_before(frame)
        self.stats.update(characters=int(act.sum()), queue=len(self.queue))

    def _announce(self, frame: int) -> None:
        due = []
        while self.due and self.due[0][0] <= frame:
            c = heapq.heappop(self.due)[2]
            if c.name in self.chars and c not in due:
                due.append(c)
        pb = self.playback
        for c in due:
            while c.arrivals and c.arrivals[0][0] <= frame:
                f, pend = c.arrivals.pop(0)
                if pend.kind == "pick_up":
                    c.carrying = pend.marker
                if pend.kind == "put_down":
                    if c.carrying:
                        r0 = pb.root_at(c.slot, f)
                        fwd = (math.sin(r0[2]), math.cos(r0[2]))
                        self.box_place[c.carrying] = (r0[0] + BOX_REACH * fwd[0], r0[1] + BOX_REACH * fwd[1], r0[2])
                    c.carrying = None
                r = pb.root_at(c.slot, f)
                self.world.emit(ARRIVAL_EVENTS[pend.kind], c.name, position=(float(r[0]), float(r[1])),
                                heading=float(r[2]), marker=pend.marker, frame=f, start_frame=pend.start_frame)
                if not c.arrivals and not c.goals and c.state is CharacterState.MOVING:
                    c.state = CharacterState.IDLE

    # -- what is drawn ---------------------------------------------------------------------------------------
    def box_positions(self) -> np.ndarray:
        """Bottom-centre (x, y, z) and heading of every box marker, carried ones in the hands."""
        if self.env is None:
            return np.zeros((0, 4))
        boxes = self.env.markers_with_role("box")
        carried = {c.carrying: c for c in self.chars.values() if c.carrying}
        pb = self.playback
        out = []
        for m in boxes:
            c = carried.get(m.path)
            if c is None:
                p = self.box_place.get(m.path, (m.position[0], m.position[1], m.heading))
                out.append((p[0], 0.0, p[1], p[2]))
            else:
                r = pb.root_at(c.slot, pb.head[c.slot])
                fwd = np.array([math.sin(r[2]), math.cos(r[2])])
                out.append((r[0] + 0.35 * fwd[0], 0.85, r[1] + 0.35 * fwd[1], r[2]))
        return np.array(out, dtype=np.float64).reshape(-1, 4)

