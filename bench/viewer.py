"""Benchmark: viewer frame rate under software rendering (llvmpipe), 500 and 2000 characters.

Each run renders the example world with a :class:`runtime.viewer.TrackScene` of N characters
(wandering the default library; the area grows with N so density stays about one character per
4 m^2) at 1280x720, the camera framing every character (the worst case: all on screen). The full
frame loop runs for ``--seconds`` after a warm-up: events, scene step (ticks at 30 Hz), pose
interpolation, all draws, HUD, ``glFinish`` (so a frame's time includes the rasterizer's work).

Columns: frames per second of the whole loop, and of the same frames with the scene paused (the
viewer's own cost); median milliseconds (live run) of the scene step, the pose
fetch (``scene.joint_positions``), the CPU side of rendering and the wait for GL to finish; the
figures' level-of-detail split; and the character pass alone (bone buffers + impostor draws,
bracketed by ``glFinish``) against the baseline in the same process -- the conventional
instanced capsule mesh, one instance per bone (``runtime.viewer.baseline``) -- as a ratio; and
the frame rate of ENVIRONMENT.md's reference renderer (20-bone line figures) on the same figures
in the same run, which calibrates how fast this machine is at the moment (it is often shared):
the viewer's frame rate relative to it, times the reference's recorded idle-machine rate, is an
estimate for an idle machine (labelled as such).

Backends: ``--mode headless`` (EGL, default) or ``--mode xvfb`` (starts a private Xvfb and opens a
real window). The machine may be shared: the load average is printed. No asserts.

``--plaza`` measures the living plaza instead (``crowdweave run``'s default sample: its named
characters, 300 ambient people kept busy by ``runtime.world.ambient``, the tiled zone and the
flocks, all on one World planning live under its budget) at 1280x720 from the opening view: frame
rate of the whole loop (target >= 30 fps) and the World's tick times, p50 / p99 / max (target p99
<= 16 ms), with the planning figures of the run; the same frames with the scene paused give the
viewer's own cost, and a few more paused frames the median time of each pass bracketed by
``glFinish`` (each bracket also pays for a flush of llvmpipe's queued work, so the passes add up
to more than a frame).

    CROWDWEAVE_CACHE=/tmp/cwcache .venv/bin/python bench/viewer.py [--counts 500,2000] [--seconds 6]
    CROWDWEAVE_CACHE=/tmp/cwcache .venv/bin/python bench/viewer.py --plaza [--seconds 30]
"""
from __future__ import annotations

