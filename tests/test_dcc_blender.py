"""Blender as a real DCC client of baked crowds: Blender's own USD importer
(``bpy.ops.wm.usd_import``, bpy 4.2.0 from the package registry) reads a baked stage, single
layer, value clips and instanced: one armature per character, the scene frame range is the
stage's start/end, joint world positions in Blender equal the runtime's forward kinematics within
1 cm at sampled frames, and every part of every character has the material of its look. Outside
instances every mesh is skinned by its character's armature with the look's width as the value
of its ``wide`` shape key; Blender 4.2 skins no mesh inside an instance (instances are imported
as copies, ``support_scene_instancing=False``, else one armature serves a whole prototype).

Blender runs in a subprocess (bpy and pxr in one process may load two different USD
libraries). Blender is Z-up: its importer turns the Y-up stage by +90 degrees about X, so our
(x, y, z) is Blender's (x, -z, y); the test applies that mapping explicitly. Blender keeps its
own scene rate (24 fps) and plays time code t at frame t, so frames are compared as time codes;
the script reports the rate it found and sets the stage's.

Marked ``dcc``; skipped with the reason when bpy is not installed (``.ci/run`` installs it):
run with ``pytest -m dcc``, leave out with ``pytest -m "not dcc"``.
"""
import importlib.util
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from runtime.appearance import PROPS, looks_for, srgb_to_linear
from runtime.crowd.tracks import Track
from runtime.pose import locked_joint_positions
from usd_io.crowd import build_crowd_stage, save_crowd_stage, wide_weight

pytestmark = pytest.mark.dcc

BLENDER_SCRIPT = textwrap.dedent('''
    import json, sys
    import bpy
    out, paths, frames = sys.argv[1], sys.argv[2:-1], json.loads(sys.argv[-1])
    result = {"blender": bpy.app.version_string, "stages": []}
    for path in paths:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        # instances as copies: scene instancing would share one armature between all characters
        assert bpy.ops.wm.usd_import(filepath=path, support_scene_instancing=False) == {"FINISHED"}, path
        scene = bpy.context.scene
        fps_found = scene.render.fps / scene.render.fps_base
        scene.render.fps, scene.render.fps_base = 30, 1.0     # the stage's timeCodesPerSecond
        arms = [o for o in bpy.data.objects if o.type == "ARMATURE"]
        stage = {"path": path, "frame_start": scene.frame_start, "frame_end": scene.frame_end,
                 "fps_found": fps_found, "armatures": {}, "materials": {}, "props": {}}

        def character(o):
            # the importer makes every prim an object named after it: the character is the
            # SkelRoot's empty, the child of /World/Characters
            while o.parent is not None and o.parent.name != "Characters":
                o = o.parent
            return o.name

        for a in arms:
            stage["armatures"][character(a)] = {"bones": [b.name for b in a.pose.bones], "heads": {}}
        scene.frame_set(frames[-1])         # shape key values come from their animation
        for o in bpy.data.objects:
            if o.type != "MESH" or o.parent is None:
                continue
            mats = stage["materials"].setdefault(character(o), {})
            keys = o.data.shape_keys
            stage["props"].setdefault(character(o), {})[o.name.split(".")[0]] = {
                "armature": [character(m.object) for m in o.modifiers if m.type == "ARMATURE" and m.object],
                "wide": keys.key_blocks["wide"].value if keys and "wide" in keys.key_blocks else None}
            for slot in o.material_slots:
                bsdf = slot.material.node_tree.nodes.get("Principled BSDF") if slot.material else None
                if bsdf is not None:
                    mats[o.name.split(".")[0]] = list(bsdf.inputs["Base Color"].default_value)[:3]
        for f in frames:
            scene.frame_set(f)
            dg = bpy.context.evaluated_depsgraph_get()
            for a in arms:
                ae = a.evaluated_get(dg)
                stage["armatures"][character(a)]["heads"][str(f)] = [list(ae.matrix_world @ pb.head)
                                                                     for pb in ae.pose.bones]
        result["stages"].append(stage)
    with open(out, "w") as fh:
        json.dump(result, fh)
''')

# our Y-up (x, y, z) in Blender's Z-up world: (x, -z, y)
Y_UP_TO_Z_UP = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])


@pytest.fixture(scope="module")
def bpy_available():
    if importlib.util.find_spec("bpy") is None:
        pytest.skip("bpy (Blender as a Python module) is not installed: pip install bpy==4.2.0 "
                    "(.ci/run installs it; CPython 3.11 only)")


