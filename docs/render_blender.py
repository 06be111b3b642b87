"""Render a baked crowd in Blender, headless: bake a sample (or take a baked stage), import it
with Blender's own USD importer (``bpy.ops.wm.usd_import``, bpy 4.2 from the package registry)
and render one still with Workbench (material colours, studio light) or Cycles on the CPU.

    python docs/render_blender.py                                  # bakes samples/plaza, frame 300
    python docs/render_blender.py --usd plaza.usdc --frame 120 --out docs/plaza_blender.png
    python docs/render_blender.py --engine cycles --samples 16    # slower, path traced

Needs ``pip install bpy==4.2.0`` (CPython 3.11). Blender runs in a subprocess (bpy and pxr in
one process may load two different USD libraries). The import expands instances into copies
(``support_scene_instancing=False``): with scene instancing Blender would share one armature
between every character of a prototype. The camera looks down on the characters' bounding box at
the rendered frame from the south-east, over a ground plane.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

BLENDER = r'''
import json, math, sys
import bpy
from mathutils import Vector
cfg = json.loads(sys.argv[-1])
bpy.ops.wm.read_factory_settings(use_empty=True)
assert bpy.ops.wm.usd_import(filepath=cfg["usd"], support_scene_instancing=False) == {"FINISHED"}
scene = bpy.context.scene
scene.frame_set(cfg["frame"])
dg = bpy.context.evaluated_depsgraph_get()

def under(o, name):
    while o is not None:
        if o.name == name:
            return True
        o = o.parent
    return False

pts = []
for o in scene.objects:
    if o.type == "MESH" and under(o, "Characters"):
        oe = o.evaluated_get(dg)
        pts += [oe.matrix_world @ Vector(c) for c in oe.bound_box]
if not pts:
    raise SystemExit("no character meshes in " + cfg["usd"])
lo = Vector((min(p.x for p in pts), min(p.y for p in pts), min(p.z for p in pts)))
hi = Vector((max(p.x for p in pts), max(p.y for p in pts), max(p.z for p in pts)))
centre = (lo + hi) / 2
size = max(hi.x - lo.x, hi.y - lo.y, 4.0)
cam_data = bpy.data.cameras.new("Camera")
cam_data.lens = 35
cam = bpy.data.objects.new("Camera", cam_data)
scene.collection.objects.link(cam)
d = Vector((0.55, -0.75, 0.62)).normalized()
cam.location = centre + d * size * 1.2
cam.rotation_euler = (centre - cam.location).to_track_quat("-Z", "Y").to_euler()
scene.camera = cam
bpy.ops.mesh.primitive_plane_add(size=size * 4, location=(centre.x, centre.y, 0.0))
ground = bpy.context.active_object
ground_mat = bpy.data.materials.new("Ground")
ground_mat.diffuse_color = (0.62, 0.61, 0.58, 1.0)
ground_mat.use_nodes = True
ground_mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.62, 0.61, 0.58, 1.0)
ground.data.materials.append(ground_mat)
world = bpy.data.worlds.new("World")
world.color = (0.78, 0.83, 0.88)
world.use_nodes = True
world.node_tree.nodes["Background"].inputs[0].default_value = (0.78, 0.83, 0.88, 1.0)
scene.world = world
sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
sun.data.energy = 3.0
sun.rotation_euler = (math.radians(40), 0, math.radians(30))
scene.collection.objects.link(sun)
r = scene.render
r.resolution_x, r.resolution_y = cfg["width"], cfg["height"]
r.filepath = cfg["out"]
r.image_settings.file_format = "PNG"
if cfg["engine"] == "cycles":
    r.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = cfg["samples"]
else:
    r.engine = "BLENDER_WORKBENCH"
    sh = scene.display.shading
    sh.light = "STUDIO"
    sh.color_type = "MATERIAL"
    sh.show_shadows = True
    sh.show_cavity = True
    scene.display.shadow_focus = 0.6
bpy.ops.render.render(write_still=True)
n = sum(1 for o in scene.objects if o.type == "ARMATURE")
print(json.dumps({"armatures": n, "centre": list(centre), "size": size}))
'''


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--usd", default=None, help="a baked stage (default: bake --sample first)")
    ap.add_argument("--sample", default=str(ROOT / "samples" / "plaza"), help="the sample to bake")
    ap.add_argument("--out", default=str(ROOT / "docs" / "plaza_blender.png"))
    ap.add_argument("--frame", type=int, default=300)
    ap.add_argument("--engine", choices=("workbench", "cycles"), default="workbench")
    ap.add_argument("--samples", type=int, default=16, help="Cycles samples per pixel")
    ap.add_argument("--width", type=int, default=1600)
    ap.add_argument("--height", type=int, default=900)
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        usd = a.usd
        if usd is None:
            sys.path.insert(0, str(ROOT))
            from authoring.commands.bake import bake_sample
            usd = str(Path(tmp) / "bake.usdc")
            t0 = time.perf_counter()
            code = bake_sample(a.sample, usd)
            print(f"baked {a.sample} in {time.perf_counter() - t0:.1f} s (checker {'passed' if code == 0 else 'failed'})")
            if not Path(usd).exists():
                raise SystemExit("the bake wrote no stage")
        script = Path(tmp) / "render_in_blender.py"
        script.write_text(BLENDER)
        cfg = {"usd": str(Path(usd).resolve()), "out": str(Path(a.out).resolve()), "frame": a.frame,
               "engine": a.engine, "samples": a.samples, "width": a.width, "height": a.height}
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, str(script), json.dumps(cfg)], capture_output=True, text=True)
        if proc.returncode != 0:
            sys.stderr.write(proc.stdout[-3000:] + proc.stderr[-3000:])
            return proc.returncode
        info = json.loads([line for line in proc.stdout.splitlines() if line.startswith("{")][-1])
        print(f"Blender imported {info['armatures']} armatures and rendered frame {a.frame} with {a.engine} "
              f"in {time.perf_counter() - t0:.1f} s: {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
