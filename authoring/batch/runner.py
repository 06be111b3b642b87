"""Run a sweep on a Dask cluster: one task per variant, results as they come, the summary at
the end.

Faults: a worker that dies takes its running variant with it; the scheduler starts that
variant again on another worker (up to its ``allowed-failures`` setting, 3 by default; a variant
that kills every worker it runs on is reported as ``lost``). A variant that fails raises nothing
here: its record says ``error`` or ``failed`` and the other variants go on. Outputs are written
once (see :mod:`authoring.batch.task`); temporary directories of attempts that died are removed
at the end.
"""
from __future__ import annotations

import shutil
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from .task import ATTEMPTS, SCENARIO, VariantJob, read_record, run_variant, tmp_prefix
from .variants import make_variants, scenario_text

__all__ = ["BatchError", "BatchResult", "run_batch", "prepare_batch"]


class BatchError(RuntimeError):
    """A batch that cannot start (its output directory holds other results); one line."""


@dataclass
class BatchResult:
    out: Path
    variants: list
    records: dict                       # variant id -> record
    attempts: dict                      # variant id -> times started
    counts: dict = field(default_factory=dict)
    seconds: float = 0.0
    reused: int = 0                     # variants kept from an earlier run (resume)

    @property
    def ok(self) -> bool:
        return all(r.get("status") == "passed" for r in self.records.values()) and \
            len(self.records) == len(self.variants)


def prepare_batch(sweep, out, resume: bool = False):
    """The variants and their jobs; records of variants already finished in ``out`` (kept with
    ``resume`` when their scenario text is the same, else :class:`BatchError`)."""
    out = Path(out).resolve()
    variants = make_variants(sweep)
    jobs, done = [], {}
    for v in variants:
        text = scenario_text(v, out / v.id)
        final = out / v.id
        if final.exists():
            same = (final / SCENARIO).is_file() and (final / SCENARIO).read_text(encoding="utf-8") == text
            rec = read_record(final) if same else None
            if not same:
                raise BatchError(f"{final}: already exists and holds another scenario; use another --out")
            if rec is None:
                raise BatchError(f"{final}: already exists without a finished variant (no variant.json); "
                                 "remove it or use another --out")
            if not resume:
                raise BatchError(f"{final}: already baked; give --resume to keep the variants already baked")
            done[v.id] = rec
            continue
        jobs.append((v, VariantJob(str(out), v.id, v.index, v.params, text)))
    return out, variants, jobs, done


def _count_attempts(out: Path) -> dict:
    counts: dict = {}
    folder = out / ATTEMPTS
    if folder.is_dir():
        for p in folder.iterdir():
            vid = p.name.split("@", 1)[0]
            counts[vid] = counts.get(vid, 0) + 1
    return counts


def _remove_leftovers(out: Path, variants) -> None:
    """Temporary directories of attempts that died with their worker."""
    prefixes = tuple(tmp_prefix(v.id) for v in variants)
    for p in out.iterdir():
        if p.is_dir() and p.name.startswith(prefixes):
            shutil.rmtree(p, ignore_errors=True)


def _lost(vid: str, err: BaseException) -> dict:
    reason = " ".join(str(err).split()) or type(err).__name__
    return {"id": vid, "status": "lost", "error": f"{type(err).__name__}: {reason}"}


def run_batch(sweep, out, *, client, progress=None, resume: bool = False) -> BatchResult:
    """Bake every variant of ``sweep`` into ``out`` on the cluster of ``client`` and write the
    summary. ``progress(record)`` is called as each variant finishes."""
    from distributed import as_completed

    from .summary import write_summary
    t0 = time.perf_counter()
    out, variants, jobs, done = prepare_batch(sweep, out, resume)
    out.mkdir(parents=True, exist_ok=True)
    if any(v.scenario.get("library", "default") == "default" for v, _ in jobs):
        from authoring.default_library import ensure_library     # once here, not on every worker at once
        ensure_library("default", out, log=lambda *a: None, progress=False)
    records = dict(done)
    run = uuid.uuid4().hex[:8]
    # long variants first (a rough cost: characters x seconds), so the last ones to finish are short
    futures = {client.submit(run_variant, job, key=f"crowdweave-variant-{job.id}-{run}", pure=False,
                             priority=int(v.cost)): v.id for v, job in jobs}
    try:
        for fut in as_completed(list(futures), loop=client.loop):
            vid = futures[fut]
            try:
                rec = fut.result()
            except Exception as e:     # KilledWorker, a lost scheduler: reported, the rest goes on
                rec = _lost(vid, e)
            records[vid] = rec
            fut.release()
            if progress is not None:
                progress(rec)
    finally:
        client.cancel(list(futures))
    _remove_leftovers(out, variants)
    attempts = _count_attempts(out)
    for vid, rec in done.items():
        attempts.setdefault(vid, 0)
    counts = write_summary(out, sweep, variants, records, attempts)
    shutil.rmtree(out / ATTEMPTS.parent, ignore_errors=True)
    return BatchResult(out, variants, records, attempts, counts, time.perf_counter() - t0, len(done))

