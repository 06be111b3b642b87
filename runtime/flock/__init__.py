"""Data-driven groups (paper 004) at run time: configuration metric, DDG assets, regions and the
vectorized walk of many flocks (:class:`FlockSystem`), plus an independent walk checker.
Never imports ``authoring``."""
from .check import WalkChecker
from .ddg import DDG, load_ddg, save_ddg
from .region import Box, Polygon, Region, region_from_dict
from .walk import FlockSystem

__all__ = ["DDG", "load_ddg", "save_ddg", "FlockSystem", "Region", "Polygon", "Box", "region_from_dict",
           "WalkChecker"]
