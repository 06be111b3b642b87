"""Benchmark: two variants of the segment search on the same inputs (paired), inside a crowd run.

A generated scenario (``authoring.scenario_gen``) is planned as usual
(``runtime.crowd.scheduler.plan_scenario``, variant A's parameters). Every search the ladder of
alternatives runs (``runtime.crowd.goals.SegmentLadder.run``: the first search of a segment and
every rung) is first run twice more on exactly its inputs -- start, goal, way points, route,
iteration limit, the same random state, the same planned characters, no motion reuse -- once
with variant A's parameters and once with B's; then the run goes on with A's own search. So the
two variants meet the same problems, and one scenario gives a few hundred paired searches: a
change to the search shows in them even when the whole crowd's outcome moves by chance (any
change reshuffles which characters meet whom).

A variant is a list of ``FIELD=VALUE``: any ``SearchParams`` field, or ``still_static`` (whether
the search's static filter sees who stays put, ``CrowdPolicy.still_static``).

    CROWDWEAVE_CACHE=/tmp/cwcache .venv/bin/python bench/search_pairs.py --characters 24 --seed 0 \\
        --kind rooms --a still_static=false --b still_static=true

Prints, per variant: searches, searches that found a clean motion (every constraint within eps,
collision-free), those clean in this variant only, CPU seconds and iterations; and B/A ratios.
Figures only, no asserts.
"""
from __future__ import annotations

import argparse
import copy
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from authoring.roadmap import build_roadmap  # noqa: E402
from authoring.scenario_gen import generate_scenario  # noqa: E402
from runtime.crowd import goals  # noqa: E402
from runtime.crowd.planner import CrowdPolicy, SearchParams, run_to_completion  # noqa: E402
from runtime.crowd.scheduler import plan_scenario  # noqa: E402

import crowd_sweep  # noqa: E402

KINDS = ("mixed",) + crowd_sweep.KINDS


def parse_variant(items: list[str]) -> dict:
    """``FIELD=VALUE`` items: SearchParams fields (typed like their defaults) and ``still_static``."""
    out = {}
    defaults = SearchParams()
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            raise SystemExit(f"search_pairs: expected FIELD=VALUE, got {item!r}")
        if key == "still_static":
            out[key] = crowd_sweep.typed_value(True, value)
            continue
        if not hasattr(defaults, key):
            raise SystemExit(f"search_pairs: {key!r} is not a SearchParams field nor still_static")
        d = getattr(defaults, key)
        if not isinstance(d, (bool, int, float)):
            raise SystemExit(f"search_pairs: {key!r} cannot be set from the command line")
        try:
            out[key] = crowd_sweep.typed_value(d, value)
        except ValueError:
            raise SystemExit(f"search_pairs: {key} must be a {type(d).__name__}, got {value!r}") from None
    return out


def paired_run(characters: int, seed: int, kind: str, passes: int, a: dict, b: dict) -> list[tuple]:
    """Plan the scenario with A; returns one (clean A, clean B, CPU A, CPU B, iterations A,
    iterations B) per ladder search."""
    graph = crowd_sweep._graph()
    gen = generate_scenario(seed=seed, characters=characters, kind=kind)
    sc = gen.scenario(node_labels=set(graph.node_labels_all()))
    roadmap = build_roadmap(gen.env, seed=0)
    rows = []
    original = goals.SegmentLadder.run

    def run(self, cfg, goal, n_max=None, planner=None, waypoints=None, rung=True, schedule=None):
        pl = planner or self.planner
        spent = rung and self.rung_left is not None and self.rung_left <= 0
        if not spent:
            n = self.n_retry if n_max is None else n_max
            if rung and self.rung_left is not None:
                n = min(n, self.rung_left)
            saved = (pl.p, pl.cache, pl.still)
            pl.cache = None
            got = []
            for variant in (a, b):
                prm = {k: v for k, v in variant.items() if k != "still_static"}
                pl.still = saved[2] if variant.get("still_static", True) else None
                pl.p = pl.collider.p = dataclasses.replace(saved[0], **prm)
                t = time.process_time()
                res = run_to_completion(pl.run(cfg, goal, copy.deepcopy(self.rng), name=self.name, n_max=n,
                                               waypoints=waypoints, schedule=schedule))
                got.append((not res.warning, time.process_time() - t, res.iterations))
            pl.p = pl.collider.p = saved[0]
            pl.cache, pl.still = saved[1], saved[2]
            rows.append((got[0][0], got[1][0], got[0][1], got[1][1], got[0][2], got[1][2]))
        return (yield from original(self, cfg, goal, n_max, planner, waypoints, rung, schedule=schedule))

    goals.SegmentLadder.run = run
    try:
        params = SearchParams(eps=sc.epsilon, **{k: v for k, v in a.items() if k != "still_static"})
        policy = CrowdPolicy(passes=passes, still_static=a.get("still_static", True) or b.get("still_static", True))
        plan_scenario(sc, graph, gen.env, roadmap, params=params, policy=policy)
    finally:
        goals.SegmentLadder.run = original
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--characters", type=int, default=60, help="characters in the scenario (default 60)")
    ap.add_argument("--seed", type=int, default=2, help="scenario seed (default 2)")
    ap.add_argument("--kind", default="mixed", choices=KINDS, help="crowd kind (default mixed)")
    ap.add_argument("--passes", type=int, default=1, help="planning passes (default 1: the first pass's searches)")
    ap.add_argument("--a", nargs="*", default=[], metavar="FIELD=VALUE", help="variant A (default: the defaults)")
    ap.add_argument("--b", nargs="*", default=[], metavar="FIELD=VALUE", help="variant B")
    args = ap.parse_args(argv)
    a, b = parse_variant(args.a), parse_variant(args.b)
    rows = paired_run(args.characters, args.seed, args.kind, args.passes, a, b)
    print(f"paired searches: {args.characters} characters, {args.kind}, seed {args.seed}, {args.passes} pass(es); "
          f"A = {a or 'defaults'}, B = {b or 'defaults'}")
    print(f"{'variant':8s} {'searches':>8s} {'clean':>6s} {'only':>5s} {'cpu s':>8s} {'iterations':>10s}")
    for k, name in ((0, "A"), (1, "B")):
        clean = sum(r[k] for r in rows)
        only = sum(r[k] and not r[1 - k] for r in rows)
        print(f"{name:8s} {len(rows):8d} {clean:6d} {only:5d} {sum(r[2 + k] for r in rows):8.1f} "
              f"{sum(r[4 + k] for r in rows):10d}")
    ca, cb = sum(r[2] for r in rows), sum(r[3] for r in rows)
    na, nb = sum(r[0] for r in rows), sum(r[1] for r in rows)
    print(f"B/A: clean {nb / max(na, 1):.2f}, cpu {cb / max(ca, 1e-9):.2f}")


if __name__ == "__main__":
    main()
