"""Benchmark: the Table 1 and its Figures 11 and 12 on the sample scenarios.

* **Table 1** -- for every sample (``samples/<name>``, loaded with
  ``authoring.commands.bake.load_sample``, planned with ``runtime.crowd.scheduler.plan_scenario``):
  the number of characters, the mean duration of a character's motion (time of its last
  goal's arrival), the mean synthesis time per character (the total over all planning passes
  divided by the characters), the total synthesis time, the passes run (``pass``), the
  planner's warnings and the independent checker's verdict (``runtime.crowd.checker``, run on
  the planned tracks). The paper's figures (3.0 GHz PC, 2005) are printed beside ours, with the
  ratios of our total and of our mean per character to theirs. (In the paper's rows 6a and 6b
  the total, 0.86 s and 0.90 s, is not characters x mean as in rows 1-5: 300 x 0.034 s =
  10.2 s, 500 x 0.035 s = 17.5 s. The table prints a note; both ratios are shown.)
  ``reused`` counts the segments whose motion was another character's with the same task
  (``runtime.crowd.motion_cache``) out of all segments planned; the grid rows are planned a
  second time with reuse off -- every character searched -- and that baseline's total and the
  ratio are printed under them.

A two-character plan runs first, untimed, so that loading numba's compiled kernels (once per
process) is not counted in the first row measured; its time is printed.
* **Figure 11** -- mean synthesis time per character for a 300-character grid (20 x 15,
  ``samples/make_samples.grid_scenario``) at grid spacings 2.2, 2.6, 3.0 and 3.5 m (the samples
  use 3.0 m), widest first, each row printed when done with its ratio to the widest spacing
  measured in the same run (``--spacings 2.6,3.0`` picks the spacings).
* **Figure 12** -- total (and per-character) synthesis time for spell70 with the adjustment
  tolerance eps scaled by 0.5, 1, 2, 4 and 8, the ratio to eps x 1 measured in the same run; the
  checker uses the scaled eps of each row.

``--plot PNG`` draws Figure 11 to PNG and Figure 12 to the same name with ``-fig12`` (with
``--only fig12``: Figure 12 to PNG).

Figures only, no asserts. Timings are wall-clock on this machine; planning is single-threaded.

    CROWDWEAVE_CACHE=/tmp/cwcache .venv/bin/python bench/crowd_table.py [--quick] [--only NAME] [--spacings ...] [--quiet]

``--no-reuse`` makes every character search (``CrowdPolicy.reuse_motions = False``), as
in the paper; the dense rows of Figure 11 then take 15-30 min each.

``--quick`` plans at most 10 characters of each sample (a prefix of the planning order, which
keeps every timing dependency), a 10 x 6 grid instead of the 300/500 ones, three spacings and
three eps scales. ``--only NAME`` runs one sample's Table 1 row, or ``table1`` (all its rows),
``fig11`` or ``fig12``.
"""
from __future__ import annotations

import argparse
import copy
import sys
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
SAMPLES_DIR = ROOT / "samples"
if str(SAMPLES_DIR) not in sys.path:
    sys.path.insert(0, str(SAMPLES_DIR))

# (example, sample, paper: characters, mean duration s, mean synthesis s per character, total s)
TABLE1 = [
    ("1", "meet20", (20, 14.8, 0.21, 4.2)),
    ("2", "spell70", (70, 21.3, 0.18, 12.6)),
    ("3", "rooms_box", (1, 83.3, 0.01, 0.01)),
    ("4", "theater40", (40, 30.2, 0.35, 14.0)),
    ("5", "fetch_boxes20", (20, 23.6, 0.15, 3.0)),
    ("6a", "grid300", (300, 25.3, 0.034, 0.86)),
    ("6b", "grid500", (500, 25.6, 0.035, 0.90)),
]
FIG11_SPACINGS = (2.2, 2.6, 3.0, 3.5)
FIG12_SCALES = (0.5, 1.0, 2.0, 4.0, 8.0)
QUICK_CHARACTERS = 10


