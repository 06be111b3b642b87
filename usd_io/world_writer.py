"""Writing world stages that follow :mod:`usd_io.world`'s conventions.

:class:`WorldBuilder` makes a Y-up, metre stage: obstacles (cubes, cylinders, walls with door
gaps, nested groups under rotated and translated Xforms) under ``/World/Obstacles``, seat
markers under ``/World/Seats`` and box markers under ``/World/Boxes``. Markers face their local
+Z; yaws and headings are degrees about +Y (0 faces +Z). The stage stays in memory until
:meth:`WorldBuilder.save` writes it atomically; :meth:`WorldBuilder.environment` reads it back
as :mod:`usd_io.world` would read the saved file. The same calls give byte-identical files.
"""
from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from runtime.assets import atomic_path

from .world import ROLE_ATTR, read_world_stage

__all__ = ["WorldBuilder", "OBSTACLES", "SEATS", "BOXES"]

OBSTACLES = "/World/Obstacles"
SEATS = "/World/Seats"
BOXES = "/World/Boxes"


class WorldBuilder:
    """A Y-up, metre world stage: obstacles under /World/Obstacles, seats under /World/Seats,
    boxes under /World/Boxes (markers face their local +Z; heading degrees about +Y)."""

    def __init__(self, doc: str):
        self.stage = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(self.stage, 1.0)
        world = UsdGeom.Xform.Define(self.stage, "/World")
        self.stage.SetDefaultPrim(world.GetPrim())
        self.stage.GetRootLayer().documentation = doc
        for p in (OBSTACLES, SEATS, BOXES):
            UsdGeom.Scope.Define(self.stage, p)
        self._used = set()

    @staticmethod
    def _xform(prim, x, y, z, yaw=0.0, scale=None):
        api = UsdGeom.XformCommonAPI(prim)
        api.SetTranslate((float(x), float(y), float(z)))
        if yaw:
            api.SetRotate((0.0, float(yaw), 0.0))
        if scale is not None:
            api.SetScale(tuple(float(s) for s in scale))

    def _path(self, parent, name):
        p = f"{parent}/{name}"
        if p in self._used:
            raise ValueError(f"duplicate prim {p}")
        self._used.add(p)
        return p

    def group(self, name, x, z, yaw=0.0, parent=OBSTACLES) -> str:
        """An Xform at (x, z) turned by ``yaw`` degrees: obstacles made with ``parent`` = the
        returned path are placed in its frame (nested transforms)."""
        xf = UsdGeom.Xform.Define(self.stage, self._path(parent, name))
        self._xform(xf.GetPrim(), x, 0.0, z, yaw)
        return xf.GetPath().pathString

    def cube(self, name, x, z, size=1.0, scale=(1.0, 1.0, 1.0), yaw=0.0, parent=OBSTACLES):
        """A Cube of edge ``size`` scaled by ``scale`` (x, y, z; non-uniform), turned by ``yaw``
        degrees and standing on the ground at (x, z) of its parent's frame."""
        cube = UsdGeom.Cube.Define(self.stage, self._path(parent, name))
        cube.CreateSizeAttr(float(size))
        self._xform(cube.GetPrim(), x, size * scale[1] / 2, z, yaw, scale)
        return cube

    def block(self, name, x0, z0, x1, z1, height=2.5, yaw=0.0, parent=OBSTACLES):
        """An axis-aligned (before ``yaw``) box obstacle spanning [x0, x1] x [z0, z1]."""
        cube = UsdGeom.Cube.Define(self.stage, self._path(parent, name))
        cube.CreateSizeAttr(1.0)
        self._xform(cube.GetPrim(), (x0 + x1) / 2, height / 2, (z0 + z1) / 2, yaw,
                    (abs(x1 - x0), height, abs(z1 - z0)))
        return cube

    def pillar(self, name, x, z, radius, height=3.0, parent=OBSTACLES):
        """An upright Cylinder of ``radius`` standing at (x, z) of its parent's frame."""
        cyl = UsdGeom.Cylinder.Define(self.stage, self._path(parent, name))
        cyl.CreateAxisAttr("Y")
        cyl.CreateRadiusAttr(float(radius))
        cyl.CreateHeightAttr(float(height))
        self._xform(cyl.GetPrim(), x, height / 2, z)
        return cyl

    def wall(self, name, a, b, doors=(), thickness=0.2, height=2.5):
        """A straight axis-aligned wall from a=(x, z) to b with door gaps ``(centre, width)``
        measured along the wall from ``a``. Each solid piece is one Cube."""
        a, b = np.asarray(a, float), np.asarray(b, float)
        length = float(np.hypot(*(b - a)))
        d = (b - a) / length
        cuts = sorted((c - w / 2, c + w / 2) for c, w in doors)
        pieces, s = [], 0.0
        for lo, hi in cuts:
            if lo > s:
                pieces.append((s, lo))
            s = max(s, hi)
        if s < length:
            pieces.append((s, length))
        n = np.array([-d[1], d[0]]) * thickness / 2
        for k, (s0, s1) in enumerate(pieces):
            p0, p1 = a + d * s0, a + d * s1
            lo = np.minimum(p0, p1) - np.abs(n)
            hi = np.maximum(p0, p1) + np.abs(n)
            self.block(f"{name}_{k}", lo[0], lo[1], hi[0], hi[1], height)

    def _marker(self, parent, name, role, x, z, heading_deg):
        xf = UsdGeom.Xform.Define(self.stage, self._path(parent, name))
        prim = xf.GetPrim()
        prim.CreateAttribute(ROLE_ATTR, Sdf.ValueTypeNames.String, custom=True).Set(role)
        self._xform(prim, x, 0.0, z, heading_deg)
        return prim.GetPath().pathString

    def seat(self, name, x, z, heading_deg):
        """A seat marker (root of a seated character, facing ``heading_deg``) with a chair
        under it (the marker's own geometry, not an obstacle)."""
        path = self._marker(SEATS, name, "seat", x, z, heading_deg)
        chair = UsdGeom.Cube.Define(self.stage, path + "/Chair")
        chair.CreateSizeAttr(1.0)
        self._xform(chair.GetPrim(), 0.0, 0.22, -0.05, scale=(0.5, 0.44, 0.5))
        back = UsdGeom.Cube.Define(self.stage, path + "/Back")
        back.CreateSizeAttr(1.0)
        self._xform(back.GetPrim(), 0.0, 0.65, -0.27, scale=(0.5, 0.9, 0.06))
        return path

    def box(self, name, x, z, heading_deg):
        """A box marker: the character picks it up standing in front of it (on its +Z side)."""
        path = self._marker(BOXES, name, "box", x, z, heading_deg)
        crate = UsdGeom.Cube.Define(self.stage, path + "/Crate")
        crate.CreateSizeAttr(0.4)
        self._xform(crate.GetPrim(), 0.0, 0.2, 0.0)
        return path

    def text(self) -> str:
        """The stage as .usda text."""
        return self.stage.GetRootLayer().ExportToString()

    def environment(self):
        """The :class:`runtime.crowd.environment.Environment` of the stage as built so far, read
        as :func:`usd_io.world.read_world` reads the saved file (``WorldError`` if unusable)."""
        return read_world_stage(self.stage, "<world being built>")

    def save(self, path):
        with atomic_path(path) as tmp:
            self.stage.GetRootLayer().Export(str(tmp))
