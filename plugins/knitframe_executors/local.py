"""Executor ``local``: runs jobs in this process or a process pool, with a config-hash cache."""

from __future__ import annotations

from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from typing import Any, Callable, ClassVar

import attrs

from knitframe import hookimpl, validators as v
from knitframe.cache import JobCache


@attrs.frozen
class LocalExecutor:
    """Run jobs locally: serially (``workers = 1``) or in a process pool; cached by job hash."""

    name: ClassVar[str] = "local"
    description: ClassVar[str] = "jobs in this process or a local process pool, cached by config hash"

    workers: int = attrs.field(default=1, validator=v.in_range(1, 1024))  #: processes
    cache_dir: str | None = None  #: where finished results are kept; None disables the cache

    def map(self, fn: Callable[[Mapping[str, Any]], Any], jobs: list[Mapping[str, Any]]) -> list[Any]:
        cache = JobCache(self.cache_dir)
        keys, results, todo = cache.split(fn, jobs)
        if self.workers == 1 or len(todo) <= 1:
            for i in todo:
                results[i] = fn(jobs[i])
                cache.put(keys[i], results[i])  # each finished job is kept at once
        else:
            with ProcessPoolExecutor(max_workers=self.workers) as pool:
                futures = {i: pool.submit(fn, jobs[i]) for i in todo}
                for i, fut in futures.items():
                    results[i] = fut.result()
                    cache.put(keys[i], results[i])
        return results


@hookimpl
def register_executors(register):
    register(LocalExecutor)
