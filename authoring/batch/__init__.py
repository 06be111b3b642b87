"""Batches of bakes on a Dask cluster (``crowdweave batch``).

A sweep file (:mod:`.sweep`) names a base scenario or a generator (:mod:`.generators`) and the
axes to vary; every combination is a variant (:mod:`.variants`), baked on a worker exactly as
``crowdweave bake`` would (:mod:`.task`), the results gathered as they finish and summarised
(:mod:`.runner`, :mod:`.summary`). :mod:`.cluster` connects to a scheduler or starts a
LocalCluster.
"""
from .cluster import ClusterError, check_scheduler, connect, dask_client, local_cluster
from .runner import BatchError, BatchResult, run_batch
from .sweep import Sweep, SweepError, load_sweep, parse_sweep
from .variants import Variant, make_variants, scenario_text

__all__ = ["ClusterError", "check_scheduler", "connect", "dask_client", "local_cluster", "BatchError", "BatchResult",
           "run_batch", "Sweep", "SweepError", "load_sweep", "parse_sweep", "Variant", "make_variants",
           "scenario_text"]
