"""Writes samples/plaza/world.usda and scenario.toml (deterministic). Run from the repository
root: ``.venv/bin/python samples/plaza/make_plaza.py``."""
import math
from pathlib import Path

from pxr import Gf, Sdf, Usd, UsdGeom

HERE = Path(__file__).resolve().parent


def marker(stage, path, role, x, z, heading_deg):
    xf = UsdGeom.Xform.Define(stage, path)
    xf.AddTranslateOp().Set(Gf.Vec3d(x, 0, z))
    xf.AddRotateYOp().Set(heading_deg)
    xf.GetPrim().CreateAttribute("crowdweave:role", Sdf.ValueTypeNames.String).Set(role)


ZONE = (14.0, 24.0, -5.0, 5.0)     # x0, x1, z0, z1 of the tiled interaction zone's fence
# where the ambient people walk: inside the sky region's bounds, with no obstacle added, so the
# square's roadmap (and with it the bake of the named characters) stays what it was
AMBIENT = (-34.0, -34.0, 44.0, 34.0)   # x0, z0, x1, z1
AMBIENT_COUNT = 300
STALL_X = (-27.0, -16.0, -5.0, 6.0, 17.0, 28.0)   # market pitches (a crate each) along the north and south
STALL_Z = 30.0
# benches of three seats (x, z, heading the sitters face, degrees)
BENCHES = [(-24.0, -8.0, 90.0), (-24.0, 8.0, 90.0), (24.0, -16.0, -90.0), (24.0, 16.0, -90.0),
           (-8.0, -18.0, 0.0), (8.0, 18.0, 180.0), (-8.0, 18.0, 180.0), (8.0, -18.0, 0.0),
           (-30.0, 0.0, 90.0), (30.0, 0.0, -90.0)]


def region(stage, path, x0, z0, x1, z1):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr([(x0, 0, z0), (x1, 0, z0), (x1, 0, z1), (x0, 0, z1)])
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    m.CreateVisibilityAttr("invisible")
    m.GetPrim().CreateAttribute("crowdweave:role", Sdf.ValueTypeNames.String).Set("region")


def world():
    stage = Usd.Stage.CreateNew(str(HERE / "world.usda"))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    w = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(w.GetPrim())
    UsdGeom.Scope.Define(stage, "/World/Obstacles")
    f = UsdGeom.Cylinder.Define(stage, "/World/Obstacles/fountain")
    f.CreateRadiusAttr(1.6)
    f.CreateHeightAttr(0.8)
    f.CreateAxisAttr("Y")
    UsdGeom.Xformable(f).AddTranslateOp().Set(Gf.Vec3d(0, 0.4, 0))
    for i, (x, z) in enumerate([(-7, -7), (7, -7), (-7, 7), (7, 7)]):
        c = UsdGeom.Cube.Define(stage, f"/World/Obstacles/planter{i}")
        c.CreateSizeAttr(1.0)
        xf = UsdGeom.Xformable(c)
        xf.AddTranslateOp().Set(Gf.Vec3d(x, 0.3, z))
        xf.AddRotateYOp().Set(20.0 * i)
        xf.AddScaleOp().Set(Gf.Vec3f(2.0, 0.6, 1.2))
    kiosk = UsdGeom.Cube.Define(stage, "/World/Obstacles/kiosk")
    kiosk.CreateSizeAttr(1.0)
    UsdGeom.Xformable(kiosk).AddTranslateOp().Set(Gf.Vec3d(10.5, 1.0, 0))
    UsdGeom.Xformable(kiosk).AddScaleOp().Set(Gf.Vec3f(1.4, 2.0, 3.0))
    # the tiled interaction zone east of the kiosk: a low fence (an obstacle for the crowd's
    # roadmap: the crowd planner does not see tiled characters) around a region marker
    x0, x1, z0, z1 = ZONE
    for name, (cx, cz, sx, sz) in {"fenceW": (x0, 0.5 * (z0 + z1), 0.2, z1 - z0 + 0.2),
                                   "fenceE": (x1, 0.5 * (z0 + z1), 0.2, z1 - z0 + 0.2),
                                   "fenceS": (0.5 * (x0 + x1), z0, x1 - x0 + 0.2, 0.2),
                                   "fenceN": (0.5 * (x0 + x1), z1, x1 - x0 + 0.2, 0.2)}.items():
        c = UsdGeom.Cube.Define(stage, f"/World/Obstacles/{name}")
        c.CreateSizeAttr(1.0)
        UsdGeom.Xformable(c).AddTranslateOp().Set(Gf.Vec3d(cx, 0.3, cz))
        UsdGeom.Xformable(c).AddScaleOp().Set(Gf.Vec3f(sx, 0.6, sz))
    UsdGeom.Scope.Define(stage, "/World/Regions")
    region(stage, "/World/Regions/stage", x0 + 0.35, z0 + 0.35, x1 - 0.35, z1 - 0.35)
    region(stage, "/World/Regions/sky", -35.0, -35.0, 45.0, 35.0)
    region(stage, "/World/Regions/ambient", *AMBIENT)
    UsdGeom.Scope.Define(stage, "/World/Seats")
    # benches on a ring around the fountain, sitters facing out
    for i in range(8):
        a = 2 * math.pi * (i + 0.5) / 8
        r = 4.2
        marker(stage, f"/World/Seats/s{i:02d}", "seat", r * math.sin(a), r * math.cos(a), math.degrees(a))
    for b, (x, z, h) in enumerate(BENCHES):
        r = math.radians(h)
        for k in (-1, 0, 1):       # seats 1.4 m apart along the bench
            marker(stage, f"/World/Seats/bench{b}_{k + 1}", "seat", x + 1.4 * k * math.cos(r), z - 1.4 * k * math.sin(r), h)
    UsdGeom.Scope.Define(stage, "/World/Boxes")
    for i in range(4):
        marker(stage, f"/World/Boxes/b{i}", "box", 7.6, -2.4 + 1.6 * i, -90.0)   # 2.2 m off the kiosk: room to turn round carrying
    for i, x in enumerate(STALL_X):      # a crate at each market pitch, carried from pitch to pitch
        marker(stage, f"/World/Boxes/stall_n{i}", "box", x, STALL_Z, 180.0)
        marker(stage, f"/World/Boxes/stall_s{i}", "box", x, -STALL_Z, 0.0)
    UsdGeom.Scope.Define(stage, "/World/Spawns")
    for i in range(4):
        a = 2 * math.pi * i / 4
        marker(stage, f"/World/Spawns/p{i}", "spawn", 11 * math.sin(a), 11 * math.cos(a), math.degrees(a) + 180)
    stage.GetRootLayer().Save()


