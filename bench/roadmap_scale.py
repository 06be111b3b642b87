"""How `crowdweave author roadmap` scales with the number of obstacles.

Generates world stages of N obstacles (rotated boxes and upright cylinders on a jittered grid,
one per 3.5 m x 3.5 m cell, so the free area and the roadmap grow with N as well), then times
the real command (``python -m authoring.cli author roadmap WORLD --out X.cwpack --quiet``) in a
subprocess for each source tree given, and prints wall and CPU seconds per tree, the growth of
the CPU time from the smallest to the largest world, and the exponent k of CPU ~ N^k fitted over
all sizes (n log n shows as k a little above 1; quadratic as 2). CPU time is the figure to
compare on a shared machine: the wall time also counts waiting for other processes.

    python bench/roadmap_scale.py                         # this checkout
    python bench/roadmap_scale.py --trees /work/main .    # baseline tree first, then this one
    python bench/roadmap_scale.py --sizes 500,1000 --trees .

The trees are used through ``PYTHONPATH``; every tree runs every size with the same world file.
"""
from __future__ import annotations

import argparse
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CELL = 3.5        # m per obstacle


def write_world(path: Path, n: int, seed: int = 0) -> None:
    """A Y-up metre world stage of ``n`` obstacles: 2/3 boxes (0.6-1.6 m, any rotation), 1/3
    upright cylinders (radius 0.3-0.8 m), one per cell of a square grid, jittered."""
    rng = np.random.default_rng(seed)
    side = int(math.ceil(math.sqrt(n)))
    lines = ['#usda 1.0', '(', '    defaultPrim = "World"', '    metersPerUnit = 1', '    upAxis = "Y"', ')', '',
             'def Xform "World"', '{', '    def Scope "Obstacles"', '    {']
    for k in range(n):
        i, j = divmod(k, side)
        x = (i + 0.5 + rng.uniform(-0.15, 0.15)) * CELL
        z = (j + 0.5 + rng.uniform(-0.15, 0.15)) * CELL
        if k % 3 == 2:
            r = rng.uniform(0.3, 0.8)
            lines += [f'        def Cylinder "C{k}"', '        {', '            uniform token axis = "Y"',
                      '            double height = 2', f'            double radius = {r:.4f}',
                      f'            double3 xformOp:translate = ({x:.4f}, 1, {z:.4f})',
                      '            uniform token[] xformOpOrder = ["xformOp:translate"]', '        }']
        else:
            sx, sz = rng.uniform(0.6, 1.6, size=2)
            a = rng.uniform(0, 360)
            lines += [f'        def Cube "B{k}"', '        {', '            double size = 1',
                      f'            float3 xformOp:scale = ({sx:.4f}, 2, {sz:.4f})',
                      f'            float xformOp:rotateY = {a:.3f}',
                      f'            double3 xformOp:translate = ({x:.4f}, 1, {z:.4f})',
                      '            uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateY", '
                      '"xformOp:scale"]', '        }']
    lines += ['    }', '}', '']
    path.write_text("\n".join(lines))


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_tree(tree: Path, world: Path, out: Path, timeout: float) -> tuple[float, float, str]:
    """(wall seconds, CPU seconds, what was built) of one run of the command."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    cmd = [sys.executable, "-m", "authoring.cli", "author", "roadmap", str(world), "--out", str(out), "--quiet"]
    t0, c0 = time.perf_counter(), _children_cpu()
    try:
        r = subprocess.run(cmd, env=env, cwd=str(tree), capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return float("nan"), float("nan"), f"timed out after {timeout:g} s"
    dt, cpu = time.perf_counter() - t0, _children_cpu() - c0
    if r.returncode != 0:
        return float("nan"), float("nan"), (r.stderr.strip().splitlines() or ["failed"])[-1]
    last = r.stdout.strip().splitlines()[-1]
    return dt, cpu, last.split(": ", 1)[-1].split(" (")[0]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", default="500,1000,2000,5000", help="obstacle counts (default 500,1000,2000,5000)")
    p.add_argument("--trees", nargs="+", default=[str(Path(__file__).resolve().parents[1])],
                   help="source trees to time (PYTHONPATH), e.g. a baseline checkout and this one")
    p.add_argument("--timeout", type=float, default=1800.0, help="seconds per run before giving up (default 1800)")
    args = p.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    trees = [Path(t).resolve() for t in args.trees]
    wall, cpu = {}, {}
    with tempfile.TemporaryDirectory(prefix="roadmap_scale.") as d:
        for n in sizes:
            world = Path(d) / f"world_{n}.usda"
            write_world(world, n)
            for t in trees:
                wall[n, t], cpu[n, t], what = run_tree(t, world, Path(d) / f"rm_{n}.cwpack", args.timeout)
                print(f"  {n:6d} obstacles  {t}: {wall[n, t]:8.2f} s wall, {cpu[n, t]:8.2f} s CPU  ({what})",
                      file=sys.stderr, flush=True)
    print(f"\n`crowdweave author roadmap` over a generated world (one obstacle per {CELL:g} m x {CELL:g} m): "
          "seconds wall / CPU (CPU time does not depend on what else the machine runs)")
    print(f"{'obstacles':>10} " + " ".join(f"{str(t)[-28:]:>28}" for t in trees))
    for n in sizes:
        print(f"{n:>10} " + " ".join(f"{f'{wall[n, t]:.2f} / {cpu[n, t]:.2f}':>28}" for t in trees))
    if len(sizes) > 1:
        a, b = sizes[0], sizes[-1]
        print(f"{'growth':>10} " + " ".join(f"{f'CPU x{cpu[b, t] / cpu[a, t]:.1f} for x{b / a:g}':>28}" for t in trees))
        ln = np.log(sizes)
        ks = []
        for t in trees:
            y = np.log([cpu[n, t] for n in sizes])
            ks.append(np.polyfit(ln, y, 1)[0] if np.all(np.isfinite(y)) else float("nan"))
        print(f"{'exponent':>10} " + " ".join(f"{f'CPU ~ N^{k:.2f}':>28}" for k in ks))
        nlogn = b * math.log(b) / (a * math.log(a))
        print(f"(n log n would be x{nlogn:.1f} from {a} to {b}; n^2 x{(b / a) ** 2:g})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
