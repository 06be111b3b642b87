"""Experiment 5 (Sung, Kovar and Gleicher 2005, Figure 9): seated characters fetch boxes, put
them down and return to their seats."""
from __future__ import annotations

import math

import numpy as np

from .geometry import position
from .scenario_file import readme_text, write_sample
from usd_io.world_writer import WorldBuilder

__all__ = ["WALK_SPEED", "FETCH_SEAT_X", "FETCH_ROWS", "FETCH_DOORS", "FETCH_ROUND_SLACK", "FETCH_GAP",
           "FETCH_LANES", "FETCH_PICK_X", "FETCH_CARRY", "FETCH_ROOM_B", "fetch_world", "fetch_boxes",
           "fetch_scenario", "build"]

WALK_SPEED = 1.0        # m/s used to lay out time windows (the library walks at 0.6-1.6 m/s)
FETCH_SEAT_X = 1.5 + 1.6 * np.arange(5)
FETCH_ROWS = ((1.2, 0.0), (6.8, 180.0), (9.2, 0.0), (14.8, 180.0))   # (z, heading): two corridors
FETCH_DOORS = (4.0, 12.0)            # z of the doors' centres (3 m wide), on the corridors' axes
FETCH_ROUND_SLACK = 4.0               # s between a corridor's near round back in its seats and its far round leaving
FETCH_GAP = 6.0                       # s between consecutive characters of a corridor
FETCH_LANES = np.concatenate([1.1 + 1.5 * np.arange(5), 14.9 - 1.5 * np.arange(5)[::-1]])   # z of room B's ten lanes, five per door
FETCH_PICK_X = (14.0, 20.0)           # x where a character stands to pick up the near and far box
FETCH_CARRY = 3.0                     # m carried straight on along the lane to the put-down spot
FETCH_ROOM_B = (10.0, 25.5)           # x extent of room B


def fetch_world() -> WorldBuilder:
    """Room A (x 0..10, z 0..16) with 20 seats in four rows of five facing two 4 m wide
    corridors; room B (x 10..25.5) with 20 boxes on ten lanes; two 3 m doors (z = 2.5, 13.5)."""
    w = WorldBuilder("crowdweave sample fetch_boxes20: a seating room and a store room with 20 boxes "
                     "(metres, Y up). Written by samples/make_samples.py.")
    xb = FETCH_ROOM_B[1]
    w.wall("North", (0, 0), (xb, 0))
    w.wall("East", (xb, 0), (xb, 16))
    w.wall("South", (0, 16), (xb, 16))
    w.wall("West", (0, 0), (0, 16))
    w.wall("Between", (10, 0), (10, 16), doors=[(z, 3.0) for z in FETCH_DOORS])
    w.block("Divider", 0.1, 7.9, 9.9, 8.1, 1.0)       # low divider between the back-to-back rows
    for r, (z, h) in enumerate(FETCH_ROWS):
        for j, x in enumerate(FETCH_SEAT_X):
            w.seat(f"s{r * 5 + j + 1:02d}", x, z, h)
    for k, (x, z, h) in enumerate(fetch_boxes()):
        w.box(f"b{k + 1:02d}", x, z, h)
    return w


def fetch_boxes():
    """(x, z, heading) of the 20 boxes: two on each of room B's ten lanes (z = ``FETCH_LANES``,
    1.5 m apart, 1 m from the walls), a near one and a far one, all facing -X (towards the doors). A character picks
    a box up facing away from the door, carries it ``FETCH_CARRY`` m straight on along its lane
    and puts it down there: the library's carrying clips turn only while walking on (about 1 m
    per 60 degrees), so no one has to turn round with a box. Numbered lane by lane, near box
    first."""
    from runtime.crowd.scenario import BOX_REACH
    return [(x + BOX_REACH, float(z), -90.0) for z in FETCH_LANES for x in FETCH_PICK_X]


