"""Experiment 4 (Sung, Kovar and Gleicher 2005, Figure 8): a lobby and theater seats."""
from __future__ import annotations

import numpy as np

from .geometry import position
from .scenario_file import readme_text, write_sample
from usd_io.world_writer import WorldBuilder

__all__ = ["SEAT_X", "ROW_PITCH", "ROW_Z", "RAIL_HALF_WIDTH", "THEATER_DOORS", "THEATER_GAP", "theater_world",
           "theater_scenario", "build"]

SEAT_X = -5.25 + 1.5 * np.arange(8)            # 8 seats a row, 1.5 m apart
ROW_PITCH = 3.2
ROW_Z = 7.5 - ROW_PITCH * np.arange(5)         # back row first
RAIL_HALF_WIDTH = 6.0                          # row partitions span the seat block, x -6..6
THEATER_DOORS = (-7.5, 7.5)
THEATER_GAP = 4.0                              # s between consecutive seats of a half theater


def theater_world() -> WorldBuilder:
    """A 20 x 22 m hall (x -10..10, z -10..12) with a stage at -Z and 5 rows of 8 seats facing
    it (1.5 m between seats, 3.2 m between rows, 4 m side aisles), and a lobby (z 12..24)
    joined to the hall by two 3 m doors at x = -7.5 and 7.5.

    Between consecutive rows (and behind the back row, in front of the front row) a 0.2 m row
    partition -- the seat backs of the row in front -- spans the seat block: a row is entered
    from the side aisles only, and its lane (the 2.1 m between its seats' front edge and the
    next partition) fits a walking character (radius up to 0.63 m) in front of its empty seats
    while a seated character (0.62-0.72 m) clears the partition behind it."""
    w = WorldBuilder("crowdweave sample theater40: lobby, two doors, hall with 5 rows of 8 seats facing a "
                     "stage (metres, Y up). Written by samples/make_samples.py.")
    w.wall("North", (-10, -10), (10, -10))
    w.wall("East", (10, -10), (10, 24))
    w.wall("South", (-10, 24), (10, 24))
    w.wall("West", (-10, -10), (-10, 24))
    w.wall("Foyer", (-10, 12), (10, 12), doors=[(d + 10, 3.0) for d in THEATER_DOORS])
    w.block("Stage", -7.0, -9.9, 7.0, -8.2, 1.0)
    w.pillar("LobbyPillar", 0.0, 17.5, 0.5)
    w.block("Counter", -1.5, 22.4, 1.5, 23.6, 1.1)
    for k, z in enumerate(list(ROW_Z + 1.0) + [ROW_Z[-1] - ROW_PITCH + 1.0]):
        w.block(f"RowPartition{k + 1}", -RAIL_HALF_WIDTH, z - 0.1, RAIL_HALF_WIDTH, z + 0.1, 0.9)
    for b, z in enumerate(ROW_Z):
        for j, x in enumerate(SEAT_X):
            w.seat(f"r{b + 1}_s{j + 1}", x, z, 180.0)
    return w


def theater_scenario(seed: int = 0) -> dict:
    """40 characters wait in the lobby in two 4 x 5 blocks (2 m spacing) beside the two doors
    and take seats row by row, back row first and inner seats first in each half row (so no
    one passes a seated character closely). Those nearest their door go first; seat k of a
    half-theater is reached in [18 + g k, 18 + g (k + 1)] s with g = ``THEATER_GAP`` (4 s: the
    one before has sat down by then, so the two are not walking the row's lane together)."""
    chars = []
    order = []
    for side, door_x in zip((-1, 1), THEATER_DOORS):
        xs = door_x + side * (np.arange(4) * 2.0 - 1.5) * -1        # towards the centre
        lobby = np.array([(x, z) for x in xs for z in 14.0 + 2.0 * np.arange(5)])
        dist = np.hypot(lobby[:, 0] - door_x, lobby[:, 1] - 12.0)
        lobby = lobby[np.lexsort((lobby[:, 0] * side, dist))]
        seats = []
        for b in range(len(ROW_Z)):
            for k in range(4):
                j = 3 - k if side < 0 else 4 + k
                seats.append((b, j))
        order.append(list(zip(lobby, seats)))
    n = 0
    for i in range(20):
        for side in range(2):
            (p, (b, j)) = order[side][i]
            n += 1
            t = 18.0 + THEATER_GAP * i
            chars.append({"name": f"c{n:02d}",
                          "start": {"position": position(p), "heading": 180.0, "pose": "stand"},
                          "goal": [{"seat": f"/World/Seats/r{b + 1}_s{j + 1}", "time": [t, t + THEATER_GAP]}]})
    return {"name": "theater40", "description": "Experiment 4 (Sung, Kovar and Gleicher 2005, Figure 8): 40 characters walk from "
            "a lobby to theater seats", "world": "world.usda", "library": "default",
            "duration": 18.0 + THEATER_GAP * 20 + 4.0,
            "seed": seed, "character": chars}

def build(folder):
    """Write the ``theater40`` sample into ``folder``."""
    write_sample(folder, theater_scenario(), readme_text("theater40", world=True), theater_world())
