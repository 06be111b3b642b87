"""Independent checker for flock walks (Lai, Chenney and Fan 2005, section 5: a walk keeps the
flock's centre inside its region and plays recorded motion).

It sees only what a viewer or a bake sees -- world positions of every agent, tick after tick --
and never the graph, the plan or the correspondence, so it does not trust the synthesizer:

- region containment of every flock's centre of mass (per flock region, optional);
- the largest per-tick displacement of any agent, against the recorder's largest per-step
  displacement (``max_step``) times ``1 + tolerance`` scaled to the tick length; a swap of agent
  identities at a transition shows up here as a jump of a few metres.

Streaming: call :meth:`WalkChecker.update` once per tick, then :meth:`WalkChecker.report` for
the :class:`WalkReport` (or :meth:`WalkChecker.summary` for its summary dict).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..check import CheckReport, format_summary

__all__ = ["WalkChecker", "WalkReport"]


@dataclass(eq=False)
class WalkReport(CheckReport):
    """What a :class:`WalkChecker` found over the ticks it saw.

    Args:
        ticks: ticks checked.
        frames_outside: (flocks,) ticks each flock's centre was outside its region.
        worst_step_m: largest per-tick displacement of any agent, metres.
        worst_step_ratio: that step over the recorder's largest step scaled to the tick length.
        step_violations: agent-ticks whose step exceeded the allowed one.
    """

    ticks: int
    frames_outside: np.ndarray
    worst_step_m: float
    worst_step_ratio: float
    step_violations: int

    kind = "flock"

    @property
    def passed(self) -> bool:
        return bool(self.frames_outside.sum() == 0 and self.step_violations == 0)

    def figures(self) -> dict:
        outside = self.frames_outside
        return {
            "ticks": self.ticks,
            "flocks": int(len(outside)),
            "frames_outside": int(outside.sum()),
            "flocks_outside": int(np.count_nonzero(outside)),
            "worst_step_m": self.worst_step_m,
            "worst_step_ratio": self.worst_step_ratio,     # worst step / recorder's largest step
            "step_violations": self.step_violations,
            "ok": self.passed,
        }

    def details(self) -> dict:
        """Per flock: ticks outside its region."""
        return {"frames_outside": [int(n) for n in self.frames_outside]}

    def __str__(self) -> str:
        return format_summary(self.kind, self.summary(), [k for k in self.figures() if k != "ok"])


class WalkChecker:
    """Streaming checker of flock walks (see the module docstring).

    Args:
        max_step: the recorder's largest per-step displacement, metres.
        fps: the recording's frame rate (a tick of ``dt`` may span ``dt * fps`` steps).
        regions: per flock, its region or ``None`` (``None``: no containment check).
        tolerance: allowed excess over ``max_step`` (0.1: 10 %).
    """

    def __init__(self, max_step: float, fps: float, regions=None, tolerance: float = 0.1):
        self.max_step = float(max_step)
        self.fps = float(fps)
        self.regions = regions
        self.tolerance = float(tolerance)
        self._prev = None
        self.ticks = 0
        self.worst_step = 0.0
        self.worst_ratio = 0.0
        self.step_violations = 0
        self.outside = None

    def update(self, positions: np.ndarray, dt: float) -> None:
        """``positions`` (flocks, agents, 3) after a tick of ``dt`` seconds."""
        p = np.asarray(positions, dtype=np.float64)
        if self.outside is None:
            self.outside = np.zeros(p.shape[0], dtype=np.int64)
        if self.regions is not None:
            c = p.mean(axis=1)
            for k, r in enumerate(self.regions):
                if r is not None and not bool(r.contains(c[k][None])[0]):
                    self.outside[k] += 1
        if self._prev is not None and dt > 0:
            step = np.sqrt(((p - self._prev) ** 2).sum(-1))
            allowed = self.max_step * (1.0 + self.tolerance) * max(dt * self.fps, 1.0)
            worst = float(step.max())
            self.worst_step = max(self.worst_step, worst)
            self.worst_ratio = max(self.worst_ratio, worst / (self.max_step * max(dt * self.fps, 1.0)))
            self.step_violations += int(np.count_nonzero(step > allowed))
        self._prev = p.copy()
        self.ticks += 1

    def report(self) -> WalkReport:
        """The figures so far (a snapshot: later updates do not change it)."""
        outside = self.outside.copy() if self.outside is not None else np.zeros(0, np.int64)
        return WalkReport(self.ticks, outside, self.worst_step, self.worst_ratio, self.step_violations)

    def summary(self) -> dict:
        """``report().summary()``: ``kind``, ``passed`` and the figures (``ok`` equals ``passed``)."""
        return self.report().summary()