def _tracks(graph):
    rng = np.random.default_rng(11)
    out = {}
    for name, frames, start in (("walker", 60, 0), ("second one", 60, 0), ("late", 40, 12)):
        a = int(rng.integers(0, len(graph.frame_heading) - frames - 1))
        fa = np.arange(a, a + frames)
        root = np.column_stack([rng.uniform(-4, 4) + np.cumsum(rng.normal(0, 0.03, frames)),
                                rng.uniform(-4, 4) + np.cumsum(rng.normal(0, 0.03, frames)),
                                rng.uniform(-3, 3) + np.cumsum(rng.normal(0, 0.05, frames))])
        out[name] = Track(fa, fa + 1, rng.uniform(0, 1, frames).astype(np.float32), root, start)
    return out


def test_blender_imports_the_baked_crowd(bpy_available, default_graph, tmp_path):
    tracks = _tracks(default_graph)
    stages = []
    for name, kw in (("instanced.usdc", {"instancing": True}), ("single.usdc", {}),
                     ("clips.usdc", {"clips_per": 2, "workers": 1})):
        out = tmp_path / name
        save_crowd_stage(build_crowd_stage(tracks, default_graph, 30.0, out_path=out, **kw), out)
        stages.append(out)
    frames = [0, 12, 30, 51, 59]
    script = tmp_path / "import_in_blender.py"
    script.write_text(BLENDER_SCRIPT)
    res_path = tmp_path / "blender.json"
    proc = subprocess.run([sys.executable, str(script), str(res_path), *map(str, stages), json.dumps(frames)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]
    result = json.loads(res_path.read_text())
    assert result["blender"].startswith("4.2")
    sk = default_graph.skeleton
    for stage in result["stages"]:
        where = stage["path"]
        # one armature per character, named after its SkelRoot, with every joint as a bone
        assert sorted(stage["armatures"]) == ["late", "second_one", "walker"], where
        for arm in stage["armatures"].values():
            assert arm["bones"] == list(sk.names), where
        # the stage's start/end time codes are the scene's frame range (Blender plays time code t at frame t)
        assert (stage["frame_start"], stage["frame_end"]) == (0, 59), where
        print(f"{where}: Blender scene rate on import {stage['fps_found']:g} fps (stage: 30 time codes/s)")
        worst = 0.0
        for name, tr in tracks.items():
            ours = locked_joint_positions(default_graph, tr)        # runtime FK as baked (feet locked), Y-up m
            heads = stage["armatures"][name.replace(" ", "_")]["heads"]
            for f in frames:
                i = min(max(f - tr.start_frame, 0), len(tr) - 1)    # before/after its samples USD holds the ends
                blender = np.array(heads[str(f)])
                d = np.linalg.norm(blender - ours[i] @ Y_UP_TO_Z_UP.T, axis=1).max()
                worst = max(worst, d)
                assert d < 0.01, f"{where} {name} frame {f}: joint off by {d * 100:.2f} cm"
        # every character's parts have the materials of its look, and the looks differ
        looks = looks_for(list(tracks))
        colours = looks.colours()
        assert sorted(stage["materials"]) == ["late", "second_one", "walker"], where
        for i, name in enumerate(tracks):
            mats = stage["materials"][name.replace(" ", "_")]
            for k, part in enumerate(("Skin", "Shirt", "Trousers", "Shoes")):
                np.testing.assert_allclose(mats[part], srgb_to_linear(colours[i, k]), atol=1e-4,
                                           err_msg=f"{where} {name} {part}")
            prop = PROPS[int(looks.prop[i])]
            assert ("Hat" in mats, "Bag" in mats) == (prop == "hat", prop == "bag"), (where, name, sorted(mats))
            meshes = stage["props"][name.replace(" ", "_")]
            if "instanced" in where:
                continue      # Blender 4.2 makes no Armature modifier for a mesh inside an instance
            for part, m in meshes.items():
                # skinned by its own character's armature; the width as the shape key's value
                assert m["armature"] == [name.replace(" ", "_")], (where, name, part, m)
                if part in ("Skin", "Shirt", "Trousers", "Shoes"):
                    assert abs(m["wide"] - wide_weight(float(looks.width[i]))) < 1e-4, (where, name, part, m)
        assert len({tuple(np.round(m["Shirt"], 4)) + tuple(np.round(m["Skin"], 4))
                    for m in stage["materials"].values()}) > 1, where
        # and the characters really are somewhere else at the end than at the start
        assert np.linalg.norm(np.array(stage["armatures"]["walker"]["heads"]["59"][0]) -
                              np.array(stage["armatures"]["walker"]["heads"]["0"][0])) > 0.05
        print(f"{where}: worst joint distance Blender vs runtime FK {worst * 1000:.3f} mm")
