"""Reading world stages: footprints in world space, markers, units (a Z-up centimetre twin),
instancing, every error naming the prim or file, and `crowdweave world check`."""
import json
import math
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from runtime.crowd.geometry import polygon_area
from usd_io.world import WorldError, read_world, read_world_report

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "samples" / "example_world" / "world.usda"


# -- building stages: a Y-up metre spec, authored natively or as its Z-up centimetre twin ---------

# the twin's coordinates are C p with C = 100 * R, R taking Y-up to Z-up: (x, y, z) -> (x, -z, y)
_R = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])


def _add_ops(xf, ops, twin):
    for kind, v in ops:
        if kind == "t":
            xf.AddTranslateOp().Set(Gf.Vec3d(*((100.0 * _R @ np.array(v, float)) if twin else v)))
        elif kind == "s":
            sx, sy, sz = v
            xf.AddScaleOp().Set(Gf.Vec3f(*((sx, sz, sy) if twin else (sx, sy, sz))))
        elif kind == "rx":
            xf.AddRotateXOp().Set(v)
        elif kind == "ry":
            (xf.AddRotateZOp() if twin else xf.AddRotateYOp()).Set(v)
        elif kind == "rz":
            (xf.AddRotateYOp() if twin else xf.AddRotateZOp()).Set(-v if twin else v)


_AXIS_TWIN = {"X": "X", "Y": "Z", "Z": "Y"}  # a symmetric shape along R @ axis

ROCK = np.random.default_rng(4).normal(size=(30, 3)) * [0.5, 0.3, 0.4]

SPEC = [
    # (path, type, ops, params)
    ("/World/Obstacles/Group", "Xform", [("t", (2, 0, 1)), ("ry", 30.0), ("s", (1.5, 1, 0.8))], {}),
    ("/World/Obstacles/Group/Sub", "Xform", [("t", (1, 0.5, 0)), ("rx", 20.0), ("rz", 10.0)], {}),
    ("/World/Obstacles/Group/Sub/Box", "Cube", [("s", (1, 2, 0.5))], {"size": 0.8}),
    ("/World/Obstacles/Group/Sub/Pipe", "Cylinder", [("t", (0, 0, 1))], {"radius": 0.2, "height": 2.0, "axis": "Z"}),
    ("/World/Obstacles/Group/Sub/Cap", "Capsule", [("t", (0, 0, -1.5))], {"radius": 0.25, "height": 0.5, "axis": "X"}),
    ("/World/Obstacles/Group/Sub/Ball", "Sphere", [("t", (-1, 0, 0))], {"radius": 0.4}),
    ("/World/Obstacles/Group/Sub/Rock", "Mesh", [("t", (0, 0, 2.5)), ("ry", 15.0)], {"points": ROCK}),
    ("/World/Obstacles/Post", "Cylinder", [("t", (-3, 1, -2))], {"radius": 0.3, "height": 2.0, "axis": "Y"}),
    ("/World/Obstacles/Bollard", "Capsule", [("t", (-4, 1, 3)), ("s", (2, 2, 2))], {"radius": 0.2, "height": 0.5, "axis": "Y"}),
    ("/World/Obstacles/Cone", "Cone", [("t", (4, 0.5, -4)), ("rx", 60.0)], {"radius": 0.5, "height": 1.0, "axis": "Y"}),
    ("/World/Props", "Xform", [], {}),
    ("/World/Props/Tilted", "Cube", [("t", (5, 0.5, 5)), ("rz", 35.0), ("ry", 10.0)], {"size": 1.0, "role": "obstacle"}),
    ("/World/Seats", "Xform", [("t", (0, 0, -1))], {}),
    ("/World/Seats/s1", "Xform", [("t", (1, 0, -2)), ("ry", 120.0)], {"role": "seat"}),
    ("/World/Regions/r1", "Xform", [("t", (0, 0, 5)), ("ry", -30.0)], {"role": "region", "extent": (4.0, 2.0)}),
]


