"""The interactive tiling's clock and the accounting of one tick's work, shared by its parts
(:mod:`.interactive`, :mod:`.extension`, :mod:`.cornering`)."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["TickState"]


@dataclass
class TickState:
    """``t`` / ``frame``: the clock (seconds, clock frame). ``work``: estimated work spent
    this tick, in units of about a millisecond on a quiet machine (candidate queries,
    deformations, look-aheads, commits). ``epoch``: bumped by every commit and retraction, so
    a paused search knows the world moved on. ``yields``: patches taken back from others this
    tick."""
    t: float = 0.0
    frame: int = 0
    work: float = 0.0
    epoch: int = 0
    yields: int = 0
