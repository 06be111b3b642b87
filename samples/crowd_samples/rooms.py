"""Experiment 3 (Sung, Kovar and Gleicher 2005, Figure 7): cross the rooms and pick up a box."""
from __future__ import annotations

import numpy as np

from .geometry import heading_deg, position
from .scenario_file import readme_text, write_sample
from usd_io.world_writer import WorldBuilder

__all__ = ["ROOMS_DOOR", "rooms_world", "ROOM_POINTS", "rooms_scenario", "build"]

ROOMS_DOOR = 2.4            # door widths: the walking cylinder is up to 1.26 m wide


def rooms_world() -> WorldBuilder:
    """Six 8 x 8 m rooms (x 0..24, z -8..8; "up" in a top view is -Z) with 2.4 m doors placed so
    that the lower-right room reaches the upper-right one only through the four others, and
    furniture in every room (tables, shelves, pillars, crates)."""
    w = WorldBuilder("crowdweave sample rooms_box: six rooms with doors and furniture; box b01 in the "
                     "upper-right room (metres, Y up). Written by samples/make_samples.py.")
    D = ROOMS_DOOR
    w.wall("OuterNorth", (0, -8), (24, -8))
    w.wall("OuterEast", (24, -8), (24, 8))
    w.wall("OuterSouth", (0, 8), (24, 8))
    w.wall("OuterWest", (0, -8), (0, 8))
    w.wall("Middle", (0, 0), (24, 0), doors=[(3.0, D)])                  # lower-left <-> upper-left
    w.wall("West", (8, -8), (8, 8), doors=[(3.0, D), (13.5, D)])         # z = -5 and z = 5.5
    w.wall("East", (16, -8), (16, 8), doors=[(5.0, D), (12.0, D)])       # z = -3 and z = 4
    # furniture: every gap to a wall or another piece is either closed (< 0.6 m) or at least
    # 1.9 m wide: a walking character's cylinder (radius up to 0.63 m) plus clearance on both
    # sides, so that the roadmap (obstacles grown by 0.6 m) never routes one through a slot
    # its stride cannot follow
    # lower right (start room)
    w.block("LR_Table", 18.5, 0.1, 20.5, 1.0, 0.75)
    w.block("LR_Cabinet", 22.8, 6.4, 23.9, 7.9, 1.8)
    # lower middle
    w.block("LM_Sofa", 11.4, 3.2, 12.4, 6.0, 0.8)
    w.block("LM_Crates", 14.9, 6.6, 15.9, 7.9, 1.0)
    w.block("LM_Desk", 8.1, 0.1, 10.1, 1.2, 0.75)
    # lower left
    w.block("LL_Shelf", 0.6, 6.2, 2.2, 7.6, 2.0)
    w.block("LL_Table", 4.4, 2.0, 6.0, 3.0, 0.75)
    # upper left
    w.block("UL_Table", 0.1, -4.4, 2.5, -3.2, 0.75)
    w.pillar("UL_Pillar", 5.6, -2.6, 0.4)
    w.block("UL_Cabinet", 5.8, -7.6, 7.4, -6.6, 1.8)
    # upper middle
    w.block("UM_LongTable", 10.0, -4.6, 14.0, -3.4, 0.75)
    w.block("UM_Crates", 11.0, -1.1, 12.0, -0.1, 1.0)
    w.block("UM_Cabinet", 12.0, -7.9, 13.5, -7.2, 1.8)
    # upper right (the box)
    w.block("UR_Shelf", 22.6, -7.6, 23.6, -3.0, 2.2)
    w.block("UR_Crates", 18.0, -1.6, 19.2, -0.6, 1.0)
    w.pillar("UR_Pillar", 19.0, -5.6, 0.3)
    w.box("b01", 21.6, -5.0, -90.0)          # faces -X: picked up from its west side
    return w


# (room, points) the other characters walk between; each >= 1 m from furniture, >= 2 m from doors
ROOM_POINTS = {
    "LR": [(18.6, 6.4), (22.4, 1.2), (19.8, 4.2)],
    "LM_a": [(9.6, 3.0), (14.4, 2.0), (13.8, 5.0)],
    "LM_b": [(10.4, 6.8), (13.6, 1.2), (10.6, 2.4)],
    "LL": [(1.6, 2.2), (5.6, 6.8), (2.2, 4.6)],
    "UL": [(1.6, -6.4), (4.4, -5.6), (1.4, -1.8)],
    "UM_a": [(9.6, -1.4), (14.0, -1.2), (11.0, -6.4)],
    "UM_b": [(14.6, -6.2), (9.6, -6.6), (13.6, -2.2)],
    "UR": [(20.6, -1.8), (17.6, -6.8), (21.0, -3.4)],
}


def rooms_scenario(seed: int = 0, movers: bool = False) -> dict:
    """The character "main" starts in the lower-right room at (21.5, 6.5) and must pick up box
    /World/Boxes/b01 in the upper-right room, with no time constraint -- the paper's
    Experiment 3 is this one character. With ``movers``, eight more characters first walk round
    triangles of points in the rooms (5 goals each, windows 2 s wide laid out at 1.1 m/s plus a
    2 s pause) and are moving obstacles to it (a harder variant, not the paper's)."""
    chars = []
    for k, (room, pts) in enumerate(ROOM_POINTS.items() if movers else ()):
        pts = [np.array(p, float) for p in pts]
        start = pts[-1]
        t = 3.0 + 1.5 * k
        goals = []
        prev = start
        for q in range(5):                      # round the triangle of points, starting at the last
            p = pts[q % 3]
            t += float(np.hypot(*(p - prev))) / 1.1 + 2.0
            goals.append({"position": position(p), "time": [round(t, 1), round(t + 2.0, 1)]})
            t += 2.0
            prev = p
        chars.append({"name": f"m{k + 1}_{room.split('_')[0].lower()}",
                      "start": {"position": position(start), "heading": round(heading_deg(pts[0] - start), 3), "pose": "stand"},
                      "goal": goals})
    chars.append({"name": "main", "start": {"position": [21.5, 6.5], "heading": -90.0, "pose": "stand"},
                  "goal": [{"box": "/World/Boxes/b01"}]})
    return {"name": "rooms_box", "description": "Experiment 3 (Sung, Kovar and Gleicher 2005, Figure 7): one character crosses "
            "rooms full of obstacles and picks up a box",
            "world": "world.usda", "library": "default", "duration": 75.0, "seed": seed, "character": chars}

def build(folder):
    """Write the ``rooms_box`` sample into ``folder``."""
    write_sample(folder, rooms_scenario(), readme_text("rooms_box", world=True), rooms_world())