import argparse
import os
import select
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def start_xvfb():
    """Start a private Xvfb and point DISPLAY at it; returns the process and the -displayfd
    pipe, which must stay open while Xvfb runs (closing it early is fatal to it)."""
    exe = shutil.which("Xvfb")
    if exe is None:
        raise SystemExit("Xvfb is not installed (apt-get install -y xvfb), or use --mode headless")
    r, w = os.pipe()
    proc = subprocess.Popen([exe, "-displayfd", str(w), "-screen", "0", "1280x720x24", "-nolisten", "tcp"],
                            pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(w)
    line = _read_line(r, 20.0)
    if not line:
        proc.kill()
        raise SystemExit("Xvfb did not start")
    os.environ["DISPLAY"] = ":" + line
    return proc, r


def _read_line(fd, timeout):
    """The display number Xvfb writes to -displayfd, up to its newline."""
    buf, end = b"", time.monotonic() + timeout
    while not buf.endswith(b"\n"):
        ready, _, _ = select.select([fd], [], [], max(0.0, end - time.monotonic()))
        if not ready:
            break
        chunk = os.read(fd, 64)
        if not chunk:
            break
        buf += chunk
    return buf.decode().strip()


def gl_time(fn, gl):
    gl.glFinish()
    t0 = time.perf_counter()
    fn()
    gl.glFinish()
    return (time.perf_counter() - t0) * 1e3


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--counts", default="500,2000")
    ap.add_argument("--seconds", type=float, default=6.0)
    ap.add_argument("--mode", choices=("headless", "xvfb"), default="headless")
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--baseline-frames", type=int, default=3)
    ap.add_argument("--screenshot-dir", default=None, help="save the last frame of each run here")
    ap.add_argument("--plaza", action="store_true", help="the living plaza (samples/plaza with its ambient people)")
    ap.add_argument("--budget-ms", type=float, default=None, help="--plaza: the World's planning budget (default: "
                                                                   "crowdweave run's for an ambient scenario)")
    args = ap.parse_args(argv)
    xvfb, display_fd = start_xvfb() if args.mode == "xvfb" else (None, None)
    try:
        run_plaza(args) if args.plaza else run(args)
    finally:
        if xvfb is not None:
            xvfb.terminate()
            xvfb.wait(10)
            os.close(display_fd)


def paused_fps(viewer, seconds: float) -> float:
    """Frame rate of the viewer with its scene paused (the viewer's own cost), over ``seconds``."""
    viewer.paused = True
    frames, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        viewer.run(max_frames=1)
        frames += 1
    viewer.paused = False
    return frames / (time.perf_counter() - t0)


def pass_times(viewer, gl, frames: int = 20) -> dict:
    """Median milliseconds of each pass of a paused frame, each bracketed by ``glFinish``."""
    r = viewer.renderer
    parts = {"backdrop": (r.backdrop, "draw"), "characters": (r.characters, "draw"), "HUD": (viewer, "_draw_hud"),
             "floor": (r.m_floor, "draw"), "environment": (r.m_env, "draw"), "flocks": (r.m_agents, "draw"),
             "decals": (r.m_decals, "draw")}
    times = {k: [] for k in parts}

    def timed(name, fn):
        def call(*a, **kw):
            gl.glFinish()
            t0 = time.perf_counter()
            out = fn(*a, **kw)
            gl.glFinish()
            times[name].append((time.perf_counter() - t0) * 1e3)
            return out
        return call

    for name, (obj, attr) in parts.items():
        setattr(obj, attr, timed(name, getattr(obj, attr)))
    viewer.paused = True
    try:
        viewer.run(max_frames=frames)
    finally:
        viewer.paused = False
        for obj, attr in parts.values():
            del obj.__dict__[attr]          # the class's method again
    return {k: float(np.median(v)) for k, v in times.items() if v}


def run_plaza(args):
    """The living plaza at ``--width`` x ``--height`` from the opening view."""
    from runtime.viewer import headless, make_viewer
    headless.configure(args.mode == "headless")
    from pyglet import gl

    from authoring.commands.bake import load_sample
    from runtime.world import World
    from runtime.world.ambient import AMBIENT_BUDGET_MS, AMBIENT_JOB_SLICE
    sc, graph, env, roadmap = load_sample(ROOT / "samples" / "plaza", log=lambda *a: None, progress=False)
    budget = AMBIENT_BUDGET_MS if args.budget_ms is None else args.budget_ms
    world = World(graph, world=env, roadmap=roadmap, seed=sc.seed, budget_ms=budget,
                  job_slice=AMBIENT_JOB_SLICE if sc.ambient else None)
    world.apply_scenario(sc)
    world.add_scenario_flocks(sc)
    world.add_scenario_tiling(sc)
    life = world.add_scenario_ambient(sc)
    viewer = make_viewer(world, headless=(args.mode == "headless"), width=args.width, height=args.height)
    viewer.run(max_frames=5)                           # warm-up: shader compilation, first ticks
    t_warm, ticks0 = world.time, world.stats["ticks"]
    frame_ms, step_ms = [], []
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < args.seconds:
        t = time.perf_counter()
        viewer.run(max_frames=1)
        frame_ms.append((time.perf_counter() - t) * 1e3)
        step_ms.append(viewer.frame_ms.get("step", 0.0))
    elapsed = time.perf_counter() - t0
    n_ticks = world.stats["ticks"] - ticks0
    ticks = world.tick_times[np.arange(ticks0, ticks0 + n_ticks) % len(world.tick_times)]
    fps_paused = paused_fps(viewer, max(1.0, args.seconds / 6))
    passes = pass_times(viewer, gl)
    renderer_name = gl.gl_info.get_renderer()
    lod = dict(viewer.renderer.lod_counts)
    if args.screenshot_dir:
        Path(args.screenshot_dir).mkdir(parents=True, exist_ok=True)
        viewer.save_screenshot(Path(args.screenshot_dir) / "viewer_plaza.png")
    viewer.close()
    load = os.getloadavg()
    fps = len(frame_ms) / elapsed
    s = life.stats
    print(f"living plaza, {args.mode} ({renderer_name}), {args.width}x{args.height}, opening view, "
          f"{args.seconds:g} s of frames after a 5-frame warm-up")
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} CPUs")
    print(f"characters {len(world.names)} ({len(life.names)} ambient), tiled {sum(len(z) for z in world.tilings)}, "
          f"flock agents {len(world.flock_positions()[0])}; planning budget {budget:g} ms/tick")
    print()
    print(f"{'':14} {'p50':>8} {'p99':>8} {'max':>8}   (ms)")
    print(f"{'frame':14} {np.percentile(frame_ms, 50):>8.1f} {np.percentile(frame_ms, 99):>8.1f} {max(frame_ms):>8.1f}")
    print(f"{'scene step':14} {np.percentile(step_ms, 50):>8.1f} {np.percentile(step_ms, 99):>8.1f} {max(step_ms):>8.1f}")
    if n_ticks:
        print(f"{'World tick':14} {np.percentile(ticks, 50):>8.1f} {np.percentile(ticks, 99):>8.1f} {ticks.max():>8.1f}"
              f"   ({n_ticks} ticks)")
    print()
    print(f"frame rate {fps:.1f} fps (target >= 30), {fps_paused:.1f} fps paused (the viewer alone); "
          f"LOD near/far {lod.get('near', 0)}/{lod.get('far', 0)}")
    if n_ticks:
        print(f"World tick p99 {np.percentile(ticks, 99):.1f} ms (target <= 16); "
              f"{world.time - t_warm:.1f} s simulated in {elapsed:.1f} s")
    print("paused frame by pass (ms, glFinish-bracketed medians): "
          + ", ".join(f"{k} {v:.2f}" for k, v in passes.items()))
    print(f"planning: plans used {world.stats['plans_done']}, not used {world.stats['plans_failed']}; ambient: "
          f"{int((life.goals_had > 0).sum())}/{len(life.names)} people have had goals, {s['arrived']} arrivals, "
          f"timed goals met on time {s['met']}/{s['met'] + s['late'] + s['failed']}")


