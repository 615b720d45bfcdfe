"""Load-path continuation with adaptive cut-back, and the per-step checkpoints of a run.

:func:`continuation` follows a load parameter t from t0 through a list of targets, halving the
increment on failure and growing it again after successes. :class:`StepCheckpoints` stores
converged steps so a killed run can resume. Both are the building blocks of the unit-cell run
skeleton :class:`knitframe.numerics.cellrun.CellRun`.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from knitframe.errors import NumericalError
from knitframe.numerics.newton import NewtonResult
from knitframe.outdir import write_atomic

__all__ = ["continuation", "StepCheckpoints"]


def continuation(
    solve_at: Callable[[float, np.ndarray], NewtonResult],
    x0: np.ndarray,
    targets: Sequence[float],
    *,
    t0: float = 0.0,
    min_fraction: float = 1.0 / 256,
    grow: float = 2.0,
    on_target: Callable[[int, float, NewtonResult], None] | None = None,
) -> list[NewtonResult]:
    """Follow the load parameter from ``t0`` through every target with adaptive cut-back.

    ``solve_at(t, x_start)`` solves the state at load parameter t from the start x_start and
    raises NumericalError on failure. A failed increment is halved; once it falls below
    ``min_fraction`` of the target spacing the path stops with a NumericalError carrying the
    last diagnostic. After a success the increment grows by ``grow`` (never past the next target);
    a new target starts from ``grow`` times the last increment that converged, not from its whole
    span, so a path that needed small increments does not fail its way down again at every target.

    Returns the result at each target; ``on_target(index, t, result)`` is called as each is reached.
    """
    out: list[NewtonResult] = []
    x = np.asarray(x0, dtype=np.float64)
    t = float(t0)
    prev = t
    last_ok = math.inf  # the last increment that converged, carried into the next target's span
    for n, target in enumerate(targets):
        span = max(float(target) - prev, 1e-300)
        dt = min(span, grow * last_ok)
        min_dt = span * min_fraction
        while True:
            t_try = min(t + dt, float(target))
            try:
                result = solve_at(t_try, x)
            except NumericalError as e:
                dt *= 0.5
                if dt < min_dt:
                    raise NumericalError(
                        f"load step cut back below {min_dt:.3g} at t = {t:.6g} (target {target:.6g}): {e}"
                    ) from None
                continue
            last_ok = t_try - t
            x, t = result.x, t_try
            if t >= float(target) - 1e-15 * max(1.0, abs(float(target))):
                break
            dt = min(dt * grow, float(target) - t)
        out.append(result)
        if on_target is not None:
            on_target(n, float(target), result)
        prev = float(target)
    return out


class StepCheckpoints:
    """Converged steps saved as ``step-NNNN.npz`` (+ JSON metadata) in a directory, written atomically.

    ``key`` identifies the run (a hash of its inputs); checkpoints with another key are ignored,
    so a resumed run never continues someone else's path.
    """

    def __init__(self, directory: str | Path, key: str):
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.key = key

    def save(self, index: int, arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> Path:
        """Store step ``index`` (arrays plus JSON-able metadata)."""
        meta_json = np.array(json.dumps({**meta, "key": self.key, "index": index}))
        return write_atomic(
            self.directory / f"step-{index:04d}.npz",
            lambda fh: np.savez(fh, **arrays, __meta__=meta_json),
            prefix=".step-",
            suffix=".npz.tmp",
        )

    def announce(self, index: int, total: int) -> None:
        """Log the one line a resumed run prints: ``resuming from step N of M (checkpoint …)``."""
        logging.getLogger("knitframe").info(
            "resuming from step %d of %d (checkpoint %s)",
            index + 1,
            total,
            self.directory / f"step-{index:04d}.npz",
        )

    def _mine(self):
        """(index, path, meta) of this run's readable checkpoints, the latest first."""
        for path in sorted(self.directory.glob("step-*.npz"), reverse=True):
            try:
                with np.load(path) as data:
                    meta = json.loads(str(data["__meta__"]))
            except (OSError, ValueError, KeyError):
                continue
            if meta.get("key") == self.key:
                yield int(meta["index"]), path, meta

    def latest(self) -> tuple[int, dict[str, np.ndarray], dict[str, Any]] | None:
        """The highest saved step of this run's key, or None."""
        for index, path, meta in self._mine():
            try:
                with np.load(path) as data:
                    arrays = {k: data[k] for k in data.files if k != "__meta__"}
            except (OSError, ValueError, KeyError):
                continue
            return index, arrays, meta
        return None

    def discard_after(self, index: int) -> None:
        """Delete this run's checkpoints of steps after ``index``, the latest first (a run killed on the
        way resumes from a checkpoint whose earlier steps are all there); other runs' files are kept."""
        for i, path, _ in list(self._mine()):
            if i > index:
                path.unlink(missing_ok=True)
