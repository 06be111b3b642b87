"""The parameters of the scenario generator and the rules a generated scenario obeys."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["KINDS", "GenParams", "ScenarioGenError", "KIND_PREFIX"]

# the crowd kinds; "mixed" draws one of them per group of characters
KINDS = ("crossing", "rooms", "meeting", "seats", "boxes")
KIND_PREFIX = {"crossing": "cross", "rooms": "room", "meeting": "meet", "seats": "seat", "boxes": "box"}


class ScenarioGenError(ValueError):
    """The parameters cannot be satisfied (e.g. too many characters for the area)."""


@dataclass
class GenParams:
    """Everything a generated scenario depends on besides the seed.

    Sizes: the ground is ``characters x area_per_character`` m^2 (obstacles included), cut
    into districts of about ``group_size`` characters each; every district holds one kind of
    crowd task (seats and boxes districts get more ground per character: ``layout.KIND_AREA``). The defaults give moderate densities: 60 characters of mixed kinds
    get a plaza of about 38 x 25 m, 150 about 49 x 49 m.

    Validity rules (Sung, Kovar and Gleicher 2005 plan exact constraints; a scenario must be
    solvable in principle): every start and goal at least ``clearance`` from obstacles (seats
    ``seat_clearance``, the crate of a box ``crate_clearance``, where a box is picked up and put
    down ``box_clearance``); every two endpoints (starts,
    goals, seats in use) at least ``spacing`` apart; every goal reachable from the previous one
    in the free space grown by ``walk_radius``; a window opens no earlier than the geodesic
    distance at ``walk_speed`` (``carry_speed`` carrying a box) plus the time of any state
    change plus the slack, after the previous window closed; windows are ``window_width`` wide;
    the scenario lasts until everyone can arrive plus ``margin``.
    """
    characters: int = 60
    kind: str = "mixed"
    area_per_character: float = 14.0   # m^2 of ground per character, obstacles included
    group_size: int = 10                # characters per district (one kind of task each)
    library: str = "default"
    # validity
    clearance: float = 0.6              # m from obstacles: starts, position goals, box stand points
    seat_clearance: float = 0.85        # m from obstacles: a seated character (cylinder up to 0.72 m)
    crate_clearance: float = 0.35       # m from obstacles: a box's crate (0.4 m cube)
    box_clearance: float = 0.75         # m from obstacles: where a box is picked up and put down, and the
                                        # straight carry between (the default library's pick-up, carry and
                                        # put-down clips sweep cylinders up to 0.69 m)
    spacing: float = 1.5                # m between any two endpoints (two standing cylinders <= 0.72 m each)
    walk_radius: float = 0.6            # m: free space = obstacles grown by a walking cylinder
    grid: float = 0.25                  # m: cell size of the free-space grid (reachability, geodesics)
    approach: float = 1.0               # m in front of a seat that must be free and reachable
    # timing
    walk_speed: float = 1.0             # m/s along the geodesic, for the earliest arrival
    carry_speed: float = 0.7            # m/s carrying a box
    sit_time: float = 2.9               # s: sitting down (the default library's longest such clip)
    pick_time: float = 3.0              # s: picking a box up
    put_time: float = 2.8               # s: putting a box down
    slack: float = 2.0                  # s added to every earliest arrival ...
    slack_ratio: float = 0.15           # ... plus this share of its travel time
    window_width: tuple = (1.0, 3.0)    # s: width of an arrival window
    window_share: float = 0.4           # share of free goals (crossing, rooms, seats) given a window
    after_share: float = 0.15           # share of free goals timed relative to another character
    margin: float = 10.0                # s after the latest possible arrival
    untimed_factor: float = 1.5         # an untimed goal may take this times its earliest arrival
    attempts: int = 8                   # whole layouts tried before giving up
    tries: int = 400                    # candidate endpoints drawn per character

    def validate(self):
        if self.characters < 1:
            raise ScenarioGenError(f"characters must be at least 1, got {self.characters}")
        if self.kind != "mixed" and self.kind not in KINDS:
            raise ScenarioGenError(f"unknown kind {self.kind!r} (known: mixed, {', '.join(KINDS)})")
        if not self.area_per_character > 0:
            raise ScenarioGenError(f"area_per_character must be positive, got {self.area_per_character}")
        if self.group_size < 2:
            raise ScenarioGenError(f"group_size must be at least 2, got {self.group_size}")
        if min(self.slack, self.slack_ratio, self.margin) < 0 or min(self.walk_speed, self.carry_speed) <= 0:
            raise ScenarioGenError("slack, slack_ratio and margin must not be negative, speeds must be positive")
        if self.box_clearance < self.clearance:
            raise ScenarioGenError(f"box_clearance ({self.box_clearance} m) must be at least clearance ({self.clearance} m)")
        if self.clearance < self.walk_radius:
            raise ScenarioGenError(f"clearance ({self.clearance} m) must be at least walk_radius ({self.walk_radius} m): "
                                   f"endpoints must lie in the free space walks are planned in")
        lo, hi = self.window_width
        if not 0 < lo <= hi:
            raise ScenarioGenError(f"window_width must be 0 < low <= high, got {self.window_width}")