def run(args):
    from runtime.viewer import TrackScene, headless, make_viewer
    headless.configure(args.mode == "headless")
    from pyglet import gl

    from runtime.library import load_library
    from runtime.viewer.baseline import InstancedCapsules, LineFigures
    from usd_io.world import read_world

    graph = load_library("default")
    env = read_world(ROOT / "samples" / "example_world" / "world.usda")
    rows = []
    for n in [int(c) for c in args.counts.split(",")]:
        half = max(10.0, float(np.sqrt(4.0 * n)) / 2)
        area = (-half, -half, half, half)
        scene = TrackScene(graph, n, env, seed=1, area=area)
        viewer = make_viewer(scene, headless=(args.mode == "headless"), width=args.width, height=args.height)
        viewer.camera.frame(area, margin=0.8)
        viewer.run(max_frames=5)                       # warm-up: shader compilation, first ticks
        times = {k: [] for k in ("step", "poses", "render", "gl wait")}
        frames = 0
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < args.seconds:
            viewer.run(max_frames=1)
            frames += 1
            for k in times:
                times[k].append(viewer.frame_ms.get(k, 0.0))
        elapsed = time.perf_counter() - t0
        fps = frames / elapsed
        # the same scene paused: the viewer's own cost (the stand-in scene's ticks excluded)
        fps_paused = paused_fps(viewer, max(1.0, args.seconds / 2))
        renderer_name = gl.gl_info.get_renderer()
        if args.screenshot_dir:
            Path(args.screenshot_dir).mkdir(parents=True, exist_ok=True)
            viewer.save_screenshot(Path(args.screenshot_dir) / f"viewer_{n}.png")
        lod = dict(viewer.renderer.lod_counts)
        bones = viewer.renderer.num_bones
        # the character pass alone: impostors vs the instanced-mesh baseline, same positions
        w, h = viewer.framebuffer_size()
        view, proj = viewer.camera.view(), viewer.camera.projection(w, h)
        P = np.asarray(scene.joint_positions()).copy()
        gl.glEnable(gl.GL_DEPTH_TEST)
        imp = [gl_time(lambda: viewer.renderer.draw_characters(view, proj, w, h, P), gl) for _ in range(5)]
        baseline = InstancedCapsules(scene.skeleton)        # GL objects live with this viewer's context
        gl_time(lambda: baseline.draw_characters(view, proj, w, h, P), gl)  # warm-up (shader compile)
        base = [gl_time(lambda: baseline.draw_characters(view, proj, w, h, P), gl) for _ in range(args.baseline_frames)]
        # calibration: ENVIRONMENT.md's line-figure renderer, same figures, same run
        lines = LineFigures(scene.skeleton)
        lf, t2 = 0, time.perf_counter()
        while time.perf_counter() - t2 < max(1.0, args.seconds / 3):
            lines.draw_frame(view, proj, w, h, np.asarray(scene.joint_positions()))
            gl.glFinish()
            viewer.window.flip()
            lf += 1
        fps_lines = lf / (time.perf_counter() - t2)
        rows.append((n, frames, fps, fps_paused, {k: float(np.median(v)) for k, v in times.items()}, lod, bones,
                     float(np.median(imp)), float(np.median(base)), fps_lines))
        viewer.close()
    load = os.getloadavg()
    print(f"viewer frame rate, {args.mode} ({renderer_name}), {args.width}x{args.height}, "
          f"example world + TrackScene, camera framing all characters, {args.seconds:g} s per run")
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} CPUs")
    print()
    head = (f"{'chars':>6} {'frames':>6} {'fps':>6} {'paused':>6} {'step ms':>8} {'poses ms':>8} {'render ms':>9} "
            f"{'GL wait':>8} {'LOD near/far':>13} | {'char pass ms':>12} {'instanced ms':>12} {'ratio':>6} | "
            f"{'lines fps':>9} {'paused/lines':>12}")
    print(head)
    print("-" * len(head))
    for n, frames, fps, fps_paused, t, lod, bones, imp, base, fl in rows:
        print(f"{n:>6} {frames:>6} {fps:>6.1f} {fps_paused:>6.1f} {t['step']:>8.2f} {t['poses']:>8.2f} "
              f"{t['render']:>9.2f} {t['gl wait']:>8.2f} {lod.get('near', 0):>6}/{lod.get('far', 0):<6} | "
              f"{imp:>12.1f} {base:>12.1f} {base / imp:>5.1f}x | {fl:>9.1f} {fps_paused / fl:>12.2f}")
    print()
    print("char pass = the character pass alone (near figures: 14 ray-cast capsule impostors each; far figures:")
    print("one screen-space quad each); instanced = one instance of an 8-sided capsule mesh per bone, 14 per figure.")
    print("fps = the whole loop with the scene ticking at 30 Hz; paused = the same frame, scene not stepping.")
    print("lines fps = ENVIRONMENT.md's reference renderer (20-bone line figures, one VBO + glBufferSubData) on")
    print("the same figures in the same run; ENVIRONMENT.md records 500 ~225 fps, 2000 ~70-97 fps on an idle machine.")
    ref = {500: 225.0, 2000: 83.0}
    for n, _, fps, fps_paused, *rest in rows:
        fl = rest[-1]
        line = f"{n} characters: {fps:.1f} fps live, {fps_paused:.1f} fps paused"
        if n in ref:
            line += (f"; scaled to an idle machine by the line-figure calibration ({ref[n]:g} / {fl:.1f}): "
                     f"~{fps_paused * ref[n] / fl:.0f} fps paused, ~{fps * ref[n] / fl:.0f} fps live")
        print(line + (" (target >= 30 fps)" if n == 2000 else ""))


if __name__ == "__main__":
    main()
