"""World stages of the samples (pxr), following :mod:`usd_io.world`'s conventions."""
from __future__ import annotations

import numpy as np

from runtime.assets import atomic_path

__all__ = ["WorldBuilder"]


class WorldBuilder:
    """A Y-up, metre world stage: obstacles under /World/Obstacles, seats under /World/Seats,
    boxes under /World/Boxes (markers face their local +Z; heading degrees about +Y)."""

    def __init__(self, doc: str):
        from pxr import Sdf, Usd, UsdGeom
        self.Sdf, self.Usd, self.UsdGeom = Sdf, Usd, UsdGeom
        self.stage = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(self.stage, 1.0)
        world = UsdGeom.Xform.Define(self.stage, "/World")
        self.stage.SetDefaultPrim(world.GetPrim())
        self.stage.GetRootLayer().documentation = doc
        for p in ("/World/Obstacles", "/World/Seats", "/World/Boxes"):
            UsdGeom.Scope.Define(self.stage, p)
        self._used = set()

    def _xform(self, prim, x, y, z, yaw=0.0, scale=None):
        api = self.UsdGeom.XformCommonAPI(prim)
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

    def block(self, name, x0, z0, x1, z1, height=2.5, yaw=0.0, parent="/World/Obstacles"):
        """An axis-aligned (before ``yaw``) box obstacle spanning [x0, x1] x [z0, z1]."""
        cube = self.UsdGeom.Cube.Define(self.stage, self._path(parent, name))
        cube.CreateSizeAttr(1.0)
        self._xform(cube.GetPrim(), (x0 + x1) / 2, height / 2, (z0 + z1) / 2, yaw,
                    (abs(x1 - x0), height, abs(z1 - z0)))
        return cube

    def pillar(self, name, x, z, radius, height=3.0):
        cyl = self.UsdGeom.Cylinder.Define(self.stage, self._path("/World/Obstacles", name))
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
        xf = self.UsdGeom.Xform.Define(self.stage, self._path(parent, name))
        prim = xf.GetPrim()
        prim.CreateAttribute("crowdweave:role", self.Sdf.ValueTypeNames.String, custom=True).Set(role)
        self._xform(prim, x, 0.0, z, heading_deg)
        return prim.GetPath().pathString

    def seat(self, name, x, z, heading_deg):
        """A seat marker (root of a seated character, facing ``heading_deg``) with a chair
        under it (the marker's own geometry, not an obstacle)."""
        path = self._marker("/World/Seats", name, "seat", x, z, heading_deg)
        chair = self.UsdGeom.Cube.Define(self.stage, path + "/Chair")
        chair.CreateSizeAttr(1.0)
        self._xform(chair.GetPrim(), 0.0, 0.22, -0.05, scale=(0.5, 0.44, 0.5))
        back = self.UsdGeom.Cube.Define(self.stage, path + "/Back")
        back.CreateSizeAttr(1.0)
        self._xform(back.GetPrim(), 0.0, 0.65, -0.27, scale=(0.5, 0.9, 0.06))
        return path

    def box(self, name, x, z, heading_deg):
        """A box marker: the character picks it up standing in front of it (on its +Z side)."""
        path = self._marker("/World/Boxes", name, "box", x, z, heading_deg)
        crate = self.UsdGeom.Cube.Define(self.stage, path + "/Crate")
        crate.CreateSizeAttr(0.4)
        self._xform(crate.GetPrim(), 0.0, 0.2, 0.0)
        return path

    def save(self, path):
        with atomic_path(path) as tmp:
            self.stage.GetRootLayer().Export(str(tmp))
