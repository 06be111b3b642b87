"""Settings of the tiler (Kim, Hwang, Hyun and Lee 2012, section 5): the energy Eq. 6, the
annealing of Algorithm 1, the port matching, the jitter of Algorithm 2 and the collision index."""
from __future__ import annotations

from dataclasses import dataclass

from .deform import DEFAULT_LIMITS, Limits

__all__ = ["TilerConfig"]


@dataclass
class TilerConfig:
    """Everything the tiler's behaviour depends on besides the library, the scene and the seed.

    ``alpha`` (Eq. 6), ``k``, ``T_max``, ``dT`` (the acceptance ``exp(-dE / kT)`` of Algorithm 1,
    ``T`` falling by ``dT`` per sample), ``limits`` (the deformation limits of every frame) and
    ``fps`` (the clock the boxes are resampled on); the other fields are described beside them.
    """
    alpha: float = 0.2
    k: float = 0.03
    T_max: float = 200.0
    dT: float = 1.0
    i_max: int = 300                  # Algorithm 1: samples in a row without acceptance
    seeds: int | None = None          # Algorithm 1: at most this many unanchored placements
    anchor_prob: float = 0.5
    match_pos: float = 0.35           # m: a port stitches to a dangling port this close ...
    match_dir: float = 20.0           # deg
    match_time: float = 0.3           # s
    jitter_min: tuple = (0.6, 15.0, 0.3)
    jitter_max: tuple = (1.0, 25.0, 0.5)
    jitter_tries: int = 8
    max_candidates: int = 32          # Algorithm 2: candidates tried per dangling port per visit
    margin: float = 0.02              # collision margin (m): covers pose blending between frames
    cell: float | None = None         # space-time hash cell (m); default: from the library's largest box
    max_query_margin: float = 0.25    # largest margin a query may use (sets the default cell)
    limits: Limits = DEFAULT_LIMITS
    fps: float = 30.0
    max_removals: int = 100000
    rigid_step: float = 0.005         # m: an exactly aligned stitch whose Eq. 2 step differs by less stays rigid