def prefix(sc, n: int):
    """The scenario restricted to the first ``n`` characters of its planning order (a prefix
    of a topological order keeps every 'after' target)."""
    from runtime.crowd.scenario import planning_order
    if len(sc.characters) <= n:
        return sc
    keep = sorted(planning_order(sc)[:n])
    out = copy.copy(sc)
    out.characters = [sc.characters[i] for i in keep]
    return out


def default_graph():
    from runtime.library import load_library
    return load_library("default", None)


REUSE = True        # --no-reuse: every character searches (the paper's own method, section 3)


def run(sc, graph, env, roadmap, eps=None, quiet=True, reuse=None):
    """Plan and check one scenario; returns a dict of the figures. ``reuse``: the planner tries
    motions found for other characters' same tasks first (``CrowdPolicy.reuse_motions``)."""
    from tqdm import tqdm

    from runtime.crowd.checker import check_crowd
    from runtime.crowd.scheduler import plan_scenario
    from runtime.crowd.planner import CrowdPolicy, SearchParams
    eps = tuple(eps or sc.epsilon)
    params = SearchParams(eps=eps)
    policy = CrowdPolicy(reuse_motions=REUSE if reuse is None else reuse)
    with tqdm(total=len(sc.characters), desc=sc.name, unit="char", leave=False, disable=quiet) as bar:
        res = plan_scenario(sc, graph, env, roadmap, params=params, policy=policy, progress=bar.update)
    tracks = {c.name: c.track for c in res.characters}
    rep = check_crowd(sc, tracks, graph, env, res.fps, eps=eps)
    s = rep.summary()
    n = len(res.characters)
    return {"n": n,
            "duration": sum(c.motion_seconds for c in res.characters) / max(n, 1),
            # all passes count: the total over the characters (failed ones are planned again)
            "per_char": res.total_seconds / max(n, 1),
            "passes": res.passes,
            "reused": res.reused, "searched": res.searched,
            "total": res.total_seconds,
            "max_char": max((c.seconds for c in res.characters), default=0.0),
            "warnings": sum(len(c.warnings) for c in res.characters),  # of the pass kept
            "passed": s["passed"], "summary": s,
            "by_name": {c.name: (c.motion_seconds, c.seconds, len(c.warnings)) for c in res.characters}}


def reused(r) -> str:
    """Segments whose motion was reused / all segments planned (counting every try)."""
    n = r["reused"] + r["searched"]
    return f"{r['reused']}/{n}" if n else "-"


def verdict(r) -> str:
    s = r["summary"]
    if r["passed"]:
        return "PASS"
    why = []
    if s["max_position_error_mm"] > 1.0 or s["max_heading_error_deg"] > 0.1:
        why.append("goal error")
    if s["goals_in_window"] < s["goals"]:
        why.append(f"{s['goals'] - s['goals_in_window']} late/early")
    if s["poses_ok"] < s["goals"]:
        why.append(f"{s['goals'] - s['poses_ok']} poses")
    if s["fraction_within_eps"] < 0.99:
        why.append(f"eps {s['characters_within_eps']}/{s['characters']}")
    if s["character_overlap_pairs"]:
        why.append(f"{s['character_overlap_pairs']} overlapping pairs")
    if s["obstacle_overlap_characters"]:
        why.append(f"{s['obstacle_overlap_characters']} in obstacles")
    return "FAIL (" + ", ".join(why) + ")"


def warm_up(graph):
    """Plan a two-character scenario, untimed: the first planning in a process loads numba's
    compiled kernels from its cache (or compiles them), which a running game pays once at start."""
    from runtime.crowd.scenario import parse_scenario
    from runtime.crowd.scheduler import plan_scenario
    chars = [{"name": f"w{k}", "start": {"position": [0.0, 3.0 * k], "heading": 90.0, "pose": "stand"},
              "goal": [{"position": [6.0, 3.0 * (1 - k)]}]} for k in range(2)]
    t0 = time.perf_counter()
    plan_scenario(parse_scenario({"name": "warm-up", "duration": 12.0, "character": chars}), graph)
    return time.perf_counter() - t0


