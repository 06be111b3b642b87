"""Benchmark: the goal-directed planner (Sung, Kovar and Gleicher 2005) over generated scenarios.

For each size (``--sizes 60x20,150x5``: 20 scenarios of 60 characters, seeds 0-19, and 5 of
150, seeds 0-4) every scenario is generated (``authoring.scenario_gen``: crossing flows, room
swaps, meetings, seats, boxes; ``--kind``), its roadmap built (not timed), then planned with
``runtime.crowd.scheduler.plan_scenario`` -- a fresh planning context per scenario, in a fresh
worker process with ``--jobs N`` -- and checked by the independent checker
``runtime.crowd.checker.check_crowd`` on the planned tracks. A row is printed as each
scenario finishes, a summary row per size when the size is done:

* ``pass``: scenarios the checker passes.
* ``exact``: characters meeting every constraint exactly (position within 1 mm, heading within
  0.1 deg, arrival in its window, the pose) with the per-frame adjustment within eps; count and
  share of all characters.
* ``warned``: characters whose ``CharacterResult.warnings`` is not empty.
* ``late``, ``relaxed``, ``waiting``: characters whose plan used that rung of the planner's
  ladder (``CharacterResult.ladder``, :mod:`runtime.crowd.goals`): arriving after their window,
  an adjustment over eps (up to 4 x), or left waiting in place; a character counts once per kind.
* ``pairs``: overlapping character pairs; ``obst.fr``: frames inside obstacles, summed over
  characters (``obst.ch``: characters).
* planning seconds per character (``CharacterResult.seconds``, wall clock, all passes): p50,
  p95 and max over the characters of the size; per scenario (``CrowdResult.total_seconds``):
  the max; ``cpu/scen``: the CPU seconds of the scenario's planning (the max; its worker
  processes included, ``CrowdResult.cpu_seconds``), which other work on a shared machine
  inflates less than the wall clock.

Under each size, a line per crowd kind gives the characters that fail and why: ``eps``
(adjustment over eps), ``window`` / ``pose`` / ``position`` (a goal not met exactly),
``overlap`` (in an overlapping pair), ``obstacle`` (inside an obstacle); a character can have
several causes.

    CROWDWEAVE_CACHE=/tmp/cwcache .venv/bin/python bench/crowd_sweep.py [--quick] [--sizes 60x20,150x5]
        [--seeds 0-4] [--kind mixed] [--jobs 1] [--csv out.csv] [--policy reserve_starts=all ...]

``--quick``: 3 scenarios of 30 characters. ``--jobs 1`` (default) plans one scenario at a time
so that timings are clean (the machine's other work still shows). Figures only, no asserts.
"""
from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for _p in (ROOT, HERE):             # the project, and crowd_table beside this file
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

from authoring.scenario_gen.params import KINDS  # noqa: E402

GIVEN_UP = ("late", "relaxed", "waiting")
CAUSES = ("eps", "window", "pose", "position", "overlap", "obstacle")
_GRAPH = None


def _graph():
    """The default library, loaded once per process, with the compiled kernels warmed up by
    an untimed two-character plan."""
    global _GRAPH
    if _GRAPH is None:
        from crowd_table import default_graph, warm_up
        _GRAPH = default_graph()
        warm_up(_GRAPH)
    return _GRAPH


def character_causes(report, name) -> set:
    """Why the checker's report counts character ``name`` as failing (empty: it is exact)."""
    causes = set()
    if not report.characters[name]["within_eps"]:
        causes.add("eps")
    for g in report.goals:
        if g["character"] != name:
            continue
        if not g["in_window"]:
            causes.add("window")
        if not g["pose_ok"]:
            causes.add("pose")
        if g["position_error_m"] > 1e-3 or (g["heading_error_deg"] or 0.0) > 0.1:
            causes.add("position")
    if any(name in (o["a"], o["b"]) for o in report.character_overlaps):
        causes.add("overlap")
    if any(o["character"] == name for o in report.obstacle_overlaps):
        causes.add("obstacle")
    return causes


