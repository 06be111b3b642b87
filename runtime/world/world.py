"""World: the runtime a game embeds -- a fixed-timestep loop of systems, commands, poses.

The tick::

    accumulate real time; for each whole dt (runtime.clock.FixedStep):
        every system's tick, in order:
            crowd:   apply queued commands
            flocks:  advance each flock along its DDG walk
            tiling:  extend each tiling zone's horizon with new patch instances
            (systems added with add_system, in the order added)
        planner steps until the per-tick budget, counted from the tick's start, is spent
        (the other systems' work comes out of it; the first step always runs)
        the clock advances one frame
        every system's after_tick (the crowd: read heads, idle refills, arrival events)
    render: poses interpolated between the last two ticks, all characters in one pass

A *system* is any object with ``tick(world)`` (before the clock advances) and, optionally,
``after_tick(world)`` (after it). The World also implements the viewer's scene protocol
(:mod:`runtime.view`).

Errors: every public method checks its arguments before it changes anything
(:mod:`runtime.world.args`), so a call that raises leaves the World as it was. A wrong type
raises ``TypeError``; a value that is not finite, out of range (coordinates within 1e6 m, times
from 0 to 1e7 s), of the wrong shape, a reversed window, a name in use or an unknown pose
``ValueError``; a method that needs a character now (``remove``, ``state``, ``position``,
``slot``) raises ``KeyError`` for an unknown name. Commands are queued: what can only be known
at the next tick (the character was removed, the world has no such seat or box, no plan was
found) becomes a ``warning`` event instead. ``step`` never raises (its built-in systems never do;
an error of a system added with :meth:`add_system` is the caller's and propagates).
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..compiled import preload as preload_kernels
from ..clock import FixedStep
from ..crowd.planner import CrowdPolicy, SearchParams
from ..crowd.tracks import evaluate_poses
from ..motion.fk import forward_kinematics
from ..motion.graph import MotionGraph
from ..pose import PoseBatch, PoseState
from . import args
from .crowd import CharacterState, CrowdSystem
from .events import EventBus
from .flocks import FlockHost
from .scenario import scenario_flock_starts, scenario_tiling_zones
from .tiling import TilingHost

__all__ = ["World"]

MAX_TICKS_PER_STEP = 8     # ticks one step() may run; a longer stall drops whole ticks (keeps the phase)
TICK_HISTORY = 9000        # ticks whose durations are kept (5 min at 30 Hz)


class World:
    """Characters, flocks and tiling zones on one fixed clock.

    Args:
        library: a motion graph, or the name/path of a motion-graph pack (``"default"``).
        world: the environment (:class:`runtime.crowd.environment.Environment`, e.g. from
            ``usd_io.world.read_world(path)``), or None for open ground.
        roadmap: the environment's roadmap (:class:`runtime.crowd.roadmap.Roadmap`), or None.
        dt: tick length in seconds.
        budget_ms: time per tick for the tick's work and planning (milliseconds): the planner
            steps until this much has passed since the tick began (at least one step).
        seed: the random stream of the planner and of unseeded flocks.
        params: search parameters of the online planner (default
            :func:`runtime.world.crowd.online_params`); policy: the crowd policy.
        capacity: character slots to start with (grows as needed).
        job_slice: planner steps one goal's planning runs before it gives way to the goals
            waiting behind it (round robin; None: each runs to its end, first come first served).
    """

    def __init__(self, library="default", world=None, roadmap=None, dt: float = 1.0 / 30.0,
                 budget_ms: float = 4.0, seed: int = 0, params: SearchParams | None = None,
                 policy: CrowdPolicy | None = None, capacity: int = 64, job_slice: int | None = None):
        from ..library import load_library
        for what, v, lo, hi in (("dt", dt, 1e-4, 1e4), ("budget_ms", budget_ms, 0.0, args.MAX_TIME * 1e3)):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
                raise TypeError(f"{what} must be a number, not {type(v).__name__}")
            if not (np.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"{what} must be finite, from {lo:g} to {hi:g}, got {v}")
        for what, v, lo in (("seed", seed, 0), ("capacity", capacity, 1)) + ((("job_slice", job_slice, 1),)
                                                                              if job_slice is not None else ()):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise TypeError(f"{what} must be an integer, not {type(v).__name__}")
            if v < lo:
                raise ValueError(f"{what} must be at least {lo}, got {v}")
        if world is not None and not hasattr(world, "polygons"):
            raise TypeError(f"world must be an Environment or None, not {type(world).__name__}: read a stage "
                            f"with usd_io.world.read_world(path)")
        self.graph: MotionGraph = library if isinstance(library, MotionGraph) else load_library(library)
        self.env = world
        self.roadmap = roadmap
        self.clock = FixedStep(dt, MAX_TICKS_PER_STEP)
        self.dt = self.clock.dt
        self.fps = 1.0 / self.dt
        self.rng = np.random.default_rng(seed)
        self.frame = 0
        self.bus = EventBus()
        self.stats = {"tick_ms": 0.0, "plan_ms": 0.0, "plan_cpu_ms": 0.0, "plan_steps": 0, "characters": 0,
                      "queue": 0, "ticks": 0, "plans_done": 0, "plans_failed": 0,
                      "plans_shifted": 0, "plans_redone": 0, "plans_retried": 0}
        self.crowd = CrowdSystem(self, self.graph, self.env, roadmap, budget_ms / 1000.0, self.rng, params, policy,
                                 capacity, job_slice)
        self.params = self.crowd.params
        self.flock_host = FlockHost(self.rng)
        self.tiling = TilingHost()
        self.systems: list = [self.crowd, self.flock_host, self.tiling]
        self.flocks: list = self.flock_host.systems      # the FlockSystems (one per DDG)
        self.tilings: list = self.tiling.zones           # the TilingZones
        self.selected = None
        self.ambient = None              # the AmbientLife of add_scenario_ambient, if any
        self.tick_times = np.zeros(TICK_HISTORY)    # ms of the last ticks (ring, see tick_percentile)
        self._pose_batch = None          # render-side poses (joint_positions)
        self._pose_at = None
        preload_kernels()                # compiled kernels loaded now, not inside a tick
        self._pose_slots = None

    # -- systems and the clock ---------------------------------------------------------------------------
    def add_system(self, system) -> None:
        """Tick ``system`` after the built-in ones: an object with ``tick(world)`` and optionally
        ``after_tick(world)``, or a plain callable ``f(world)`` (run as its tick)."""
        self.systems.append(system)

    def emit(self, kind: str, name: str, **data) -> None:
        """Emit an event at the current world time (listeners: :meth:`on`)."""
        self.bus.emit(kind, name, self.frame / self.fps, **data)

    def on(self, kind: str, callback) -> None:
        """Call ``callback(event)`` for events of ``kind`` ("*" for all)."""
        self.bus.on(kind, callback)

    @property
    def events(self) -> list:
        return self.bus.events

    def tick(self) -> None:
        """One fixed step of every system (see the module docstring)."""
        t0 = time.perf_counter()
        for s in self.systems:
            s.tick(self) if hasattr(s, "tick") else s(self)
        ts = time.perf_counter()
        self.crowd.plan(t0 + self.crowd.queue.budget)
        self.stats["plan_ms"] = (time.perf_counter() - ts) * 1000
        self.frame += 1
        for s in self.systems:
            after = getattr(s, "after_tick", None)
            if after is not None:
                after(self)
        ms = (time.perf_counter() - t0) * 1000
        self.tick_times[self.stats["ticks"] % TICK_HISTORY] = ms
        self.stats.update(tick_ms=ms, ticks=self.stats["ticks"] + 1)

    def tick_percentile(self, q: float) -> float:
        """The ``q``-th percentile (0-100) of the last ticks' durations, ms (0 before any tick)."""
        n = min(self.stats["ticks"], TICK_HISTORY)
        return float(np.percentile(self.tick_times[:n], q)) if n else 0.0

    def step(self, real_dt: float) -> int:
        """Advance by ``real_dt`` seconds of real time; returns the ticks run (at most
        ``MAX_TICKS_PER_STEP``, so a stall never snowballs). Never raises: a ``real_dt`` that is
        not a finite, non-negative number runs no tick and emits a ``warning`` event."""
        try:
            dt = args.seconds(real_dt, "real_dt")
        except (TypeError, ValueError) as e:
            self.emit("warning", "", message=f"step: {e}; no tick run")
            return 0
        n = self.clock.advance(dt)
        for _ in range(n):
            self.tick()
        return n

    @property
    def budget(self) -> float:
        """Planning time per tick, seconds."""
        return self.crowd.queue.budget

    @budget.setter
    def budget(self, seconds: float) -> None:
        self.crowd.queue.budget = args.seconds(seconds, "budget")

    @property
    def time(self) -> float:
        return self.frame / self.fps

    @property
    def alpha(self) -> float:
        """Fraction of a tick between the last tick and the next (for render interpolation)."""
        return self.clock.alpha

    # -- characters and commands (queued, applied at the next tick) --------------------------------------------
    @property
    def names(self) -> list[str]:
        """Active characters in slot order (the rows of :meth:`poses`)."""
        return self.crowd.names

    def spawn(self, name: str, position, heading: float = 0.0, pose: str = "stand") -> int:
        """Add a character standing (or seated: pose "sit") at ``position`` (x, z), facing
        ``heading`` (radians, 0 = +Z). Returns its slot."""
        return self.crowd.spawn(name, position, heading, pose)

    def _known(self, name) -> str:
        """``name`` if it is a character now, else KeyError naming it."""
        if args.character_name(name) not in self.crowd.chars:
            raise KeyError(f"no character named {name!r}")
        return name

    def remove(self, name: str) -> None:
        self.crowd.remove(self._known(name))

    def slot(self, name: str) -> int:
        """The character's row in the playback buffers (:attr:`playback`)."""
        return self.crowd.chars[self._known(name)].slot

    @property
    def playback(self):
        """Every character's buffered future (:class:`runtime.world.playback.Playback`)."""
        return self.crowd.playback

    def state(self, name: str) -> CharacterState:
        return self.crowd.chars[self._known(name)].state

    def position(self, name: str) -> np.ndarray:
        """(x, z, heading) of the character now."""
        pb, s = self.playback, self.slot(name)
        return pb.root_at(s, pb.head[s]).copy()

    def go_to(self, name, position, heading=None, arrive=None, queue: bool = False):
        """Walk to ``position`` (x, z), optionally facing ``heading`` (radians) and arriving in
        the absolute time window ``arrive = (t0, t1)`` seconds. A new go_to replaces goals that
        are still waiting for the planner unless ``queue`` is True (then it comes after them)."""
        cmd = ("go_to", args.character_name(name), args.point(position), args.heading(heading, optional=True),
               args.window(arrive), queue)
        if not isinstance(queue, bool):
            raise TypeError(f"queue must be True or False, not {type(queue).__name__}")
        self.crowd.commands.append(cmd)

    def sit(self, name, seat):
        """Sit down on the seat marker ``seat`` (a prim path of the world stage)."""
        self.crowd.commands.append(("sit", args.character_name(name), None, None, None, args.marker_path(seat, "seat")))

    def stand(self, name):
        self.crowd.commands.append(("stand", args.character_name(name), None, None, None, None))

    def pick_up(self, name, box):
        """Walk to the box marker ``box`` and pick it up."""
        self.crowd.commands.append(("pick_up", args.character_name(name), None, None, None,
                                    args.marker_path(box, "box")))

    def put_down(self, name, position, heading=None):
        self.crowd.commands.append(("put_down", args.character_name(name), args.point(position),
                                    args.heading(heading, optional=True), None, None))

    def meet(self, names, position, time_s):
        """Characters arrive together at ``time_s`` around ``position``, facing its centre
        (``names``: a non-empty list of distinct names)."""
        import math
        names = args.names(names)
        position = args.point(position)
        time_s = args.seconds(time_s, "time_s")
        arrive = args.window((time_s, time_s + 0.5), "time_s")
        n = len(names)
        r = 0.0 if n == 1 else max(0.55, 0.75 / (2 * math.sin(math.pi / n)))
        cmds = []
        for k, name in enumerate(names):
            a = 2 * math.pi * k / n
            p = args.point(np.asarray(position, float) + r * np.array([math.sin(a), math.cos(a)]))
            h = math.atan2(position[0] - p[0], position[1] - p[1]) if n > 1 else None
            cmds.append(("go_to", name, p, h, arrive, False))
        self.crowd.commands.extend(cmds)      # all or none

    def pose_nodes(self, label: str) -> np.ndarray:
        """Nodes of pose ``label`` where a character can wait standing still."""
        return self.crowd.pose_nodes(label)

    # -- poses -----------------------------------------------------------------------------------------------
    def root_states(self):
        """Current (x, z, heading) of every active character (N, 3), in slot order."""
        return self.playback.gather(0)[4]

    def poses(self, alpha: float | None = None):
        """Joint world positions (N, J, 3) of all characters (slot order = :attr:`names`),
        interpolated between the previous and the current tick by ``alpha`` (default: the
        clock's fraction); exact rotations (slerp + forward kinematics, float64)."""
        alpha = self.alpha if alpha is None else args.alpha(alpha)
        pb = self.playback
        s, a, b, t, root = pb.gather(0)
        if len(s) == 0:
            return np.zeros((0, self.graph.skeleton.num_joints, 3))
        pos, rot = evaluate_poses(self.graph, a, b, t, root)
        cur = forward_kinematics(self.graph.skeleton, pos, rot)[1]
        if alpha >= 1.0:
            return cur
        _, a0, b0, t0, root0 = pb.gather(-1)
        pos0, rot0 = evaluate_poses(self.graph, a0, b0, t0, root0)
        prev = forward_kinematics(self.graph.skeleton, pos0, rot0)[1]
        return prev + (cur - prev) * alpha

    # -- the viewer's scene protocol (runtime.view) --------------------------------------------------------------
    @property
    def environment(self):
        if self.env is None:
            from ..crowd.environment import Environment
            self.env = Environment.open_ground()
        return self.env

    @property
    def skeleton(self):
        return self.graph.skeleton

    def joint_positions(self):
        """What the viewer draws: the crowd through the table evaluator of :mod:`runtime.pose`
        (a :class:`~runtime.pose.PoseBatch` pushed once per tick, interpolated per frame;
        float32, within a few mm of :meth:`poses`), then every tiling zone's characters."""
        pb = self.playback
        s = np.flatnonzero(pb.active)
        if self._pose_batch is None:
            self._pose_batch = PoseBatch(self.graph)
        if self._pose_at != self.frame or not np.array_equal(s, self._pose_slots):
            if self._pose_at != self.frame - 1 or not np.array_equal(s, self._pose_slots):
                self._pose_batch.reset()
                self._pose_batch.push(PoseState(*pb.gather(-1)[1:]))
            self._pose_batch.push(PoseState(*pb.gather(0)[1:]))
            self._pose_at, self._pose_slots = self.frame, s
        pos = self._pose_batch.positions(self.alpha)
        if not self.tiling.zones:
            return pos
        return np.concatenate([pos] + [self.tiling.zone_positions(z, self.time, self.alpha) for z in self.tiling.zones])

    def hud_stats(self) -> dict:
        out = {"tick ms": round(self.stats["tick_ms"], 2), "synthesis ms": round(self.stats["plan_ms"], 2),
               "characters": self.stats["characters"], "queue": self.stats["queue"]}
        if self.tiling.zones:
            out["tiled"] = len(self.tiling)
            out["tiling ms"] = round(self.stats.get("tiling_ms", 0.0), 2)
        if self.flock_host.systems:
            out["flock agents"] = self.flock_host.agent_count()
        for s in self.systems:              # systems that report (e.g. the ambient people)
            extra = getattr(s, "hud_stats", None)
            if extra is not None:
                out.update(extra())
        out["p99 tick ms"] = round(self.tick_percentile(99), 1)
        out["time s"] = round(self.time, 1)
        return out

    def landmarks(self) -> dict:
        """Named places worth looking at, name -> (x, y, z, radius): the ambient people's
        busiest stretch ("plaza"), each tiling zone ("tiled") and the flocks ("flocks", where
        they are now)."""
        out = {}
        if self.ambient is not None:
            out["plaza"] = self.ambient.busiest()
        for z in self.tiling.zones:
            x0, z0, x1, z1 = z.bounds
            out.setdefault("tiled", (0.5 * (x0 + x1), 0.0, 0.5 * (z0 + z1), 0.5 * math.hypot(x1 - x0, z1 - z0)))
        if self.flock_host.systems:
            p = self.flock_positions()[0]
            if len(p):
                c = p.mean(0)
                out["flocks"] = (float(c[0]), float(c[1]), float(c[2]), float(np.linalg.norm(p - c, axis=1).max()))
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
        self.tiling.steer(i - len(names), np.asarray(xz, float))

    def box_positions(self):
        """Bottom-centre (x, y, z) and heading of every box marker, carried ones in the hands."""
        return self.crowd.box_positions()

    def flock_positions(self):
        """All flock agents: positions (M, 3) and headings (M,)."""
        return self.flock_host.positions()

    # -- flocks, tiling zones, scenarios ----------------------------------------------------------------------------
    def add_flocks(self, ddg, positions, headings=None, regions=None, seed: int | None = None):
        """Start flocks walking ``ddg`` (a :class:`runtime.flock.DDG` or a pack path): their
        centroids at ``positions`` (k, 3), optionally each constrained to a region. All flocks
        of one DDG advance together in one vectorized system. Returns (system index, flock rows)."""
        positions, headings = args.flock_starts(positions, headings, regions, seed)
        return self.flock_host.add(ddg, positions, headings, regions, seed)

    def add_tiling(self, zone):
        """Register a :class:`runtime.tiling.zone.TilingZone` (interactive motion-patch tiling of
        its teams): stepped every tick after the flocks, drawn with the crowd."""
        return self.tiling.add(zone)

    def apply_scenario(self, sc) -> None:
        """Spawn a scenario's characters and queue their goals as run-time commands (staged: each
        goal is planned while the previous one plays). Seats and boxes become sit and pick_up; a
        "stand" goal while carrying becomes put_down; relative timing (``after``) is not used
        online. (Flocks: :meth:`add_scenario_flocks`, once their graphs are loaded.)"""
        for c in sc.characters:
            self.spawn(c.name, c.position, c.heading, c.pose)
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

    def add_scenario_flocks(self, sc) -> None:
        """Start the ``[[flock]]`` entries of a scenario (their DDGs resolved into
        ``spec.loaded`` by the caller, see ``authoring.commands.bake.load_sample``)."""
        for spec, ddg, pos, headings, regions in scenario_flock_starts(sc, self.env):
            self.add_flocks(ddg, pos, headings, regions, seed=spec.seed)

    def add_scenario_ambient(self, sc, **options):
        """Start the scenario's ``[ambient]`` people (:class:`~.ambient.AmbientLife`, added as a
        system): in its region, out of every tiling zone (grown by 1.5 m), using the seats and
        boxes no ``[[character]]`` goal names, and out of the rectangle round the characters'
        starts and goals (grown by 2 m) for the scenario's duration. ``options`` go to
        AmbientLife. Returns it (None without an ``[ambient]`` table)."""
        from .ambient import AmbientLife
        spec = getattr(sc, "ambient", None)
        if spec is None or spec.count == 0:
            return None
        used = {c.start_marker for c in sc.characters} | {g.marker for c in sc.characters for g in c.goals}
        env = self.environment
        seats = sorted(m.path for m in env.markers_with_role("seat") if m.path not in used)
        boxes = sorted(m.path for m in env.markers_with_role("box") if m.path not in used)
        exclude = [(x0 - 1.5, z0 - 1.5, x1 + 1.5, z1 + 1.5) for x0, z0, x1, z1 in (t.bounds for t in sc.tilings)]
        pts = [c.position for c in sc.characters] + [g.position for c in sc.characters for g in c.goals]
        pts = np.array([p for p in pts if p is not None], float).reshape(-1, 2)
        if len(pts):
            lo, hi = pts.min(0) - 2.0, pts.max(0) + 2.0
            options.setdefault("keep_clear", [((lo[0], lo[1], hi[0], hi[1]), sc.duration)])
        life = AmbientLife(self, spec.count, seed=spec.seed, area=spec.bounds, exclude=exclude, seats=seats,
                           boxes=boxes, linger=spec.linger, **options)
        self.add_system(life)
        self.ambient = life
        return life

    def add_scenario_tiling(self, sc, libraries: dict | None = None) -> None:
        """Start the ``[[tiling]]`` zones of a scenario (:func:`~.scenario.scenario_tiling_zones`)."""
        for zone in scenario_tiling_zones(sc, self.graph, self.env, self.time, libraries):
            self.add_tiling(zone)