def table1(names, quick, quiet):
    from authoring.commands.bake import load_sample
    from runtime.crowd.scenario import parse_scenario
    print("Table 1 (Sung, Kovar and Gleicher 2005): goal-directed synthesis of the sample scenarios"
          + (f"  [--quick: at most {QUICK_CHARACTERS} characters each; grids 10 x 6]" if quick else ""))
    head = (f"{'ex':<3} {'sample':<14} {'chars':>5} {'duration':>9} {'synth/char':>11} {'total':>9} "
            f"{'max char':>9} {'warn':>5} {'pass':>4}  {'paper: chars dur synth/char total':<34} {'total/paper':>11} "
            f"{'per char/paper':>14}  {'reused':>7}  checker")
    print(head)
    print("-" * len(head))
    for ex, name, paper in TABLE1:
        if name not in names:
            continue
        t0 = time.perf_counter()
        if quick and name.startswith("grid"):
            import make_samples
            graph = default_graph()
            data = make_samples.grid_scenario(10, 6, spacing=3.0, seed=0, name=f"{name}-quick",
                                              start_still=(name == "grid500"))
            sc = parse_scenario(data, f"<{name} quick>", node_labels=set(graph.node_labels_all()))
            env = roadmap = None
        else:
            sc, graph, env, roadmap = load_sample(SAMPLES_DIR / name, log=lambda m: None, progress=False)
            if quick:
                sc = prefix(sc, QUICK_CHARACTERS)
        load_s = time.perf_counter() - t0
        r = run(sc, graph, env, roadmap, quiet=quiet)
        pc, pd, ps, pt = paper
        print(f"{ex:<3} {name:<14} {r['n']:>5} {r['duration']:>8.1f}s {r['per_char']:>10.3f}s {r['total']:>8.2f}s "
              f"{r['max_char']:>8.2f}s {r['warnings']:>5} {r['passes']:>4}  {pc:>5} {pd:>5.1f}s {ps:>8.3f}s {pt:>6.2f}s    "
              f"{r['total'] / pt:>10.1f}x {r['per_char'] / ps:>13.2f}x  {reused(r):>7}  {verdict(r)}", flush=True)
        if abs(pc * ps - pt) > 0.2 * pt and r['n'] == pc:
            print(f"    (the paper's total {pt:g} s is not its {pc} characters x {ps:g} s = {pc * ps:.1f} s, "
                  f"unlike rows 1-5: against that product ours is {r['total'] / (pc * ps):.2f}x)")
        if name.startswith("grid") and r["reused"] and REUSE:
            # the baseline in the same run: every character searched for its own motion
            b = run(sc, graph, env, roadmap, quiet=quiet, reuse=False)
            print(f"    (every character searched, no reuse: total {b['total']:.2f} s, {b['per_char']:.3f} s per character, "
                  f"{b['warnings']} warnings, checker {verdict(b)}; reuse is {b['total'] / r['total']:.1f}x faster)",
                  flush=True)
        if "main" in r["by_name"] and r["n"] > 1:
            d, t, w = r["by_name"]["main"]
            print(f"    (the crossing character 'main' alone: duration {d:.1f} s, synthesis {t:.3f} s, {w} warnings; "
                  f"the others are its moving obstacles)")
        if load_s > 5:
            print(f"    (loading the sample, library and roadmap took {load_s:.1f} s, not counted)")


def plot_fig11(rows, path, title):
    """Figure 11 as a picture: planning seconds per character against grid spacing (rows:
    (spacing, seconds per character, passed)), written atomically to ``path`` (PNG)."""
    import plotting
    rows = sorted(rows)
    fig, (ax,) = plotting.figure()
    xs = [r[0] for r in rows]
    ys = [r[1] for r in rows]
    ax.plot(xs, ys, "o-", color=plotting.OURS, label="crowdweave (this machine)")
    for x, y, ok in rows:
        plotting.verdict_label(ax, x, y, ok)
    ax.set_xlabel("grid spacing (m)")
    ax.set_ylabel("planning time per character (s)")
    ax.set_title(textwrap.fill(title, 75), fontsize=9)     # one line would run off the figure
    ax.invert_xaxis()                    # denser to the right, as the paper reads
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    plotting.save_atomic(fig, path)


