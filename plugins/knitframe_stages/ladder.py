"""Stage ``[ladder]``: one fabric and scene through rungs of fidelity, with what each costs.

::

    [ladder]
    rungs = ["reduced", "rod:8", "rod:16", "rod:32", "volumetric:p1:coarse"]   # default: see below
    max_time = 900                   # s: skip rungs whose estimated time is over it
    executor = "local"               # or { kind = "dask", workers = 2 }: rungs of a wave run in parallel
                                     # (a config's [executor] table, if it has one, is used instead)
    solver_options = { volumetric = { contact_modulus = 1.2 } }   # for every rung of that solver

    [fabric]                         # read as the [solver] stage reads them
    pattern = "jersey"
    stitch_length = 11
    yarn = "cotton"

    [scene]
    effects = ["large_deformation", "bending", "contact", "self_contact", "prestress", "anisotropy"]
    load = { kind = "equibiaxial", max_strain = 0.3, steps = 6 }

The work is done by :mod:`knitframe.ladder` (the waves by :mod:`knitframe.ladder.runner`); this
stage reads the config into it. The rungs are :data:`knitframe.ladder.RUNGS`. Each simulated
rung simulates the scene's effects that its solver models (the rod has no anisotropic section,
for instance; the CSV lists them). The best rung that converged is the reference; ``reduced`` is
the paper's model fitted to it (hgo; hgo2m when a side is free), so its error is what the
three-parameter model costs in accuracy. With a ``[data]`` table, the measured curves of the same
load are compared as well (their points up to the path's largest stretch).

Rungs run in waves, cheapest first, through the executor (``executor.map``): each rung in a fresh
process, whose wall time and peak memory are the rung's. Before a wave, each rung's estimated time
and memory are logged, from :class:`knitframe.ladder.CostModel` fitted to the rungs already run,
the ``timings`` files and the shipped timings; a rung estimated over ``max_time`` is skipped with a
one-line notice. Finished rungs are kept in the executor's cache (``cache_dir``), so a rerun only
runs what is new.

Writes ``ladder.csv``, ``ladder.md``, ``ladder.png`` (time against error, log axes),
``curves.png`` and ``ladder-curves.csv``.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, ClassVar

import attrs

from knitframe import __version__, hookimpl
from knitframe import validators as v
from knitframe.config import PluginSpec, instantiate
from knitframe.errors import ConfigError, KnitframeError, NumericalError
from knitframe.executors import executor_from_config
from knitframe.interfaces import Stage
from knitframe.ladder import (
    DEFAULT_RUNGS,
    RUNGS,
    CostModel,
    LadderResult,
    TimingPoint,
    convergence_table,
    plot_curves,
    plot_pareto,
    read_timings,
    rung,
    shipped_timings_path,
    write_convergence,
    write_csv,
    write_table,
)
from knitframe.ladder.runner import (
    compare,
    convergence_rows,
    fabric_label,
    measured_curves,
    run_reduced,
    run_waves,
    rung_rows,
    scene_label,
)
from knitframe.records import Scene
from knitframe.report import write_responses_csv
from knitframe.schema import build


@attrs.frozen
class LadderTable:
    """Schema of the ``[ladder]`` table."""

    #: rung names (docs/ladder.md): those listed there, or rod:N, volumetric:p1:r/X, volumetric:p2:r/X at any
    #: resolution; default: reduced, rod:8, rod:16, rod:32, volumetric:p1:coarse, volumetric:p1:r/3,
    #: volumetric:p2:r/1.67
    rungs: list[str] = attrs.Factory(lambda: list(DEFAULT_RUNGS))
    #: skip the rungs whose estimated wall time is over this, s; unset: run them all
    max_time: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: executor plugin name, or a table with ``kind`` and its options; the rungs of a wave go through its
    #: ``map``
    executor: str | dict[str, Any] = "local"
    #: keep finished rungs in the executor's cache and reuse them
    cache: bool = True
    #: where the finished rungs are kept; unset: the executors' cache, which `knitframe cache clear` empties
    #: ($KNITFRAME_CACHE_DIR, else knitframe/jobs in $XDG_CACHE_HOME or ~/.cache)
    cache_dir: str | None = None
    #: measured timings for the cost model: ladder.csv files of earlier ladders, or JSON files like the
    #: shipped one
    timings: list[str] = attrs.Factory(list)
    #: let the cost model use the timings shipped with knitframe
    shipped_timings: bool = True
    #: solver options for every rung of a solver, by solver name: ``{ volumetric = { contact_modulus = 1.2 }
    #: }``
    solver_options: dict[str, Any] = attrs.Factory(dict)
    #: the reduced rung's homogenizer; "auto": hgo, or hgo2m when the load leaves a side free
    reduced_model: str | dict[str, Any] = "auto"
    #: the reduced rung's fitter name, or a table with ``kind`` and options
    reduced_fitter: str | dict[str, Any] = "lbfgs"


def default_cache_dir() -> Path:
    """The executors' result cache (:func:`knitframe.cache.default_cache_dir`), which ``knitframe cache
    clear`` empties: a rung's key holds its inputs, the knitframe version and a hash of the code."""
    from knitframe.executors import default_cache_dir as jobs_cache_dir

    return jobs_cache_dir()


