"""The preference function of the tiling (Kim, Hwang, Hyun and Lee 2012, Eq. 7): where, facing
where, when and with which labels the user would like patch instances."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..motion.planar import wrap_angle

__all__ = ["Preference"]


@dataclass
class Preference:
    """Eq. 7: ``F = exp(-f1/s1) exp(-f2/s2) exp(-f3/s3) exp(-f4/s4)`` with ``f1`` the squared
    distance of the instance (``at="centre"``) or of its exits' mean (``at="exits"``) to
    ``target``, ``f2`` the squared heading difference to ``heading``, ``f3`` the squared time
    difference to ``time``, ``f4`` the summed ``label_cost`` of the patch's labels. ``size_power``
    biases Algorithm 1 towards larger patches (characters x seconds)."""
    target: tuple | None = None
    sigma_pos: float = 8.0
    heading: float | None = None
    sigma_dir: float = 1.0
    time: float | None = None
    sigma_time: float = 8.0
    label_cost: dict = field(default_factory=dict)
    sigma_label: float = 1.0
    at: str = "centre"
    size_power: float = 1.0

    @property
    def places(self) -> bool:
        """Whether any placement term (target, heading or time) is set."""
        return self.target is not None or self.heading is not None or self.time is not None

    def label_factor(self, labels) -> float:
        """``exp(-f4 / sigma_label)`` for a patch's labels."""
        f4 = sum(float(self.label_cost.get(l, 0.0)) for l in labels)
        return math.exp(-f4 / self.sigma_label)

    def place_log(self, pos, heading, t):
        """log F without the label term, vectorized over candidates."""
        out = np.zeros(np.shape(t), np.float64)
        if self.target is not None:
            d = np.asarray(pos) - np.asarray(self.target, np.float64)
            out -= np.sum(d * d, axis=-1) / self.sigma_pos
        if self.heading is not None:
            dh = wrap_angle(np.asarray(heading) - self.heading)
            out -= dh * dh / self.sigma_dir
        if self.time is not None:
            dt = np.asarray(t) - self.time
            out -= dt * dt / self.sigma_time
        return out
