"""Experiment 1 (Sung, Kovar and Gleicher 2005, Figure 5): meet in configurations at the same time."""
from __future__ import annotations

import math

import numpy as np

from .geometry import heading_deg, position
from .scenario_file import readme_text, write_sample

__all__ = ["MEET_GROUPS", "meet_scenario", "build"]

MEET_GROUPS = (2, 3, 2, 4, 2, 3, 2, 2)


def meet_scenario(groups=MEET_GROUPS, seed: int = 0, name: str | None = None) -> dict:
    """20 characters scattered over a 31 m square walk to 8 groups on a ring of radius 5 m --
    five facing pairs (1.2 m apart), two triangles and a square (circles of 0.8 and 0.85 m
    radius, members facing the group centre) -- and all arrive in [12, 12.5] s. ``groups``
    gives the group sizes (2, 3 or 4) around the ring.

    Start spots come from a jittered 2.6 m lattice (nothing within 2 m of a goal); each goal
    gets the spot that best gives a 7.5-10.5 m walk approaching the goal from behind (the final turn
    on the spot is at most about 60 degrees), by one assignment (Hungarian, scipy)."""
    from scipy.optimize import linear_sum_assignment
    rng = np.random.default_rng(seed)
    goals = []                              # (x, z, heading deg)
    for k, n in enumerate(groups):
        a = 2 * math.pi * k / len(groups)
        centre = 5.0 * np.array([math.sin(a), math.cos(a)])
        radius = {2: 0.6, 3: 0.8, 4: 0.85}[n]
        # pairs stand along the ring's tangent; larger groups are turned by a fixed offset
        base = a + math.pi / 2 if n == 2 else a + math.pi / n
        for m in range(n):
            b = base + 2 * math.pi * m / n
            p = centre + radius * np.array([math.sin(b), math.cos(b)])
            goals.append((p[0], p[1], heading_deg(centre - p)))
    goals = np.array(goals)
    u = np.arange(-6, 7) * 2.6
    cand = np.stack(np.meshgrid(u, u, indexing="ij"), -1).reshape(-1, 2) + rng.uniform(-0.5, 0.5, (len(u) ** 2, 2))
    dmin = np.hypot(cand[:, None, 0] - goals[None, :, 0], cand[:, None, 1] - goals[None, :, 1]).min(1)
    cand = cand[dmin > 2.0]
    d = goals[None, :, :2] - cand[:, None, :]
    dist = np.hypot(d[..., 0], d[..., 1])
    turn = np.abs((np.degrees(np.arctan2(d[..., 0], d[..., 1])) - goals[None, :, 2] + 180) % 360 - 180)
    cost = np.maximum(0, np.abs(dist - 9.0) - 1.5) + 0.1 * np.maximum(0, turn - 60)
    ci, gi = linear_sum_assignment(cost)
    order = np.argsort(gi)
    n = len(goals)
    chars = []
    for k, o in enumerate(order):
        s, g = cand[ci[o]], goals[gi[o]]
        chars.append({"name": f"c{k + 1:02d}",
                      "start": {"position": position(s), "heading": round(heading_deg(g[:2] - s), 3), "pose": "stand"},
                      "goal": [{"position": position(g[:2]), "heading": round(float(g[2]), 3), "pose": "stand",
                                "time": [12.0, 12.5]}]})
    return {"name": name or f"meet{n}", "description": f"Experiment 1 (Sung, Kovar and Gleicher 2005, Figure 5): {n} characters "
            "arrive simultaneously in pairs, triangles and a square, facing each other",
            "library": "default", "duration": 16.0, "seed": seed, "character": chars}

def build(folder):
    """Write the ``meet20`` sample into ``folder``."""
    write_sample(folder, meet_scenario(), readme_text("meet20"))