@attrs.frozen
class LadderStage(Stage):
    """Run the rungs of the accuracy ladder on the config's fabric and scene and compare them."""

    name: ClassVar[str] = "ladder"
    description: ClassVar[str] = (
        "accuracy ladder: one fabric and scene through rungs of fidelity, with time, memory and error"
    )
    order: ClassVar[int] = 40
    uses: ClassVar[tuple[str, ...]] = ("fabric", "scene", "yarns", "executor")
    schema: ClassVar[type] = LadderTable

    #: the validated [ladder] table
    settings: LadderTable
    #: in the order of fidelity (Rung.fidelity)
    rungs: tuple[str, ...]
    #: each simulated rung's validated simulate stage (solver, fabric, scene)
    stages: dict[str, Any]
    #: each simulated rung's executor job (plain data)
    jobs: dict[str, dict[str, Any]]
    #: the reduced rung's job without its reference curve
    reduced: dict[str, Any] | None
    scene: Scene
    executor: Any
    executor_name: str
    timings: tuple[TimingPoint, ...]
    source: str | None = None

    @classmethod
    def from_config(cls, config, ctx) -> LadderStage:
        src = ctx.source
        table = build(LadderTable, config["ladder"], "ladder", source=src)
        names = _check_rungs(table.rungs, src)
        scene_table = config.get("scene", {})
        if isinstance(scene_table, dict) and isinstance(scene_table.get("load"), list):
            raise ConfigError(
                "scene.load",
                "the ladder follows one load path: give one load table (an array of "
                "loads is for the [solver] stage)",
                source=src,
            )
        scene = build(Scene, scene_table, "scene", source=src)
        simulate = ctx.registry["stage"]["simulate"]
        used_solvers = {rung(n).solver for n in names if n != "reduced"}
        options = _check_solver_options(table.solver_options, used_solvers, src)
        stages, jobs = {}, {}
        for name in names:
            rg = rung(name)
            if rg.solver == "reduced":
                continue
            solver_cls = ctx.registry["solver"][rg.solver]
            effects = sorted(scene.effects & solver_cls.effects)
            solver_table = {
                "kind": rg.solver,
                "on_failure": "truncate",
                **options.get(rg.solver, {}),
                **rg.options,
            }
            sub = {
                "solver": solver_table,
                "scene": {**scene_table, "effects": effects, "outputs": ["response"]},
            }
            sub.update({k: config[k] for k in ("fabric", "yarns") if k in config})
            try:
                stages[name] = simulate.from_config(sub, ctx)
            except ConfigError as e:
                path = e.path
                if path.startswith("solver."):
                    path = f"ladder.solver_options.{rg.solver}.{path[len('solver.') :]}"
                raise ConfigError(path, e.problem, source=src) from None
            jobs[name] = {
                "rung": name,
                "solver": solver_table,
                "config": sub,
                "knitframe": __version__,
                "attempt": 0,
            }
        reduced = None
        if "reduced" in names:
            reduced = _reduced_job(table, scene, scene_table, ctx.registry, src)
        executor, executor_name = _executor(table, config, ctx)
        timings: list[TimingPoint] = []
        for i, f in enumerate(table.timings):
            timings += read_timings(ctx.path(f, f"ladder.timings[{i}]"), "given")
        if table.shipped_timings and shipped_timings_path().is_file():
            timings += read_timings(shipped_timings_path(), "shipped")
        return cls(table, names, stages, jobs, reduced, scene, executor, executor_name, tuple(timings), src)

    # ------------------------------------------------------------------------------------ run
    def run(self, ctx) -> None:
        executor = self.executor
        if getattr(ctx, "no_cache", False) and "cache_dir" in _fields(executor):  # a run without the cache
            executor = attrs.evolve(executor, cache_dir=None)
        ctx.used("stage", self.name)
        ctx.used("executor", self.executor_name)
        for st in self.stages.values():
            ctx.used("solver", st.solver_name)
        first = next(iter(self.stages.values()))
        fabric = first.fabric
        ctx.used("pattern", fabric.pattern)
        t_start = time.time()
        curves: dict[str, Any] = {}
        rows = rung_rows(self.stages, self.jobs, self.scene, ctx.registry, fabric)
        run_waves(
            executor,
            self.jobs,
            rows,
            CostModel(self.timings),
            budget=self.settings.max_time,
            parallel=self._parallel(),
            t_start=t_start,
            curves=curves,
        )
        finished = [n for n in self.rungs if rows.get(n, {}).get("status") == "ok"]
        reference = finished[-1] if finished else None
        if self.reduced is not None:
            rows["reduced"] = run_reduced(
                executor, self.reduced, self.scene, reference, curves, t_start, fabric
            )
        if not curves:
            statuses = "; ".join(f"{n}: {rows[n].get('status')}" for n in self.rungs if n in rows)
            if all(str(r.get("status", "")).startswith("skipped") for r in rows.values()):
                raise ConfigError(
                    "ladder.max_time", f"every rung was skipped ({statuses})", source=self.source
                )
            raise NumericalError(f"no rung of the ladder finished: {statuses}")
        measured = measured_curves(self.scene, ctx.responses)
        compare(rows, curves, reference, measured)
        ordered = [rows[n] for n in self.rungs if n in rows]
        convergence = convergence_rows(curves, self.scene)
        self._write(ctx, ordered, curves, measured, fabric, reference, convergence)

    def _parallel(self) -> bool:
        """Whether the executor runs a wave's jobs side by side (the local one with one worker does not)."""
        return self.executor_name != "local" or getattr(self.executor, "workers", 1) > 1

    def _write(self, ctx, rows, curves, measured, fabric, reference, convergence=()) -> None:
        title = f"{fabric_label(fabric)}, {scene_label(self.scene)}"
        labels = [m.label for m in measured]
        write_csv(ctx.output("ladder.csv"), rows)
        md = ctx.output("ladder.md")
        table = write_table(md, rows, title=title, measured=labels)
        if convergence:
            write_convergence(ctx.output("convergence.csv"), convergence)
            table += convergence_table(convergence)
            md.write_text(table, encoding="utf-8")
        plot_pareto(ctx.output("ladder.png"), rows, title=title)
        ordered = {n: curves[n] for n in self.rungs if n in curves}
        plot_curves(
            ctx.output("curves.png"),
            ordered,
            measured,
            title=title,
            load=self.scene.load.response_kind,
            reference=reference,
        )
        write_responses_csv(ctx.output("ladder-curves.csv"), list(ordered.values()))
        done = [r for r in rows if r.get("wall_time_s") is not None]
        skipped = [r["rung"] for r in rows if str(r.get("status", "")).startswith("skipped")]
        headline = (
            f"{len(done)} of {len(rows)} rungs ran, best {reference or 'none'}"
            + (f"; skipped {', '.join(skipped)}" if skipped else "")
            + (f"; measured: {', '.join(labels)}" if labels else "")
        )
        ctx.results[self.name] = {
            "reference": reference,
            "rungs": rows,
            "measured": labels,
            "headline": headline,
        }
        ctx.objects[self.name] = LadderResult(rows, ordered, measured, reference, table)


