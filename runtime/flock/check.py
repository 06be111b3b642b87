"""Independent checker for flock walks (paper 004, section 5 acceptance).

It sees only what a viewer or a bake sees -- world positions of every agent, tick after tick --
and never the graph, the plan or the correspondence, so it does not trust the synthesizer:

- region containment of every flock's centre of mass (per flock region, optional);
- the largest per-tick displacement of any agent, against the recorder's largest per-step
  displacement (``max_step``) times ``1 + tolerance`` scaled to the tick length; a swap of agent
  identities at a transition shows up here as a jump of a few metres.

Streaming: call :meth:`WalkChecker.update` once per tick, then :meth:`WalkChecker.summary`.
"""
from __future__ import annotations

import numpy as np

__all__ = ["WalkChecker"]


class WalkChecker:
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

    def summary(self) -> dict:
        outside = self.outside if self.outside is not None else np.zeros(0, np.int64)
        return {
            "ticks": self.ticks,
            "flocks": int(len(outside)),
            "frames_outside": int(outside.sum()),
            "flocks_outside": int(np.count_nonzero(outside)),
            "worst_step_m": self.worst_step,
            "worst_step_ratio": self.worst_ratio,     # worst step / recorder's largest step
            "step_violations": self.step_violations,
            "ok": bool(outside.sum() == 0 and self.step_violations == 0),
        }
