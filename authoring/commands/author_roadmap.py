"""``crowdweave author roadmap world.usda --out roadmap.cwpack``: probabilistic roadmap of a world
(Sung, Kovar and Gleicher 2005, section 3.2), built offline for the runtime to load."""
from __future__ import annotations

import sys
import time

from authoring.commands.args import check_output, integer, limits, number
from authoring.roadmap import WALK_RADIUS
from runtime.limits import MAX_ROADMAP_NODES, MAX_SEED


def configure(p):
    p.add_argument("world", help="world stage (.usda/.usdc/.usd)")
    p.add_argument("--out", required=True, help="output pack (.cwpack)")
    p.add_argument("--radius", type=number(0, 10), default=WALK_RADIUS,
                   help=f"character radius the obstacles are grown by, m (default {WALK_RADIUS}: a walking "
                        "character's bounding cylinder; 0-10)")
    p.add_argument("--connect", type=number(0, 100, lo_open=True), default=3.0,
                   help="largest edge length, m (default 3; > 0, at most 100)")
    p.add_argument("--samples", type=integer(2, MAX_ROADMAP_NODES), default=None,
                   help=f"number of nodes (default: about two per m^2 of free ground; {limits(2, MAX_ROADMAP_NODES)})")
    p.add_argument("--seed", type=integer(0, MAX_SEED), default=0,
                   help=f"random seed (default 0; {limits(0, MAX_SEED)})")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args) -> int:
    from tqdm import tqdm

    from authoring.commands import CLIError
    from authoring.roadmap import build_roadmap
    from usd_io.world import WorldError, read_world

    out = check_output(args.out)
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
    rm.save(out)
    s = rm.summary()
    print(f"wrote {out}: {s['nodes']} nodes, {s['edges']} edges, mean degree {s['mean_degree']}, "
          f"{s['components']} component{'s' if s['components'] != 1 else ''} "
          f"(largest {s['largest_component']}), radius {rm.radius:g} m, connect {rm.connect_distance:g} m, "
          f"seed {args.seed} ({time.perf_counter() - t0:.1f} s)")
    return 0
