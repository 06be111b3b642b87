"""The space-time scene of a tiling: the region to fill, obstacles and portals (Kim, Hwang, Hyun
and Lee 2012, section 5.3: repeating tiles, dynamic obstacles, sources and sinks).

Shared by the tiler (:mod:`.state`, :mod:`.tiler`), the interactive tiling, the tiling pack
(:mod:`.result`) and the checker (:mod:`.check`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Region", "Obstacle", "Portal", "minimum_image"]


def minimum_image(d, period):
    """Offsets ``d`` wrapped to the nearest periodic image, ``d - period * round(d / period)``
    (unchanged when ``period`` is None).

    Args:
        d: offsets, any shape broadcasting against ``period``.
        period: the period per axis (array or scalar), or None for no wrapping.
    """
    if period is None:
        return d
    return d - period * np.round(d / period)


@dataclass
class Region:
    """The rectangle ``[x0, x1] x [z0, z1]`` over ``[t0, t1]`` seconds; ``wrap_space`` makes it a
    repeating tile (offsets use the minimum image), ``wrap_time`` a loop in time."""
    x0: float
    z0: float
    x1: float
    z1: float
    t0: float = 0.0
    t1: float = 20.0
    wrap_space: bool = False
    wrap_time: bool = False

    @property
    def size(self):
        return (self.x1 - self.x0, self.z1 - self.z0)

    def inside(self, xz, t):
        """Strictly inside (the boundary counts as outside), per wrapped dimension always."""
        xz = np.atleast_2d(xz)
        t = np.atleast_1d(t)
        ok = np.ones(len(t), bool)
        if not self.wrap_space:
            ok &= (xz[:, 0] > self.x0) & (xz[:, 0] < self.x1) & (xz[:, 1] > self.z0) & (xz[:, 1] < self.z1)
        if not self.wrap_time:
            ok &= (t > self.t0 + 1e-9) & (t < self.t1 - 1e-9)
        return ok


@dataclass
class Obstacle:
    """An oriented box obstacle: ``center`` (2,) static or (F, 2) per clock frame from the region
    start (moving; held at the last row afterwards), ``half`` (hx, hz) half extents along its
    lateral/forward axes, ``heading`` (scalar or (F,)), ``height`` (top, m)."""
    center: np.ndarray
    half: tuple
    heading: float | np.ndarray = 0.0
    height: float = 2.0
    name: str = ""

    def __post_init__(self):
        self.center = np.asarray(self.center, np.float64)
        self.half = tuple(float(h) for h in self.half)
        self.heading = np.asarray(self.heading, np.float64)

    @property
    def moving(self) -> bool:
        return self.center.ndim == 2

    def at(self, frames):
        """(centre (n, 2), heading (n,)) at clock frames (relative to the region start)."""
        frames = np.asarray(frames, np.int64)
        if self.moving:
            f = np.clip(frames, 0, len(self.center) - 1)
            c = self.center[f]
            h = self.heading[f] if self.heading.ndim else np.full(len(frames), float(self.heading))
        else:
            c = np.broadcast_to(self.center, (len(frames), 2))
            h = np.full(len(frames), float(self.heading))
        return c, h


@dataclass
class Portal:
    """Source (characters may enter: dangling entries allowed), sink (may leave: dangling exits
    allowed) or both, a disc of ``radius`` about (x, z)."""
    x: float
    z: float
    radius: float
    kind: str = "both"

    def __post_init__(self):
        if self.kind not in ("source", "sink", "both"):
            raise ValueError(f"portal kind must be source, sink or both, not {self.kind!r}")
