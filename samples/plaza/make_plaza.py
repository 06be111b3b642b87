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
    UsdGeom.Scope.Define(stage, "/World/Seats")
    # benches on a ring around the fountain, sitters facing out
    for i in range(8):
        a = 2 * math.pi * (i + 0.5) / 8
        r = 4.2
        marker(stage, f"/World/Seats/s{i:02d}", "seat", r * math.sin(a), r * math.cos(a), math.degrees(a))
    UsdGeom.Scope.Define(stage, "/World/Boxes")
    for i in range(4):
        marker(stage, f"/World/Boxes/b{i}", "box", 8.6, -2.4 + 1.6 * i, -90.0)
    UsdGeom.Scope.Define(stage, "/World/Spawns")
    for i in range(4):
        a = 2 * math.pi * i / 4
        marker(stage, f"/World/Spawns/p{i}", "spawn", 11 * math.sin(a), 11 * math.cos(a), math.degrees(a) + 180)
    stage.GetRootLayer().Save()


def scenario():
    lines = ['name = "plaza"',
             'description = "The product at a glance: people walk to benches and sit, meet in pairs, fetch boxes from a kiosk"',
             'world = "world.usda"', 'library = "default"', 'duration = 40.0', 'seed = 0', '']

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
    for i in range(6):
        a = 2 * math.pi * (i + 0.5) / 8
        x, z = 11.5 * math.sin(a + 0.4), 11.5 * math.cos(a + 0.4)
        char(f"sitter{i}", x, z, math.degrees(a) + 180, [{"seat": f'"/World/Seats/s{i:02d}"'}])
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
        char(f"mover{i}", 4.0 + 1.5 * i, 9.0, 180.0,
             [{"box": f'"/World/Boxes/b{i}"'},
              {"position": f"[{-2.0 + 2.0 * i:.2f}, 9.5]", "heading": "0.0", "pose": '"stand"'}])
    (HERE / "scenario.toml").write_text("\n".join(lines))


if __name__ == "__main__":
    world()
    scenario()
