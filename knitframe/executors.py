"""The ``[executor]`` table and what the executor plugins share: the table read into an executor,
the running counts a map reports through its progress callback, and the failure modes.

Every executor runs ``map(fn, jobs)``: ``[fn(job) for job in jobs]`` in order, ``fn`` a
module-level function and each job a plain dict (both picklable), with finished results kept in a
:class:`~knitframe.cache.JobCache`. The built-in ones (plugins of kind ``"executor"``:
``local`` and ``dask``) also take two keywords:

* ``failures = "keep"``: a job that raises gives a :class:`~knitframe.cache.JobFailure` (its
  one-line reason) in its place and the others go on; the default ``"raise"`` stops at the first;
* ``progress``: a ``progress(finished, total, message)`` callback (:data:`knitframe.interfaces.Progress`)
  called as jobs finish, with a message ``"3 done, 1 failed, 2 running"``; an object with a
  ``note(text)`` method also gets one-off lines (the Dask dashboard's address).

::

    [executor]
    kind = "dask"               # or "local" (the default: processes on this machine)
    workers = 2                 # LocalCluster workers (dask) or processes (local)
    threads_per_worker = 1      # dask
    memory_limit = "4GB"        # dask, per worker; "auto" shares the machine's memory
    # address = "tcp://10.0.0.5:8786"   # dask: an existing scheduler instead of a LocalCluster
    cache_dir = "cache"         # default: knitframe's user cache folder (knitframe cache clear)
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

from knitframe.cache import JobFailure, default_cache_dir, failure_reason

__all__ = [
    "executor_from_config",
    "Tally",
    "FAILURE_MODES",
    "check_failures",
    "start_map",
    "JobFailure",
    "failure_reason",
    "default_cache_dir",
]

FAILURE_MODES = ("raise", "keep")


def executor_from_config(config: Mapping[str, Any], ctx: Any, *, path: str = "executor") -> tuple[Any, str]:
    """The executor the config's ``[executor]`` table names (``local`` when there is none) and its name.

    Validated like any plugin table: errors name ``executor.<key>`` in one line. ``cache_dir``
    resolves against the config's folder and defaults to :func:`knitframe.cache.default_cache_dir`.
    """
    import attrs

    from knitframe.cache import default_cache_dir
    from knitframe.config import PluginSpec, instantiate
    from knitframe.errors import ConfigError

    table = config.get(path, {"kind": "local"})
    if not isinstance(table, dict):
        raise ConfigError(path, f"expected a table, got {table!r}", source=ctx.source)
    table = {"kind": "local", **table}
    spec = PluginSpec.parse(table, path)
    executor = instantiate(ctx.registry, "executor", table, path, source=ctx.source)
    if attrs.has(type(executor)) and "cache_dir" in attrs.fields_dict(type(executor)):
        given = spec.options.get("cache_dir")
        where = ctx.path(given, f"{path}.cache_dir", must_exist=False) if given else default_cache_dir()
        if where.exists() and not where.is_dir():
            raise ConfigError(f"{path}.cache_dir", f"not a folder: {given or where}", source=ctx.source)
        executor = attrs.evolve(executor, cache_dir=str(where))
    return executor, spec.kind


class Tally:
    """Counts of a map in progress, reported through a ``progress(finished, total, message)`` callback."""

    def __init__(self, total: int, cached: int, progress: Callable[..., Any] | None):
        self.total, self.cached, self.progress = total, cached, progress
        self.done = self.failed = self.running = 0
        self.t0 = time.perf_counter()

    def message(self) -> str:
        text = f"{self.done} done, {self.failed} failed, {self.running} running"
        return text + (f", {self.cached} cached" if self.cached else "")

    def report(self, running: int | None = None) -> None:
        if running is not None:
            self.running = running
        if self.progress is not None:
            self.progress(self.done + self.failed, self.total, self.message())

    def finished(self, failed: bool, running: int | None = None) -> None:
        if failed:
            self.failed += 1
        else:
            self.done += 1
        self.report(running)

    def note(self, text: str) -> None:
        """A one-off line: through the progress object's ``note`` if it has one, else the log."""
        note = getattr(self.progress, "note", None)
        if note is not None:
            note(text)
        else:
            import logging

            logging.getLogger("knitframe").info(text)


def check_failures(failures: str) -> None:
    if failures not in FAILURE_MODES:
        raise ValueError(f"failures must be one of {', '.join(FAILURE_MODES)}, got {failures!r}")


def start_map(
    fn: Callable[[Mapping[str, Any]], Any],
    jobs: list[Mapping[str, Any]],
    *,
    cache_dir: str | None,
    failures: str,
    progress: Callable[..., Any] | None,
) -> tuple[Any, list[str], list[Any], list[int], Tally]:
    """What every executor's ``map`` does first: checks ``failures``, opens the result cache in
    ``cache_dir`` and takes from it the jobs already done, and starts the :class:`Tally`.

    Returns ``(cache, keys, results, todo, tally)``: the :class:`~knitframe.cache.JobCache`, each
    job's cache key, the results in job order (cached ones filled in), the indices of the jobs
    still to run, and the tally of those. When ``todo`` is empty every result came from the cache
    and the tally has already reported it: the executor returns ``results``.
    """
    from knitframe.cache import JobCache

    check_failures(failures)
    cache = JobCache(cache_dir)
    keys, results, todo = cache.split(fn, jobs)
    tally = Tally(len(todo), len(jobs) - len(todo), progress)
    if not todo:
        tally.report(0)
    return cache, keys, results, todo, tally
