"""The goal-directed segment planner (Sung, Kovar and Gleicher 2005, section 3).

Modules, in the order a segment uses them: :mod:`.types` (configurations, goals, results, step
kinds), :mod:`.params` (search parameters and crowd policy), :mod:`.library` (precomputed arrays
over the motion graph), :mod:`.waypoints` (the roadmap's path), :mod:`.seeds` (greedy seeds),
:mod:`.costs` (the splice cost, Eq. 1-2), :mod:`.search` (the randomized search),
:mod:`.splice` (displacement maps and time resampling), :mod:`.collision` (the final tests),
:mod:`.motion_cache` (reuse between characters with the same task), :mod:`.kernels` (numba
kernels of the hot loops) and :mod:`.segment` (one segment, start to finish).
"""
from .library import MotionLibrary
from .motion_cache import MotionCache
from .params import CrowdPolicy, SearchParams
from .segment import SegmentPlanner, run_to_completion
from .types import Config, Goal, SegmentResult, Step

__all__ = ["Config", "Goal", "SegmentResult", "Step", "SearchParams", "CrowdPolicy", "MotionLibrary",
           "MotionCache", "SegmentPlanner", "run_to_completion"]