def build_stage(path, spec=SPEC, twin=False, units=True):
    stage = Usd.Stage.CreateNew(str(path))
    if units:
        UsdGeom.SetStageMetersPerUnit(stage, 0.01 if twin else 1.0)
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if twin else UsdGeom.Tokens.y)
    UsdGeom.Xform.Define(stage, "/World")
    s = 100.0 if twin else 1.0
    for prim_path, typ, ops, params in spec:
        schema = getattr(UsdGeom, typ).Define(stage, prim_path)
        _add_ops(schema, ops, twin)
        prim = schema.GetPrim()
        for k, v in params.items():
            if k == "size":
                schema.GetSizeAttr().Set(v * s)
            elif k == "radius":
                schema.GetRadiusAttr().Set(v * s)
            elif k == "height":
                schema.GetHeightAttr().Set(v * s)
            elif k == "axis":
                schema.GetAxisAttr().Set(_AXIS_TWIN[v] if twin else v)
            elif k == "points":
                p = (s * (np.asarray(v) @ _R.T)) if twin else np.asarray(v)
                schema.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(p.astype(np.float32)))
            elif k == "role":
                prim.CreateAttribute("crowdweave:role", Sdf.ValueTypeNames.String, custom=True).Set(v)
            elif k == "extent":
                prim.CreateAttribute("crowdweave:extent", Sdf.ValueTypeNames.Float2, custom=True).Set(Gf.Vec2f(v[0] * s, v[1] * s))
    stage.GetRootLayer().Save()
    return Path(path)


def _probe(env, n=4000, seed=0):
    x0, z0, x1, z1 = env.bounds(1.0)
    return np.random.default_rng(seed).uniform((x0, z0), (x1, z1), size=(n, 2))


# -- the Z-up centimetre twin ------------------------------------------------------------------

def test_zup_centimetre_twin_imports_to_the_same_footprints(tmp_path):
    a = read_world(build_stage(tmp_path / "yup_m.usda"))
    b = read_world(build_stage(tmp_path / "zup_cm.usda", twin=True))
    assert a.obstacle_paths == b.obstacle_paths
    assert len(a.polygons) == len(b.polygons) == 7 and len(a.circles) == len(b.circles) == 2
    np.testing.assert_allclose(b.circles, a.circles, atol=1e-9)
    for pa, pb in zip(a.polygons, b.polygons):
        assert math.isclose(polygon_area(pa), polygon_area(pb), rel_tol=1e-6)
        # the same set of vertices (up to where the hull starts); float32 mesh points in cm differ slightly
        assert len(pa) == len(pb)
        d = np.linalg.norm(pa[:, None, :] - pb[None, :, :], axis=-1)
        assert d.min(axis=1).max() < 1e-6
    p = _probe(a)
    np.testing.assert_allclose(b.distance(p), a.distance(p), atol=1e-6)
    for path, ma in a.markers.items():
        mb = b.markers[path]
        assert ma.role == mb.role
        np.testing.assert_allclose(mb.position, ma.position, atol=1e-9)
        assert math.isclose(mb.heading, ma.heading, abs_tol=1e-9)
        if ma.polygon is not None:
            np.testing.assert_allclose(polygon_area(mb.polygon), polygon_area(ma.polygon), rtol=1e-9)


def test_known_values_in_the_yup_stage(tmp_path):
    env = read_world(build_stage(tmp_path / "w.usda"))
    paths = env.obstacle_paths
    P = len(env.polygons)
    post = env.circles[paths.index("/World/Obstacles/Post") - P]
    np.testing.assert_allclose(post, [-3, -2, 0.3], atol=1e-12)
    bollard = env.circles[paths.index("/World/Obstacles/Bollard") - P]
    np.testing.assert_allclose(bollard, [-4, 3, 0.4], atol=1e-12)  # uniform scale 2
    seat = env.markers["/World/Seats/s1"]
    np.testing.assert_allclose(seat.position, [1, -3], atol=1e-12)  # nested translate
    assert math.isclose(seat.heading, math.radians(120), abs_tol=1e-9)
    region = env.markers["/World/Regions/r1"]
    assert math.isclose(polygon_area(region.polygon), 8.0, rel_tol=1e-9)
    np.testing.assert_allclose(region.polygon.mean(axis=0), [0, 5], atol=1e-9)
    tilted = env.polygons[paths.index("/World/Props/Tilted")]
    # local rotation Rz(35) Ry(10): a unit cube's shadow along the world up direction has area
    # |n|_1, n = the up direction in the cube's frame = Ry^T Rz^T e_y
    s35, c35 = math.sin(math.radians(35)), math.cos(math.radians(35))
    s10, c10 = math.sin(math.radians(10)), math.cos(math.radians(10))
    assert math.isclose(polygon_area(tilted), s35 * c10 + c35 + s35 * s10, rel_tol=1e-9)


