"""One variant, run on a worker: plan, bake, check and write it exactly as ``crowdweave bake``.

Every attempt works in its own temporary directory beside the final one
(``OUT/.<variant>.tmp-<host>-<pid>-<token>/``): the variant's ``scenario.toml``, the stage
``stage.usdc``, the checker's ``report.json``, what the bake printed (``bake.log``) and the
outcome ``variant.json``. The finished directory is renamed to ``OUT/<variant>/`` by the
attempt that finishes first: a rename onto a directory that exists fails, so an attempt that
lost the race (a worker the scheduler gave up on that still finished) removes its own copy, and
every output is written once. An attempt killed with its worker leaves only its temporary
directory, which the batch removes at the end.

``OUT/.batch/attempts/<variant>@<host>-<pid>-<token>`` records each attempt as it starts (the
summary counts them: a variant whose worker was lost has two or more).
"""
from __future__ import annotations

import json
import os
import shutil
import socket
import sys
import threading
import time
import traceback
import uuid
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from dataclasses import dataclass
from pathlib import Path

__all__ = ["VariantJob", "run_variant", "read_record", "ATTEMPTS", "RECORD", "tmp_prefix"]

ATTEMPTS = Path(".batch") / "attempts"
RECORD = "variant.json"
STAGE = "stage.usdc"
REPORT = "report.json"
LOG = "bake.log"
SCENARIO = "scenario.toml"

# A worker started with several threads runs its variants one at a time: a bake prints to this
# process's stdout, which each variant captures into its own log.
_ONE_AT_A_TIME = threading.Lock()


@dataclass
class VariantJob:
    """What a worker needs for one variant (small: the scenario travels as text)."""
    out: str                 # the batch's output directory (absolute; the same path on every worker)
    id: str
    index: int
    params: dict
    scenario_text: str


def tmp_prefix(variant_id: str) -> str:
    return f".{variant_id}.tmp-"


def _fsync_tree(folder: Path) -> None:
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            with open(p, "rb") as f:
                os.fsync(f.fileno())
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _report_figures(report_path: Path) -> dict:
    """The figures the summary shows, from the checker's report."""
    if not report_path.is_file():
        return {}
    r = json.loads(report_path.read_text())
    s = r.get("summary", {})
    t = r.get("timing", {})
    keys = ("characters", "goals", "goals_in_window", "poses_ok", "characters_within_eps",
            "character_overlap_pairs", "obstacle_overlap_characters", "max_position_error_mm",
            "max_adjust_m_s", "max_adjust_deg_s", "max_adjust_s_s")
    fig = {k: s[k] for k in keys if k in s}
    fig["plan_seconds"] = t.get("plan_seconds")
    fig["write_seconds"] = t.get("write_seconds")
    fig["warnings"] = len(r.get("warnings", []))
    if "flocks" in r:
        fig["flocks_passed"] = bool(r["flocks"].get("passed"))
    if "tiling" in r:
        fig["tiling_passed"] = bool(r["tiling"].get("passed"))
    return fig


def read_record(folder) -> dict | None:
    """The outcome recorded in a finished variant directory (None when there is none)."""
    p = Path(folder) / RECORD
    try:
        return json.loads(p.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None


@contextmanager
def _output_to(path: Path):
    """Everything this process prints while the variant bakes -- Python's stdout and stderr and
    the C++ libraries' messages (USD warnings) -- into ``path``."""
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(path, "a", encoding="utf-8", buffering=1) as log:
            os.dup2(log.fileno(), 1)
            os.dup2(log.fileno(), 2)
            try:
                with redirect_stdout(log), redirect_stderr(log):
                    yield
            finally:
                log.flush()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
    finally:
        for fd in saved:
            os.close(fd)


def _bake(tmp: Path) -> tuple[str, str]:
    """Bake the scenario in ``tmp``; returns (status, error)."""
    from authoring.commands import CLIError
    from authoring.commands.bake import bake_sample
    try:
        code = bake_sample(tmp / SCENARIO, tmp / STAGE, report=str(tmp / REPORT), quiet=True)
    except CLIError as e:
        return "error", str(e)
    except Exception as e:                     # a variant that fails does not stop the batch
        traceback.print_exc()
        return "error", f"{type(e).__name__}: {' '.join(str(e).split())}"
    return ("passed" if code == 0 else "failed"), ""


def run_variant(job: VariantJob) -> dict:
    """Bake one variant into ``job.out/job.id`` (see the module docstring); returns its record."""
    out = Path(job.out)
    final = out / job.id
    token = f"{socket.gethostname()}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    attempts = out / ATTEMPTS
    attempts.mkdir(parents=True, exist_ok=True)
    (attempts / f"{job.id}@{token}").write_text(f"{socket.gethostname()} {os.getpid()} {time.time():.3f}\n")
    if final.is_dir():                         # finished by an attempt the scheduler gave up on
        return read_record(final) or {"id": job.id, "status": "error", "error": f"{final}: no {RECORD}"}
    tmp = out / f"{tmp_prefix(job.id)}{token}"
    tmp.mkdir()
    try:
        (tmp / SCENARIO).write_text(job.scenario_text, encoding="utf-8")
        started = time.time()
        t0 = time.perf_counter()
        with _ONE_AT_A_TIME, _output_to(tmp / LOG):
            status, error = _bake(tmp)
        error = error.replace(str(tmp), str(final))      # name the files where they end up
        record = {"id": job.id, "index": job.index, "params": job.params, "status": status, "error": error,
                  "seconds": time.perf_counter() - t0, "started": started,
                  "worker": f"{socket.gethostname()}:{os.getpid()}",
                  **_report_figures(tmp / REPORT)}
        (tmp / RECORD).write_text(json.dumps(record, indent=1, default=float) + "\n", encoding="utf-8")
        _fsync_tree(tmp)
        try:
            os.rename(tmp, final)
        except OSError:
            if not final.is_dir():
                raise
            shutil.rmtree(tmp, ignore_errors=True)     # another attempt finished first: keep its copy
            return read_record(final) or record
        return record
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise

