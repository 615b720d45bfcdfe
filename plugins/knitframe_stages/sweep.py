"""Stage ``[sweep]``: many fabrics through the simulate and fit stages, on one machine or a Dask cluster.

::

    [sweep]
    name = "rod-sweep"                  # the library's name in library.json
    grid = { pattern = ["jersey", "rib"], stitch_length = [10, 11, 12], yarn = ["cotton", "nylon"] }
    # or a list:  points = [{ pattern = "jersey", stitch_length = 11, yarn = "cotton" }, ...]

    [sweep.solver]                      # the [solver] of every point
    kind = "rod"
    segments_per_stitch = 10

    [sweep.scene]                       # the [scene] of every point
    effects = ["large_deformation", "bending", "contact", "prestress"]
    load = { kind = "equibiaxial", max_strain = 0.2, steps = 4 }

    [sweep.fit]                         # the reduced model fitted to every simulated curve
    model = "hgo"
    fitter = "lbfgs"

    [executor]                          # where the points run (default: local, one process)
    kind = "dask"
    workers = 2

A grid is the product of its lists, in the order written (the first key varies slowest); a list
gives each point as a table. A point's keys are ``[fabric]`` keys (``pattern``, ``yarn``,
``stitch_length``, ``arc_length``, ``course_pitch``, ``wale_pitch``, ``pattern_options``),
``[scene]`` keys (``load``: a table merged into the base load, or an array of loads, each
simulated and all fitted jointly; and ``effects``), ``solver`` (a table of solver options merged
into ``[sweep.solver]``) or any option of the base solver by name (``segments_per_stitch = [10,
16]``); a listed point may also have a ``name``. ``[sweep.fabric]`` gives the fabric keys common
to all points.

Every point is validated before any work exactly as the ``[solver]``/``[fabric]``/``[scene]``
tables of the simulate stage are (the same code: yarn names or tables, the pattern's cell, the
solver's effects and loads, its own checks); an error names the point's key in one line
(``sweep.points[3].stitch_length: ...``, ``sweep.grid.yarn[1]: ...``).

The work is done by :mod:`knitframe.sweep`; this stage reads the config into it. Each point is
one job, ``run_point(job)`` (:func:`knitframe.sweep.run_point`), a plain dict of its resolved
solver, fabric (with the yarn's numbers), scenes and fit tables, run through the ``[executor]``:
simulate the unit cell under each load, fit the reduced model to the simulated curves. A point
that raises is recorded as ``failed`` with its one-line reason and the others go on. Finished
points are cached (``knitframe run --no-cache`` computes them afresh; ``knitframe cache clear``
empties the cache).

Writes

* ``sweep.csv``: one row per point: its inputs, status and reason, fitted parameters (θ in
  degrees), NRMSE, relaxed pitches, limits, wall times and whether it came from the cache;
* ``library.json``: a :class:`~knitframe.garment.library.FabricLibrary` of the points that
  finished, which ``[design] library = ".../library.json"`` and :func:`knitframe.design` read
  directly. The pitches are those of the relaxed simulated cell (the rod solver reports its
  lattice vectors L1 = 2 course pitches and L2 = 2 wale pitches, and the stretches the relaxation
  reached: pitch = |L|·λ/2; a solver that does not gets the knitted cell's pitches, said in
  ``pitch_source``); the limits are the largest simulated course tension and stretch, the end of
  the simulated load path, not a measured failure (said in ``source``);
* ``params.png``: the paper's Fig. 4, each fitted parameter against stitch length, lines per
  pattern (colour), markers per yarn.
* ``trends.md``: when the model has a, b and θ (hgo) and the points span 2 or more stitch lengths,
  patterns and yarns (one fit each), the paper's four trends judged on the fits, with the numbers
  (:func:`knitframe.sweep.trends.trends`).

Against measured tests: a point may carry ``measured = { files = [...], reader = "singal2024",
max_strain = 0.6 }`` (:class:`~knitframe.sweep.MeasuredTable`). The files are read (and
checked) with the config; each test is simulated as it was made, uniaxial along its direction
with the sides free, from the relaxed cell to its largest strain (at most ``max_strain``) in the
base load's steps, and compared with :func:`knitframe.report.validate_uniaxial`. A load or a fit
of such a point that fails is recorded and the rest of the point is kept. sweep.csv then gains
per-curve columns (each ``_course`` and ``_wale``: the file, status, strain ranges, NRMSE against
the measurement, the simulated/measured tension at 10/20/30 % and the lateral strains at 20 %),
and the run writes ``validation.csv`` (one row per curve, with the measured tension at 10 %),
``validation.png`` (the simulated curves over the measured ones) and ``goals.md``: the four
validation goals judged on the curves (:mod:`knitframe.sweep.goals`): the median tension ratio within
1.5× of 1, every curve within 3×, the patterns in the measured order of stiffness, and the
lateral contraction within 0.05. ``[sweep.goals]`` sets the thresholds (``median_within``,
``curve_within``, ``lateral_within``).
"""