def test_footprints_agree_with_usd_bounding_boxes(tmp_path):
    """Independent check with UsdGeom.BBoxCache: each footprint's x/z range lies inside the
    world-aligned bound of the prim (USD transforms the local box, which is looser), and equals
    it for cubes and upright round footprints, where the transformed local box is tight."""
    path = build_stage(tmp_path / "w.usda")
    env = read_world(path)
    stage = Usd.Stage.Open(str(path))
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_], useExtentsHint=False)
    P = len(env.polygons)
    for i, prim_path in enumerate(env.obstacle_paths):
        prim = stage.GetPrimAtPath(prim_path)
        rng = cache.ComputeWorldBound(prim).ComputeAlignedRange()
        lo, hi = np.array(rng.GetMin())[[0, 2]], np.array(rng.GetMax())[[0, 2]]
        if i < P:
            poly = env.polygons[i]
            flo, fhi = poly.min(axis=0), poly.max(axis=0)
        else:
            x, z, r = env.circles[i - P]
            flo, fhi = np.array([x - r, z - r]), np.array([x + r, z + r])
        assert np.all(flo >= lo - 1e-6) and np.all(fhi <= hi + 1e-6), prim_path
        if prim.GetTypeName() == "Cube" or i >= P:
            np.testing.assert_allclose(flo, lo, atol=1e-6, err_msg=prim_path)
            np.testing.assert_allclose(fhi, hi, atol=1e-6, err_msg=prim_path)


# -- the example stage ---------------------------------------------------------------------------

def test_example_world():
    env, found, issues = read_world_report(EXAMPLE)
    assert issues == []
    assert len(env.polygons) == 7 and len(env.circles) == 2
    assert {m.role for m in env.markers.values()} == {"seat", "box", "spawn", "region"}
    assert len(env.markers_with_role("seat")) == 4
    # geometry under a marker is the marker's own, not an obstacle; the ground mesh is ignored
    assert "/World/Seats/s01/Chair" not in env.obstacle_paths
    assert "/World/Boxes/b02" not in env.obstacle_paths and "/World/Ground" not in env.obstacle_paths
    assert "/World/Props/Crate" in env.obstacle_paths  # role "obstacle" outside /World/Obstacles
    area = {f.path: f.area for f in found if f.role == "obstacle"}
    assert math.isclose(area["/World/Obstacles/Table"], 2.0, rel_tol=1e-12)
    assert math.isclose(area["/World/Obstacles/Log"], 2.5 * 0.4, rel_tol=1e-12)
    assert math.isclose(area["/World/Obstacles/Shelving/Unit/Left"], 0.4 * 1.5, rel_tol=1e-6)
    assert math.isclose(env.markers["/World/Seats/s03"].heading, math.pi, abs_tol=1e-9) or \
        math.isclose(env.markers["/World/Seats/s03"].heading, -math.pi, abs_tol=1e-9)
    assert math.isclose(np.ptp(env.markers["/World/Regions/Plaza"].polygon[:, 0]), 6.0)
    # every seat is in free space with room for a character
    seats = np.array([m.position for m in env.markers_with_role("seat")])
    assert np.all(env.distance(seats) > 0.35)
    # nested transform: the shelving unit's left board centre, computed by hand
    c45 = math.cos(math.radians(45))
    local = np.array([-0.6, 0.0 + 1.0])  # (x, z) in Shelving: Unit scales (z = 0 stays 0), then translates z by 1
    expect = np.array([6 + c45 * local[0] + c45 * local[1], -c45 * local[0] + c45 * local[1]])
    left = env.polygons[env.obstacle_paths.index("/World/Obstacles/Shelving/Unit/Left")]
    np.testing.assert_allclose(left.mean(axis=0), expect, atol=1e-6)


