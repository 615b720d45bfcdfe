"""The unit-cell run skeleton: phases, continuation, checkpoints and resume, VTU, truncate, provenance.

A unit-cell solver's ``simulate`` is a run of phases on the periodic cell, step by step:

1. pre-stress (scene effect ``prestress``): a parameter t from 0 to 1 in ``n_prestress`` steps
   t_k = k / n at F̄ = I (:meth:`CellRun.prestress`);
2. the solver's own steps between the two, if any (the rod solver's relaxed lattice:
   ``extra_steps``), accepted with :meth:`CellRun.accept`;
3. the scene's load path λ1(τ), λ2(τ), τ = 1 … n_load (:meth:`CellRun.load`), each step
   giving a row (λ1, λ2, T1, T2) of the Response.

Each phase is followed by :func:`~knitframe.numerics.continuation.continuation` with adaptive
cut-back. The solver supplies the model and the phase hooks:

* ``solve(t, q0) -> NewtonResult``: the converged state at the phase parameter t from the start
  q0, raising :class:`~knitframe.errors.NumericalError` on failure;
* ``row(tau, result) -> (λ1, λ2, T1, T2)``: the Response row of a converged load step;
* ``write_vtu(path, q)``: the VTU file of a state.

:class:`CellRun` owns the rest: the step counter over all phases, the checkpoint store
(step k is ``step-kkkk.npz`` with ``q``, the rows so far and the solver's extra arrays, and the
solver's ``state`` as metadata: at least ``phase`` and ``target``, the index of the phase's last
converged target), resume from the latest checkpoint, the ``<prefix>-kkkk.vtu`` files and their
``.pvd`` (a step's file is written before its checkpoint, so every checkpointed step has its
file), progress reports ``progress(done, total, message)``, the notes and warnings, truncate on
failure (``on_failure = "truncate"`` keeps the converged load steps, ``converged = false``) and
the Provenance and Response. A new solver writes its model and these hooks; see
:mod:`knitframe.testing.springcell` for a small complete one.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from knitframe.errors import KnitframeWarning, NumericalError
from knitframe.numerics.continuation import StepCheckpoints, continuation
from knitframe.numerics.stepfiles import StepSeries
from knitframe.records import Fabric, Provenance, Response, Scene

__all__ = ["CellRun", "checkpoint_key"]


def checkpoint_key(fabric: Fabric, scene: Scene, *options: Any) -> str:
    """The key of a run's checkpoints: a hash of the fabric, the scene and the solver's ``options``.

    ``options`` are JSON-able (e.g. ``attrs.asdict(solver)``, a resolved plugin's fields); a
    checkpoint is resumed only by a run with the same key (:class:`StepCheckpoints`).
    """
    text = json.dumps([fabric.to_dict(), scene.to_dict(), *options], sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


#: ``continuation``'s signature: (solve, x0, targets, *, t0, min_fraction, on_target) -> results
Follow = Callable[..., list]


class CellRun:
    """One run of a unit-cell solver on a fabric and a scene: steps, checkpoints, files, rows and notes.

    Parameters
    ----------
    solver : str
        The solver's name, e.g. ``"rod"``: the Provenance's ``solver``, and errors and warnings
        begin with ``"<solver> solver (<pattern>, <yarn>): "``.
    fabric, scene : Fabric, Scene
        What is simulated; the scene gives the load path, and ``"vtu"`` in its outputs asks for
        the VTU files.
    n_prestress : int
        Pre-stress steps of this run (0 without pre-stress).
    extra_steps : int
        The solver's own steps between pre-stress and load path (counted in the progress total).
    state : dict, optional
        The solver's JSON-able state, saved as every checkpoint's metadata and restored on
        resume (keys the checkpoint lacks become None). ``phase`` (default ``"prestress"``) and
        ``target`` (default −1) are set by :meth:`accept`. The dict is kept, not copied.
    checkpoints : StepCheckpoints, optional
        Where converged steps are saved, under the solver's key for these inputs.
    output_dir : path, optional
        Where ``<prefix>-NNNN.vtu`` and ``<prefix>.pvd`` go.
    prefix : str
        The VTU files' stem.
    write_vtu : callable, optional
        ``write_vtu(path, q)`` writes the VTU file of state q.
    arrays : callable, optional
        ``arrays() -> dict`` of extra arrays saved with each checkpoint (besides ``q`` and ``rows``).
    meta : callable, optional
        ``meta() -> dict`` of state entries updated at every accepted step (e.g. a parameter of
        the model that the step's phase changed).
    progress : callable, optional
        ``progress(done, total, message)`` after every converged step.
    on_failure : {"raise", "truncate"}
    t_start : float, optional
        ``time.perf_counter()`` at the start of ``simulate`` (the Provenance's wall time).
    """

    def __init__(
        self,
        solver: str,
        fabric: Fabric,
        scene: Scene,
        *,
        n_prestress: int,
        extra_steps: int = 0,
        state: dict[str, Any] | None = None,
        checkpoints: StepCheckpoints | None = None,
        output_dir: str | Path | None = None,
        prefix: str = "cell",
        write_vtu: Callable[[Path, np.ndarray], object] | None = None,
        arrays: Callable[[], dict[str, np.ndarray]] | None = None,
        meta: Callable[[], dict[str, Any]] | None = None,
        progress: Callable[[int, int, str], None] | None = None,
        on_failure: str = "raise",
        t_start: float | None = None,
    ):
        self.solver = solver
        self.fabric, self.scene = fabric, scene
        self.where = f"{solver} solver ({fabric.pattern}, {fabric.yarn.name})"
        self.t_start = time.perf_counter() if t_start is None else t_start
        t_load, lam1, lam2 = scene.load.stretches()
        self.n_load = len(t_load)
        self.n_prestress = n_prestress
        self.total = self.n_load + n_prestress + extra_steps
        #: the progress count before the first load step
        self.offset = self.total - self.n_load
        #: λ1 and λ2 at τ = 0, 1, …, n_load (None for a free side)
        self.stretch_paths = tuple(
            None if lam is None else np.concatenate([[1.0], lam]) for lam in (lam1, lam2)
        )
        self.state = {} if state is None else state
        self.state.setdefault("phase", "prestress")
        self.state.setdefault("target", -1)
        self.checkpoints = checkpoints
        self.output_dir = output_dir
        self.prefix = prefix
        self.write_vtu = write_vtu
        self.vtu = write_vtu is not None and output_dir is not None and "vtu" in scene.outputs
        self.series: StepSeries | None = None
        self.arrays = arrays or dict
        self.meta = meta or dict
        self.progress = progress or (lambda done, total, message: None)
        self.on_failure = on_failure
        #: (λ1, λ2, T1, T2) of every converged load step
        self.rows: list[tuple[float, float, float, float]] = []
        self.notes: list[str] = []
        self.converged = True
        #: the index of the next step written
        self.step = 0

    # ------------------------------------------------------------------------ steps and files
    def open(self) -> dict[str, np.ndarray] | None:
        """Resume from this run's latest checkpoint, if any, and open the VTU series.

        Restores the rows, the state's declared keys (those the checkpoint lacks keep their initial
        values) and the step counter and logs ``resuming from step N
        of M``; returns the checkpoint's arrays (``q``, ``rows`` and the solver's own), or None.
        """
        saved = None if self.checkpoints is None else self.checkpoints.latest()
        if saved is not None:
            index, arrays, meta = saved
            self.rows[:] = [tuple(r) for r in arrays["rows"].tolist()]
            # a key the checkpoint lacks (written before the solver declared it) keeps its initial value
            self.state.update({k: meta.get(k, v) for k, v in self.state.items()})
            self.step = index + 1
            self.checkpoints.announce(index, self.total)
        self.series = StepSeries(self.output_dir, self.prefix, self.step) if self.vtu else None
        return None if saved is None else saved[1]

    def rows_array(self) -> np.ndarray:
        """The rows as an (n, 4) float64 array."""
        return np.array(self.rows, dtype=np.float64).reshape(-1, 4)

    def report(self, done: int, message: str) -> None:
        """``progress(done, total, message)``."""
        self.progress(done, self.total, message)

    def accept(self, phase: str, index: int, q: np.ndarray, message: str, done: int, **meta: Any) -> None:
        """Step ``index`` of ``phase`` converged at state q: its VTU file, its checkpoint, a progress report.

        ``meta`` and the run's ``meta()`` update the state saved with it.
        """
        self.state.update({"phase": phase, "target": index, **self.meta(), **meta})
        if self.series is not None:  # before the checkpoint: every checkpointed step has its file
            self.series.write(self.step, lambda path: self.write_vtu(path, q))
        if self.checkpoints is not None:
            self.checkpoints.save(self.step, {"q": q, "rows": self.rows_array(), **self.arrays()}, self.state)
        self.step += 1
        self.report(done, message)

    def rewind(self, step: int) -> None:
        """Drop the checkpoints and VTU files after step ``step``; the next step written is ``step``.

        Checkpoints go first, the latest first, so a run killed on the way resumes from a
        checkpoint whose files are all there; the file of ``step`` itself is rewritten next.
        """
        if self.checkpoints is not None:
            self.checkpoints.discard_after(step)
        if self.series is not None:
            self.series = StepSeries(self.output_dir, self.prefix, step + 1)
        self.step = step

    # ------------------------------------------------------------------------------------ phases
    def prestress(
        self,
        solve: Callable[[float, np.ndarray], Any],
        q: np.ndarray,
        *,
        min_fraction: float,
        first: int = 0,
        n_steps: int | None = None,
        label: str = "",
        record: bool = True,
        follow: Follow = continuation,
    ) -> np.ndarray:
        """The pre-stress from step ``first`` (t = first/n) to t = 1 in steps t_k = k/n; the last state.

        ``n_steps`` defaults to ``n_prestress``. With ``record`` every step is accepted
        (:meth:`accept`, phase ``"prestress"``); without, it is only reported as progress (a trial
        path that is not checkpointed). ``follow`` is the continuation used.
        """
        n = self.n_prestress if n_steps is None else n_steps
        targets = [k / n for k in range(first + 1, n + 1)]

        def on_target(i: int, t: float, res: Any) -> None:
            idx = int(round(t * n)) - 1
            message = f"pre-stress{label} {idx + 1}/{n}"
            if record:
                self.accept("prestress", idx, res.x, message, idx + 1)
            else:
                self.report(self.n_prestress, message)

        out = follow(solve, q, targets, t0=first / n, min_fraction=min_fraction, on_target=on_target)
        return out[-1].x if out else q

    def stretches(self, tau: float) -> tuple[float | None, float | None]:
        """The load path's prescribed (λ1, λ2) at load time τ, interpolated linearly (None: free)."""
        times = np.arange(self.n_load + 1)
        return tuple(None if p is None else float(np.interp(tau, times, p)) for p in self.stretch_paths)

    def load(
        self,
        solve: Callable[[float, np.ndarray], Any],
        q: np.ndarray,
        t0: float = 0.0,
        *,
        row: Callable[[float, Any], tuple[float, float, float, float]],
        min_fraction: float,
        on_step: Callable[[int, Any], None] | None = None,
        follow: Follow = continuation,
    ) -> np.ndarray:
        """The load path from load time ``t0`` and state q through τ = ⌊t0⌋ + 1, …, n_load; the last state.

        Each converged load step k (at τ = k) appends ``row(τ, result)`` to the rows, calls
        ``on_step(k, result)`` and is accepted (phase ``"load"``, target k − 1). NumericalError
        if a step fails (the rows so far are kept).
        """

        def on_target(i: int, tau: float, res: Any) -> None:
            self.rows.append(tuple(row(tau, res)))
            k = int(round(tau))
            if on_step is not None:
                on_step(k, res)
            self.accept("load", k - 1, res.x, f"load step {k}/{self.n_load}", self.offset + k)

        targets = list(np.arange(np.floor(t0) + 1, self.n_load + 1, dtype=float))
        out = follow(solve, q, targets, t0=t0, min_fraction=min_fraction, on_target=on_target)
        return out[-1].x if out else q

    # ------------------------------------------------------------------------ failure and notes
    @contextlib.contextmanager
    def truncating(self) -> Iterator[None]:
        """Run the phases in this block; a NumericalError ends them.

        It is raised again, prefixed with the solver and fabric, with ``on_failure = "raise"`` or
        when no load step converged; otherwise the run is truncated: the converged rows are kept,
        ``converged`` is false and a note says where it stopped.
        """
        try:
            yield
        except NumericalError as e:
            if self.on_failure == "raise" or not self.rows:
                raise NumericalError(f"{self.where}: {e}") from None
            self.converged = False
            self.notes.append(f"stopped after {len(self.rows)} of {self.n_load} load steps: {e}")

    def warn(self, message: str, stacklevel: int = 2) -> None:
        """A note in the Provenance that is also a :class:`~knitframe.errors.KnitframeWarning`."""
        self.notes.append(message)
        warnings.warn(message, KnitframeWarning, stacklevel=stacklevel + 1)

    def response(self, *, source: str, mesh: str, label: str, extra: dict[str, Any]) -> Response:
        """The Response of the rows, with the Provenance of this run (wall time, converged, notes)."""
        arr = self.rows_array()
        prov = Provenance(
            kind="simulation",
            source=source,
            solver=self.solver,
            mesh=mesh,
            wall_time=time.perf_counter() - self.t_start,
            converged=self.converged,
            notes="; ".join(self.notes),
            extra=extra,
        )
        return Response(
            arr[:, 0],
            arr[:, 1],
            arr[:, 2],
            arr[:, 3],
            load=self.scene.load.response_kind,
            label=label,
            provenance=prov,
        )