def scenario():
    lines = ['name = "plaza"',
             'description = "The product at a glance: people walk to benches and sit, meet in pairs, fetch boxes from '
             'a kiosk; two teams meet and greet in a tiled interaction zone; birds flock overhead"',
             'world = "world.usda"', 'library = "default"', 'duration = 45.0', 'seed = 0', '']

    def char(name, x, z, h, goals):
        lines.append("[[character]]")
        lines.append(f'name = "{name}"')
        lines.append(f"start = {{ position = [{x:.2f}, {z:.2f}], heading = {h:.1f}, pose = \"stand\" }}")
        for g in goals:
            lines.append("  [[character.goal]]")
            for k, v in g.items():
                lines.append(f"  {k} = {v}")
        lines.append("")

    # sitters come in from the edges
    # (benches 1-6: none comes from the north-east, where the box movers start)
    for i in range(6):
        a = 2 * math.pi * (i + 1.5) / 8
        x, z = 13.0 * math.sin(a + 0.4), 13.0 * math.cos(a + 0.4)      # clear of the planters and the kiosk
        char(f"sitter{i}", x, z, math.degrees(a) + 180, [{"seat": f'"/World/Seats/s{i + 1:02d}"'}])
    # two pairs meet, face to face, at the same moment
    for k, (cx, cz) in enumerate([(-5.0, 0.0), (0.0, -6.0)]):
        for s in (-1, 1):
            x, z = cx + s * 6.0, cz + 6.0 * (1 if k else -1)
            gx = cx + s * 0.6 if k == 0 else cx
            gz = cz if k == 0 else cz + s * 0.6
            h = -90.0 * s if k == 0 else (180.0 if s > 0 else 0.0)
            char(f"meet{k}{'ab'[s > 0]}", x, z, 0.0,
                 [{"position": f"[{gx:.2f}, {gz:.2f}]", "heading": f"{h:.1f}", "pose": '"stand"', "time": "[16.0, 16.5]"}])
    # box movers: pick a box at the kiosk, put it down by the benches
    for i in range(3):
        char(f"mover{i}", 4.0 + 1.5 * i, 10.5, 180.0,     # 1.5 m clear of planter3 (at 9.0 mover2 faced it 0.8 m away)
             [{"box": f'"/World/Boxes/b{i}"'},
              {"position": f"[{-2.0 + 2.0 * i:.2f}, 9.5]", "heading": "0.0", "pose": '"stand"'}])
    # the tiled interaction zone: two teams of four swap ends and meet in the middle
    x0, x1, z0, z1 = ZONE
    cx, cz = 0.5 * (x0 + x1), 0.5 * (z0 + z1)
    lines += ["[[tiling]]", 'name = "stage"', 'zone = "/World/Regions/stage"', 'patches = "synthetic"',
              "period = 8.0", "seed = 0", ""]
    for k, s in enumerate((-1, 1)):
        sx = cx + s * 3.0
        lines += ["  [[tiling.team]]", "  count = 4", f"  start = [{sx:.2f}, {cz:.2f}]",
                  f"  heading = {-90.0 * s:.1f}",
                  f"  targets = [[{cx - s * 3.0:.2f}, {cz:.2f}], [{cx + s * 0.9:.2f}, {cz + s * 1.0:.2f}], "
                  f"[{cx + s * 3.0:.2f}, {cz:.2f}]]", ""]
    # a flock of birds over the plaza (the same recording recipe as samples/flock_region_3d)
    lines += ["[[flock]]", 'name = "birds"', "ddg = { dim = 3, agents = 20, seconds = 150.0, seed = 1 }", "count = 2",
              'region = "/World/Regions/sky"', "altitude = [6.0, 40.0]", ""]
    # people going about their day all over the square (runtime.world.ambient)
    lines += ["[ambient]", f"count = {AMBIENT_COUNT}", "seed = 0", 'region = "/World/Regions/ambient"',
              "linger = [20.0, 50.0]", ""]
    (HERE / "scenario.toml").write_text("\n".join(lines))


if __name__ == "__main__":
    world()
    scenario()
