"""Data-driven groups (Lai, Chenney and Fan 2005) at run time: the configuration metric
(``metric``), DDG assets (``ddg``), regions (``region``), the vectorized walk of many flocks
(:class:`FlockSystem` in ``walk``, with ``playback``, ``containment``, ``lookahead`` and
``streams``) and an independent walk checker (``check``). Never imports ``authoring``."""
from .check import WalkChecker, WalkReport
from .ddg import DDG, load_ddg, save_ddg
from .region import Box, Polygon, Region, region_from_dict
from .walk import FlockSystem

__all__ = ["DDG", "load_ddg", "save_ddg", "FlockSystem", "Region", "Polygon", "Box", "region_from_dict",
           "WalkChecker", "WalkReport"]
