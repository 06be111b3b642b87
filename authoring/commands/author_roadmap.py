"""``crowdweave author roadmap world.usda --out roadmap.cwpack``: probabilistic roadmap of a world
(Sung, Kovar and Gleicher 2005, section 3.2), built offline for the runtime to load."""
from __future__ import annotations

import sys
import time
from pathlib import Path

from authoring.roadmap import WALK_RADIUS


def configure(p):
    p.add_argument("world", help="world stage (.usda/.usdc/.usd)")
    p.add_argument("--out", required=True, help="output pack (.cwpack)")
    p.add_argument("--radius", type=float, default=WALK_RADIUS, help=f"character radius the obstacles are grown by, m (default {WALK_RADIUS}: a walking character's bounding cylinder)")
    p.add_argument("--connect", type=float, default=3.0, help="largest edge length, m (default 3)")
    p.add_argument("--samples", type=int, default=None, help="number of nodes (default: about one per 2 m^2 of free ground)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args) -> int:
    from tqdm import tqdm

    from authoring.commands import CLIError
    from authoring.roadmap import build_roadmap
    from usd_io.world import WorldError, read_world

    t0 = time.perf_counter()
    quiet = args.quiet or not sys.stderr.isatty()
    try:
        env = read_world(args.world)
    except WorldError as e:
        raise CLIError(str(e)) from None
    print(f"{args.world}: {len(env.polygons)} polygon and {len(env.circles)} circle obstacles, "
          f"{len(env.markers)} markers")
    bars = {}

    def progress(stage, done, total):
        bar = bars.get(stage)
        if bar is None:
            bar = bars[stage] = tqdm(total=total, desc=stage, unit="pt" if stage == "sampling" else "edge",
                                     disable=quiet, leave=False)
        bar.total = total
        bar.n = done
        bar.refresh()

    try:
        rm = build_roadmap(env, radius=args.radius, n_samples=args.samples, connect_distance=args.connect,
                           seed=args.seed, progress=progress)
    except ValueError as e:
        raise CLIError(f"{args.world}: {e}") from None
    finally:
        for b in bars.values():
            b.close()
    out = Path(args.out)
    rm.save(out)
    s = rm.summary()
    print(f"wrote {out}: {s['nodes']} nodes, {s['edges']} edges, mean degree {s['mean_degree']}, "
          f"{s['components']} component{'s' if s['components'] != 1 else ''} "
          f"(largest {s['largest_component']}), radius {rm.radius:g} m, connect {rm.connect_distance:g} m, "
          f"seed {args.seed} ({time.perf_counter() - t0:.1f} s)")
    return 0
