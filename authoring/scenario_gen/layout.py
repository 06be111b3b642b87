"""The world of a generated scenario: a walled plaza cut into districts, one crowd kind each.

* **crossing** -- start and goal bands on opposite sides (one way, counter-flow, or two flows
  crossing at right angles) with random obstacles between them.
* **rooms** -- the district walled in and split into two rooms by a wall with one or two
  doors (2.4-3 m), one door to the outside, a piece of furniture per room where it fits.
* **meeting** -- open ground with a few obstacles.
* **seats** -- rows of seat markers (1.6 m apart, facing one way) with a low partition 1 m
  behind each row, each row a turned Xform holding its partition.
* **boxes** -- open ground with a few obstacles; the boxes are placed with the tasks.

Random obstacles (:class:`~.obstacles.Placer`) keep 2 m between each other and from walls and
partitions, so the passages between them are wide enough for walking characters.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from usd_io.world_writer import WorldBuilder

from .obstacles import Placer, turn
from .params import KINDS, GenParams, ScenarioGenError

__all__ = ["District", "plan_districts", "build_world", "SIDES", "OPPOSITE", "BAND", "KIND_AREA", "ROW_PITCH",
           "SEAT_PITCH", "PARTITION_BEHIND"]

SIDES = ("-x", "+x", "-z", "+z")
OPPOSITE = {"-x": "+x", "+x": "-x", "-z": "+z", "+z": "-z"}
BAND = 3.0              # m: least depth of a crossing district's start and goal bands
BAND_AREA = 4.5         # m^2 of band per endpoint in it (random points 1.5 m apart fill ~55% of a plane)
# ground per character of each kind, relative to GenParams.area_per_character: a carrier has
# three endpoints (start, box stand point, put-down spot) and a crate; seat rows and their lanes
# take ground no start may use (docs/decisions.md)
KIND_AREA = {"crossing": 1.0, "rooms": 1.0, "meeting": 1.0, "seats": 1.25, "boxes": 1.6}
SEAT_PITCH = 1.6        # m between seats of a row
ROW_PITCH = 3.6         # m between rows: 1 m to the partition behind, a 2.5 m lane in front
PARTITION_BEHIND = 1.0  # m from a seat's root to the middle of the partition behind it
DOOR_WIDTH = (2.4, 3.0)
MIN_SIDE = 8.0          # m: the narrowest district (two rooms with a door, two seat rows)


@dataclass
class District:
    """One group of characters and the part of the world it uses. ``rect`` = (x0, z0, x1, z1)."""
    index: int
    kind: str
    rect: tuple
    n: int
    bands: dict = field(default_factory=dict)      # crossing: side -> band rect
    flows: list = field(default_factory=list)      # crossing: (from side, to side)
    rooms: list = field(default_factory=list)      # rooms: room rects
    seats: list = field(default_factory=list)      # seats: (path, (x, z), heading degrees)

    def inset(self, m: float) -> tuple:
        x0, z0, x1, z1 = self.rect
        return (x0 + m, z0 + m, x1 - m, z1 - m)

    @property
    def area(self) -> float:
        x0, z0, x1, z1 = self.rect
        return (x1 - x0) * (z1 - z0)


def _split(n: int, weights) -> list:
    """``n`` split in proportion to ``weights`` (largest remainders; ties to the first)."""
    w = np.asarray(weights, float)
    share = n * w / w.sum()
    out = np.floor(share).astype(int)
    for i in np.argsort(-(share - out), kind="stable")[: n - int(out.sum())]:
        out[i] += 1
    return [int(v) for v in out]


def plan_districts(p: GenParams, rng) -> tuple:
    """(world width, world depth, districts): ``cols x rows`` equal square districts of about
    ``group_size`` characters each; kinds drawn from the seed (``mixed``: every kind once in
    turn, in a random order, as long as districts last). A district of kind k holds characters
    in inverse proportion to ``KIND_AREA[k]``, so that it has ``area_per_character x
    KIND_AREA[k]`` m^2 per character."""
    groups = max(1, int(round(p.characters / p.group_size)))
    cols = int(math.ceil(math.sqrt(groups)))
    rows = int(math.ceil(groups / cols))
    groups = cols * rows
    if groups > p.characters:          # fewer characters than districts: one row
        groups = cols = max(1, p.characters // 2)
        rows = 1
    if p.kind == "mixed":
        kinds = []
        while len(kinds) < groups:
            kinds += [KINDS[i] for i in rng.permutation(len(KINDS))]
        kinds = kinds[:groups]
    else:
        kinds = [p.kind] * groups
    sizes = _split(p.characters, [1.0 / KIND_AREA[k] for k in kinds])
    area = p.area_per_character * sum(n * KIND_AREA[k] for n, k in zip(sizes, kinds))
    side = round(math.sqrt(area / groups), 1)
    if side < MIN_SIDE:
        raise ScenarioGenError(f"{p.characters} characters in districts of about {p.group_size} at "
                               f"{p.area_per_character:g} m^2 each make districts {side:g} m wide; at least "
                               f"{MIN_SIDE:g} m are needed (walls, doors, seat rows): give more area per character "
                               f"or larger groups")
    out = []
    for g in range(groups):
        c, r = g % cols, g // cols
        rect = (round(c * side, 3), round(r * side, 3), round((c + 1) * side, 3), round((r + 1) * side, 3))
        out.append(District(g, kinds[g], rect, sizes[g]))
    return round(cols * side, 3), round(rows * side, 3), out


def _band(rect, side, depth):
    x0, z0, x1, z1 = rect
    return {"-x": (x0, z0, x0 + depth, z1), "+x": (x1 - depth, z0, x1, z1),
            "-z": (x0, z0, x1, z0 + depth), "+z": (x0, z1 - depth, x1, z1)}[side]


def _crossing(d: District, rng):
    axis = ("-x", "+x") if rng.random() < 0.5 else ("-z", "+z")
    a, b = (axis if rng.random() < 0.5 else axis[::-1])
    pattern = rng.choice(["one-way", "counter", "cross"], p=[0.3, 0.4, 0.3])
    d.flows = [(a, b)]
    if pattern == "counter":
        d.flows.append((b, a))
    elif pattern == "cross":
        other = [s for s in SIDES if s not in axis]
        c = other[int(rng.integers(2))]
        d.flows.append((c, OPPOSITE[c]))
    x0, z0, x1, z1 = d.rect
    side = min(x1 - x0, z1 - z0)
    per_band = d.n if len(d.flows) == 1 or pattern == "counter" else int(math.ceil(d.n / 2))
    depth = round(min(max(BAND, per_band * BAND_AREA / side + 0.6), 0.35 * side), 2)
    for s in sorted({s for f in d.flows for s in f}):
        d.bands[s] = _band(d.rect, s, depth)


def _room_walls(d: District, districts, world_size, placer: Placer, rng):
    """Outer walls where the district is not on the plaza's edge (a wall shared with an earlier
    rooms district is drawn once), one outer door, and the inner wall with its doors."""
    x0, z0, x1, z1 = d.rect
    W, D = world_size
    edges = {"-x": ((x0, z0), (x0, z1)), "+x": ((x1, z0), (x1, z1)),
             "-z": ((x0, z0), (x1, z0)), "+z": ((x0, z1), (x1, z1))}
    on_edge = {"-x": x0 <= 1e-9, "+x": x1 >= W - 1e-9, "-z": z0 <= 1e-9, "+z": z1 >= D - 1e-9}

    def neighbour(side):
        cx, cz = (x0 + x1) / 2, (z0 + z1) / 2
        step = {"-x": (-(x1 - x0), 0), "+x": (x1 - x0, 0), "-z": (0, -(z1 - z0)), "+z": (0, z1 - z0)}[side]
        q = (cx + step[0], cz + step[1])
        return next((o for o in districts if o.rect[0] < q[0] < o.rect[2] and o.rect[1] < q[1] < o.rect[3]), None)

    inner = [s for s in SIDES if not on_edge[s]]
    door_side = inner[int(rng.integers(len(inner)))] if inner else None
    for s in inner:
        nb = neighbour(s)
        if nb is not None and nb.kind == "rooms" and nb.index < d.index:
            continue
        a, b = edges[s]
        length = float(np.hypot(b[0] - a[0], b[1] - a[1]))
        doors = []
        if s == door_side:
            w = round(float(rng.uniform(*DOOR_WIDTH)), 2)
            doors = [(round(float(rng.uniform(1.5 + w / 2, length - 1.5 - w / 2)), 2), w)]
        placer.wall(f"D{d.index}_Wall{s.replace('-', 'm').replace('+', 'p')}", a, b, doors=doors)
    # the inner wall, across the longer side (either way for a square)
    across_x = (x1 - x0) > (z1 - z0) or ((x1 - x0) == (z1 - z0) and rng.random() < 0.5)
    f = float(rng.uniform(0.42, 0.58))
    if across_x:
        xs = round(x0 + f * (x1 - x0), 2)
        a, b = (xs, z0), (xs, z1)
        d.rooms = [(x0, z0, xs, z1), (xs, z0, x1, z1)]
    else:
        zs = round(z0 + f * (z1 - z0), 2)
        a, b = (x0, zs), (x1, zs)
        d.rooms = [(x0, z0, x1, zs), (x0, zs, x1, z1)]
    length = float(np.hypot(b[0] - a[0], b[1] - a[1]))
    n_doors = 2 if (rng.random() < 0.3 and length > 10.0) else 1
    doors = []
    for k in range(n_doors):
        w = round(float(rng.uniform(*DOOR_WIDTH)), 2)
        lo, hi = (1.2 + w / 2, length - 1.2 - w / 2) if n_doors == 1 else \
            ((1.2 + w / 2, length / 2 - 1.0 - w / 2) if k == 0 else (length / 2 + 1.0 + w / 2, length - 1.2 - w / 2))
        doors.append((round(float(rng.uniform(lo, max(lo, hi))), 2), w))
    placer.wall(f"D{d.index}_Inner", a, b, doors=doors)


def _seat_rows(d: District, placer: Placer, rng):
    """Rows of seats across one side of the district, the partition behind each row inside a
    turned Xform (the row's frame); the whole block turned by a few degrees where it fits."""
    x0, z0, x1, z1 = d.rect
    need = d.n + 1
    facing = float(rng.choice([0.0, 90.0, 180.0, 270.0]))
    along = (x1 - x0) if facing in (0.0, 180.0) else (z1 - z0)
    depth = (z1 - z0) if facing in (0.0, 180.0) else (x1 - x0)
    per_row = max(2, int((along - 3.0) // SEAT_PITCH) + 1)
    rows = int(math.ceil(need / per_row))
    per_row = int(math.ceil(need / rows))
    if (rows - 1) * ROW_PITCH + PARTITION_BEHIND + 2.5 > depth - 1.5:     # too deep: fewer rows (and seats)
        rows = max(1, int((depth - 1.5 - PARTITION_BEHIND - 2.5) // ROW_PITCH) + 1)
    row_len = (per_row - 1) * SEAT_PITCH + 0.8
    # the block's back (partitions) against the district side behind the seats, centred along
    c = np.array([(x0 + x1) / 2, (z0 + z1) / 2])
    back = -turn(np.array([0.0, 1.0]), facing)              # unit vector behind the seats
    back_dist = depth / 2 - 0.4 - 0.1
    for _ in range(12):
        tilt = round(float(rng.uniform(-8.0, 8.0)), 1)
        yaw = facing + tilt
        rows_xz = []
        ok = True
        for r in range(rows):
            centre = c + back * back_dist + turn(np.array([0.0, PARTITION_BEHIND + r * ROW_PITCH]), yaw) + \
                turn(np.array([float(rng.uniform(-0.3, 0.3)), 0.0]), yaw)
            corners = [centre + turn(np.array([sx * row_len / 2, -PARTITION_BEHIND + sz * 0.1]), yaw)
                       for sx in (-1, 1) for sz in (-1, 1)]
            if any(not (x0 + 0.3 <= q[0] <= x1 - 0.3 and z0 + 0.3 <= q[1] <= z1 - 0.3) for q in corners):
                ok = False
                break
            rows_xz.append(centre)
        if ok:
            break
    else:
        yaw, rows_xz = facing, [c + back * back_dist + turn(np.array([0.0, PARTITION_BEHIND + r * ROW_PITCH]), facing)
                                for r in range(rows)]
    for r, centre in enumerate(rows_xz):
        centre = np.round(centre, 3)
        g = placer.world.group(f"D{d.index}_Row{r}", centre[0], centre[1], yaw)
        placer.world.cube("Partition", 0.0, -PARTITION_BEHIND, 1.0, (row_len, 1.0, 0.2), 0.0, parent=g)
        a = centre + turn(np.array([-row_len / 2, -PARTITION_BEHIND]), yaw)
        b = centre + turn(np.array([row_len / 2, -PARTITION_BEHIND]), yaw)
        placer.walls.append((a, b, 0.1))
        for j in range(per_row):
            s = centre + turn(np.array([(j - (per_row - 1) / 2) * SEAT_PITCH, 0.0]), yaw)
            s = np.round(s, 3)
            path = placer.world.seat(f"d{d.index}_r{r}_s{j}", s[0], s[1], yaw)
            d.seats.append((path, s, yaw))
            placer.keep_out(s, 1.5)
        # the lane in front of the row stays clear of random obstacles
        front = centre + turn(np.array([0.0, 1.5]), yaw)
        placer.keep_out(front, row_len / 2)


def build_world(rng, size, districts, doc: str) -> WorldBuilder:
    """The world stage: perimeter, walls, seat rows and random obstacles (the boxes come with
    the tasks)."""
    W, D = size
    world = WorldBuilder(doc)
    placer = Placer(world, rng)
    placer.wall("Perimeter_S", (0.0, 0.0), (W, 0.0))
    placer.wall("Perimeter_E", (W, 0.0), (W, D))
    placer.wall("Perimeter_N", (0.0, D), (W, D))
    placer.wall("Perimeter_W", (0.0, 0.0), (0.0, D))
    # structure first (walls, seat rows), then the random obstacles around it
    for d in districts:
        if d.kind == "rooms":
            _room_walls(d, districts, size, placer, rng)
        elif d.kind == "seats":
            _seat_rows(d, placer, rng)
        elif d.kind == "crossing":
            _crossing(d, rng)
    for d in districts:
        name = f"D{d.index}_Obstacle"
        if d.kind == "crossing":
            x0, z0, x1, z1 = d.inset(1.0)
            for s in d.bands:       # centres 3 m from a band's outer side (obstacles may reach into bands)
                x0, z0, x1, z1 = {"-x": (d.rect[0] + 3.0, z0, x1, z1), "+x": (x0, z0, d.rect[2] - 3.0, z1),
                                  "-z": (x0, d.rect[1] + 3.0, x1, z1), "+z": (x0, z0, x1, d.rect[3] - 3.0)}[s]
            placer.scatter(name, (x0, z0, x1, z1), max(1, int(round(d.area / 22.0))))
        elif d.kind == "rooms":
            for k, (x0, z0, x1, z1) in enumerate(d.rooms):
                placer.scatter(f"D{d.index}_Furniture{k}", (x0 + 2.2, z0 + 2.2, x1 - 2.2, z1 - 2.2), 1,
                               shares=(0.6, 0.4, 0.0), tries=20)
        elif d.kind in ("meeting", "boxes"):
            placer.scatter(name, d.inset(1.0), max(1, int(round(d.area / 40.0))))
    return world
