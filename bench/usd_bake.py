"""USD bake throughput: N characters x F frames, each character its own data.

Writes one SkelRoot per character (Skeleton + SkelAnimation + body + crowdweave attributes)
three ways in the same run and prints seconds (authoring incl. pose evaluation, saving,
total), the size on disk (all layers) and the speed-up against the baseline:

- plain ``Usd.Attribute.Set`` per time sample (the baseline; no body mesh);
- ``usd_io.crowd.build_crowd_stage``: Sdf specs and ``SetTimeSample`` in one change block,
  one layer;
- the same with ``clips_per=N``: value-clip layers of N characters each, written by
  ``--workers`` processes, plus the top stage (directory renamed into place, then the stage).

    .venv/bin/python bench/usd_bake.py                  # 1000 characters x 300 frames
    .venv/bin/python bench/usd_bake.py --characters 200 --frames 300 --clips-per 50

``--instancing`` compares instead the instanced layout (one shared Skeleton and body per prop
kind, UsdSkel bind-state instancing) with the non-instanced one (``instancing=False``) on the
same tracks, at each of ``--counts`` characters: authoring and saving seconds, file size, the
size of the same stage with one frame per character (what is not animation), and, each in a
fresh process, the seconds to open the stage and traverse it (instance proxies included) and to
populate a ``UsdSkel.Cache`` for every character:

    .venv/bin/python bench/usd_bake.py --instancing --counts 100,1000 --frames 300
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pxr import Sdf, UsdGeom, UsdSkel, Vt  # noqa: E402

from runtime.crowd.tracks import Track, evaluate_poses  # noqa: E402
from runtime.library import load_library  # noqa: E402
from usd_io.crowd import CHARACTERS, build_crowd_stage, save_crowd_stage  # noqa: E402
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


def _cpu() -> float:
    """CPU seconds of this process and its finished children (the clip writers)."""
    import resource
    return sum(r.ru_utime + r.ru_stime for r in (resource.getrusage(resource.RUSAGE_SELF),
                                                 resource.getrusage(resource.RUSAGE_CHILDREN)))


def _size(path: Path) -> tuple[float, int]:
    """MB and number of files of a stage and the clip directories beside it."""
    files = [path] + [f for d in path.parent.iterdir() if d.is_dir() and d.name.startswith(path.name + ".clips-")
                      for f in d.iterdir()]
    return sum(os.path.getsize(f) for f in files) / 1e6, len(files)


METHODS = ("set", "layer", "clips")


def run_method(a, method: str) -> dict:
    """Build and save one way in this process (a fresh one per method: see main)."""
    graph = load_library("default")
    tracks = make_tracks(graph, a.characters, a.frames)
    if method == "set":
        label, build, save = "Usd Attribute.Set per sample", lambda out: bake_attribute_set(tracks, graph, 30.0), save_stage
    elif method == "layer":
        label, build, save = "Sdf change block, one layer", lambda out: build_crowd_stage(tracks, graph, 30.0), save_stage
    else:
        label = f"value clips {a.clips_per}/layer, {a.workers} proc"
        build = lambda out: build_crowd_stage(tracks, graph, 30.0, out_path=out, clips_per=a.clips_per,  # noqa: E731
                                              workers=a.workers)
        save = save_crowd_stage
    out = Path(a.dir) / f"bake_{method}{a.ext}"
    c0, t0 = _cpu(), time.perf_counter()
    stage = build(out)
    t1 = time.perf_counter()
    save(stage, out)
    t2 = time.perf_counter()
    mb, nf = _size(out)
    return dict(label=label, author=t1 - t0, save=t2 - t1, cpu=_cpu() - c0, mb=mb, files=nf)


def load_times(path: str) -> dict:
    """Seconds to open a stage and traverse every prim (instance proxies too), and to populate a
    UsdSkel cache for every SkelRoot; run in a fresh process."""
    from pxr import Usd
    t0 = time.perf_counter()
    stage = Usd.Stage.Open(path)
    prims = sum(1 for _ in Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies()))
    t1 = time.perf_counter()
    cache = UsdSkel.Cache()
    roots = [p for p in stage.GetPrimAtPath(CHARACTERS).GetChildren()]
    for r in roots:
        cache.Populate(UsdSkel.Root(r), Usd.TraverseInstanceProxies())
    skels = sum(1 for p in Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies()) if p.IsA(UsdSkel.Skeleton)
                and cache.GetSkelQuery(UsdSkel.Skeleton(p)))
    t2 = time.perf_counter()
    return dict(open=t1 - t0, populate=t2 - t1, prims=prims, skeletons=skels, prototypes=len(stage.GetPrototypes()))


def instancing_table(a) -> int:
    """Instanced against non-instanced bakes of the same tracks (see the module docstring)."""
    graph = load_library("default")
    print(f"USD bake layouts: {a.frames} frames x {graph.skeleton.num_joints} joints, {a.ext}, same tracks per row")
    print(f"{'chars':>6} {'layout':>13} {'author s':>9} {'save s':>7} {'MB':>8} {'1-frame MB':>10} "
          f"{'open+trav s':>11} {'populate s':>10} {'prims':>7} {'skels':>6} {'protos':>6}")
    build_crowd_stage(make_tracks(graph, 4, 30), graph, 30.0)           # warm-up: compiled kernels, caches
    with tempfile.TemporaryDirectory() as d:
        for n in [int(c) for c in a.counts.split(",")]:
            tracks = make_tracks(graph, n, a.frames)
            J = graph.skeleton.num_joints
            raw = {"root translate": 12, "rotations": 16 * J, "crowdweave:root": 24}
            print(f"{n:6d} raw time samples: " + ", ".join(f"{k} {v * n * a.frames / 1e6:.1f} MB"
                                                          for k, v in raw.items()))
            first = {k: Track(t.frames_a[:1], t.frames_b[:1], t.frames_t[:1], t.root[:1], 0) for k, t in tracks.items()}
            for inst in (True, False):
                out = Path(d) / f"crowd_{n}_{inst}{a.ext}"
                t0 = time.perf_counter()
                stage = build_crowd_stage(tracks, graph, 30.0, instancing=inst)
                t1 = time.perf_counter()
                save_stage(stage, out)
                t2 = time.perf_counter()
                small = Path(d) / f"one_{n}_{inst}{a.ext}"
                save_stage(build_crowd_stage(first, graph, 30.0, instancing=inst), small)
                res = subprocess.run([sys.executable, __file__, "--load", str(out)], capture_output=True, text=True)
                line = [ln for ln in res.stdout.splitlines() if ln.startswith("RESULT ")]
                if res.returncode != 0 or not line:
                    raise SystemExit(f"loading {out} failed:\n{res.stderr[-3000:]}")
                r = json.loads(line[0][7:])
                print(f"{n:6d} {'instanced' if inst else 'not instanced':>13} {t1 - t0:9.2f} {t2 - t1:7.2f} "
                      f"{out.stat().st_size / 1e6:8.2f} {small.stat().st_size / 1e6:10.3f} {r['open']:11.3f} "
                      f"{r['populate']:10.3f} {r['prims']:7d} {r['skeletons']:6d} {r['prototypes']:6d}")
                out.unlink()
                small.unlink()
    print("1-frame MB: the same characters with one frame each (prims, looks, bodies: all but the animation); "
          "open+trav and populate: a fresh process each")
    try:
        print(f"load average during the run: {os.getloadavg()[0]:.2f}")
    except OSError:
        pass
    return 0


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--characters", type=int, default=1000)
    p.add_argument("--frames", type=int, default=300)
    p.add_argument("--ext", default=".usdc", choices=[".usdc", ".usda"])
    p.add_argument("--clips-per", type=int, default=100, help="characters per value-clip layer")
    p.add_argument("--workers", type=int, default=2, help="processes writing clip layers")
    p.add_argument("--method", choices=METHODS, help=argparse.SUPPRESS)   # internal: one method, JSON out
    p.add_argument("--dir", help=argparse.SUPPRESS)
    p.add_argument("--instancing", action="store_true", help="compare the instanced and non-instanced layouts")
    p.add_argument("--counts", default="100,1000", help="characters per row of --instancing")
    p.add_argument("--load", help=argparse.SUPPRESS)                         # internal: load times of one stage
    a = p.parse_args(argv)
    if a.load:
        print("RESULT " + json.dumps(load_times(a.load)))
        return 0
    if a.instancing:
        return instancing_table(a)
    if a.method:
        print("RESULT " + json.dumps(run_method(a, a.method)))
        return 0
    graph = load_library("default")
    tracks = make_tracks(graph, a.characters, a.frames)
    # what the runtime's pose evaluation alone costs (every method below includes it)
    from usd_io.timesamples import POSE_BATCH_FRAMES, SkelValues, batches, pose_arrays
    sv = SkelValues.of(graph.skeleton)
    c0, t0 = _cpu(), time.perf_counter()
    for batch in batches(list(tracks.items()), POSE_BATCH_FRAMES):
        pose_arrays(graph, [tr for _, tr in batch], sv)
    t_pose, c_pose = time.perf_counter() - t0, _cpu() - c0
    rows = []
    with tempfile.TemporaryDirectory() as d:
        # Each method runs in its own process (as a bake from the command line does), after
        # os.sync(), so the memory and the pending disk writes of one do not weigh on the next.
        for method in METHODS:
            os.sync()
            cmd = [sys.executable, __file__, "--method", method, "--dir", d, "--characters", str(a.characters),
                   "--frames", str(a.frames), "--ext", a.ext, "--clips-per", str(a.clips_per),
                   "--workers", str(a.workers)]
            res = subprocess.run(cmd, capture_output=True, text=True)
            line = [ln for ln in res.stdout.splitlines() if ln.startswith("RESULT ")]
            if res.returncode != 0 or not line:
                raise SystemExit(f"{method} failed:\n{res.stderr[-3000:]}")
            r = json.loads(line[0][7:])
            rows.append((r["label"], r["author"], r["save"], r["cpu"], r["mb"], r["files"]))
            for f in Path(d).iterdir():
                shutil.rmtree(f) if f.is_dir() else f.unlink()
    print(f"USD bake: {a.characters} characters x {a.frames} frames x {graph.skeleton.num_joints} joints "
          f"({a.ext}, each character its own data; {os.cpu_count()} CPUs)")
    print(f"{'method':34s}{'author s':>9s}{'save s':>8s}{'total s':>9s}{'cpu s':>8s}{'MB':>8s}{'files':>7s}"
          f"{'vs Set':>8s}")
    base = rows[0][1] + rows[0][2]
    for label, ta, ts, cpu, mb, nf in rows:
        print(f"{label:34s}{ta:9.2f}{ts:8.2f}{ta + ts:9.2f}{cpu:8.2f}{mb:8.1f}{nf:7d}{base / (ta + ts):7.2f}x")
    print("each method in its own process after os.sync(); seconds are wall clock; author includes pose evaluation (runtime) and, for value clips, the worker "
          "processes writing their layers; cpu = CPU seconds of this process and the workers; "
          "vs Set = Attribute.Set total / total; target <= 5 s total")
    print(f"of which animation arrays (runtime.pose.skel_arrays, one process): {t_pose:.2f} s "
          f"({c_pose:.2f} cpu s)")
    try:
        print(f"load average during the run: {os.getloadavg()[0]:.2f}")
    except OSError:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