def plot_fig12(rows, path, n_characters, eps, reuse=True):
    """Figure 12 as a picture: planning seconds per character against the adjustment tolerance
    eps (rows: (eps scale, seconds per character, passed); ``eps`` the scenario's eps x 1 as
    (m/s, deg/s, s/s)), the total for ``n_characters`` on the right-hand axis, ``reuse`` whether
    characters reused each other's motions (``--no-reuse``: the paper's method); written
    atomically to ``path`` (PNG). The paper draws this curve without printing its values, so
    only ours is drawn."""
    import plotting
    rows = sorted(rows)
    fig, (ax,) = plotting.figure(height=3.9)
    xs = [r[0] for r in rows]
    ys = [r[1] for r in rows]
    how = "motions reused between same tasks" if reuse else "every character searched, as the paper"
    ax.plot(xs, ys, "o-", color=plotting.OURS, label=f"crowdweave (this machine), {n_characters} characters,\n{how}")
    for x, y, ok in rows:
        plotting.verdict_label(ax, x, y, ok)
    ax.set_xscale("log", base=2)
    ax.set_xticks(xs)
    ax.set_xticklabels([f"x{k:g}\n{k * eps[0] * 100:g} cm/s" for k in xs], fontsize=8)
    ax.set_xlabel(f"adjustment tolerance eps (x1 = {eps[0] * 100:g} cm/s, {eps[1]:g} deg/s, "
                  f"{eps[2]:.4g} s/s)", fontsize=8)
    ax.set_ylabel("planning time per character (s)")
    n = max(n_characters, 1)
    right = ax.secondary_yaxis("right", functions=(lambda y: y * n, lambda y: y / n))
    right.set_ylabel(f"total for {n_characters} characters (s)")
    ax.set_ylim(bottom=0, top=max(ys + [0.0]) * 1.2 or 1.0)
    ax.set_title("Figure 12 (Sung, Kovar and Gleicher 2005): synthesis time against eps, spell70", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, title="the paper prints no values for this figure", title_fontsize=7)
    fig.tight_layout()
    plotting.save_atomic(fig, path)


def fig11(quick, quiet, spacings=None, plot=None):
    import make_samples
    from runtime.crowd.scenario import parse_scenario
    cols, rows = (10, 6) if quick else (20, 15)
    spacings = spacings or ((2.2, 3.0, 3.5) if quick else FIG11_SPACINGS)
    graph = default_graph()
    labels = set(graph.node_labels_all())
    print(f"\nFigure 11 (Sung, Kovar and Gleicher 2005): mean synthesis time per character vs grid spacing, {cols * rows} characters "
          f"({cols} x {rows} grid to a translated grid, perturbed targets)")
    head = (f"{'spacing':>8} {'synth/char':>11} {'total':>9} {'duration':>9} {'warn':>5} {'vs widest':>10} "
            f"{'reused':>8}  checker")
    print(head)
    print("-" * len(head))
    ref = None
    points = []
    for sp in sorted(spacings, reverse=True):        # widest first: each row prints its ratio when done
        data = make_samples.grid_scenario(cols, rows, spacing=sp, seed=0, name=f"grid{cols * rows}-{sp:g}m")
        sc = parse_scenario(data, f"<grid spacing {sp:g}>", node_labels=labels)
        r = run(sc, graph, None, None, quiet=quiet)
        ref = ref or r["per_char"]
        print(f"{sp:>7.1f}m {r['per_char']:>10.3f}s {r['total']:>8.2f}s {r['duration']:>8.1f}s {r['warnings']:>5} "
              f"{r['per_char'] / ref:>9.2f}x {reused(r):>8}  {verdict(r)}", flush=True)
        points.append((sp, r["per_char"], bool(r["passed"])))
    if plot:
        plot_fig11(points, plot, f"Figure 11 (Sung, Kovar and Gleicher 2005): {cols * rows} characters, "
                                 f"{cols} x {rows} grid to a translated grid")
        print(f"(Figure 11 drawn to {plot})")


