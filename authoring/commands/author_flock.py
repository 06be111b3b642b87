"""``crowdweave author flock --agents 20 --dim 2 --seconds 300 --seed 1 --out flock.cwpack``:
record a boids flock and build its data-driven group graph (Lai, Chenney and Fan 2005)."""
from __future__ import annotations

import sys
import time

from authoring.commands.args import check_output, integer, limits, number
from runtime.limits import MAX_FLOCK_AGENT_SECONDS, MAX_FLOCK_AGENTS, MAX_FLOCK_SECONDS, MAX_SEED


def configure(p):
    p.add_argument("--agents", type=integer(2, MAX_FLOCK_AGENTS), default=20,
                   help=f"agents in the flock (default 20; {limits(2, MAX_FLOCK_AGENTS)})")
    p.add_argument("--dim", type=int, choices=(2, 3), default=2, help="2: on the ground plane, 3: flying (default 2)")
    p.add_argument("--seconds", type=number(0, MAX_FLOCK_SECONDS, lo_open=True), default=300.0,
                   help=f"seconds of flock to record (default 300; {limits(0, MAX_FLOCK_SECONDS, lo_open=True)}, "
                        f"and agents x seconds at most {MAX_FLOCK_AGENT_SECONDS:g})")
    p.add_argument("--seed", type=integer(0, MAX_SEED), default=0,
                   help=f"random seed of the simulation (default 0; {limits(0, MAX_SEED)})")
    p.add_argument("--out", required=True, help="output pack (.cwpack, kind 'ddg')")
    p.add_argument("--stride", type=integer(1, 3000), default=None,
                   help="frames between candidate configurations (default 15; 1-3000)")
    p.add_argument("--transitions-per-minute", type=number(0, 10000, lo_open=True), default=None,
                   help="local minima taken per minute of recording (default 30; > 0, at most 10000)")
    p.add_argument("--max-rms", type=number(0, 100, lo_open=True), default=None,
                   help="largest configuration distance joined, metres (default 0.6 in 2D, 0.9 in 3D; "
                        "> 0, at most 100)")
    p.add_argument("--brute-force", action="store_true",
                   help="evaluate the exact metric for every pair (no lower-bound pruning; same result, slower)")
    p.add_argument("--workers", type=integer(1, 64), default=1, help="processes for the exact metric (default 1; 1-64)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args) -> int:
    from tqdm import tqdm

    from authoring.boids import BoidsParams, record_flock
    from authoring.commands import CLIError
    from authoring.ddg import DDGBuildParams, build_ddg
    from runtime.flock.ddg import save_ddg

    out = check_output(args.out)
    if args.agents * args.seconds > MAX_FLOCK_AGENT_SECONDS:
        raise CLIError(f"--agents {args.agents} x --seconds {args.seconds:g} is more than the limit of "
                       f"{MAX_FLOCK_AGENT_SECONDS:g} agent-seconds of recording")
    quiet = args.quiet or not sys.stderr.isatty()
    kw = {}
    if args.stride is not None:
        kw["candidate_stride"] = args.stride
    if args.transitions_per_minute is not None:
        kw["transitions_per_minute"] = args.transitions_per_minute
    if args.max_rms is not None:
        kw["max_rms"] = args.max_rms
    if args.brute_force:
        kw["use_bound"] = False
    kw["workers"] = args.workers
    try:
        bparams = DDGBuildParams(**kw)
        rparams = BoidsParams(n_agents=args.agents, dim=args.dim)
    except ValueError as e:
        raise CLIError(str(e)) from None

    t0 = time.perf_counter()
    steps = int(round(args.seconds * rparams.fps))
    with tqdm(total=steps, desc="recording boids", unit="step", disable=quiet) as bar:
        rec = record_flock(rparams, args.seconds, seed=args.seed, progress=bar.update)
    print(f"recorded {rec.n_agents} agents ({args.dim}D) for {rec.virtual_seconds:.1f} s at {rec.fps:g} fps: "
          f"{rec.cost_per_virtual_second * 1e3:.2f} ms of simulation per virtual second, "
          f"largest step {rec.max_step * 100:.1f} cm")

    def progress(desc, total):
        return tqdm(total=total, desc=desc, unit="pair", disable=quiet, leave=False)

    try:
        ddg, st = build_ddg(rec, bparams, progress=progress)
    except ValueError as e:
        raise CLIError(f"cannot build a flock graph: {e}") from None
    save_ddg(out, ddg)
    print(f"difference matrix: {st.candidates} candidates, {st.pairs} pairs, {st.exact_evaluations} exact "
          f"evaluations ({100 * st.skipped_fraction:.1f}% skipped by the lower bound, {st.rounds} rounds, "
          f"tau {st.tau:.3f} m^2)")
    print(f"transitions: {st.local_minima} local minima considered, {st.accepted_pairs} taken "
          f"(rejected: {st.rejected_spacing} too close to a cut, {st.rejected_blend} no smooth blend), "
          f"{st.directions} directions")
    print(f"graph: {ddg.n_nodes} nodes, {ddg.n_edges} edges, {ddg.n_transitions} transitions "
          f"({st.nodes_trimmed} nodes trimmed as dead ends), {ddg.frames.shape[0]} frames stored, "
          f"{ddg.nbytes / 1e6:.2f} MB")
    print(f"wrote {out} (build {st.seconds_total:.1f} s, total {time.perf_counter() - t0:.1f} s)")
    return 0
