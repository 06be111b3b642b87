"""``crowdweave world check world.usda``: list what a world stage gives the crowd runtime
(obstacles with footprint areas, markers by role) and every prim that could not be used, with
the reason. Exit code 0 if the world is usable, 2 if it has errors."""
from __future__ import annotations

import json
import math


def configure(p):
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    c = sub.add_parser("check", help="list obstacles, markers and unusable prims of a world stage",
                       description="list obstacles, markers and unusable prims of a world stage")
    c.add_argument("world", help="world stage (.usda/.usdc/.usd)")
    c.add_argument("--json", action="store_true", help="print JSON instead of text")


def _report(path):
    from usd_io.world import read_world_report, world_units
    env, found, issues = read_world_report(path)
    mpu, up, _ = world_units(path)
    return env, found, issues, mpu, up


def run(args) -> int:
    from usd_io.world import WorldError

    try:
        env, found, issues, mpu, up = _report(args.world)
    except WorldError as e:
        print(f"crowdweave world: error: {e}")
        return 2
    errors = [i for i in issues if i.error]
    obstacles = [f for f in found if f.role == "obstacle"]
    markers = [f for f in found if f.role != "obstacle"]
    if args.json:
        print(json.dumps({
            "world": str(args.world), "meters_per_unit": mpu, "up_axis": up, "usable": not errors,
            "obstacles": [{"path": f.path, "shape": f.shape, "area_m2": round(f.area, 6),
                           "position": [round(float(v), 6) for v in f.position]} for f in obstacles],
            "markers": [{"path": f.path, "role": f.role, "position": [round(float(v), 6) for v in f.position],
                         "heading_deg": round(math.degrees(f.heading), 4),
                         **({"area_m2": round(f.area, 6)} if f.area is not None else {})} for f in markers],
            "not_used": [{"path": i.path, "reason": i.reason, "error": i.error} for i in issues],
        }, indent=2))
        return 2 if errors else 0
    print(f"{args.world}: metersPerUnit {mpu:g}, upAxis {up} (read as metres, Y up)")
    line = f"obstacles: {len(obstacles)}"
    if obstacles:
        x0, z0, x1, z1 = env.bounds()
        line += (f" ({len(env.polygons)} polygons, {len(env.circles)} circles), total footprint "
                 f"{sum(f.area for f in obstacles):.3f} m^2, bounds x [{x0:.2f}, {x1:.2f}] z [{z0:.2f}, {z1:.2f}]")
    print(line)
    for f in obstacles:
        print(f"  {f.path}: {f.shape}, {f.area:.3f} m^2 at ({f.position[0]:.2f}, {f.position[1]:.2f})")
    roles = {}
    for f in markers:
        roles.setdefault(f.role, []).append(f)
    print(f"markers: {len(markers)} (" + ", ".join(f"{len(v)} {k}" for k, v in roles.items()) + ")" if markers else "markers: 0")
    for role, items in roles.items():
        print(f"  {role}:")
        for f in items:
            extra = f", {f.area:.3f} m^2" if f.area is not None else ""
            print(f"    {f.path}: ({f.position[0]:.2f}, {f.position[1]:.2f}), heading {math.degrees(f.heading):.1f} deg{extra}")
    if issues:
        nw = len(issues) - len(errors)
        print(f"not used / problems: {len(errors)} error{'s' if len(errors) != 1 else ''}, "
              f"{nw} warning{'s' if nw != 1 else ''}")
        for i in issues:
            print(f"  {'ERROR' if i.error else 'warning'} {i.path}: {i.reason}")
    else:
        print("not used / problems: none")
    print("usable: no" if errors else "usable: yes")
    return 2 if errors else 0