from __future__ import annotations

import time
import warnings
from typing import Any, ClassVar

import attrs

from knitframe import hookimpl
from knitframe.config import PluginSpec, instantiate
from knitframe.errors import ConfigError, KnitframeWarning
from knitframe.executors import executor_from_config
from knitframe.interfaces import Stage
from knitframe.report import plot_validation
from knitframe.schema import build, field_names, to_dict
from knitframe.sweep import (
    MET,
    GoalSettings,
    Point,
    SweepFits,
    SweepProgress,
    cached_points,
    expand,
    forget_partial,
    goals_markdown,
    held_fixed,
    map_points,
    plot_params,
    point_job,
    resolve_point,
    validate_point,
    validation_goals,
    validation_headline,
    write_csv,
    write_trends,
)

#: failed points named one per line at the end of a run (the rest are in sweep.csv)
SHOWN_FAILURES = 10


@attrs.frozen
class SweepFit:
    """Schema of ``[sweep.fit]``."""

    #: homogenizer name, or a table with ``kind`` and options
    model: str | dict[str, Any] = "hgo"
    #: fitter name, or a table with ``kind`` and options
    fitter: str | dict[str, Any] = "lbfgs"


@attrs.frozen
class SweepTable:
    """Schema of the ``[sweep]`` table."""

    #: the fabric library's name (library.json) and the sweep's label
    name: str = "sweep"
    #: lists of values whose product gives the points: [fabric] keys, load, effects, solver (tables of
    #: options), solver options by name, or measured
    grid: dict[str, list[Any]] = attrs.Factory(dict)
    #: the points as tables of the same keys, plus an optional ``name``; ``measured = { files = [...], reader
    #: = "singal2024", max_strain = 0.6 }`` simulates the tests' own loads and compares (docs/sweeps.md)
    points: list[dict[str, Any]] = attrs.Factory(list)
    #: the [solver] table of every point (``kind`` and options)
    solver: dict[str, Any] = attrs.Factory(lambda: {"kind": "rod"})
    #: [fabric] keys common to every point
    fabric: dict[str, Any] = attrs.Factory(dict)
    #: the [scene] table of every point
    scene: dict[str, Any] = attrs.Factory(dict)
    #: the reduced model and fitter for every point
    fit: SweepFit = attrs.Factory(SweepFit)
    #: the thresholds of the validation goals judged in goals.md (points with measured tests)
    goals: GoalSettings = attrs.Factory(GoalSettings)


