"""Small layout functions of the sample generators: headings, rounded positions, spacing."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["heading_deg", "position", "min_spacing"]


def heading_deg(v) -> float:
    """Heading (degrees about +Y, 0 facing +Z) of the direction ``v`` = (x, z)."""
    return float(np.degrees(math.atan2(v[0], v[1])))


def position(p):
    """A scenario position: ``[x, z]`` rounded to 4 decimals."""
    return [round(float(p[0]), 4), round(float(p[1]), 4)]


def min_spacing(points) -> float:
    from scipy.spatial.distance import pdist
    p = np.asarray(points, float)
    return float(pdist(p).min()) if len(p) > 1 else math.inf
