"""The planning queue: staged synthesis under a per-tick budget (Sung, Kovar and Gleicher 2005,
section 5: "the search can be broken into stages").

Characters with a goal wait in a queue; one at a time is the *active job*, a time-sliced
planner generator (:meth:`runtime.crowd.planner.SegmentPlanner.run`). Every ``next()`` is a
*step* of the kind the planner yielded before it (:class:`~runtime.crowd.planner.Step`); using a
finished plan is a step of its own (:data:`FINISH`). A step starts only when its predicted
duration (:class:`StepCosts`, a high running estimate per kind) fits in what is left of the
budget, and the first step of a tick always runs, so planning progresses even when a single step
is longer than the budget (the Recast/Detour pattern of a sliced query: init, update with a
budget, finalize).

With ``slice_steps`` set, a job that has run that many steps while others wait goes to the back
of the queue, its planner kept as it is, and resumes when its turn comes again (round robin):
a goal whose ladder needs thousands of steps no longer holds up the short plans behind it. A
plan that finishes after its hand-off has played is handled as any late plan (moved to a later
idle-loop end, or planned again).
"""
from __future__ import annotations

import time
from collections import deque

from ..crowd.planner import Step

__all__ = ["StepCosts", "PlanningQueue", "FINISH", "START"]

FINISH = "finish"        # the step kind of using a finished plan
START = Step.WAYPOINTS   # the kind of a job's first step


class StepCosts:
    """Predicted duration of a planner step, per kind: running averages (rate ``rate``) of the
    duration and of its absolute deviation from the average, ``mean + k * deviation``, and at
    least a decaying maximum (each new duration of the kind multiplies it by ``decay``): some
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


class PlanningQueue:
    """Whose goal is planned next, and the budgeted loop of planner steps.

    Args:
        budget: seconds of planning per tick.
        ready: ``ready(c) -> bool | None``: may ``c``'s first goal be planned now; False defers
            it behind the rest of the queue, None drops ``c`` from the queue (gone, or nothing
            left to plan).
        start: ``start(c) -> generator``: the planner job for ``c``'s first goal (may raise).
        finish: ``finish(c, result)``: use a finished plan.
        failed: ``failed(c, message, pop)``: a job could not start, raised, or its result could
            not be used (``pop``: drop the goal it was for).
        slice_steps: steps a job runs before it yields its place to a waiting one (None: it
            runs to its end).
    """

    def __init__(self, budget: float, ready, start, finish, failed, slice_steps: int | None = None):
        self.budget = budget
        self.slice_steps = slice_steps
        self.suspended: dict = {}    # id(character) -> the next step kind of its suspended job
        self.job_steps = 0           # steps the active job has run since it (re)started
        self.ready, self._start, self._finish, self._failed = ready, start, finish, failed
        self.queue: deque = deque()
        self.active = None           # the character whose job is running
        self.next_kind = START       # the kind of the active job's next step
        self.done = None             # (character, result) of a finished plan, used as its own step
        self.costs = StepCosts()

    def __len__(self) -> int:
        """Characters waiting or being planned."""
        return len(self.queue) + (self.active is not None) + (self.done is not None)

    def push(self, c) -> None:
        self.queue.append(c)

    def forget(self, c) -> None:
        """Drop everything about ``c`` (it was removed from the world)."""
        if self.active is c:
            self.active = None
        if self.done is not None and self.done[0] is c:
            self.done = None
        if c in self.queue:
            self.queue.remove(c)
        self.suspended.pop(id(c), None)

    def _next_job(self) -> bool:
        """Make the first queued character that is ready the active job; False when none."""
        tries = len(self.queue)
        while self.queue and self.active is None and tries > 0:
            tries -= 1
            c = self.queue.popleft()
            if id(c) in self.suspended:          # a job that gave way: resume it
                self.next_kind = self.suspended.pop(id(c))
                self.active, self.job_steps = c, 0
                break
            verdict = self.ready(c)
            if verdict is None:
                continue
            if not verdict:
                self.queue.append(c)
                continue
            try:
                c.job = self._start(c)
                self.active = c
                self.next_kind = START
                self.job_steps = 0
            except Exception as e:
                self._failed(c, f"planning failed to start: {e}", pop=True)
        return self.active is not None

    def _advance(self) -> None:
        c = self.active
        try:
            self.next_kind = next(c.job)
            self.job_steps += 1
            if self.slice_steps is not None and self.job_steps >= self.slice_steps and self.queue:
                self.suspended[id(c)] = self.next_kind       # others wait: give way
                self.queue.append(c)
                self.active = None
        except StopIteration as stop:
            self.active = None
            self.done = (c, stop.value)
        except Exception as e:
            self.active = None
            c.job = None
            self._failed(c, f"planning failed: {type(e).__name__}: {e}", pop=True)

    def _use_result(self) -> None:
        c, res = self.done
        self.done = None
        try:
            self._finish(c, res)
        except Exception as e:
            self._failed(c, f"could not use the plan: {e}", pop=False)

    def run(self, stats: dict, deadline: float | None = None) -> None:
        """Planner steps under the per-tick budget (see the module docstring) until
        ``deadline`` (a ``time.perf_counter()`` instant; default: the budget from now); writes
        ``plan_cpu_ms`` and ``plan_steps`` into ``stats``."""
        t0 = time.perf_counter()
        if deadline is None:
            deadline = t0 + self.budget
        c0 = time.thread_time()
        steps = 0
        while True:
            if self.done is not None:
                kind, run = FINISH, self._use_result
            elif self.active is not None or self._next_job():
                kind, run = self.next_kind, self._advance
            else:
                break
            if steps and time.perf_counter() + self.costs.predict(kind) > deadline:
                break
            ts = time.perf_counter()
            run()
            self.costs.record(kind, time.perf_counter() - ts)
            steps += 1
        stats["plan_cpu_ms"] = (time.thread_time() - c0) * 1000
        stats["plan_steps"] = steps