# ------------------------------------------------------------------------------------------ stage
@attrs.frozen
class SweepStage(Stage):
    """Simulate and fit many fabrics (a grid or a list) through an executor; a fabric library comes out."""

    name: ClassVar[str] = "sweep"
    description: ClassVar[str] = (
        "many fabrics (a grid or a list) through simulate and fit, locally or on Dask"
    )
    order: ClassVar[int] = 30
    uses: ClassVar[tuple[str, ...]] = ("executor", "yarns")
    schema: ClassVar[type] = SweepTable

    settings: SweepTable
    points: tuple[Point, ...]
    jobs: tuple[dict[str, Any], ...]
    model: Any
    model_name: str
    fitter_name: str
    executor: Any
    executor_name: str
    source: str | None = None
    #: the yarns this config defines itself (its ``[yarns]`` table)
    own_yarns: tuple[str, ...] = ()

    @classmethod
    def from_config(cls, config, ctx) -> SweepStage:
        src = ctx.source
        table = build(SweepTable, config["sweep"], "sweep", source=src)
        if not table.name.strip() or "\n" in table.name:
            raise ConfigError("sweep.name", "must be one line of text", source=src)
        model = instantiate(ctx.registry, "homogenizer", table.fit.model, "sweep.fit.model", source=src)
        fitter = instantiate(ctx.registry, "fitter", table.fit.fitter, "sweep.fit.fitter", source=src)
        model_name = PluginSpec.parse(table.fit.model, "sweep.fit.model").kind
        fitter_name = PluginSpec.parse(table.fit.fitter, "sweep.fit.fitter").kind
        solver_base = {"kind": "rod", **table.solver}
        base_solver = instantiate(ctx.registry, "solver", solver_base, "sweep.solver", source=src)
        solver_fields = set(field_names(type(base_solver))) if attrs.has(type(base_solver)) else set()
        expanded = expand(table, solver_fields, src)
        base = {"solver": solver_base, "fabric": table.fabric, "scene": table.scene}
        fit = {
            "model": {"kind": model_name, **to_dict(model)},
            "fitter": {"kind": fitter_name, **to_dict(fitter)},
        }
        names: dict[str, int] = {}
        points = tuple(
            resolve_point(i, *point, base=base, config=config, ctx=ctx, names=names)
            for i, point in enumerate(expanded)
        )
        jobs = tuple(point_job(p, fit) for p in points)
        executor, executor_name = executor_from_config(config, ctx)
        own_yarns = tuple(config.get("yarns", {}))
        return cls(
            table, points, jobs, model, model_name, fitter_name, executor, executor_name, src, own_yarns
        )

    @property
    def label(self) -> str:
        return "sweep"

    @property
    def fits(self) -> SweepFits:
        """The sweep's name, model and fitter, as its rows and library entries take them."""
        return SweepFits(self.settings.name, self.model, self.model_name, self.fitter_name)

    @property
    def validating(self) -> bool:
        """True when some point carries measured tests (sweep.csv then has the per-curve columns)."""
        return any(p.measured for p in self.points)

    def run(self, ctx) -> None:
        ctx.used("stage", self.name)
        ctx.used("executor", self.executor_name)
        ctx.used("homogenizer", self.model_name)
        ctx.used("fitter", self.fitter_name)
        for p in self.points:
            ctx.used("solver", p.stage.solver_name)
            ctx.used("pattern", p.stage.fabric.pattern)
        results, cached, wall = self._map(ctx)
        rows, entries, panels, curves = [], [], [], []
        for p, res, hit in zip(self.points, results, cached, strict=False):
            row, entry = self.fits.row(p, res, hit)
            if self.validating:
                columns, point_panels, point_curves = validate_point(p, res)
                row.update(columns)
                panels += point_panels
                curves += point_curves
            rows.append(row)
            if entry is not None:
                entries.append(entry)
        failed = [r for r in rows if r["status"] == "failed"]
        _warn_failed(failed)
        write_csv(ctx.output("sweep.csv"), rows)
        verdicts = self._write_trends(ctx, rows)
        self._write_library(ctx, rows, entries, len(failed))
        self._results(ctx, rows, entries, len(failed), wall, verdicts)
        if self.validating:
            self._write_validation(ctx, panels, curves)

    def _map(self, ctx) -> tuple[list[Any], list[bool], float]:
        """Every point through the executor (with the run's progress bar): ``(results, cached,
        wall time)``, each result the point's or its JobFailure."""
        executor = self.executor
        if ctx.no_cache and attrs.has(type(executor)) and "cache_dir" in attrs.fields_dict(type(executor)):
            executor = attrs.evolve(executor, cache_dir=None)
        jobs = [dict(j) for j in self.jobs]
        cache, keys, cached = cached_points(executor, jobs)
        bar = None
        if not ctx.quiet:
            where = self.executor_name
            n = getattr(executor, "workers", None)
            if n is not None and not getattr(executor, "address", None):
                where += f", {n} worker{'s' if n != 1 else ''}"
            bar = SweepProgress(f"sweep {self.settings.name} ({len(jobs)} fabrics, {where})")
        t0 = time.perf_counter()
        try:
            results = map_points(executor, jobs, bar)
        finally:
            if bar is not None:
                bar.close()
        wall = time.perf_counter() - t0
        forget_partial(cache, keys, results)  # a validation point with a failed load or fit is tried again
        return results, cached, wall

    # -------------------------------------------------------------------------------- outputs
    def _write_trends(self, ctx, rows: list[dict[str, Any]]) -> dict[str, str]:
        """trends.md (:func:`knitframe.sweep.write_trends`); the verdicts by trend."""
        return write_trends(ctx.output, rows, self.fits.param_keys(), self.fits.title(self.points))

    def _write_library(self, ctx, rows: list[dict[str, Any]], entries: list[Any], failed: int) -> None:
        """library.json and params.png of the points that finished, or a warning when none did."""
        if entries:
            from knitframe.garment.library import FabricLibrary

            source = self.fits.library_source(self.points, len(entries))
            lib = FabricLibrary(self.settings.name, tuple(entries), source)
            lib.save(ctx.output("library.json"))
            title = self.fits.title(self.points)
            plot_params(ctx.output("params.png"), rows, self.model, title=title, failed=failed)
        else:
            warnings.warn(
                "no sweep point finished: library.json and params.png are not written (reasons in sweep.csv)",
                KnitframeWarning,
                stacklevel=3,
            )

    def _results(
        self, ctx, rows: list[dict[str, Any]], entries: list[Any], failed: int, wall: float, verdicts
    ) -> None:
        done = len(rows) - failed
        n_cached = sum(1 for r in rows if r["cached"] == "yes")
        ctx.results[self.label] = {
            "points": len(rows),
            "done": done,
            "failed": failed,
            "cached": n_cached,
            "in_library": len(entries),
            "executor": self.executor_name,
            "wall_time_s": round(wall, 3),
            "headline": (
                f"{len(rows)} fabrics: {done} done, {failed} failed, {n_cached} from the cache; "
                f"library of {len(entries)} fabrics; {wall:.1f} s on {self.executor_name}"
            ),
        }
        if verdicts:
            ctx.results[self.label]["trends"] = verdicts

    def _write_validation(self, ctx, panels: list[dict[str, Any]], curves: list[dict[str, Any]]) -> None:
        """validation.csv and validation.png, and the measured tests in the results."""
        write_csv(ctx.output("validation.csv"), curves)
        solvers = ", ".join(sorted({p.stage.solver_name for p in self.points}))
        plot_validation(
            ctx.output("validation.png"),
            panels,
            title=f"sweep {self.settings.name}: simulated ({solvers}, solid) over measured (dashed) tension",
        )
        ctx.results[self.label]["validation"] = curves
        ctx.results[self.label]["headline"] += "; " + validation_headline(curves)
        goals = validation_goals(curves, self.settings.goals)
        fixed = held_fixed(
            common={
                "sweep.solver": self.settings.solver,
                "sweep.fabric": self.settings.fabric,
                "sweep.scene": self.settings.scene,
            },
            points=self.settings.points,
            grid=self.settings.grid,
            yarns=list(dict.fromkeys(p.stage.fabric.yarn.name for p in self.points)),
            own_yarns=self.own_yarns,
        )
        ctx.output("goals.md").write_text(
            goals_markdown(
                goals, title=f"Validation goals: sweep {self.settings.name} ({solvers})", fixed=fixed
            ),
            encoding="utf-8",
        )
        ctx.results[self.label]["goals"] = {g.key: g.verdict for g in goals}
        met = sum(g.verdict == MET for g in goals)
        ctx.results[self.label]["headline"] += f"; goals met: {met} of {len(goals)} (goals.md)"


def _warn_failed(failed: list[dict[str, Any]]) -> None:
    """The failed points, one warning each up to :data:`SHOWN_FAILURES`, then how many more."""
    for r in failed[:SHOWN_FAILURES]:
        warnings.warn(
            f"sweep point {r['index']} ({r['name']}) failed: {r['reason']}",
            KnitframeWarning,
            stacklevel=3,
        )
    if len(failed) > SHOWN_FAILURES:
        warnings.warn(
            f"{len(failed) - SHOWN_FAILURES} more sweep points failed; see sweep.csv",
            KnitframeWarning,
            stacklevel=3,
        )


@hookimpl
def register_stages(register):
    register(SweepStage)
