"""Executor ``dask``: runs jobs on a dask.distributed cluster, with a config-hash cache.

A LocalCluster is started unless ``address`` names a running scheduler. Dask's nanny sets
``MALLOC_TRIM_THRESHOLD_=65536`` in workers, which slows scikit-fem assembly several-fold; the
executor overrides it before starting the cluster.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Callable, ClassVar

import attrs

from knitframe import hookimpl, validators as v
from knitframe.cache import JobCache
from knitframe.errors import PluginError


def _client(address: str | None, workers: int):
    try:
        import dask
        from distributed import Client, LocalCluster
    except ImportError:
        raise PluginError("the dask executor needs dask: pip install 'knitframe[dask]'") from None
    if address:
        return Client(address), None
    # keep glibc's default trimming in workers (see module docstring)
    dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None})
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    return Client(cluster), cluster


@attrs.frozen
class DaskExecutor:
    """Run jobs on dask.distributed (a LocalCluster, or a scheduler ``address``); cached by job hash."""

    name: ClassVar[str] = "dask"
    description: ClassVar[str] = "jobs on a dask.distributed cluster (LocalCluster or scheduler address)"

    workers: int = attrs.field(default=2, validator=v.in_range(1, 4096))  #: LocalCluster workers
    address: str | None = None  #: scheduler address, e.g. "tcp://10.0.0.5:8786"
    cache_dir: str | None = None  #: where finished results are kept; None disables the cache

    def map(self, fn: Callable[[Mapping[str, Any]], Any], jobs: list[Mapping[str, Any]]) -> list[Any]:
        from distributed import as_completed

        cache = JobCache(self.cache_dir)
        keys, results, todo = cache.split(fn, jobs)
        if not todo:
            return results
        client, cluster = _client(self.address, self.workers)
        try:
            futures = {client.submit(fn, jobs[i], key=f"knitframe-{keys[i]}", pure=False): i for i in todo}
            for fut in as_completed(futures):
                i = futures[fut]
                results[i] = fut.result()
                cache.put(keys[i], results[i])  # kept as soon as it finishes
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        return results


@hookimpl
def register_executors(register):
    register(DaskExecutor)