def run_one(characters: int, seed: int, kind: str, policy: dict | None = None) -> dict:
    """Generate, plan and check one scenario; the figures as a dict (picklable)."""
    from authoring.roadmap import build_roadmap
    from authoring.scenario_gen import generate_scenario
    from runtime.crowd.checker import check_crowd
    from runtime.crowd.scheduler import plan_scenario
    graph = _graph()
    t0 = time.perf_counter()
    gen = generate_scenario(seed=seed, characters=characters, kind=kind)
    sc = gen.scenario(node_labels=set(graph.node_labels_all()))
    roadmap = build_roadmap(gen.env, seed=0)
    setup = time.perf_counter() - t0
    from runtime.crowd.planner import CrowdPolicy
    res = plan_scenario(sc, graph, gen.env, roadmap, policy=CrowdPolicy(**(policy or {})))
    cpu = res.cpu_seconds
    report = check_crowd(sc, {c.name: c.track for c in res.characters}, graph, gen.env, res.fps)
    s = report.summary()
    given = {k: 0 for k in GIVEN_UP}
    by_kind = {}
    exact = 0
    for c in res.characters:
        for k in {st.kind for st in c.ladder}:
            if k in GIVEN_UP:
                given[k] += 1
        causes = character_causes(report, c.name)
        exact += not causes
        row = by_kind.setdefault(gen.kinds[c.name], {"characters": 0, "failing": 0, **{k: 0 for k in CAUSES}})
        row["characters"] += 1
        row["failing"] += bool(causes)
        for k in causes:
            row[k] += 1
    return {"characters": characters, "seed": seed, "kind": kind, "passed": bool(report.passed), "exact": exact,
            "warned": sum(1 for c in res.characters if c.warnings), **given,
            "pairs": len(report.character_overlaps),
            "obstacle_frames": int(sum(o["frames"] for o in report.obstacle_overlaps)),
            "obstacle_characters": len(report.obstacle_overlaps),
            "seconds": [float(c.seconds) for c in res.characters], "total": float(res.total_seconds), "cpu": cpu,
            "passes": res.passes, "setup": setup, "by_kind": by_kind,
            "within_eps": s["characters_within_eps"], "goals_in_window": s["goals_in_window"], "goals": s["goals"]}


HEAD = (f"{'size':>5} {'seed':>5} {'pass':>6} {'exact':>11} {'%':>6} {'warned':>6} {'late':>5} {'relax':>5} "
        f"{'wait':>5} {'pairs':>6} {'obst.fr':>8} {'obst.ch':>7} {'s/char p50':>10} {'p95':>7} {'max':>7} "
        f"{'s/scen max':>10} {'cpu/scen':>8}")


def _row(size, seed, passed, exact, n, r, secs, scen_max, cpu_max) -> str:
    p50, p95, mx = (np.percentile(secs, [50, 95, 100]) if len(secs) else (0.0, 0.0, 0.0))
    return (f"{size:>5} {seed:>5} {passed:>6} {f'{exact}/{n}':>11} {100.0 * exact / max(n, 1):>5.1f}% "
            f"{r['warned']:>6} {r['late']:>5} {r['relaxed']:>5} {r['waiting']:>5} {r['pairs']:>6} "
            f"{r['obstacle_frames']:>8} {r['obstacle_characters']:>7} {p50:>10.2f} {p95:>7.2f} {mx:>7.2f} "
            f"{scen_max:>10.1f} {cpu_max:>8.1f}")


def scenario_row(r) -> str:
    return _row(r["characters"], r["seed"], "PASS" if r["passed"] else "fail", r["exact"], r["characters"], r,
                r["seconds"], r["total"], r["cpu"])


def size_summary(rows) -> list:
    """The summary line of one size and its per-kind failure lines."""
    n = sum(r["characters"] for r in rows)
    tot = {k: sum(r[k] for r in rows) for k in ("warned", "late", "relaxed", "waiting", "pairs",
                                                 "obstacle_frames", "obstacle_characters")}
    passed = sum(r["passed"] for r in rows)
    lines = [_row(rows[0]["characters"], "all", f"{passed}/{len(rows)}", sum(r["exact"] for r in rows), n, tot,
                  [s for r in rows for s in r["seconds"]], max(r["total"] for r in rows), max(r["cpu"] for r in rows))]
    kinds = {}
    for r in rows:
        for k, v in r["by_kind"].items():
            acc = kinds.setdefault(k, {key: 0 for key in v})
            for key, x in v.items():
                acc[key] += x
    for k, v in sorted(kinds.items()):
        why = ", ".join(f"{c} {v[c]}" for c in CAUSES if v[c])
        lines.append(f"      {k:<9} failing {v['failing']}/{v['characters']}" + (f" ({why})" if why else ""))
    return lines


def typed_value(default, value: str):
    """``value`` read as the type of a dataclass field's ``default`` (bools from 1/true/yes);
    ValueError when it does not read as that type."""
    if isinstance(default, bool):
        return value.lower() in ("1", "true", "yes")
    if default is None:             # an optional number (``workers``, ``rung_budget``)
        for kind in (int, float):
            try:
                return kind(value)
            except ValueError:
                pass
        return value
    return type(default)(value) if isinstance(default, (int, float)) else value


