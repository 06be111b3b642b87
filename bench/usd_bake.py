"""USD bake throughput (issue 6): N characters x F frames, each character its own data.

Writes one SkelRoot per character (Skeleton + SkelAnimation + crowdweave attributes) twice in
the same run: through ``usd_io.crowd.build_crowd_stage`` (time samples authored with Sdf inside
change blocks) and through plain ``Usd.Attribute.Set`` per time sample; prints seconds for
defining + authoring, saving, and the file size, and the ratio.

    .venv/bin/python bench/usd_bake.py                  # 1000 characters x 300 frames
    .venv/bin/python bench/usd_bake.py --characters 200 --frames 300
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pxr import Sdf, UsdGeom, UsdSkel, Vt  # noqa: E402

from runtime.crowd.tracks import Track, evaluate_poses  # noqa: E402
from runtime.library import load_library  # noqa: E402
from usd_io.crowd import CHARACTERS, build_crowd_stage  # noqa: E402
from usd_io.skel import bind_animation, bind_skeleton, define_skel_root, define_skeleton, joint_paths  # noqa: E402
from usd_io.stage import new_stage, save_stage, set_default_prim  # noqa: E402


def make_tracks(graph, n, frames, seed=0):
    """Distinct tracks: each character plays its own random walk through the library's frames
    from its own start (so usdc cannot de-duplicate identical arrays)."""
    rng = np.random.default_rng(seed)
    T = len(graph.frame_heading)
    tracks = {}
    for i in range(n):
        start = int(rng.integers(0, T - frames - 1))
        fa = np.arange(start, start + frames)
        root = np.zeros((frames, 3))
        root[:, 0] = rng.uniform(-50, 50) + np.cumsum(rng.normal(0, 0.02, frames))
        root[:, 1] = rng.uniform(-50, 50) + np.cumsum(rng.normal(0, 0.02, frames))
        root[:, 2] = rng.uniform(-3, 3) + np.cumsum(rng.normal(0, 0.01, frames))
        tracks[f"c{i:04d}"] = Track(fa, fa + 1, np.full(frames, 0.25, np.float32), root, 0)
    return tracks


def bake_attribute_set(tracks, graph, fps):
    """The same prims, time samples through Usd.Attribute.Set (the baseline)."""
    n = max(len(t) for t in tracks.values())
    stage = new_stage(fps, 0, n - 1)
    world = UsdGeom.Xform.Define(stage, "/World")
    set_default_prim(stage, world.GetPrim())
    UsdGeom.Scope.Define(stage, CHARACTERS)
    sk = graph.skeleton
    paths = joint_paths(sk)
    for name, tr in tracks.items():
        rp = Sdf.Path(CHARACTERS).AppendChild(name)
        root = define_skel_root(stage, rp)
        skel = define_skeleton(stage, rp.AppendChild("Skel"), sk, paths=paths)
        anim = UsdSkel.Animation.Define(stage, skel.GetPath().AppendChild("Anim"))
        anim.CreateJointsAttr(Vt.TokenArray(paths))
        pos, rot = evaluate_poses(graph, tr.frames_a, tr.frames_b, tr.frames_t, tr.root)
        trans = np.empty(pos.shape[:1] + (sk.num_joints, 3), np.float32)
        trans[:] = sk.offsets
        trans[:, 0] = pos
        q = np.ascontiguousarray(rot[..., [1, 2, 3, 0]], dtype=np.float32)
        ta, ra = anim.CreateTranslationsAttr(), anim.CreateRotationsAttr()
        anim.CreateScalesAttr().Set(Vt.Vec3hArray.FromNumpy(np.ones((sk.num_joints, 3), np.float16)))
        ca = root.GetPrim().CreateAttribute("crowdweave:root", Sdf.ValueTypeNames.Double3)
        for k in range(len(tr)):
            ta.Set(Vt.Vec3fArray.FromNumpy(trans[k]), float(k))
            ra.Set(Vt.QuatfArray.FromNumpy(q[k]), float(k))
            ca.Set((float(tr.root[k, 0]), float(tr.root[k, 1]), float(np.degrees(tr.root[k, 2]))), float(k))
        bind_skeleton(root, skel)
        bind_animation(skel, anim)
    return stage


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--characters", type=int, default=1000)
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--ext", default=".usdc", choices=[".usdc", ".usda"])
    a = p.parse_args(argv)
    graph = load_library("default")
    tracks = make_tracks(graph, a.characters, a.frames)
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for label, fn in (("Sdf change blocks (usd_io)", lambda: build_crowd_stage(tracks, graph, 30.0)),
                          ("Usd Attribute.Set per sample", lambda: bake_attribute_set(tracks, graph, 30.0))):
            t0 = time.perf_counter()
            stage = fn()
            t1 = time.perf_counter()
            out = Path(d) / f"bake{len(rows)}{a.ext}"
            save_stage(stage, out)
            t2 = time.perf_counter()
            rows.append((label, t1 - t0, t2 - t1, os.path.getsize(out) / 1e6))
            del stage
    print(f"USD bake: {a.characters} characters x {a.frames} frames x {graph.skeleton.num_joints} joints "
          f"({a.ext}, each character its own data)")
    print(f"{'method':32s}{'author s':>10s}{'save s':>9s}{'total s':>9s}{'MB':>9s}")
    for label, ta, ts, mb in rows:
        print(f"{label:32s}{ta:10.2f}{ts:9.2f}{ta + ts:9.2f}{mb:9.1f}")
    print(f"Attribute.Set / change blocks (total): {(rows[1][1] + rows[1][2]) / (rows[0][1] + rows[0][2]):.2f}x; "
          f"target <= 5 s for the change-block bake")
    return 0


if __name__ == "__main__":
    sys.exit(main())
