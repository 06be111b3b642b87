"""The fixed-timestep clock shared by the World and the viewer's scenes.

Real time accumulates; each whole ``dt`` is one tick; what is left is the render
interpolation fraction ``alpha``. A frame that arrives very late runs at most ``max_ticks``
ticks and drops the rest of the backlog (keeping the phase), so a stall never snowballs into
ever longer frames (the "spiral of death")."""
from __future__ import annotations

__all__ = ["FixedStep"]


class FixedStep:
    """Accumulator of real time into fixed ticks of ``dt`` seconds.

    Args:
        dt: tick length in seconds.
        max_ticks: most ticks one :meth:`advance` may ask for.
    """

    def __init__(self, dt: float, max_ticks: int = 8):
        if not dt > 0:
            raise ValueError(f"tick length must be positive, got {dt}")
        self.dt = float(dt)
        self.max_ticks = int(max_ticks)
        self.accumulator = 0.0

    def advance(self, real_dt: float) -> int:
        """Add ``real_dt`` seconds (negative or NaN counts as 0) and return how many ticks to
        run now; the accumulator is already reduced by them."""
        real_dt = float(real_dt)
        self.accumulator += real_dt if real_dt > 0 else 0.0
        n = 0
        while self.accumulator >= self.dt and n < self.max_ticks:
            self.accumulator -= self.dt
            n += 1
        if self.accumulator >= self.dt:       # far behind: drop whole ticks, keep the phase
            self.accumulator %= self.dt
        return n

    @property
    def alpha(self) -> float:
        """Fraction of a tick since the last tick, in [0, 1] (render interpolation)."""
        return min(1.0, self.accumulator / self.dt)