def parse_sizes(text):
    out = []
    for part in text.split(","):
        n, _, count = part.strip().partition("x")
        out.append((int(n), int(count or 1)))
    return out


def parse_seeds(text):
    seeds = []
    for part in text.split(","):
        a, _, b = part.strip().partition("-")
        seeds += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return seeds


def write_csv(path, rows):
    import csv
    import io

    from runtime.assets import atomic_write_bytes
    buf = io.StringIO()
    cols = ["characters", "seed", "kind", "passed", "exact", "within_eps", "goals_in_window", "goals", "warned",
            "late", "relaxed", "waiting", "pairs", "obstacle_frames", "obstacle_characters", "passes",
            "seconds_p50", "seconds_p95", "seconds_max", "total_seconds", "cpu_seconds", "setup_seconds"]
    w = csv.writer(buf)
    w.writerow(cols)
    for r in rows:
        p50, p95, mx = np.percentile(r["seconds"], [50, 95, 100])
        extra = {"seconds_p50": p50, "seconds_p95": p95, "seconds_max": mx, "total_seconds": r["total"],
                 "cpu_seconds": r["cpu"], "setup_seconds": r["setup"]}
        w.writerow([round(extra[c], 4) if c in extra else r[c] for c in cols])
    atomic_write_bytes(path, buf.getvalue().encode())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="The goal-directed planner over generated scenarios: pass rate, "
                                             "exact characters, overlaps, obstacle frames, planning time.")
    ap.add_argument("--sizes", default="60x20,150x5", help="CHARACTERSxSCENARIOS, comma-separated (default 60x20,150x5)")
    ap.add_argument("--seeds", default=None, help="seeds for every size, e.g. 0-4 or 3,7 (default 0..SCENARIOS-1)")
    ap.add_argument("--kind", default="mixed", choices=("mixed",) + KINDS,
                    help="crowd kind of the generated scenarios (default mixed: one kind per district)")
    ap.add_argument("--quick", action="store_true", help="3 scenarios of 30 characters")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1: clean timings)")
    ap.add_argument("--csv", default=None, help="also write one row per scenario to this CSV file")
    ap.add_argument("--policy", nargs="*", default=[], metavar="FIELD=VALUE",
                    help="CrowdPolicy fields to set, e.g. reserve_starts=all order=longest passes=2")
    args = ap.parse_args(argv)
    policy = {}
    from runtime.crowd.planner import CrowdPolicy
    fields = CrowdPolicy.__dataclass_fields__
    for item in args.policy:
        key, _, value = item.partition("=")
        if key not in fields or not value:
            ap.error(f"--policy: {item!r} is not FIELD=VALUE with a CrowdPolicy field ({', '.join(fields)})")
        default = getattr(CrowdPolicy(), key)
        if value.lower() == "none":
            policy[key] = None
            continue
        try:
            policy[key] = typed_value(default, value)
        except ValueError:
            ap.error(f"--policy: {key} must be a {type(default).__name__}, got {value!r}")
    try:
        sizes = parse_sizes("30x3" if args.quick else args.sizes)
        seeds = parse_seeds(args.seeds) if args.seeds else None
    except ValueError:
        ap.error("--sizes is like 60x20,150x5 and --seeds like 0-4 or 3,7")
    from authoring.default_library import ensure_library
    ensure_library("default", log=lambda m: print(m, file=sys.stderr), progress=False)
    print(f"goal-directed crowds on generated scenarios (kind {args.kind}; policy {policy or 'default'}); planner: "
          f"runtime.crowd.scheduler.plan_scenario, checker: runtime.crowd.checker.check_crowd; jobs {args.jobs}")
    print(HEAD)
    print("-" * len(HEAD))
    all_rows = []
    pool = ProcessPoolExecutor(max_workers=args.jobs) if args.jobs > 1 else None
    try:
        for n, count in sizes:
            todo = seeds if seeds is not None else list(range(count))
            rows = []
            if pool is None:
                for s in todo:
                    rows.append(run_one(n, s, args.kind, policy))
                    print(scenario_row(rows[-1]), flush=True)
            else:
                futures = [pool.submit(run_one, n, s, args.kind, policy) for s in todo]
                for f in as_completed(futures):
                    rows.append(f.result())
                    print(scenario_row(rows[-1]), flush=True)
            rows.sort(key=lambda r: r["seed"])
            for line in size_summary(rows):
                print(line, flush=True)
            print()
            all_rows += rows
    finally:
        if pool is not None:
            pool.shutdown()
    if args.csv:
        write_csv(args.csv, all_rows)
        print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