# ------------------------------------------------------------------------------------ helpers
def _check_rungs(names: list[str], source: str | None) -> tuple[str, ...]:
    """The rung names, checked and put in the order of fidelity; one ConfigError naming a bad one."""
    if not names:
        raise ConfigError("ladder.rungs", "name at least one rung", source=source)
    seen: set[str] = set()
    for i, name in enumerate(names):
        try:
            rung(name)
        except ValueError as e:
            raise ConfigError(f"ladder.rungs[{i}]", str(e), source=source) from None
        if name in seen:
            raise ConfigError(f"ladder.rungs[{i}]", f"rung {name!r} is named twice", source=source)
        seen.add(name)
    if seen == {"reduced"}:
        raise ConfigError(
            "ladder.rungs",
            "'reduced' is fitted to the best simulated rung: name at least one "
            "rod or volumetric rung as well",
            source=source,
        )
    return tuple(sorted(seen, key=lambda n: rung(n).fidelity))


def _check_solver_options(table: dict[str, Any], solvers: set[str], source: str | None) -> dict[str, dict]:
    out = {}
    for solver, opts in table.items():
        path = f"ladder.solver_options.{solver}"
        if solver not in {r.solver for r in RUNGS.values() if r.solver != "reduced"}:
            raise ConfigError(path, "unknown solver; expected rod or volumetric", source=source)
        if not isinstance(opts, dict):
            raise ConfigError(path, f"expected a table of solver options, got {opts!r}", source=source)
        fixed = {k for r in RUNGS.values() if r.solver == solver for k in r.options} | {"kind"}
        for k in opts:
            if k in fixed:
                raise ConfigError(
                    f"{path}.{k}", "is set by each rung (choose the rungs instead)", source=source
                )
        if solver in solvers:
            out[solver] = dict(opts)
    return out