def test_instanced_obstacles_are_read(tmp_path):
    stage = Usd.Stage.CreateNew(str(tmp_path / "inst.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    proto = UsdGeom.Xform.Define(stage, "/Protos/Rock")
    UsdGeom.Cube.Define(stage, "/Protos/Rock/Geo").GetSizeAttr().Set(1.0)
    stage.GetPrimAtPath("/Protos").SetSpecifier(Sdf.SpecifierClass)
    for i, x in enumerate((0.0, 3.0)):
        xf = UsdGeom.Xform.Define(stage, f"/World/Obstacles/Rock{i}")
        xf.AddTranslateOp().Set(Gf.Vec3d(x, 0, 0))
        xf.GetPrim().GetReferences().AddInternalReference(proto.GetPath())
        xf.GetPrim().SetInstanceable(True)
    stage.GetRootLayer().Save()
    env = read_world(tmp_path / "inst.usda")
    assert env.obstacle_paths == ["/World/Obstacles/Rock0/Geo", "/World/Obstacles/Rock1/Geo"]
    np.testing.assert_allclose([p.mean(axis=0) for p in env.polygons], [[0, 0], [3, 0]], atol=1e-12)


def test_unauthored_units_read_as_metres_with_a_warning(tmp_path):
    path = build_stage(tmp_path / "nounits.usda", spec=SPEC[7:8], units=False)
    env, found, issues = read_world_report(path)
    np.testing.assert_allclose(env.circles, [[-3, -2, 0.3]])
    assert any("metersPerUnit" in i.reason and not i.error for i in issues)
    read_world(path)  # warnings do not stop reading


# -- errors name the prim or the file ------------------------------------------------------------

def _bad(tmp_path, name, make):
    stage = Usd.Stage.CreateNew(str(tmp_path / f"{name}.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.Xform.Define(stage, "/World/Obstacles")
    UsdGeom.Cube.Define(stage, "/World/Obstacles/Fine")  # a good obstacle beside the bad prim
    make(stage)
    stage.GetRootLayer().Save()
    return tmp_path / f"{name}.usda"


def _role(prim, value, typ=Sdf.ValueTypeNames.String):
    prim.CreateAttribute("crowdweave:role", typ, custom=True).Set(value)


BAD_CASES = {
    "unknown_role": ("/World/Props/Chair", "unknown crowdweave:role 'chair'",
                     lambda s: _role(UsdGeom.Xform.Define(s, "/World/Props/Chair").GetPrim(), "chair")),
    "role_not_string": ("/World/Props/Thing", "must be a string",
                        lambda s: _role(UsdGeom.Xform.Define(s, "/World/Props/Thing").GetPrim(), 3, Sdf.ValueTypeNames.Int)),
    "mesh_no_points": ("/World/Obstacles/Wall", "mesh has no points",
                       lambda s: UsdGeom.Mesh.Define(s, "/World/Obstacles/Wall")),
    "mesh_zero_area": ("/World/Obstacles/Wall", "zero footprint area",
                       lambda s: UsdGeom.Mesh.Define(s, "/World/Obstacles/Wall").GetPointsAttr().Set(
                           Vt.Vec3fArray([(0, 0, 0), (2, 0, 0), (2, 3, 0), (0, 3, 0)]))),
    "negative_radius": ("/World/Obstacles/Post", "radius is negative",
                        lambda s: UsdGeom.Cylinder.Define(s, "/World/Obstacles/Post").GetRadiusAttr().Set(-0.5)),
    "negative_size": ("/World/Obstacles/Box", "size is negative",
                      lambda s: UsdGeom.Cube.Define(s, "/World/Obstacles/Box").GetSizeAttr().Set(-1.0)),
    "zero_radius_sphere": ("/World/Obstacles/Ball", "zero footprint area",
                           lambda s: UsdGeom.Sphere.Define(s, "/World/Obstacles/Ball").GetRadiusAttr().Set(0.0)),
    "flattened_cube": ("/World/Obstacles/Flat", "zero footprint area",
                       lambda s: UsdGeom.Cube.Define(s, "/World/Obstacles/Flat").AddScaleOp().Set(Gf.Vec3f(1, 1, 0))),
    "bad_axis": ("/World/Obstacles/Pipe", "axis",
                 lambda s: UsdGeom.Cylinder.Define(s, "/World/Obstacles/Pipe").GetAxisAttr().Set("W")),
    "role_on_scope": ("/World/Seats", "needs a transformable prim",
                      lambda s: _role(UsdGeom.Scope.Define(s, "/World/Seats").GetPrim(), "seat")),
    "region_without_outline": ("/World/Zone", "needs an outline",
                               lambda s: _role(UsdGeom.Xform.Define(s, "/World/Zone").GetPrim(), "region")),
    "obstacle_role_without_geometry": ("/World/Empty", "no geometry",
                                       lambda s: _role(UsdGeom.Xform.Define(s, "/World/Empty").GetPrim(), "obstacle")),
}


@pytest.mark.parametrize("case", sorted(BAD_CASES))
def test_bad_prims_raise_world_error_naming_the_prim(tmp_path, case):
    prim, reason, make = BAD_CASES[case]
    path = _bad(tmp_path, case, make)
    with pytest.raises(WorldError) as ei:
        read_world(path)
    msg = str(ei.value)
    assert prim in msg and reason in msg and path.name in msg
    assert ei.value.prim == prim
    # the report lists the bad prim as an error and still reads the good obstacle
    env, found, issues = read_world_report(path)
    assert [i.path for i in issues if i.error] == [prim]
    assert "/World/Obstacles/Fine" in env.obstacle_paths


def test_all_errors_are_collected(tmp_path):
    def make(s):
        for case in ("unknown_role", "mesh_no_points", "negative_radius"):
            BAD_CASES[case][2](s)
    path = _bad(tmp_path, "many", make)
    _, _, issues = read_world_report(path)
    assert sorted(i.path for i in issues if i.error) == ["/World/Obstacles/Post", "/World/Obstacles/Wall", "/World/Props/Chair"]
    with pytest.raises(WorldError, match="and 2 more problems"):
        read_world(path)


def test_file_errors_name_the_file(tmp_path):
    with pytest.raises(WorldError, match="nope.usda: file not found"):
        read_world(tmp_path / "nope.usda")
    txt = tmp_path / "world.txt"
    txt.write_text("hello")
    with pytest.raises(WorldError, match="world.txt: not a USD file"):
        read_world(txt)
    junk = tmp_path / "junk.usda"
    junk.write_text("this is not usd {")
    with pytest.raises(WorldError, match="junk.usda: not a readable USD file"):
        read_world(junk)
    with pytest.raises(WorldError, match="not a file"):
        read_world(tmp_path)


# -- crowdweave world check --------------------------------------------------------------------

def test_world_check_cli(tmp_path, capsys):
    from authoring.cli import main
    assert main(["world", "check", str(EXAMPLE)]) == 0
    out = capsys.readouterr().out
    assert "/World/Obstacles/Table: polygon, 2.000 m^2" in out
    assert "4 seat" in out and "usable: yes" in out
    bad = _bad(tmp_path, "bad", lambda s: (BAD_CASES["unknown_role"][2](s), BAD_CASES["mesh_zero_area"][2](s)))
    assert main(["world", "check", str(bad)]) == 2
    out = capsys.readouterr().out
    assert "ERROR /World/Props/Chair: unknown crowdweave:role 'chair'" in out
    assert "ERROR /World/Obstacles/Wall: Mesh obstacle: zero footprint area" in out
    assert "/World/Obstacles/Fine: polygon" in out and "usable: no" in out
    assert main(["world", "check", "--json", str(bad)]) == 2
    d = json.loads(capsys.readouterr().out)
    assert d["usable"] is False and {x["path"] for x in d["not_used"]} == {"/World/Props/Chair", "/World/Obstacles/Wall"}
    assert main(["world", "check", str(tmp_path / "missing.usda")]) == 2
    assert "missing.usda: file not found" in capsys.readouterr().out


def test_obstacles_under_the_default_prim_of_a_dcc_export(tmp_path):
    stage = Usd.Stage.CreateNew(str(tmp_path / "root.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    root = UsdGeom.Xform.Define(stage, "/root")
    stage.SetDefaultPrim(root.GetPrim())
    UsdGeom.Cube.Define(stage, "/root/Obstacles/c")
    UsdGeom.Cube.Define(stage, "/root/Decor/d")  # not an obstacle
    stage.GetRootLayer().Save()
    env, found, issues = read_world_report(tmp_path / "root.usda")
    assert env.obstacle_paths == ["/root/Obstacles/c"] and issues == []
    empty = Usd.Stage.CreateNew(str(tmp_path / "empty.usda"))
    UsdGeom.Xform.Define(empty, "/World")
    empty.GetRootLayer().Save()
    env, found, issues = read_world_report(tmp_path / "empty.usda")
    assert env.num_obstacles == 0 and any("found no obstacles" in i.reason and not i.error for i in issues)


def test_missing_referenced_file_is_an_error_naming_the_prim_and_file(tmp_path):
    """A reference to a file that is not there composes (USD only warns) to a prim without its
    geometry: the reader reports it as an error on the referencing prim, naming the file."""
    def make(s):
        crate = UsdGeom.Xform.Define(s, "/World/Obstacles/Crate").GetPrim()
        crate.GetReferences().AddReference("./props/crate_missing.usda")
    path = _bad(tmp_path, "missing_ref", make)
    with pytest.raises(WorldError) as ei:
        read_world(path)
    msg = str(ei.value)
    assert "crate_missing.usda" in msg and "/World/Obstacles/Crate" in msg and path.name in msg
    env, _, issues = read_world_report(path)
    errs = [i for i in issues if i.error]
    assert [i.path for i in errs] == ["/World/Obstacles/Crate"]
    assert "referenced file not found" in errs[0].reason
    assert "/World/Obstacles/Fine" in env.obstacle_paths
    # the same reference to a file that exists is fine
    (tmp_path / "props").mkdir()
    ref = Usd.Stage.CreateNew(str(tmp_path / "props" / "crate_missing.usda"))
    UsdGeom.Xform.Define(ref, "/Crate")
    UsdGeom.Cube.Define(ref, "/Crate/Box")
    ref.SetDefaultPrim(ref.GetPrimAtPath("/Crate"))
    ref.GetRootLayer().Save()
    env = read_world(path)
    assert "/World/Obstacles/Crate/Box" in env.obstacle_paths
