"""Reading world stages: obstacles and markers for crowd synthesis.

World-stage conventions
-----------------------
* **Obstacles** are gprims -- ``Cube``, ``Sphere``, ``Cylinder`` (and ``Cylinder_1``),
  ``Capsule`` (and ``Capsule_1``), ``Cone``, ``Mesh`` -- anywhere under ``/World/Obstacles``
  (or ``/<defaultPrim>/Obstacles``, for DCC exports whose root prim is not ``World``),
  or carrying the custom attribute ``string crowdweave:role = "obstacle"`` (on the gprim, or
  on an ancestor Xform: then every gprim under it is an obstacle). Visibility and purpose do
  not matter (an invisible collision proxy is still an obstacle). The footprint is the ground
  projection of the prim's world-space geometry: nested transforms, rotation and non-uniform
  scale are honoured (``UsdGeom.XformCache``). Meshes become the convex hull of their points;
  round parts become circumscribed polygons; an upright round cylinder, capsule, sphere or
  cone base stays an exact circle (``runtime.crowd.geometry``).
* **Markers** are transformable prims (normally Xforms) with ``crowdweave:role`` = ``"seat"``,
  ``"box"``, ``"spawn"`` or ``"region"``. Position = the prim's origin; facing = its forward
  axis (local +Z in a Y-up stage; local -Y in a Z-up stage, which is the same direction after
  the up-axis conversion) projected on the ground; heading 0 faces +Z. Geometry under a marker
  (a chair under a seat, a crate under a box) is the marker's own and is not an obstacle unless
  it says ``crowdweave:role = "obstacle"`` itself. A **region** needs an outline: the marker
  prim's own geometry if it is a gprim, else ``float2 crowdweave:extent = (width, depth)`` (a
  rectangle centred on the origin, width along local X, depth along the forward axis, stage
  units), else the convex hull of the gprims under it.
* **Units**: coordinates are converted with the stage's ``metersPerUnit`` and ``upAxis`` to
  metres, Y up (a Z-up stage is rotated -90 degrees about X). A stage that does not author them
  is read as metres / Y up (crowdweave's convention, not USD's centimetre fallback) with a
  warning in the report.
* Animated prims are read at their earliest time sample (worlds are static).

Errors (``WorldError``, naming the file and the prim): a missing or unreadable file or one
that is not USD; an unknown role; a role on a prim that cannot carry it; malformed geometry
(negative or non-finite size/radius/height, bad axis); a Mesh without points; any obstacle
whose footprint has zero area. :func:`read_world_report` collects every problem instead of
stopping at the first (for ``crowdweave world check``).

No algorithms here: the footprint maths is in ``runtime.crowd.geometry``.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from runtime.crowd.environment import MARKER_ROLES, Environment, Marker
from runtime.crowd.geometry import (GeometryError, convex_hull, footprint_capsule, footprint_cube,
                                    footprint_cylinder, footprint_points, footprint_sphere, polygon_area,
                                    units_matrix)

from .stage import open_usd_file

__all__ = ["WorldError", "WorldItem", "WorldIssue", "read_world", "read_world_report", "read_world_stage", "world_units",
           "ROLE_ATTR", "EXTENT_ATTR", "OBSTACLES_PATH", "ROLES"]

ROLE_ATTR = "crowdweave:role"
EXTENT_ATTR = "crowdweave:extent"
OBSTACLES_PATH = "/World/Obstacles"
ROLES = ("obstacle",) + MARKER_ROLES
USD_SUFFIXES = (".usda", ".usdc", ".usd", ".usdz")
SUPPORTED = "Cube, Sphere, Cylinder, Capsule, Cone, Mesh"


class WorldError(ValueError):
    """A world stage cannot be used: the message names the file and, where there is one, the prim."""

    def __init__(self, path, reason: str, prim: str | None = None, issues=()):
        self.path = str(path)
        self.prim = prim
        self.reason = reason
        self.issues = list(issues)
        super().__init__(f"{path}: {prim}: {reason}" if prim else f"{path}: {reason}")


@dataclass
class WorldItem:
    """Something the reader used: an obstacle (``role`` "obstacle", ``shape`` "polygon" or
    "circle") or a marker (``shape`` "point", or "polygon" for regions). ``area`` in m^2
    (footprint or region), ``position`` (x, z) metres, ``heading`` radians (markers)."""
    path: str
    role: str
    shape: str
    position: np.ndarray
    area: float | None = None
    heading: float | None = None


@dataclass
class WorldIssue:
    """A prim (or the stage) the reader could not use, and why; ``error`` False for warnings."""
    path: str
    reason: str
    error: bool = True


# round gprims, in the order they are tested: (schema, footprint function, bottom radius
# attribute, top radius attribute; None = 0, a cone's apex towards +axis)
_ROUND_GPRIMS = ((UsdGeom.Cylinder, footprint_cylinder, "radius", "radius"),
                 (UsdGeom.Cylinder_1, footprint_cylinder, "radiusBottom", "radiusTop"),
                 (UsdGeom.Cone, footprint_cylinder, "radius", None),
                 (UsdGeom.Capsule, footprint_capsule, "radius", "radius"),
                 (UsdGeom.Capsule_1, footprint_capsule, "radiusBottom", "radiusTop"))


def _open(path) -> Usd.Stage:
    p = Path(path)
    if not p.exists():
        raise WorldError(p, "file not found")
    if not p.is_file():
        raise WorldError(p, "not a file")
    if p.suffix.lower() not in USD_SUFFIXES:
        raise WorldError(p, f"not a USD file (extension {p.suffix or 'none'!r}; expected {', '.join(USD_SUFFIXES)})")
    return open_usd_file(p, WorldError, "not a readable USD file")


def world_units(stage_or_path):
    """(metersPerUnit, upAxis, warnings) as the reader interprets the stage."""
    stage = stage_or_path if isinstance(stage_or_path, Usd.Stage) else _open(stage_or_path)
    warnings = []
    if UsdGeom.StageHasAuthoredMetersPerUnit(stage):
        mpu = float(UsdGeom.GetStageMetersPerUnit(stage))
    else:
        mpu = 1.0
        warnings.append("metersPerUnit is not authored: read as 1 (metres)")
    if stage.HasAuthoredMetadata("upAxis"):
        up = str(UsdGeom.GetStageUpAxis(stage))
    else:
        up = "Y"
        warnings.append("upAxis is not authored: read as Y")
    return mpu, up, warnings


def _role(prim):
    """The prim's ``crowdweave:role`` (lower-cased), None if absent; raises ValueError if it is
    not a string."""
    attr = prim.GetAttribute(ROLE_ATTR)
    if not attr or not attr.HasAuthoredValue():
        return None
    v = attr.Get()
    if not isinstance(v, str):
        raise ValueError(f"{ROLE_ATTR} must be a string or token, got {attr.GetTypeName()}")
    return v.strip().lower()


class _Reader:
    def __init__(self, stage: Usd.Stage, file: str):
        self.stage = stage
        self.file = file
        self.time = Usd.TimeCode.EarliestTime()
        self.xf = UsdGeom.XformCache(self.time)
        mpu, up, warnings = world_units(stage)
        try:
            self.K = units_matrix(mpu, up)
        except GeometryError as e:
            raise WorldError(file, f"stage metadata: {e}") from None
        # local forward axis: +Z in a Y-up stage, -Y in a Z-up stage (K's rotation maps it to +Z)
        self.forward = np.array([0.0, 0.0, 1.0]) if up.upper() == "Y" else np.array([0.0, -1.0, 0.0])
        self.side = np.array([1.0, 0.0, 0.0])
        self.issues = [WorldIssue(file, w, error=False) for w in warnings]
        self.found: list[WorldItem] = []
        self.polys, self.poly_paths, self.circles, self.circle_paths = [], [], [], []
        self.markers: list[Marker] = []
        self.pred = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
        self.scopes = {OBSTACLES_PATH}
        dp = stage.GetDefaultPrim()
        if dp and dp.GetPath().GetParentPath() == "/":
            self.scopes.add(f"{dp.GetPath()}/Obstacles")

    # -- internals --------------------------------------------------------------------------------
    def error(self, prim, reason):
        self.issues.append(WorldIssue(str(prim.GetPath()), reason, True))

    def warn(self, prim, reason):
        self.issues.append(WorldIssue(str(prim.GetPath()), reason, False))

    def matrix(self, prim) -> np.ndarray:
        """Local-to-world 4x4 in crowdweave's frame (metres, Y up), column-vector convention."""
        M = np.array(self.xf.GetLocalToWorldTransform(prim), dtype=np.float64).T
        if not np.all(np.isfinite(M)):
            raise GeometryError("transform is not finite")
        return self.K @ M

    def get(self, prim, name):
        attr = prim.GetAttribute(name)
        v = attr.Get(self.time) if attr else None
        if v is None:
            raise GeometryError(f"attribute {name!r} has no value")
        return v

    def footprint(self, prim):
        """Footprint of a gprim; None (with a warning) for unsupported gprim types."""
        T = self.matrix(prim)
        if prim.IsA(UsdGeom.Cube):
            return footprint_cube(T, self.get(prim, "size"))
        if prim.IsA(UsdGeom.Sphere):
            return footprint_sphere(T, self.get(prim, "radius"))
        for schema, footprint, bottom, top in _ROUND_GPRIMS:
            if prim.IsA(schema):
                r0 = self.get(prim, bottom)
                r1 = r0 if top == bottom else (self.get(prim, top) if top else 0.0)
                return footprint(T, r0, r1, self.get(prim, "height"), self.get(prim, "axis"))
        if prim.IsA(UsdGeom.Mesh):
            pts = UsdGeom.Mesh(prim).GetPointsAttr().Get(self.time)
            if pts is None or len(pts) == 0:
                raise GeometryError("mesh has no points")
            return footprint_points(T, np.asarray(pts, dtype=np.float64))
        return None

    # -- obstacles ------------------------------------------------------------------------------
    def add_obstacle(self, prim) -> bool:
        try:
            fp = self.footprint(prim)
        except GeometryError as e:
            self.error(prim, f"{prim.GetTypeName()} obstacle: {e}")
            return False
        if fp is None:
            self.warn(prim, f"{prim.GetTypeName() or 'untyped'} is not a supported obstacle type ({SUPPORTED}); not used")
            return False
        path = str(prim.GetPath())
        if fp.kind == "circle":
            self.circles.append(fp.circle)
            self.circle_paths.append(path)
            pos = fp.circle[:2]
        else:
            self.polys.append(fp.polygon)
            self.poly_paths.append(path)
            pos = fp.polygon.mean(axis=0)
        self.found.append(WorldItem(path, "obstacle", fp.kind, np.asarray(pos, dtype=np.float64), fp.area))
        return True

    # -- markers --------------------------------------------------------------------------------
    def region_polygon(self, prim, T) -> np.ndarray:
        if prim.IsA(UsdGeom.Gprim):
            fp = self.footprint(prim)
            if fp is None:
                raise GeometryError(f"{prim.GetTypeName()} cannot outline a region ({SUPPORTED})")
            return fp.as_polygon()
        attr = prim.GetAttribute(EXTENT_ATTR)
        if attr and attr.HasAuthoredValue():
            v = attr.Get(self.time)
            try:
                w, d = (float(x) for x in tuple(v)[:2])
            except (TypeError, ValueError):
                raise GeometryError(f"{EXTENT_ATTR} must be a float2 (width, depth), got {v!r}") from None
            if not (math.isfinite(w) and math.isfinite(d) and w > 0 and d > 0):
                raise GeometryError(f"{EXTENT_ATTR} must be positive and finite, got ({w:g}, {d:g})")
            corners = np.array([sx * 0.5 * w * self.side + sz * 0.5 * d * self.forward
                                for sx, sz in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
            w3 = corners @ T[:3, :3].T + T[:3, 3]
            return convex_hull(w3[:, [0, 2]])
        pts = []
        it = iter(Usd.PrimRange(prim, self.pred))
        next(it)
        for p in it:
            if p.IsA(UsdGeom.Gprim):
                fp = self.footprint(p)
                if fp is not None:
                    pts.append(fp.as_polygon())
        if not pts:
            raise GeometryError(f"a region needs an outline: make it a gprim, give it geometry, or set {EXTENT_ATTR}")
        return convex_hull(np.concatenate(pts))

    def add_marker(self, prim, role):
        if not prim.IsA(UsdGeom.Xformable):
            self.error(prim, f"role {role!r} needs a transformable prim (an Xform), not a {prim.GetTypeName() or 'typeless prim'}")
            return
        try:
            T = self.matrix(prim)
            pos = T[:3, 3][[0, 2]]
            fwd = T[:3, :3] @ self.forward
            if math.hypot(fwd[0], fwd[2]) <= 1e-9 * max(1.0, float(np.abs(T[:3, :3]).max())):
                raise GeometryError("its forward axis is vertical, so it has no heading")
            heading = math.atan2(fwd[0], fwd[2])
            poly = self.region_polygon(prim, T) if role == "region" else None
        except GeometryError as e:
            self.error(prim, f"{role} marker: {e}")
            return
        path = str(prim.GetPath())
        self.markers.append(Marker(path, role, pos, heading, poly))
        area = None if poly is None else abs(polygon_area(poly))
        self.found.append(WorldItem(path, role, "polygon" if poly is not None else "point", pos.copy(), area, heading))

    # -- traversal ------------------------------------------------------------------------------
    def visit(self, prim, in_obstacles: bool, in_marker: bool):
        path = str(prim.GetPath())
        if path in self.scopes:
            in_obstacles = True
        try:
            role = None if prim.IsPseudoRoot() else _role(prim)
        except ValueError as e:
            self.error(prim, str(e))
            role = "<invalid>"
        is_gprim = prim.IsA(UsdGeom.Gprim)
        own_obstacle_scope = False
        if role is None:
            if is_gprim and in_obstacles and not in_marker:
                self.add_obstacle(prim)
            elif in_obstacles and not in_marker and prim.IsA(UsdGeom.Boundable):
                self.warn(prim, f"{prim.GetTypeName()} is not a supported obstacle type ({SUPPORTED}); not used")
        elif role == "<invalid>":
            pass
        elif role not in ROLES:
            self.error(prim, f"unknown {ROLE_ATTR} {role!r} (expected one of {', '.join(ROLES)})")
        elif role == "obstacle":
            if is_gprim:
                self.add_obstacle(prim)
            else:
                own_obstacle_scope = True
                n_before = len(self.issues), len(self.found)
                in_obstacles, in_marker = True, False
        else:
            self.add_marker(prim, role)
            in_marker = True
        for child in prim.GetFilteredChildren(self.pred):
            self.visit(child, in_obstacles, in_marker)
        if own_obstacle_scope:
            added = any(it.role == "obstacle" for it in self.found[n_before[1]:])
            tried = any(i.path.startswith(path + "/") for i in self.issues[n_before[0]:])
            if not added and not tried:
                self.error(prim, f"role 'obstacle' on a {prim.GetTypeName() or 'typeless prim'} with no geometry under it")

    def environment(self) -> Environment:
        return Environment(self.polys, np.array(self.circles).reshape(-1, 3), self.markers,
                           self.poly_paths + self.circle_paths)


_ASSET = re.compile(r"@([^@]*)@")


def _composition_issues(stage, path: str) -> list:
    """Errors USD met composing the stage (a referenced or sublayered file that is missing or
    unreadable, a reference to a prim that does not exist...): USD only warns and composes
    without the arc, so the world would silently lack what the file held. One issue per
    error, on the prim that introduces the arc (the stage for a sublayer)."""
    out = []
    for e in stage.GetCompositionErrors():
        msg = " ".join(str(e).split())
        site = getattr(e, "rootSite", None)
        prim = str(site.path) if site is not None and not site.path.isEmpty and site.path != Sdf.Path.absoluteRootPath \
            else path
        if type(e).__name__ in ("ErrorInvalidAssetPath", "ErrorInvalidSublayerPath", "ErrorMutedAssetPath"):
            assets = _ASSET.findall(msg)
            missing = assets[0] if assets else "?"
            where = "sublayer" if "Sublayer" in type(e).__name__ else "referenced file"
            reason = f"{where} not found or unreadable: {missing}"
        else:
            reason = f"composition error: {msg[:300]}"
        out.append(WorldIssue(prim, reason, error=True))
    return out


def read_world_report(path):
    """Read a world stage, collecting problems instead of stopping at the first.

    Returns ``(env, found, skipped)``: the :class:`Environment` of every usable prim, the list
    of :class:`WorldItem` used (obstacles with footprint areas, markers), and the list of
    :class:`WorldIssue` (prims not used, with the reason; ``error`` False for warnings).
    Raises :class:`WorldError` only when the file itself cannot be read.
    """
    return _stage_report(_open(path), str(path))


def _stage_report(stage, path: str):
    r = _Reader(stage, path)
    r.issues.extend(_composition_issues(stage, path))
    r.visit(stage.GetPseudoRoot(), False, False)
    if not r.found and not any(i.error for i in r.issues):
        r.issues.append(WorldIssue(path, f"found no obstacles and no markers (obstacles go under {OBSTACLES_PATH} "
                                   f"or carry {ROLE_ATTR} = \"obstacle\")", error=False))
    return r.environment(), r.found, r.issues


def read_world(path) -> Environment:
    """The :class:`Environment` of a world stage; :class:`WorldError` (naming the file and the
    first offending prim, and how many more problems there are) if anything in it is unusable."""
    return _usable(path, read_world_report(path))


def read_world_stage(stage: Usd.Stage, name: str = "<stage>") -> Environment:
    """:func:`read_world` of a stage already open (e.g. one built in memory); ``name`` stands
    for the file in error messages."""
    return _usable(name, _stage_report(stage, name))


def _usable(path, report) -> Environment:
    env, _, issues = report
    errors = [i for i in issues if i.error]
    if errors:
        first = errors[0]
        more = f" (and {len(errors) - 1} more problem{'s' if len(errors) > 2 else ''}; run `crowdweave world check`)" \
            if len(errors) > 1 else ""
        prim = first.path if first.path != str(path) else None
        raise WorldError(path, first.reason + more, prim=prim, issues=errors)
    return env


def read_world_units(path):
    """(metersPerUnit, upAxis) of a world stage, as authored (defaults 1.0 and "Y")."""
    st = Usd.Stage.Open(str(path))
    mpu = UsdGeom.GetStageMetersPerUnit(st) if st.HasAuthoredMetadata("metersPerUnit") else 1.0
    up = UsdGeom.GetStageUpAxis(st) if st.HasAuthoredMetadata("upAxis") else "Y"
    return float(mpu), str(up)