def _reduced_job(table: LadderTable, scene: Scene, scene_table: dict, registry, source) -> dict[str, Any]:
    model = table.reduced_model
    if model == "auto":
        model = "hgo2m" if scene.load.kind == "uniaxial" else "hgo"
    instantiate(registry, "homogenizer", model, "ladder.reduced_model", source=source)
    instantiate(registry, "fitter", table.reduced_fitter, "ladder.reduced_fitter", source=source)
    effects = sorted(scene.effects & registry["solver"]["reduced"].effects)
    sub_scene = {**scene_table, "effects": effects, "outputs": ["response"]}
    build(Scene, sub_scene, "scene", source=source)
    return {
        "rung": "reduced",
        "solver": {"kind": "reduced", "model": model, "fitter": table.reduced_fitter},
        "scene": sub_scene,
        "knitframe": __version__,
        "attempt": 0,
    }


def _executor(table: LadderTable, config, ctx) -> tuple[Any, str]:
    """The executor of ``[ladder] executor``, or of the config's ``[executor]`` table when it has one."""
    if "executor" in config:
        if "executor" in config["ladder"]:
            raise ConfigError(
                "ladder.executor",
                "the config has an [executor] table as well: name the executor in one place",
                source=ctx.source,
            )
        executor, name = executor_from_config(config, ctx)
        if not table.cache and "cache_dir" in _fields(executor):
            executor = attrs.evolve(executor, cache_dir=None)
        return executor, name
    spec = PluginSpec.parse(table.executor, "ladder.executor")
    try:
        impl = ctx.registry["executor"][spec.kind]
    except KnitframeError as e:
        key = "ladder.executor.kind" if isinstance(table.executor, dict) else "ladder.executor"
        raise ConfigError(key, str(e), source=ctx.source) from None
    options = dict(spec.options)
    takes_cache = "cache_dir" in _fields(impl)
    if takes_cache and "cache_dir" not in options:
        if not table.cache:
            options["cache_dir"] = None
        elif table.cache_dir is not None:
            options["cache_dir"] = str(ctx.path(table.cache_dir, "ladder.cache_dir", must_exist=False))
        else:
            options["cache_dir"] = str(default_cache_dir())
    return instantiate(
        ctx.registry, "executor", {"kind": spec.kind, **options}, "ladder.executor", source=ctx.source
    ), spec.kind


def _fields(obj: Any) -> dict[str, Any]:
    """An attrs class's (or instance's) fields by name; empty for anything else."""
    cls = obj if isinstance(obj, type) else type(obj)
    return attrs.fields_dict(cls) if attrs.has(cls) else {}


@hookimpl
def register_stages(register):
    register(LadderStage)
