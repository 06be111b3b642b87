"""Flocks in the World: DDG walks (Lai, Chenney and Fan 2005) as one system of the tick."""
from __future__ import annotations

import numpy as np

__all__ = ["FlockHost"]


class FlockHost:
    """Every flock of the world: one :class:`~runtime.flock.FlockSystem` per DDG, all of whose
    flocks advance together (vectorized) each tick.

    Args:
        rng: seeds a new FlockSystem when no seed is given.
    """

    name = "flocks"

    def __init__(self, rng):
        self.rng = rng
        self.systems: list = []

    def add(self, ddg, positions, headings=None, regions=None, seed: int | None = None):
        """Start flocks walking ``ddg`` (a :class:`runtime.flock.DDG` or a pack path) with their
        centroids at ``positions`` (k, 3), optionally each kept in a region. Returns (system
        index, flock rows)."""
        from ..flock import FlockSystem, load_ddg
        if not hasattr(ddg, "n_agents"):
            ddg = load_ddg(ddg)
        sys_i = next((i for i, f in enumerate(self.systems) if f.ddg is ddg), None)
        if sys_i is None:
            fs = FlockSystem(ddg, seed=self.rng.integers(1 << 31) if seed is None else seed)
            self.systems.append(fs)
            sys_i = len(self.systems) - 1
        rows = self.systems[sys_i].add_flocks(positions, headings, regions)
        return sys_i, rows

    def tick(self, world) -> None:
        for fs in self.systems:
            fs.step(world.dt)

    def after_tick(self, world) -> None:
        pass

    def positions(self):
        """All agents: positions (M, 3) and headings (M,)."""
        if not self.systems:
            return np.zeros((0, 3)), np.zeros(0)
        pos = np.concatenate([f.positions().reshape(-1, 3) for f in self.systems])
        hd = np.concatenate([f.headings().reshape(-1) for f in self.systems])
        return pos, hd

    def agent_count(self) -> int:
        return int(sum(f.positions().reshape(-1, 3).shape[0] for f in self.systems))
