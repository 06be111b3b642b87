"""Random obstacles for generated worlds: rotated and scaled boxes, cylinders, nested groups
(obstacles under turned and moved parent Xforms, two levels deep) and walls with doors.

Obstacles keep ``gap`` metres between their bounding circles (and from walls), so every
passage between two of them is wide enough for a walking character with room to spare; the
parts of one nested group overlap each other (one solid piece, no slot between them).
"""
from __future__ import annotations

import math

import numpy as np

from usd_io.world_writer import WorldBuilder

__all__ = ["Placer", "OBSTACLE_GAP", "turn"]

OBSTACLE_GAP = 2.0      # m between obstacles' bounding circles: a walking character's 1.26 m plus room


def _r(v, k=3) -> float:
    return round(float(v), k)


def turn(v, yaw_deg):
    """(x, z) turned by ``yaw_deg`` degrees about +Y, as a USD rotation about Y turns it (+Z
    goes to +X)."""
    a = math.radians(yaw_deg)
    return np.array([math.cos(a) * v[0] + math.sin(a) * v[1], -math.sin(a) * v[0] + math.cos(a) * v[1]])


class Placer:
    """Places obstacles in a :class:`WorldBuilder`, keeping ``gap`` between them.

    ``circles`` (centre x, z, radius) bound every obstacle placed; ``walls`` are segments (a, b,
    half thickness) covering whole walls, doors included (nothing is put in front of a door)."""

    def __init__(self, world: WorldBuilder, rng, gap: float = OBSTACLE_GAP):
        self.world, self.rng, self.gap = world, rng, gap
        self.circles: list[tuple] = []
        self.walls: list[tuple] = []
        self.count = 0

    # -- spacing ------------------------------------------------------------------------------
    def fits(self, c, r, gap=None) -> bool:
        gap = self.gap if gap is None else gap
        c = np.asarray(c, float)
        for x, z, rr in self.circles:
            if math.hypot(c[0] - x, c[1] - z) < r + rr + gap:
                return False
        for a, b, ht in self.walls:
            ab = b - a
            t = min(1.0, max(0.0, float(np.dot(c - a, ab) / np.dot(ab, ab))))
            if float(np.hypot(*(c - a - t * ab))) < r + ht + gap:
                return False
        return True

    def keep_out(self, c, r):
        """Reserve a disc (an obstacle placed by hand, a seat block) for later placements."""
        self.circles.append((float(c[0]), float(c[1]), float(r)))

    # -- walls ----------------------------------------------------------------------------------
    def wall(self, name, a, b, doors=(), thickness=0.2, height=2.5):
        """An axis-aligned wall from a to b with door gaps (centre along the wall from a, width)."""
        self.world.wall(name, a, b, doors=doors, thickness=thickness, height=height)
        self.walls.append((np.asarray(a, float), np.asarray(b, float), thickness / 2))

    # -- random obstacles ---------------------------------------------------------------------
    def scatter(self, name, region, count, shares=(0.5, 0.3, 0.2), tries=60, parent=None):
        """Up to ``count`` obstacles with centres in ``region`` (x0, z0, x1, z1): boxes,
        cylinders and nested groups in the proportions ``shares``. Returns how many fit."""
        x0, z0, x1, z1 = region
        if x1 <= x0 or z1 <= z0:
            return 0
        made = 0
        kinds = self.rng.choice(3, size=count, p=np.asarray(shares, float) / sum(shares))
        shapes = [(self._draw_box, self._draw_cylinder, self._draw_group)[k]() for k in kinds]
        for shape in sorted(shapes, key=lambda s: -s["radius"]):     # the largest first
            for _ in range(tries):
                c = np.array([_r(self.rng.uniform(x0, x1), 2), _r(self.rng.uniform(z0, z1), 2)])
                if self.fits(c, shape["radius"]):
                    self._make(f"{name}_{made}", c, shape, parent)
                    self.keep_out(c, shape["radius"])
                    made += 1
                    break
        return made

    def _draw_box(self):
        """A Cube of edge ``size`` (0.5, 1 or 2 m) scaled to w x h x d, turned by any yaw."""
        w, d = _r(self.rng.uniform(0.4, 2.6), 2), _r(self.rng.uniform(0.4, 1.6), 2)
        h = _r(self.rng.uniform(0.6, 2.5), 2)
        size = float(self.rng.choice([0.5, 1.0, 2.0]))
        return {"kind": "box", "size": size, "scale": (w / size, h / size, d / size), "w": w, "d": d,
                "yaw": _r(self.rng.uniform(0.0, 360.0), 1), "radius": math.hypot(w, d) / 2}

    def _draw_cylinder(self):
        r = _r(self.rng.uniform(0.25, 0.8), 2)
        return {"kind": "cylinder", "r": r, "height": _r(self.rng.uniform(0.8, 3.0), 2), "radius": r}

    def _draw_group(self):
        """A turned Xform holding a box A and a turned sub-Xform at the middle of A's +X face
        holding a box B (reaching back 0.1 m into A) and a cylinder over B's far end: one solid
        piece, two levels of nested transforms."""
        a = self._draw_box()
        a["yaw"] = 0.0
        b = self._draw_box()
        b["yaw"] = 0.0
        cyl = self._draw_cylinder()
        cyl["r"] = max(cyl["r"], 0.3)
        yaw_b = _r(self.rng.uniform(-75.0, 75.0), 1)
        # B spans [-0.1, w_b - 0.1] along the sub-Xform's +X: it covers the joint point, so it
        # overlaps A; the cylinder sits on B's far end
        b_at = np.array([_r(b["w"] / 2 - 0.1), 0.0])
        c_at = np.array([_r(b["w"] - 0.1 - min(0.15, b["w"] / 4)), 0.0])
        joint = np.array([a["w"] / 2, 0.0])
        reach = max(math.hypot(a["w"], a["d"]) / 2,
                    float(np.hypot(*joint)) + float(np.hypot(*b_at)) + b["radius"],
                    float(np.hypot(*joint)) + float(np.hypot(*c_at)) + cyl["r"])
        return {"kind": "group", "yaw": _r(self.rng.uniform(0.0, 360.0), 1), "a": a, "b": b, "cyl": cyl,
                "yaw_b": yaw_b, "joint": joint, "b_at": b_at, "c_at": c_at, "radius": reach}

    def _make(self, name, c, shape, parent=None):
        w = self.world
        kw = {"parent": parent} if parent else {}
        if shape["kind"] == "box":
            w.cube(name, c[0], c[1], shape["size"], shape["scale"], shape["yaw"], **kw)
        elif shape["kind"] == "cylinder":
            w.pillar(name, c[0], c[1], shape["r"], shape["height"], **kw)
        else:
            g = w.group(name, c[0], c[1], shape["yaw"], **kw)
            a, b, cyl = shape["a"], shape["b"], shape["cyl"]
            w.cube("A", 0.0, 0.0, a["size"], a["scale"], 0.0, parent=g)
            sub = w.group("Arm", shape["joint"][0], 0.0, shape["yaw_b"], parent=g)
            w.cube("B", shape["b_at"][0], 0.0, b["size"], b["scale"], 0.0, parent=sub)
            w.pillar("C", shape["c_at"][0], 0.0, cyl["r"], cyl["height"], parent=sub)
        self.count += 1

