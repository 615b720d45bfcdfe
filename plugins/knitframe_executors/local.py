"""Executor ``local``: runs jobs in this process or a process pool, with a result cache.

``workers = 1`` runs the jobs one after the other in this process; more start a
:class:`concurrent.futures.ProcessPoolExecutor`. Results are cached as each job finishes (see
:mod:`knitframe.cache` for the key), so an interrupted map loses only the jobs that were running.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from typing import Any, ClassVar

import attrs

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.executors import JobFailure, failure_reason, start_map


@attrs.frozen
class LocalExecutor:
    """Run jobs locally: serially (``workers = 1``) or in a process pool; results cached by job hash."""

    name: ClassVar[str] = "local"
    description: ClassVar[str] = "jobs in this process or a local process pool, cached by job hash"

    #: processes; 1 runs the jobs in this process
    workers: int = attrs.field(default=1, validator=v.in_range(1, 1024))
    #: where finished results are kept; None disables the cache
    cache_dir: str | None = None

    def map(
        self,
        fn: Callable[[Mapping[str, Any]], Any],
        jobs: list[Mapping[str, Any]],
        *,
        failures: str = "raise",
        progress: Callable[..., Any] | None = None,
    ) -> list[Any]:
        """``[fn(job) for job in jobs]`` in order; ``failures = "keep"`` puts a JobFailure where a job
        raised."""
        cache, keys, results, todo, tally = start_map(
            fn, jobs, cache_dir=self.cache_dir, failures=failures, progress=progress
        )
        if not todo:
            return results
        if self.workers == 1 or len(todo) == 1:
            for n, i in enumerate(todo):
                tally.report(1)
                try:
                    results[i] = fn(jobs[i])
                except Exception as e:  # noqa: BLE001 - recorded, or re-raised below
                    if failures == "raise":
                        raise
                    results[i] = JobFailure(failure_reason(e))
                cache.put(keys[i], results[i])  # each finished job is kept at once
                tally.finished(isinstance(results[i], JobFailure), 0 if n + 1 == len(todo) else 1)
            return results
        with ProcessPoolExecutor(max_workers=min(self.workers, len(todo))) as pool:
            pending = {pool.submit(fn, jobs[i]): i for i in todo}
            tally.report(min(self.workers, len(pending)))
            try:
                while pending:
                    finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                    for fut in finished:
                        i = pending.pop(fut)
                        exc = fut.exception()
                        if exc is not None and failures == "raise":
                            raise exc
                        results[i] = JobFailure(failure_reason(exc)) if exc is not None else fut.result()
                        cache.put(keys[i], results[i])
                        tally.finished(exc is not None, min(self.workers, len(pending)))
            except BaseException:
                pool.shutdown(wait=False, cancel_futures=True)
                raise
        return results


@hookimpl
def register_executors(register):
    register(LocalExecutor)