def fig12(quick, quiet, plot=None):
    from authoring.commands.bake import load_sample
    sc, graph, env, roadmap = load_sample(SAMPLES_DIR / "spell70", log=lambda m: None, progress=False)
    if quick:
        sc = prefix(sc, 2 * QUICK_CHARACTERS)
    scales = (0.5, 1.0, 4.0) if quick else FIG12_SCALES
    print(f"\nFigure 12 (Sung, Kovar and Gleicher 2005): synthesis time vs adjustment tolerance eps, spell70 ({len(sc.characters)} characters); "
          f"eps x 1 = ({sc.epsilon[0] * 100:g} cm/s, {sc.epsilon[1]:g} deg/s, {sc.epsilon[2]:.4g} s/s)")
    head = f"{'eps x':>6} {'total':>9} {'synth/char':>11} {'warn':>5} {'vs eps x1':>10}  checker (at the scaled eps)"
    print(head)
    print("-" * len(head))
    out = []
    for k in scales:
        eps = tuple(e * k for e in sc.epsilon)
        out.append((k, run(sc, graph, env, roadmap, eps=eps, quiet=quiet)))
    ref = next(r["total"] for k, r in out if k == 1.0)
    for k, r in out:
        print(f"{k:>6g} {r['total']:>8.2f}s {r['per_char']:>10.3f}s {r['warnings']:>5} {r['total'] / ref:>9.2f}x  {verdict(r)}")
    if plot:
        plot_fig12([(k, r["per_char"], bool(r["passed"])) for k, r in out], plot, len(sc.characters), sc.epsilon,
                   REUSE)
        print(f"(Figure 12 drawn to {plot})")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Table 1 and Figures 11-12 on the sample scenarios.")
    ap.add_argument("--quick", action="store_true", help="fewer characters, smaller grids, fewer sweep points")
    ap.add_argument("--only", default=None, help="one sample name, or table1 / fig11 / fig12")
    ap.add_argument("--quiet", action="store_true", help="no progress bars")
    ap.add_argument("--spacings", default=None,
                    help="Figure 11's grid spacings in metres, comma-separated (default 2.2,2.6,3.0,3.5); "
                         "they run widest first and the ratio column is to the widest")
    ap.add_argument("--no-reuse", action="store_true",
                    help="every character searches for its own motion (no reuse of motions between characters "
                         "with the same task): the paper's method, and the planning times its Figure 11 shows")
    ap.add_argument("--plot", default=None, metavar="PNG",
                    help="draw Figure 11 (time per character against spacing) to this PNG file, and Figure 12 "
                         "(time against eps) to the same name with -fig12 before .png; with --only fig12, "
                         "Figure 12 to this file")
    args = ap.parse_args(argv)
    global REUSE
    REUSE = not args.no_reuse
    try:
        spacings = tuple(float(v) for v in args.spacings.split(",")) if args.spacings else None
    except ValueError:
        ap.error(f"--spacings: expected comma-separated metres, got {args.spacings!r}")
    if args.plot:
        import plotting
        why = plotting.check_png_path(args.plot)
        if why:
            ap.error(f"--plot: {why}")
    quiet = args.quiet or not sys.stderr.isatty()
    names = [n for _, n, _ in TABLE1]
    if args.only and args.only not in names + ["table1", "fig11", "fig12"]:
        ap.error(f"--only: unknown {args.only!r} (samples: {', '.join(names)}; or table1, fig11, fig12)")
    from authoring.default_library import ensure_library
    ensure_library("default", log=lambda m: print(m, file=sys.stderr), progress=not quiet)
    print(f"(warm-up, not counted: a 2-character plan loading the compiled kernels took {warm_up(default_graph()):.2f} s)\n")
    if args.only in (None, "table1", *names):
        table1([args.only] if args.only in names else names, args.quick, quiet)
    if args.only in (None, "fig11"):
        fig11(args.quick, quiet, spacings, args.plot)
    if args.only in (None, "fig12"):
        plot12 = args.plot
        if args.plot and args.only != "fig12":
            plot12 = args.plot[:-len(".png")] + "-fig12.png"
        fig12(args.quick, quiet, plot12)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
