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

Each point is one job, ``run_point(job)``, a plain dict of its resolved solver, fabric (with the
yarn's numbers), scenes and fit tables, run through the ``[executor]``: simulate the unit cell under
each load, fit the reduced model to the simulated curves. A point that raises is recorded as
``failed`` with its one-line reason and the others go on. Finished points are cached
(``knitframe run --no-cache`` computes them afresh; ``knitframe cache clear`` empties the cache).

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
  (:func:`knitframe.trends.trends`).

Against measured tests: a point may carry ``measured = { files = [...], reader = "singal2024",
max_strain = 0.6 }`` (:class:`MeasuredTable`). The files are read (and checked) with the config;
each test is simulated as it was made, uniaxial along its direction with the sides free, from the
relaxed cell to its largest strain (at most ``max_strain``) in the base load's steps, and compared
with :func:`knitframe.report.validate_uniaxial`. A load or a fit of such a point that fails is
recorded and the rest of the point is kept. sweep.csv then gains per-curve columns (each
``_course`` and ``_wale``: the file, status, strain ranges, NRMSE against the measurement, the
simulated/measured tension at 10/20/30 % and the lateral strains at 20 %), and the run writes
``validation.csv`` (one row per curve) and ``validation.png`` (the simulated curves over the
measured ones).
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import socket
import time
import warnings
from pathlib import Path
from typing import Any, ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.cache import JobCache, JobFailure, failure_reason, job_keys
from knitframe.config import PluginSpec, instantiate
from knitframe.errors import ConfigError, DataError, FieldError, KnitframeWarning
from knitframe.geometry import checked_cell
from knitframe.interfaces import DispatchingReader
from knitframe.progress import ProgressBar
from knitframe.records import Fabric, Response, Scene
from knitframe.report import curve, plot_validation, validate_uniaxial
from knitframe.schema import build, field_names, to_dict

#: [fabric] keys a point may set
FABRIC_KEYS = tuple(k for k in field_names(Fabric))
#: [scene] keys a point may set
SCENE_KEYS = ("load", "effects")
#: the point key that carries measured tests
MEASURED_KEY = "measured"
#: per-curve columns of sweep.csv for points with measured tests, each once per direction (``_course``, ``_wale``)
VALIDATION_COLUMNS = (
    "measured",
    "measured_status",
    "measured_to",
    "simulated_to",
    "nrmse_measured",
    "ratio_10",
    "ratio_20",
    "ratio_30",
    "lateral_at",
    "lateral_simulated",
    "lateral_measured",
)
#: most points one sweep may have
MAX_POINTS = 100_000
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
class MeasuredTable:
    """Schema of a point's ``measured`` table: the tests the point is simulated as and compared with."""

    #: test files, relative to the config file: uniaxial tests with free sides, at most one per direction
    files: list[str]
    #: reader plugin name, or a table with ``kind`` and options
    reader: str | dict[str, Any] = "auto"
    #: simulate at most to this strain; unset: to the end of each test
    max_strain: float | None = attrs.field(
        default=None, validator=v.optional(v.in_range(0.0, 5.0, lo_open=True))
    )

    def __attrs_post_init__(self) -> None:
        if not self.files:
            raise FieldError("files", "must list at least one file")


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


# ------------------------------------------------------------------------------------------ points
@attrs.frozen
class Point:
    """One validated point: its name, its merged solver table, the validated simulate stage and its cell's sizes."""

    index: int
    name: str
    #: e.g. "jersey SL11 cotton"
    label: str
    #: [solver] as merged from the config
    solver_table: dict[str, Any]
    #: the simulate stage built from the point's tables (validated)
    stage: Any
    #: yarn per stitch of the knitted cell, mm
    arc_length: float
    #: the knitted cell's course and wale pitches, mm
    cell_pitches: tuple[float, float]
    #: the measured tests the point is compared with, one per load
    measured: tuple[Response, ...] = ()
    #: their files, as the config gives them
    measured_files: tuple[str, ...] = ()


def _is_table(value: Any) -> bool:
    return isinstance(value, dict)


def _merge(base: dict[str, Any], over: dict[str, Any]) -> tuple[dict, dict, dict, dict]:
    """``(solver, fabric, scene, origin)`` tables of a point: the base tables with the point's keys;
    ``origin`` maps a config path (``fabric.stitch_length``) to the key that set it."""
    solver, fabric, scene = dict(base["solver"]), dict(base["fabric"]), dict(base["scene"])
    origin: dict[str, str] = {}
    for key, (value, where) in over.items():
        if key in FABRIC_KEYS:
            fabric[key] = value
            origin[f"fabric.{key}"] = where
        elif key == "load":  # a table is merged into a base load table; an array of loads replaces it
            load = scene.get("load", {})
            scene["load"] = {**load, **value} if _is_table(load) and _is_table(value) else value
            origin["scene.load"] = where
        elif key == "effects":
            scene["effects"] = value
            origin["scene.effects"] = where
        elif key == "solver":
            solver.update(value)
            for opt in value:
                origin[f"solver.{opt}"] = f"{where}.{opt}"
        else:  # an option of the base solver by name (checked by _expand)
            solver[key] = value
            origin[f"solver.{key}"] = where
    return solver, fabric, scene, origin


def _remap(path: str, origin: dict[str, str]) -> str:
    """A simulate-stage error path (``fabric.yarn.dk``) as the sweep key that set it."""
    for key in sorted(origin, key=len, reverse=True):
        if path == key or path.startswith(key + ".") or path.startswith(key + "["):
            return origin[key] + path[len(key) :]
    top = path.split(".")[0].split("[")[0]
    return f"sweep.{path}" if top in ("solver", "fabric", "scene") else path


def _size(fabric: Fabric) -> str:
    return f"SL{fabric.stitch_length:g}" if fabric.stitch_length is not None else f"{fabric.arc_length:g}mm"


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-." else "-" for c in text.lower()).strip("-")


def _fmt(seconds: float) -> str:
    from tqdm import tqdm

    return tqdm.format_interval(seconds)


class SweepProgress(ProgressBar):
    """The sweep's progress (the project's bar): a tqdm bar on a terminal, a line every 30 s elsewhere,
    with the counts of done, failed and running points and the time left; ``note`` prints a one-off line."""

    def line(self) -> str:
        elapsed = time.perf_counter() - self.t0
        if not self.total:
            return f"knitframe: {self.label}: starting, {_fmt(elapsed)} elapsed"
        left = (
            "unknown"
            if self.done <= 0
            else "about " + _fmt(elapsed * max(self.total - self.done, 0.0) / self.done)
        )
        return (
            f"knitframe: {self.label}: {self.done:g}/{self.total:g} finished ({self.message}), "
            f"{_fmt(elapsed)} elapsed, {left} left"
        )

    def note(self, text: str) -> None:
        if self._bar is not None:
            self._bar.write(f"knitframe: {text}", file=self.stream)
        else:
            self._print(f"knitframe: {text}")


# ------------------------------------------------------------------------------------------ the job
def run_point(job: dict[str, Any]) -> dict[str, Any]:
    """One sweep point (an executor job: plain data): simulate the cell under each of its loads, fit the
    reduced model to the simulated curves jointly.

    Runs with one BLAS/OpenMP thread (so a point gives the same bits in this process, a process
    pool or a Dask worker), numpy's floating-point warnings as errors (as on the command line) and
    knitframe's warnings collected into the result. Returns plain data: the fit (as params.json),
    the simulated Responses (as dicts), the timings, the warnings and the host.

    A point compared with measured tests (``job["validation"]``) keeps what it can: a load that
    fails gives None in ``responses`` and its reason in ``failed_loads``, the fit uses the other
    curves, and a fit that fails gives ``fit`` None and its reason in ``fit_error``. It raises only
    when no load finished.
    """
    from threadpoolctl import threadpool_limits

    from knitframe.plugins import get_registry

    registry = get_registry()
    t0 = time.perf_counter()
    with threadpool_limits(limits=1), warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", KnitframeWarning)
        warnings.simplefilter("error", RuntimeWarning)
        solver = instantiate(registry, "solver", job["solver"], "solver")
        fabric = Fabric.from_dict(job["fabric"], "fabric")
        keep_going = bool(job.get("validation"))
        responses: list[Any] = []
        failed_loads: dict[str, str] = {}
        for sc in job["scenes"]:
            scene = Scene.from_dict(sc, "scene")
            try:
                responses.append(solver.simulate(fabric, scene))
            except Exception as e:  # noqa: BLE001 - a validation point records the load's reason and goes on
                if not keep_going:
                    raise
                responses.append(None)
                failed_loads[scene.load.response_kind] = failure_reason(e)
        done = [r for r in responses if r is not None]
        if not done:
            raise RuntimeError("; ".join(f"{k}: {why}" for k, why in failed_loads.items()))
        t1 = time.perf_counter()
        model = instantiate(registry, "homogenizer", job["fit"]["model"], "fit.model")
        fitter = instantiate(registry, "fitter", job["fit"]["fitter"], "fit.fitter")
        fit, fit_error = None, ""
        try:
            fit = fitter.fit(model, done).to_json()
        except Exception as e:  # noqa: BLE001 - as above: the simulated curves still meet the measured ones
            if not keep_going:
                raise
            fit_error = failure_reason(e)
        t2 = time.perf_counter()
    notes = list(
        dict.fromkeys(
            " ".join(str(w.message).split()) for w in seen if issubclass(w.category, KnitframeWarning)
        )
    )
    out = {
        "fit": fit,
        "responses": [r.to_dict() if r is not None else None for r in responses],
        "simulate_s": t1 - t0,
        "fit_s": t2 - t1,
        "wall_time_s": t2 - t0,
        "warnings": notes,
        "host": socket.gethostname(),
    }
    if keep_going:
        out.update({"failed_loads": failed_loads, "fit_error": fit_error})
    return out


def _plugin_module(registry: Any, kind: str, name: Any) -> str | None:
    try:
        obj = registry[kind][name]
    except Exception:  # noqa: BLE001 - not a plugin of this kind
        return None
    return getattr(obj, "__module__", None)


def point_modules(job: dict[str, Any]) -> list[str]:
    """The plugin modules a point runs that no import names (chosen by name at run time): its solver
    and the solver's plugins (linear solver, contact law), pattern, yarn model, reduced model and
    fitter. The cache hashes their source and everything of knitframe they import."""
    from knitframe.plugins import get_registry

    reg = get_registry()
    found = [
        _plugin_module(reg, "solver", job["solver"].get("kind")),
        _plugin_module(reg, "pattern", job["fabric"].get("pattern")),
        _plugin_module(reg, "yarn_model", (job["fabric"].get("yarn") or {}).get("model")),
        _plugin_module(reg, "homogenizer", job["fit"]["model"].get("kind")),
        _plugin_module(reg, "fitter", job["fit"]["fitter"].get("kind")),
    ]
    for value in job["solver"].values():  # options that name plugins: linear_solver, contact_law, ...
        name = value.get("kind") if isinstance(value, dict) else value
        if isinstance(name, str):
            found += [_plugin_module(reg, kind, name) for kind in ("linear_solver", "contact_law")]
    return sorted({m for m in found if m})


run_point.cache_modules = point_modules  # type: ignore[attr-defined]


def _map(executor: Any, jobs: list[dict[str, Any]], progress: Any) -> list[Any]:
    """The points' results in order, a JobFailure in place of each point that raised."""
    return list(executor.map(run_point, jobs, failures="keep", progress=progress))


# ------------------------------------------------------------------------------------------ stage
@attrs.frozen
class SweepStage:
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

    @classmethod
    def from_config(cls, config, ctx) -> SweepStage:
        from knitframe_executors import executor_from_config

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
        points = _expand(table, solver_fields, src)
        base = {"solver": solver_base, "fabric": table.fabric, "scene": table.scene}
        simulate = ctx.registry["stage"]["simulate"]
        built: list[Point] = []
        jobs: list[dict[str, Any]] = []
        names: dict[str, int] = {}
        fit = {
            "model": {"kind": model_name, **to_dict(model)},
            "fitter": {"kind": fitter_name, **to_dict(fitter)},
        }
        for i, (over, name, suffix, context) in enumerate(points):
            measured: tuple[Response, ...] = ()
            files: tuple[str, ...] = ()
            if MEASURED_KEY in over:  # the tests' own loads replace the point's load
                over = dict(over)
                value, where = over.pop(MEASURED_KEY)
                if "load" in over:
                    raise ConfigError(
                        over["load"][1],
                        "a point with measured tests simulates their own loads; remove "
                        "load (or measured)" + context,
                        source=src,
                    )
                measured, files, loads = _measured_tests(value, where, table.scene.get("load"), ctx)
                over["load"] = (loads, where)
            solver_table, fabric_table, scene_table, origin = _merge(base, over)
            sub = {"solver": solver_table, "fabric": fabric_table, "scene": scene_table}
            if "yarns" in config:
                sub["yarns"] = config["yarns"]
            try:  # exactly the simulate stage's checks, then the cell (for its arc length and pitches)
                stage = simulate.from_config(sub, ctx)
                cell = checked_cell(stage.fabric, ctx.registry)
            except ConfigError as e:
                raise ConfigError(_remap(e.path, origin), e.problem + context, source=src) from None
            fabric = stage.fabric
            label = f"{fabric.pattern} {_size(fabric)} {fabric.yarn.name}"
            auto = name is None
            if auto:
                name = _slug(f"{fabric.pattern}-{_size(fabric)}-{fabric.yarn.name}") + suffix
            if name in names:
                if not auto:
                    raise ConfigError(
                        f"sweep.points[{i}].name",
                        f"'{name}' is also the name of point {names[name]}; names must be distinct",
                        source=src,
                    )
                name = f"{name}-{i}"
            names[name] = i
            built.append(
                Point(
                    i,
                    name,
                    label,
                    solver_table,
                    stage,
                    float(cell.arc_length_per_stitch),
                    (float(cell.course_pitch), float(cell.wale_pitch)),
                    measured,
                    files,
                )
            )
            solver = stage.solver
            solver_job = {"kind": stage.solver_name, **(to_dict(solver) if attrs.has(type(solver)) else {})}
            scenes = stage.scenes or (stage.scene,)
            jobs.append(
                {
                    "solver": solver_job,
                    "fabric": fabric.to_dict(),
                    "scenes": [sc.to_dict() for sc in scenes],
                    "fit": fit,
                    **({"validation": True} if measured else {}),
                }
            )
        executor, executor_name = executor_from_config(config, ctx)
        return cls(
            table, tuple(built), tuple(jobs), model, model_name, fitter_name, executor, executor_name, src
        )

    @property
    def label(self) -> str:
        return "sweep"

    def run(self, ctx) -> None:
        ctx.used("stage", self.name)
        ctx.used("executor", self.executor_name)
        ctx.used("homogenizer", self.model_name)
        ctx.used("fitter", self.fitter_name)
        for p in self.points:
            ctx.used("solver", p.stage.solver_name)
            ctx.used("pattern", p.stage.fabric.pattern)
        executor = self.executor
        if ctx.no_cache and attrs.has(type(executor)) and "cache_dir" in attrs.fields_dict(type(executor)):
            executor = attrs.evolve(executor, cache_dir=None)
        jobs = [dict(j) for j in self.jobs]
        cache_dir = getattr(executor, "cache_dir", None)
        cache = JobCache(cache_dir) if cache_dir else None
        keys = job_keys(run_point, jobs) if cache else []
        cached = [cache.has(k) for k in keys] if cache else [False] * len(jobs)
        bar = None
        if not ctx.quiet:
            where = self.executor_name
            n = getattr(executor, "workers", None)
            if n is not None and not getattr(executor, "address", None):
                where += f", {n} worker{'s' if n != 1 else ''}"
            bar = SweepProgress(f"sweep {self.settings.name} ({len(jobs)} fabrics, {where})")
        t0 = time.perf_counter()
        try:
            results = _map(executor, jobs, bar)
        finally:
            if bar is not None:
                bar.close()
        wall = time.perf_counter() - t0
        for key, res in zip(
            keys, results
        ):  # a validation point with a failed load or fit is tried again next run
            if isinstance(res, dict) and (res.get("failed_loads") or res.get("fit_error")):
                path = cache.path(key) if cache else None
                if path is not None:
                    path.unlink(missing_ok=True)
        rows, entries, panels, curves = [], [], [], []
        for p, res, hit in zip(self.points, results, cached):
            row, entry = self._row(p, res, hit)
            if self.validating:
                columns, point_panels, point_curves = self._validate(p, res)
                row.update(columns)
                panels += point_panels
                curves += point_curves
            rows.append(row)
            if entry is not None:
                entries.append(entry)
        failed = [r for r in rows if r["status"] == "failed"]
        for r in failed[:SHOWN_FAILURES]:
            warnings.warn(
                f"sweep point {r['index']} ({r['name']}) failed: {r['reason']}",
                KnitframeWarning,
                stacklevel=2,
            )
        if len(failed) > SHOWN_FAILURES:
            warnings.warn(
                f"{len(failed) - SHOWN_FAILURES} more sweep points failed; see sweep.csv",
                KnitframeWarning,
                stacklevel=2,
            )
        self._write_csv(ctx.output("sweep.csv"), rows)
        verdicts = self._write_trends(ctx, rows)
        if entries:
            from knitframe.garment.library import FabricLibrary

            lib = FabricLibrary(self.settings.name, tuple(entries), self._library_source(len(entries)))
            lib.save(ctx.output("library.json"))
            plot_params(ctx.output("params.png"), rows, self.model, title=self._title(), failed=len(failed))
        else:
            warnings.warn(
                "no sweep point finished: library.json and params.png are not written (reasons in sweep.csv)",
                KnitframeWarning,
                stacklevel=2,
            )
        done = len(rows) - len(failed)
        n_cached = sum(1 for r in rows if r["cached"] == "yes")
        ctx.results[self.label] = {
            "points": len(rows),
            "done": done,
            "failed": len(failed),
            "cached": n_cached,
            "in_library": len(entries),
            "executor": self.executor_name,
            "wall_time_s": round(wall, 3),
            "headline": (
                f"{len(rows)} fabrics: {done} done, {len(failed)} failed, {n_cached} from the cache; "
                f"library of {len(entries)} fabrics; {wall:.1f} s on {self.executor_name}"
            ),
        }
        if verdicts:
            ctx.results[self.label]["trends"] = verdicts
        if self.validating:
            self._write_csv(ctx.output("validation.csv"), curves)
            plot_validation(
                ctx.output("validation.png"),
                panels,
                title=f"sweep {self.settings.name}: simulated ({', '.join(sorted({p.stage.solver_name for p in self.points}))}, "
                "solid) over measured (dashed) tension",
            )
            ctx.results[self.label]["validation"] = curves
            ctx.results[self.label]["headline"] += "; " + _validation_headline(curves)

    # -------------------------------------------------------------------------------- outputs
    def _write_trends(self, ctx, rows: list[dict[str, Any]]) -> dict[str, str]:
        """trends.md: the paper's four trends judged on the fits (:mod:`knitframe.trends`), when the model
        has a, b and θ and the points span stitch lengths, patterns and yarns, one fit each."""
        from knitframe.trends import spans_trends, trends, trends_markdown

        if not {"a", "b", "theta_deg"} <= set(self._param_keys()) or not spans_trends(rows):
            return {}
        found = trends(rows)
        ctx.output("trends.md").write_text(
            trends_markdown(found, title=f"The paper's trends: {self._title()}"), encoding="utf-8"
        )
        return {t.key: t.verdict for t in found}

    def _title(self) -> str:
        p = self.points[0]
        return (
            f"{self.model_name} fitted by {self.fitter_name} to {p.stage.solver_name} simulations "
            f"({_loads(p)}): sweep {self.settings.name}"
        )

    def _library_source(self, n: int) -> str:
        return (
            f"knitframe sweep '{self.settings.name}': {n} fabrics simulated by "
            f"{', '.join(sorted({p.stage.solver_name for p in self.points}))} and fitted with {self.model_name} by "
            f"{self.fitter_name} (knitframe run, [sweep] stage)"
        )

    def _row(self, p: Point, res: Any, hit: bool) -> tuple[dict[str, Any], Any]:
        fabric, scene = p.stage.fabric, p.stage.scene
        loads = [sc.load for sc in (p.stage.scenes or (scene,))]
        row: dict[str, Any] = {
            "index": p.index,
            "name": p.name,
            "status": "done",
            "reason": "",
            "pattern": fabric.pattern,
            "yarn": fabric.yarn.name,
            "stitch_length": fabric.stitch_length,
            "arc_length_mm": fabric.arc_length if fabric.arc_length is not None else p.arc_length,
            "load": "+".join(ld.response_kind for ld in loads),
            "max_strain": "/".join(f"{ld.max_strain:g}" for ld in loads),
            "steps": "/".join(str(ld.steps) for ld in loads),
            "effects": " ".join(sorted(scene.effects)),
            "solver": p.stage.solver_name,
            "solver_options": json.dumps(
                {k: v for k, v in p.solver_table.items() if k != "kind"}, sort_keys=True
            ),
            "model": self.model_name,
            "fitter": self.fitter_name,
        }
        names = list(self._param_keys())
        row.update({k: "" for k in names})
        row.update(
            {
                "nrmse": "",
                "nrmse_course": "",
                "nrmse_wale": "",
                "converged": "",
                "course_pitch_mm": "",
                "wale_pitch_mm": "",
                "max_tension_N_per_mm": "",
                "max_stretch": "",
                "wall_time_s": "",
                "simulate_s": "",
                "fit_s": "",
                "cached": "yes" if hit else "no",
                "in_library": "no",
                "library_note": "",
                "at_bound": "",
                "warnings": "",
                "host": "",
            }
        )
        if isinstance(res, JobFailure) or not isinstance(res, dict):
            row["status"] = "failed"
            row["reason"] = (
                str(res) if isinstance(res, JobFailure) else f"unexpected result {type(res).__name__}"
            )
            row["cached"] = "no"
            return row, None
        sims = [
            r for r in res["responses"] if r is not None
        ]  # a validation point keeps the loads that finished
        fit = res["fit"] or {}
        row["reason"] = "; ".join(
            [f"{load} failed: {why}" for load, why in (res.get("failed_loads") or {}).items()]
            + ([f"fit failed: {res['fit_error']}"] if res.get("fit_error") else [])
        )
        row.update({k: fit.get(k) for k in names})
        nrmse = fit.get("nrmse") or {}
        row.update(
            {
                "nrmse": nrmse.get("overall"),
                "nrmse_course": nrmse.get("course"),
                "nrmse_wale": nrmse.get("wale"),
                "converged": all(r["provenance"].get("converged", True) for r in sims),
                "wall_time_s": round(res["wall_time_s"], 3),
                "simulate_s": round(res["simulate_s"], 3),
                "fit_s": round(res["fit_s"], 3),
                "at_bound": " ".join(fit.get("at_bound") or ()),
                "warnings": " | ".join(res.get("warnings", ())),
                "host": res.get("host", ""),
            }
        )
        cp, wp, pitch_source = self._pitches(p, sims[0])
        # the limits: the largest course tension and stretch of any simulated curve
        t_max = max(float(np.max(np.asarray(r["T1"], dtype=np.float64))) for r in sims)
        l_max = max(float(np.max(np.asarray(r["lambda1"], dtype=np.float64))) for r in sims)
        row.update(
            {"course_pitch_mm": cp, "wale_pitch_mm": wp, "max_tension_N_per_mm": t_max, "max_stretch": l_max}
        )
        if res["fit"] is None:
            entry, note = None, f"no fit: {res.get('fit_error', '')}"
        else:
            entry, note = self._entry(p, fit, cp, wp, pitch_source, t_max, l_max)
        row["in_library"] = "yes" if entry is not None else "no"
        row["library_note"] = note
        return row, entry

    @property
    def validating(self) -> bool:
        """True when some point carries measured tests (sweep.csv then has the per-curve columns)."""
        return any(p.measured for p in self.points)

    def _validate(
        self, p: Point, res: Any
    ) -> tuple[dict[str, Any], list[dict[str, Any]], list[dict[str, Any]]]:
        """The point's per-curve columns of sweep.csv (empty for a point without measured tests), its
        panels of validation.png and its rows of validation.csv."""
        columns: dict[str, Any] = {f"{c}_{d}": "" for d in ("course", "wale") for c in VALIDATION_COLUMNS}
        sims: dict[str, Response] = {}
        failed_loads: dict[str, str] = {}
        if isinstance(res, dict):
            sims = {r["load"]: Response.from_dict(r, "response") for r in res["responses"] if r is not None}
            failed_loads = res.get("failed_loads") or {}
        panels, curves = [], []
        for mea, file in zip(p.measured, p.measured_files):
            d = "course" if mea.loaded_direction == 0 else "wale"
            sim = sims.get(mea.load)
            metrics: dict[str, Any] | None = None
            reason = ""
            if sim is not None:
                metrics = validate_uniaxial(sim, mea)
            else:
                reason = failed_loads.get(mea.load) or (
                    str(res) if not isinstance(res, dict) else "not simulated"
                )
            curve_row = {
                "index": p.index,
                "name": p.name,
                "pattern": p.stage.fabric.pattern,
                "yarn": p.stage.fabric.yarn.name,
                "direction": d,
                "measured": file,
                "measured_status": "done" if metrics is not None else "failed",
                "reason": reason,
            }
            for c in VALIDATION_COLUMNS[2:]:  # validate_uniaxial's "nrmse" is the column nrmse_measured
                curve_row[c] = (
                    metrics.get(c.replace("nrmse_measured", "nrmse")) if metrics is not None else None
                )
            if metrics is None:
                ((_, e, _, _),) = curve(mea)
                curve_row["measured_to"] = float(np.max(e))
            columns.update({f"{c}_{d}": curve_row[c] for c in VALIDATION_COLUMNS})
            curves.append(curve_row)
            panels.append(
                {
                    "title": f"{p.name}: pulled along the {d}",
                    "measured": mea,
                    "simulated": sim,
                    "metrics": metrics,
                    "reason": reason,
                }
            )
        return columns, panels, curves

    def _param_keys(self):
        from knitframe.fitting import params_to_json

        return params_to_json(self.model.param_names, [0.0] * len(self.model.param_names)).keys()

    @staticmethod
    def _pitches(p: Point, response: dict[str, Any]) -> tuple[float, float, str]:
        """Relaxed pitches from the simulated cell's lattice, or the knitted cell's when the solver gives none."""
        extra = response["provenance"].get("extra", {})
        L1, L2, lam = extra.get("L1_mm"), extra.get("L2_mm"), extra.get("relaxed_stretch")
        if L1 is not None and L2 is not None and lam is not None and all(x is not None for x in lam):
            cp = float(np.linalg.norm(L1)) * float(lam[0]) / 2.0
            wp = float(np.linalg.norm(L2)) * float(lam[1]) / 2.0
            return (
                cp,
                wp,
                (
                    f"relaxed {p.stage.solver_name} cell: course pitch |L1|·λ1/2, wale pitch |L2|·λ2/2 with the "
                    f"knitted lattice L1 = {float(np.linalg.norm(L1)):.4g} mm, L2 = {float(np.linalg.norm(L2)):.4g} "
                    f"mm and the relaxation's stretches λ1 = {float(lam[0]):.4g}, λ2 = {float(lam[1]):.4g}"
                ),
            )
        cp, wp = p.cell_pitches
        return (
            cp,
            wp,
            (
                f"the knitted cell's pitches ({p.stage.solver_name} reports no relaxed lattice): not relaxed, "
                "measure them"
            ),
        )

    def _entry(
        self,
        p: Point,
        fit: dict[str, Any],
        cp: float,
        wp: float,
        pitch_source: str,
        t_max: float,
        l_max: float,
    ) -> tuple[Any, str]:
        from knitframe.garment.library import FabricEntry

        fabric = p.stage.fabric
        nrmse = (fit.get("nrmse") or {}).get("overall")
        source = (
            f"sweep '{self.settings.name}' point {p.index}: {p.stage.solver_name} simulation of {p.label}, "
            f"{_loads(p)} ({', '.join(sorted(p.stage.scene.effects))}); "
            f"{self.model_name} fitted by {self.fitter_name}"
            + (f", NRMSE {100 * nrmse:.2f} %" if isinstance(nrmse, (int, float)) else "")
            + "; limits: max_tension and max_stretch are the largest simulated course tension and stretch (the end "
            "of the simulated load path, not a measured failure)"
        )
        keys = list(self._param_keys())
        info = {
            k: fit[k]
            for k in (
                "fitter",
                "nrmse",
                "nrmse_transverse",
                "objective",
                "n_evals",
                "converged",
                "at_bound",
                "warnings",
            )
            if k in fit
        }
        try:
            entry = FabricEntry(
                name=p.name,
                pattern=fabric.pattern,
                yarn=fabric.yarn.name,
                stitch_length=fabric.stitch_length,
                arc_length=fabric.arc_length if fabric.arc_length is not None else p.arc_length,
                model=self.model_name,
                model_options=dict(fit.get("options") or {}),
                params={k: fit[k] for k in keys},
                course_pitch=cp,
                wale_pitch=wp,
                max_tension=t_max,
                max_stretch=l_max if l_max > 1.0 else None,
                source=source,
                pitch_source=pitch_source,
                fit=info,
            )
        except (ConfigError, TypeError, ValueError) as e:
            return None, " ".join(str(e).split())
        return entry, ""

    @staticmethod
    def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
        def cell(v: Any) -> Any:
            if v is None:
                return ""
            if isinstance(v, float):
                return repr(v) if math.isfinite(v) else ""
            return v

        with open(path, "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            for r in rows:
                w.writerow({k: cell(v) for k, v in r.items()})


def _expand(table: SweepTable, solver_fields: set[str], src: str | None):
    """The grid's or the list's points as ``[(keys, name, suffix, context)]``: each key with the sweep path
    that set it, the point's name if given, a name suffix for grid keys other than the fabric's, and
    a text naming a grid point in error messages."""
    allowed = set(FABRIC_KEYS) | set(SCENE_KEYS) | {"solver", MEASURED_KEY} | solver_fields
    shown = (
        ", ".join(list(FABRIC_KEYS) + list(SCENE_KEYS) + ["solver", MEASURED_KEY])
        + ", or an option of the solver"
    )
    if bool(table.grid) == bool(table.points):
        raise ConfigError(
            "sweep",
            "give the points as a grid (sweep.grid) or as a list (sweep.points), one of them",
            source=src,
        )

    def check_value(key: str, value: Any, where: str) -> None:
        if key == "solver" and not _is_table(value):
            raise ConfigError(where, f"expected a table of solver options, got {_short(value)}", source=src)
        if key == MEASURED_KEY and not _is_table(value):
            raise ConfigError(
                where, f"expected a table (files, reader, max_strain), got {_short(value)}", source=src
            )
        if key == "load" and not (
            _is_table(value) or (isinstance(value, list) and value and all(_is_table(v) for v in value))
        ):
            raise ConfigError(
                where, f"expected a load table or an array of load tables, got {_short(value)}", source=src
            )

    out = []
    if table.grid:
        keys = list(table.grid)
        for key in keys:
            where = f"sweep.grid.{key}"
            if key not in allowed:
                raise ConfigError(where, f"unknown key; a grid varies {shown}", source=src)
            if not table.grid[key]:
                raise ConfigError(where, "needs at least one value", source=src)
            for j, value in enumerate(table.grid[key]):
                check_value(key, value, f"{where}[{j}]")
        n = math.prod(len(table.grid[k]) for k in keys)
        if n > MAX_POINTS:
            raise ConfigError("sweep.grid", f"{n} points; at most {MAX_POINTS}", source=src)
        # keys other than the fabric's that take several values name their value's index in the point's name
        varied = [
            k
            for k in keys
            if len(table.grid[k]) > 1 and k not in ("pattern", "yarn", "stitch_length", "arc_length")
        ]
        for i, combo in enumerate(itertools.product(*(range(len(table.grid[k])) for k in keys))):
            over = {k: (table.grid[k][j], f"sweep.grid.{k}[{j}]") for k, j in zip(keys, combo)}
            text = ", ".join(f"{k} = {_short(table.grid[k][j])}" for k, j in zip(keys, combo))
            suffix = "".join(f"-{_slug(k)}{j}" for k, j in zip(keys, combo) if k in varied)
            out.append((over, None, suffix, f" (grid point {i}: {text})"))
        return out
    if len(table.points) > MAX_POINTS:
        raise ConfigError("sweep.points", f"{len(table.points)} points; at most {MAX_POINTS}", source=src)
    for i, point in enumerate(table.points):
        over = {}
        name = None
        for key, value in point.items():
            where = f"sweep.points[{i}].{key}"
            if key == "name":
                if not isinstance(value, str) or not value.strip() or "\n" in value:
                    raise ConfigError(where, f"expected one line of text, got {_short(value)}", source=src)
                name = value
                continue
            if key not in allowed:
                raise ConfigError(where, f"unknown key; a point sets name, {shown}", source=src)
            check_value(key, value, where)
            over[key] = (value, where)
        out.append((over, name, "", ""))
    return out


def _measured_tests(
    value: Any, where: str, base_load: Any, ctx: Any
) -> tuple[tuple[Response, ...], tuple[str, ...], list[dict[str, Any]]]:
    """A point's measured tests: the curves read (one per load), the file of each, and the loads that
    simulate them: uniaxial along the test's direction with free sides, from the relaxed cell to the
    test's largest strain (at most ``max_strain``), in the base load's number of steps."""
    src = ctx.source
    table = build(MeasuredTable, value, where, source=src)
    reader = instantiate(ctx.registry, "reader", table.reader, f"{where}.reader", source=src)
    steps = {"steps": base_load["steps"]} if _is_table(base_load) and "steps" in base_load else {}
    curves: list[Response] = []
    files: list[str] = []
    loads: list[dict[str, Any]] = []
    for j, name in enumerate(table.files):
        key = f"{where}.files[{j}]"
        path = ctx.path(name, key)
        try:
            read = (reader.reader_for(path) if isinstance(reader, DispatchingReader) else reader).read(path)
        except DataError as e:
            raise ConfigError(key, str(e), source=src) from None
        except OSError as e:
            raise ConfigError(key, f"cannot read {name}: {e.strerror or e}", source=src) from None
        if not read:
            raise ConfigError(key, f"{name} holds no curve", source=src)
        for r in read:
            if r.loaded_direction is None:
                raise ConfigError(
                    key,
                    f"a {r.load} test; a point simulates uniaxial tests (one direction pulled, "
                    "the sides free) only",
                    source=src,
                )
            ((_, e, _, _),) = curve(r)
            top = float(np.max(e)) if table.max_strain is None else min(float(np.max(e)), table.max_strain)
            if not top > 0:
                raise ConfigError(
                    key,
                    f"the test in {name} never stretches (largest strain {float(np.max(e)):g})",
                    source=src,
                )
            curves.append(r)
            files.append(name)
            loads.append(
                {
                    "kind": "uniaxial",
                    "direction": "course" if r.loaded_direction == 0 else "wale",
                    "max_strain": round(top, 4),
                    **steps,
                }
            )
    return tuple(curves), tuple(files), loads


def _validation_headline(curves: list[dict[str, Any]]) -> str:
    """The measured tests in one line: how many were simulated and the spread of the tension ratios."""
    done = [c for c in curves if c["measured_status"] == "done"]
    text = f"{len(done)} of {len(curves)} measured tests simulated"
    for key in ("ratio_10", "ratio_20", "ratio_30"):
        values = [c[key] for c in done if c[key] is not None]
        if values:
            text += (
                f"; sim/meas tension at {key[6:]} %: median {float(np.median(values)):.2g} "
                f"({min(values):.2g}-{max(values):.2g}, {len(values)} curves)"
            )
    return text


def _loads(p: Point) -> str:
    """The loads of a point in words: ``equibiaxial 0-20 % in 3 steps``."""
    parts = []
    for sc in p.stage.scenes or (p.stage.scene,):
        ld = sc.load
        what = ld.kind if ld.kind != "uniaxial" else f"uniaxial {ld.direction} (free side)"
        parts.append(f"{what} 0-{100 * ld.max_strain:g} % in {ld.steps} steps")
    return " and ".join(parts)


def _short(value: Any) -> str:
    text = json.dumps(value, sort_keys=True) if isinstance(value, (dict, list)) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


# ------------------------------------------------------------------------------------------ Fig. 4
def plot_params(
    path: Path, rows: list[dict[str, Any]], model: Any, *, title: str = "", failed: int = 0
) -> None:
    """The paper's Fig. 4: each fitted parameter against stitch length (arc length when a point has no
    stitch length), one panel each; colour per pattern, marker per yarn, a line per pattern and yarn.
    An open marker is a parameter that ended at a bound of the model's box: the data do not determine it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from knitframe.fitting import params_to_json

    keys = list(params_to_json(model.param_names, [0.0] * len(model.param_names)))
    # a point compared with measured tests may be done without a fit (its fit failed): nothing to draw
    done = [r for r in rows if r["status"] == "done" and all(r[k] not in ("", None) for k in keys)]
    log = list(getattr(model, "log_scale", (False,) * len(keys)))
    by_sl = all(r["stitch_length"] not in (None, "") for r in done)
    xkey, xlabel = (
        ("stitch_length", "stitch length (machine setting)")
        if by_sl
        else ("arc_length_mm", "yarn per stitch, mm")
    )
    patterns = list(dict.fromkeys(r["pattern"] for r in done))
    yarns = list(dict.fromkeys(r["yarn"] for r in done))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    markers = ["o", "s", "^", "D", "v", "P", "X", "*", "<", ">"]
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for r in done:
        variant = json.dumps(
            [r["load"], r["max_strain"], r["steps"], r["effects"], r["solver"], r["solver_options"]]
        )
        groups.setdefault((r["pattern"], r["yarn"], variant), []).append(r)
    variants = list(dict.fromkeys(k[2] for k in groups))
    styles = ["-", "--", ":", "-."]
    fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.9), dpi=110, squeeze=False)
    xs = sorted({float(r[xkey]) for r in done})
    for k, (key, ax) in enumerate(zip(keys, axes[0])):
        for (pattern, yarn, variant), members in groups.items():
            members = sorted(members, key=lambda r: float(r[xkey]))
            x = [float(r[xkey]) for r in members]
            y = [float(r[key]) for r in members]
            color = colors[patterns.index(pattern) % len(colors)]
            marker = markers[yarns.index(yarn) % len(markers)]
            ax.plot(x, y, styles[variants.index(variant) % len(styles)], color=color, lw=1.3)
            free = [
                key in r["at_bound"].split() for r in members
            ]  # open: at a bound, not determined by the data
            for xi, yi, f in zip(x, y, free):
                ax.plot([xi], [yi], ls="", marker=marker, ms=6, color=color, mfc="white" if f else color)
        if by_sl and len(xs) <= 12:
            ax.set_xticks(xs)
        name = key[:-4] if key.endswith("_deg") else key
        unit = ", °" if key.endswith("_deg") else (", N/mm" if name == "a" else "")
        ax.set_title(
            {"theta": "θ"}.get(name, name) + unit.replace(", ", " (").rstrip() + (")" if unit else "")
        )
        ax.set_xlabel(xlabel)
        if k < len(log) and log[k]:
            ax.set_yscale("log")
        ax.grid(alpha=0.3)
    handles = [Line2D([], [], color=colors[i % len(colors)], lw=2, label=p) for i, p in enumerate(patterns)]
    handles += [
        Line2D([], [], color="0.3", ls="", marker=markers[i % len(markers)], label=y)
        for i, y in enumerate(yarns)
    ]
    if any(r["at_bound"] for r in done):
        handles.append(Line2D([], [], color="0.3", ls="", marker="o", mfc="white", label="open: at a bound"))
    axes[0, -1].legend(handles=handles, fontsize=7, loc="best")
    note = f"; {failed} failed point{'s' if failed != 1 else ''} not shown" if failed else ""
    fig.suptitle((title or f"fitted {model.name} parameters") + note, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


@hookimpl
def register_stages(register):
    register(SweepStage)
