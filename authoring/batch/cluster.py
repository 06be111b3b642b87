"""Dask clusters for the batch and the distributed builds: a client of the scheduler at an
address, or of a LocalCluster started (and closed) for the run.

An unreachable or malformed address is a :class:`ClusterError` whose one-line message names
the address. A LocalCluster has one single-threaded worker process per core: the planner and the
USD writers hold the GIL, so processes, not threads, use the cores.
"""
from __future__ import annotations

import logging
import os
from contextlib import contextmanager

__all__ = ["ClusterError", "connect", "check_scheduler", "dask_client", "local_cluster", "block_mapper",
           "DEFAULT_TIMEOUT"]

DEFAULT_TIMEOUT = 10.0     # seconds to reach a scheduler
# Dask starts worker processes with MALLOC_TRIM_THRESHOLD_=65536, so glibc hands freed memory back
# at once and every large numpy temporary faults its pages in again: a frame-distance block took
# 1.6-1.8x the CPU time (docs/decisions.md). Local clusters start their workers without it.
NO_MALLOC_TRIM = "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_"


class ClusterError(RuntimeError):
    """A cluster that cannot be used; the message names the address."""


@contextmanager
def _quiet_logs(level=logging.CRITICAL):
    """Dask logs its own retries while connecting; the caller reports the outcome in one line."""
    names = ("distributed", "distributed.comm", "distributed.client", "distributed.core")
    loggers = [logging.getLogger(n) for n in names]
    before = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(level)
    try:
        yield
    finally:
        for lg, lv in zip(loggers, before):
            lg.setLevel(lv)


def connect(address: str, timeout: float = DEFAULT_TIMEOUT):
    """A ``distributed.Client`` of the scheduler at ``address`` (``tcp://host:8786``, or
    ``host:8786``); :class:`ClusterError` naming it when it cannot be reached in ``timeout`` s."""
    from distributed import Client
    with _quiet_logs():
        try:
            return Client(address, timeout=timeout, set_as_default=False)
        except (OSError, ValueError, TypeError) as e:
            reason = " ".join(str(e).split()) or type(e).__name__
            raise ClusterError(f"cannot reach the Dask scheduler at {address}: {reason}") from None


def check_scheduler(address: str, timeout: float = DEFAULT_TIMEOUT) -> int:
    """Connect to ``address`` and close again; returns the number of workers it has."""
    client = connect(address, timeout)
    try:
        return len(client.scheduler_info(n_workers=-1).get("workers", {}))
    finally:
        client.close()


def local_cluster(workers: int | None = None):
    """A LocalCluster of ``workers`` single-threaded worker processes (default: one per core),
    its HTTP endpoints on a free port (no dashboard without bokeh), without Dask's malloc trim
    setting (see ``NO_MALLOC_TRIM``), its own logs silenced (the batch reports every outcome
    itself)."""
    import dask
    from distributed import LocalCluster
    n = int(workers or os.cpu_count() or 1)
    with dask.config.set({NO_MALLOC_TRIM: None}):
        return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                            silence_logs=logging.CRITICAL)


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None, timeout: float = DEFAULT_TIMEOUT):
    """A client for one run: of the scheduler at ``scheduler``, or of a LocalCluster of
    ``workers`` processes started here and closed at the end."""
    from distributed import Client
    if scheduler:
        client = connect(scheduler, timeout)
        try:
            yield client
        finally:
            client.close()
        return
    cluster = local_cluster(workers)
    try:
        client = Client(cluster, set_as_default=False)
        try:
            yield client
        finally:
            client.close()
    finally:
        with _quiet_logs():
            cluster.close()


def _aligned(x):
    """``x`` with its numpy arrays aligned and C-contiguous (a dataclass, or an array): arrays
    that arrive through Dask's serialization can be neither, and numpy multiplies such arrays
    without BLAS."""
    import dataclasses

    import numpy as np
    if isinstance(x, np.ndarray):
        return np.require(x, requirements=["C", "A"])
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return dataclasses.replace(x, **{f.name: _aligned(getattr(x, f.name)) for f in dataclasses.fields(x)
                                         if isinstance(getattr(x, f.name), np.ndarray)})
    return x


_SHARED: dict = {}      # on a worker: the scattered data of the current map, its arrays aligned once


def _call_block(fn, block, shared):
    entry = _SHARED.get(id(shared))
    if entry is None or entry[0] is not shared:
        _SHARED.clear()
        entry = _SHARED[id(shared)] = (shared, tuple(_aligned(x) for x in shared))
    data, *rest = entry[1]
    return fn(data, block[0], block[1], *rest)


def block_mapper(client):
    """A ``map_blocks(fn, blocks, data, *args)`` that runs ``fn(data, s, e, *args)`` for every
    ``(s, e)`` of ``blocks`` on the workers of ``client`` and yields the results in order.
    ``data`` and ``args`` go to every worker once (scattered), each block is one small task; a
    block whose worker dies is computed again elsewhere."""
    def map_blocks(fn, blocks, data, *args):
        import uuid
        run = uuid.uuid4().hex[:8]
        [shared] = client.scatter([(data, *args)], broadcast=True, hash=False)
        futures = [client.submit(_call_block, fn, b, shared, pure=False, key=f"crowdweave-block-{b[0]}-{run}")
                   for b in blocks]
        try:
            for fut in futures:
                yield fut.result()
                fut.release()
        finally:
            client.cancel(futures)
            shared.release()
    return map_blocks
