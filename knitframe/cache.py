"""Result cache keyed by the hash of a job's config, so reruns never redo finished work."""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Callable

__all__ = ["job_key", "JobCache"]


def job_key(fn: Callable[..., Any], job: Mapping[str, Any]) -> str:
    """SHA-256 of the function's qualified name and the job's canonical JSON."""
    name = f"{getattr(fn, '__module__', '')}.{getattr(fn, '__qualname__', repr(fn))}"
    text = json.dumps({"fn": name, "job": job}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


class JobCache:
    """Pickled results under ``directory/<key>.pkl``, written atomically (rename after write)."""

    def __init__(self, directory: str | Path | None):
        self.directory = Path(directory) if directory else None
        if self.directory is not None:
            self.directory.mkdir(parents=True, exist_ok=True)

    def get(self, key: str) -> tuple[bool, Any]:
        """``(True, result)`` when cached, else ``(False, None)``."""
        if self.directory is None:
            return False, None
        p = self.directory / f"{key}.pkl"
        if not p.exists():
            return False, None
        with open(p, "rb") as fh:
            return True, pickle.load(fh)

    def split(self, fn: Callable[..., Any], jobs: list[Mapping[str, Any]]) -> tuple[list[str], list[Any], list[int]]:
        """``(keys, results, todo)``: each job's key, cached results in place (None elsewhere), and
        the indices of the jobs still to run."""
        keys = [job_key(fn, j) for j in jobs]
        results: list[Any] = [None] * len(jobs)
        todo = []
        for i, k in enumerate(keys):
            hit, value = self.get(k)
            if hit:
                results[i] = value
            else:
                todo.append(i)
        return keys, results, todo

    def put(self, key: str, value: Any) -> None:
        if self.directory is None:
            return
        fd, tmp = tempfile.mkstemp(dir=self.directory, suffix=".tmp")
        with os.fdopen(fd, "wb") as fh:
            pickle.dump(value, fh)
        os.replace(tmp, self.directory / f"{key}.pkl")
