"""Writes samples/flock_region_2d and samples/flock_region_3d (world.usda + scenario.toml),
deterministically. Run from the repository root: ``.venv/bin/python samples/make_flock_samples.py``."""
from pathlib import Path

from pxr import Gf, Sdf, Usd, UsdGeom

HERE = Path(__file__).resolve().parent


def world(path, regions, obstacles=()):
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    w = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(w.GetPrim())
    UsdGeom.Scope.Define(stage, "/World/Regions")
    for name, pts in regions:
        mesh = UsdGeom.Mesh.Define(stage, f"/World/Regions/{name}")
        mesh.CreatePointsAttr([Gf.Vec3f(x, 0, z) for x, z in pts])
        mesh.CreateFaceVertexCountsAttr([len(pts)])
        mesh.CreateFaceVertexIndicesAttr(list(range(len(pts))))
        mesh.GetPrim().CreateAttribute("crowdweave:role", Sdf.ValueTypeNames.String).Set("region")
        UsdGeom.Imageable(mesh).CreateVisibilityAttr("invisible")
    UsdGeom.Scope.Define(stage, "/World/Obstacles")
    for name, (x, z, r) in obstacles:
        c = UsdGeom.Cylinder.Define(stage, f"/World/Obstacles/{name}")
        c.CreateRadiusAttr(r)
        c.CreateHeightAttr(2.0)
        c.CreateAxisAttr("Y")
        UsdGeom.Xformable(c).AddTranslateOp().Set(Gf.Vec3d(x, 1.0, z))
    stage.GetRootLayer().Save()


def scenario_text(name, description, flock, dim, count, region, extra=()):
    """A flock sample's scenario.toml: ``count`` flocks named ``flock`` walk a ``dim``-D flock
    motion graph (built from a recorded flock of 20 agents, 150 s) inside the region mesh
    ``/World/Regions/<region>``; ``extra`` lines end the flock table."""
    lines = [f'name = "{name}"', f'description = "{description}"', 'world = "world.usda"', "duration = 60.0",
             "seed = 0", "", "[[flock]]", f'name = "{flock}"',
             f"ddg = {{ dim = {dim}, agents = 20, seconds = 150.0, seed = 1 }}", f"count = {count}",
             f'region = "/World/Regions/{region}"', *extra]
    return "\n".join(lines) + "\n"


def main():
    d2 = HERE / "flock_region_2d"
    d2.mkdir(exist_ok=True)
    # an L-shaped meadow: sheep flocks keep their centroids inside it
    world(d2 / "world.usda", [("meadow", [(-50, -50), (50, -50), (50, 0), (0, 0), (0, 50), (-50, 50)])],
          [("tree0", (25, 25, 1.5)), ("tree1", (35, 15, 1.0))])
    (d2 / "scenario.toml").write_text(scenario_text(
        d2.name, "Data-driven groups (Lai, Chenney and Fan 2005): four sheep flocks walk a flock motion graph inside an "
        "L-shaped meadow", "sheep", 2, 4, "meadow"))
    d3 = HERE / "flock_region_3d"
    d3.mkdir(exist_ok=True)
    world(d3 / "world.usda", [("sky", [(-45, -45), (45, -45), (45, 45), (-45, 45)])])
    (d3 / "scenario.toml").write_text(scenario_text(
        d3.name, "Data-driven groups (Lai, Chenney and Fan 2005), 3D: three bird flocks fly a flock motion graph inside a box "
        "of sky", "birds", 3, 3, "sky", ("altitude = [5.0, 45.0]",)))
    for d, text in ((d2, "Four flocks of 20 sheep walk a 2D flock motion graph built from a recorded boids flock; "
                         "their centroids never leave the L-shaped meadow (a `crowdweave:role = \"region\"` mesh)."),
                    (d3, "Three flocks of 20 birds fly a 3D flock motion graph inside a 90 x 90 x 40 m box of sky.")):
        (d / "README.md").write_text(f"# {d.name}\n\n{text}\n\n```sh\ncrowdweave run samples/{d.name}\n"
                                     f"crowdweave bake samples/{d.name} --out {d.name}.usdc\n```\n\n"
                                     "The flock graph is recorded and built on first use and cached "
                                     "(`~/.cache/crowdweave/flocks`).\n")


if __name__ == "__main__":
    main()
