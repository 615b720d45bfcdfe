"""Executor ``dask``: runs jobs on a dask.distributed cluster, with a result cache.

A :class:`distributed.LocalCluster` (``workers`` processes of ``threads_per_worker`` threads,
``memory_limit`` each) is started for the map and closed after it, unless ``address`` names a
running scheduler (``dask scheduler`` on one machine, ``dask worker tcp://HOST:8786`` on each of
the others). Dask does the scheduling, the retries (``retries``) and the dashboard, whose address
is printed once per map. Each job is one task; a task that raises is an erred task in Dask and,
with ``failures = "keep"``, a :class:`~knitframe.cache.JobFailure` in the results.

Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_=65536`` in the workers it spawns, which slows
scikit-fem assembly 7-8× (glibc then returns freed memory to the system after every large
temporary). The LocalCluster is started with that variable removed from
``distributed.nanny.pre-spawn-environ``; workers of an existing cluster that still have it get a
one-line warning saying how to start them without it (a Dask YAML config file that sets it to
null, in the folder ``DASK_CONFIG`` names; Dask's environment variables cannot unset it, they
lower-case the key).
"""

from __future__ import annotations

import importlib.util
import os
import time
import warnings
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import attrs

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.errors import ConfigError, FieldError, KnitframeWarning, PluginError
from knitframe.executors import JobFailure, failure_reason, start_map

#: the nanny's setting that slows assembly in workers (see the module docstring)
TRIM_KEY = "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_"
#: how often the count of running tasks is asked from the scheduler, s
RUNNING_POLL = 1.0


def _malloc_trim() -> str | None:
    return os.environ.get("MALLOC_TRIM_THRESHOLD_")


def _check_memory_limit(instance: Any, attribute: Any, value: str) -> None:
    if value == "auto":
        return
    try:
        from dask.utils import parse_bytes
    except ImportError:  # checked when the cluster starts (a one-line PluginError)
        return
    try:
        n = parse_bytes(value)
    except (ValueError, TypeError):
        raise FieldError(attribute.name, f"expected a size such as '4GB' or 'auto', got {value!r}") from None
    if n <= 0:
        raise FieldError(attribute.name, f"must be > 0, got {value!r}")


def _check_address(instance: Any, attribute: Any, value: str | None) -> None:
    if value is None:
        return
    if "://" not in value or not value.split("://", 1)[1]:
        raise FieldError(
            attribute.name, f"expected a scheduler address such as 'tcp://10.0.0.5:8786', got {value!r}"
        )


@attrs.frozen
class DaskExecutor:
    """Run jobs on dask.distributed (a LocalCluster, or a scheduler ``address``); results cached by
    job hash."""

    name: ClassVar[str] = "dask"
    description: ClassVar[str] = "jobs on a dask.distributed cluster (LocalCluster or scheduler address)"

    #: LocalCluster worker processes
    workers: int = attrs.field(default=2, validator=v.in_range(1, 4096))
    #: LocalCluster threads per worker (jobs running at once in each)
    threads_per_worker: int = attrs.field(default=1, validator=v.in_range(1, 1024))
    #: LocalCluster memory per worker, e.g. "4GB"; "auto" shares the machine's
    memory_limit: str = attrs.field(default="auto", validator=_check_memory_limit)
    #: scheduler address of an existing cluster, e.g. "tcp://10.0.0.5:8786"; unset: a LocalCluster
    address: str | None = attrs.field(default=None, validator=_check_address)
    #: LocalCluster dashboard (Dask takes another port when it is busy; ":0" any free port)
    dashboard_address: str = ":8787"
    #: Dask retries of a task that raised
    retries: int = attrs.field(default=0, validator=v.in_range(0, 100))
    #: where finished results are kept; None disables the cache
    cache_dir: str | None = None

    def _client(self):
        try:
            import dask
            from distributed import Client, LocalCluster
        except ImportError:
            raise PluginError("the dask executor needs dask: pip install 'knitframe[dask]'") from None
        if self.address:
            try:
                client = Client(self.address, timeout="10s")
            except (OSError, TimeoutError) as e:
                raise ConfigError(
                    "executor.address", f"no Dask scheduler answers at {self.address}: {failure_reason(e)}"
                ) from None
            self._check_workers(client)
            return client, None
        with dask.config.set({TRIM_KEY: None}):  # keep glibc's own trimming in the workers (module docstring)
            cluster = LocalCluster(
                n_workers=self.workers,
                threads_per_worker=self.threads_per_worker,
                memory_limit=self.memory_limit,
                processes=True,
                dashboard_address=self.dashboard_address,
            )
        try:
            return Client(cluster), cluster
        except BaseException:
            cluster.close()
            raise

    def _check_workers(self, client) -> None:
        trimmed = {w: val for w, val in client.run(_malloc_trim).items() if val is not None}
        if trimmed:
            worker, val = next(iter(trimmed.items()))
            warnings.warn(
                f"{len(trimmed)} Dask worker(s) (e.g. {worker}) run with MALLOC_TRIM_THRESHOLD_={val}, "
                "set by Dask's nanny, which slows assembly several-fold; start them with DASK_CONFIG "
                "naming a folder whose YAML file sets "
                "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_ to null (docs/sweeps.md)",
                KnitframeWarning,
                stacklevel=3,
            )

    def map(
        self,
        fn: Callable[[Mapping[str, Any]], Any],
        jobs: list[Mapping[str, Any]],
        *,
        failures: str = "raise",
        progress: Callable[..., Any] | None = None,
    ) -> list[Any]:
        """``[fn(job) for job in jobs]`` in order, one Dask task per job not in the cache;
        ``failures = "keep"`` puts a JobFailure where a task erred."""
        from distributed import as_completed

        cache, keys, results, todo, tally = start_map(
            fn, jobs, cache_dir=self.cache_dir, failures=failures, progress=progress
        )
        if not todo:
            return results
        client, cluster = self._client()
        try:
            link = client.dashboard_link if cluster is None or importlib.util.find_spec("bokeh") else None
            where = (
                self.address
                or f"LocalCluster of {self.workers} worker(s) x {self.threads_per_worker} thread(s)"
            )
            tally.note(f"dask: {where}; dashboard {link or 'not running (pip install bokeh)'}")
            name = getattr(fn, "__name__", "job")
            futures = {
                client.submit(fn, jobs[i], key=f"{name}-{keys[i]}", pure=False, retries=self.retries): i
                for i in todo
            }
            ours = {f.key for f in futures}
            last_poll = [0.0]

            def running() -> int | None:
                now = time.perf_counter()
                if now - last_poll[0] < RUNNING_POLL and tally.running:
                    return None
                last_poll[0] = now
                return sum(1 for keys_ in client.processing().values() for k in keys_ if k in ours)

            tally.report(min(len(todo), sum(client.nthreads().values())))
            for fut in as_completed(futures):
                i = futures[fut]
                if fut.status == "error":
                    if failures == "raise":
                        fut.result()  # re-raises the task's exception with its traceback
                    results[i] = JobFailure(failure_reason(fut.exception()))
                else:
                    results[i] = fut.result()
                cache.put(keys[i], results[i])  # kept as soon as it finishes
                ours.discard(fut.key)
                tally.finished(isinstance(results[i], JobFailure), running() if ours else 0)
                fut.release()
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        return results


@hookimpl
def register_executors(register):
    register(DaskExecutor)
