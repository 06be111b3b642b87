"""``crowdweave batch SWEEP.toml --out DIR [--scheduler ADDRESS]``: bake every variant of a
sweep on a Dask cluster (a LocalCluster of one worker per core unless ``--scheduler`` names
one), each into ``DIR/<variant>/`` exactly as ``crowdweave bake`` would, then write
``summary.csv``, ``summary.md`` and ``sweep.png``."""
from __future__ import annotations

import sys


def configure(p):
    p.add_argument("sweep", help="a sweep file (.toml): a base scenario or a generator, and the axes to vary")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory (one folder per variant, summary)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="the Dask scheduler to use (e.g. tcp://host:8786); default: a LocalCluster started here")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes of the LocalCluster (default: one per core)")
    p.add_argument("--timeout", type=float, default=10.0, metavar="S",
                   help="seconds to reach the scheduler (default 10)")
    p.add_argument("--resume", action="store_true",
                   help="keep variants already baked in DIR (same scenario) and bake only the others")
    p.add_argument("--list", action="store_true", help="print the variants and exit")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args) -> int:
    from authoring.batch import BatchError, ClusterError, SweepError, dask_client, load_sweep, make_variants, run_batch
    from authoring.commands import CLIError

    if args.workers is not None and args.workers < 1:
        raise CLIError(f"--workers must be at least 1, got {args.workers}")
    if args.scheduler and args.workers is not None:
        raise CLIError("--workers sizes the LocalCluster; with --scheduler the cluster has its own workers")
    if not args.timeout > 0:
        raise CLIError(f"--timeout must be positive, got {args.timeout}")
    try:
        sweep = load_sweep(args.sweep)
        variants = make_variants(sweep)
    except SweepError as e:
        raise CLIError(str(e)) from None
    if args.list:
        for v in variants:
            print(f"{v.id}: {v.characters} characters, {v.scenario.get('duration', 20.0):g} s")
        return 0
    quiet = args.quiet or not sys.stderr.isatty()
    from tqdm import tqdm
    try:
        with dask_client(args.scheduler, args.workers, args.timeout) as client:
            n_workers = len(client.scheduler_info(n_workers=-1).get("workers", {}))
            where = args.scheduler or "a local cluster"
            print(f"sweep {sweep.name}: {len(variants)} variants on {where} ({n_workers} workers)")
            with tqdm(total=len(variants), desc="variants", unit="variant", disable=quiet) as bar:
                def progress(rec):
                    bar.update(1)
                    if rec.get("status") != "passed":
                        tqdm.write(f"{rec.get('id')}: {rec.get('status')}"
                                   + (f": {rec['error']}" if rec.get("error") else ""), file=sys.stderr)
                result = run_batch(sweep, args.out, client=client, progress=progress, resume=args.resume)
    except (ClusterError, BatchError, SweepError) as e:
        raise CLIError(str(e)) from None
    c = result.counts
    print(f"{c['passed']} passed, {c['failed']} failed the checker, {c['error']} errors, {c['lost']} lost "
          f"of {len(variants)} variants" + (f" ({result.reused} kept from an earlier run)" if result.reused else "")
          + f" in {result.seconds:.1f} s")
    print(f"summary: {result.out / 'summary.md'} (table also in summary.csv, plot in sweep.png)")
    return 0 if result.ok else 1