def fetch_scenario(seed: int = 0) -> dict:
    """Each seated character stands up, walks through its corridor's door to its box in room B,
    picks it up, carries it ``FETCH_CARRY`` m on along the lane, puts it down there (pose
    "stand") and returns to its own seat. Each door serves the five lanes of its half, from
    their outer end; the near boxes go first, then the far ones (a far carrier walks through
    its lane's near spots after they are used), each time the lane nearest the door first,
    ``FETCH_GAP`` (6 s) apart, the characters seated nearest the door first; the far round
    leaves when the near round should be back in its seats. The pick-up and the
    put-down have 2.5 s windows laid out from the distances (walking 1 m/s, carrying 0.7 m/s,
    about 3.5 s per pose change); the return to the seat has none (the paper's Experiment 5
    times no goal): a character sits down when it gets there."""
    from runtime.crowd.scenario import BOX_REACH
    boxes = fetch_boxes()
    chars = []
    t_last = []
    for cor in range(2):
        seats = [(r + 2 * cor, j) for j in range(4, -1, -1) for r in range(2)]     # nearest the door first
        # lanes nearest the door first: everyone walks a straight line between the door and
        # its lane, so a character walking back crosses only lanes (on its side of the door)
        # whose users went before it and are ahead of it on the same way back, and one walking
        # out crosses none in use
        lanes = sorted(range(5 * cor, 5 * cor + 5), key=lambda i: abs(FETCH_LANES[i] - FETCH_DOORS[cor]))
        bidx = [2 * lane + far for far in (0, 1) for lane in lanes]
        door = np.array([10.0, FETCH_DOORS[cor]])
        t_prev = [-10.0, -10.0]
        back = []                   # when each character should be seated again
        for k, ((r, j), b) in enumerate(zip(seats, bidx)):
            z, h = FETCH_ROWS[r]
            seat = np.array([FETCH_SEAT_X[j], z])
            up = seat + 0.42 * np.array([math.sin(math.radians(h)), math.cos(math.radians(h))])
            pick = np.array(boxes[b][:2]) - [BOX_REACH, 0.0]
            place = pick + [FETCH_CARRY, 0.0]
            d1 = float(np.hypot(*(door - up)) + np.hypot(*(pick - door)))
            leave = 3.0 + d1 / WALK_SPEED + 4.0          # standing up, walking, picking up
            t1 = max(leave, t_prev[0] + FETCH_GAP)
            if k == 5:
                # the far round leaves once the near round is back in its seats: its first
                # carrier would otherwise meet them head-on in the corridor and the door
                t1 = max(t1, max(back) + FETCH_ROUND_SLACK + leave)
            t2 = max(t1 + 2.5 + FETCH_CARRY / 0.7 + 4.0, t_prev[1] + FETCH_GAP)
            t_prev = [t1, t2]
            d3 = float(np.hypot(*(door - place)) + np.hypot(*(up - door)))
            back.append(t2 + 2.5 + d3 / WALK_SPEED + 8.0)
            t_last.append(back[-1])
            sid = f"s{r * 5 + j + 1:02d}"
            chars.append({"name": f"c{len(chars) + 1:02d}", "start": {"seat": f"/World/Seats/{sid}"},
                          "goal": [{"box": f"/World/Boxes/b{b + 1:02d}", "time": [round(t1, 1), round(t1 + 2.5, 1)]},
                                   {"position": position(place), "pose": "stand", "time": [round(t2, 1), round(t2 + 2.5, 1)]},
                                   {"seat": f"/World/Seats/{sid}"}]})
    # interleave the corridors so that both start together in planning order
    chars = [c for pair in zip(chars[:10], chars[10:]) for c in pair]
    for i, c in enumerate(chars):
        c["name"] = f"c{i + 1:02d}"
    dur = max(t_last) + 10.0
    return {"name": "fetch_boxes20", "description": "Experiment 5 (Sung, Kovar and Gleicher 2005, Figure 9): 20 seated characters "
            "fetch boxes, put them down at designated spots and return to their seats", "world": "world.usda",
            "library": "default", "duration": float(math.ceil(dur)), "seed": seed,
            # way points to a seat pass 2 m in front of it, in the corridor's middle: a returner
            # walks there, clear of the seated row, and comes in square between its seated
            # neighbours (1.6 m apart) instead of across their places
            "synthesis": {"approach_point": 2.0}, "character": chars}

def build(folder):
    """Write the ``fetch_boxes20`` sample into ``folder``."""
    write_sample(folder, fetch_scenario(), readme_text("fetch_boxes20", world=True), fetch_world())
