"""Config-selected pipelines.

A config's top-level tables select stages: each registered :class:`~knitframe.interfaces.Stage`
owns the table named after it (``[data]``, ``[solver]``, ``[fit]`` …) and may read others it
``uses`` (``[fabric]``, ``[scene]``). A stage that declares ``repeatable = True`` may be given as
an array of tables (``[[fit]]``), one stage run per table. The pipeline

1. validates the whole config — unknown tables, every stage's options, plugin names, files,
   effects — before any work, so bad input leaves nothing behind;
2. takes the output folder through :class:`~knitframe.outdir.OutputDir` (refused if it is the
   current folder or a parent, a file, unwritable, not empty without ``--resume`` or
   ``--overwrite``, or locked by another run) and runs the present stages in ``order``, writing
   into its staging area;
3. moves the outputs into ``<out>`` and writes ``summary.json`` (stages, plugins with versions,
   timings, warnings, and exactly the files that are there) only when everything succeeded.

New stages arrive as plugins; nothing here changes when they do.
"""

from __future__ import annotations

import platform
import sys
import time
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import attrs

from knitframe.config import load_toml
from knitframe.errors import ConfigError, KnitframeWarning
from knitframe.interfaces import Stage, declared
from knitframe.outdir import OutputDir, fingerprint
from knitframe.plugins import Registry, get_registry
from knitframe.records import Response
from knitframe.version import __version__

__all__ = ["BuildContext", "RunContext", "Pipeline", "PipelineResult", "run", "RESERVED_TABLES"]

#: Top-level tables that belong to the pipeline itself rather than to a stage.
RESERVED_TABLES = ("pipeline",)


@attrs.define
class BuildContext:
    """What a stage needs while validating its config."""

    registry: Registry
    #: relative paths in the config are resolved against this directory
    base_dir: Path
    #: config file name, shown in error messages
    source: str | None = None
    #: top-level tables present in the config
    tables: frozenset[str] = frozenset()

    def path(self, value: str | Path, key: str, *, must_exist: bool = True) -> Path:
        """Resolve a config path; a missing file is a ConfigError at ``key``."""
        p = Path(value).expanduser()
        if not p.is_absolute():
            p = (self.base_dir / p).resolve()
        if must_exist and not p.exists():
            raise ConfigError(key, f"file not found: {value}", source=self.source)
        return p


@attrs.define
class RunContext:
    """Shared state of a running pipeline; stages read from and add to it."""

    registry: Registry
    #: directory the stage writes into (the run's staging area until it succeeds)
    out: Path
    #: root of the stages' checkpoint folders (kept for ``--resume``)
    checkpoints: Path | None = None
    #: measured or simulated curves
    responses: list[Response] = attrs.Factory(list)
    #: fitted reduced models
    models: list[Any] = attrs.Factory(list)
    #: rich results by stage label (a Design, …), for the API
    objects: dict[str, Any] = attrs.Factory(dict)
    #: per-stage results, by stage name
    results: dict[str, Any] = attrs.Factory(dict)
    #: files written, relative to ``out``
    outputs: list[str] = attrs.Factory(list)
    #: "kind:name" → {package, version}
    plugins: dict[str, dict[str, str]] = attrs.Factory(dict)
    #: continue from checkpoints left by a killed run
    resume: bool = False
    quiet: bool = False
    #: executors neither read nor keep cached job results (``--no-cache``)
    no_cache: bool = False

    def output(self, name: str) -> Path:
        """Path of an output file; records it for the summary."""
        self.outputs.append(name)
        p = self.out / name
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def checkpoint_dir(self, stage: str) -> Path:
        """Directory for a stage's checkpoints; it survives a killed run for ``--resume``."""
        p = (self.checkpoints or self.out / "checkpoints") / stage
        p.mkdir(parents=True, exist_ok=True)
        return p

    def used(self, kind: str, name: str) -> None:
        """Record that a plugin took part in the run (for provenance in summary.json)."""
        entry = self.registry[kind].entry(name)
        self.plugins[f"{kind}:{name}"] = {"package": entry.package, "version": entry.version}


@attrs.frozen
class PipelineResult:
    """What :func:`run` returns."""

    out: Path | None
    responses: list[Response]
    models: list[Any]
    results: dict[str, Any]
    summary: dict[str, Any]
    #: rich results by stage label (a Design, …)
    objects: dict[str, Any] = attrs.Factory(dict)


class Pipeline:
    """Validated stages of one config, ready to run."""

    def __init__(
        self,
        config: Mapping[str, Any],
        *,
        base_dir: Path,
        source: str | None = None,
        registry: Registry | None = None,
    ):
        self.registry = registry or get_registry()
        self.config = dict(config)
        self.source = source
        stage_kind = self.registry["stage"]
        owners: dict[str, str] = {}
        for name in stage_kind:
            owners[_table(stage_kind[name])] = name
            for t in stage_kind[name].uses:
                owners.setdefault(t, name)
        for key, value in self.config.items():
            if key in RESERVED_TABLES:
                continue
            if key not in owners:
                known = sorted(set(owners) | set(RESERVED_TABLES))
                raise ConfigError(key, f"unknown table; expected one of {', '.join(known)}", source=source)
            owner = stage_kind[owners[key]]
            repeatable = declared(owner, Stage, "repeatable") and _table(owner) == key
            if isinstance(value, list) and repeatable:
                if not value or not all(isinstance(v, dict) for v in value):
                    raise ConfigError(key, f"expected one or more tables ([[{key}]])", source=source)
            elif not isinstance(value, dict):
                raise ConfigError(key, f"expected a table, got {value!r}", source=source)
        self._check_pipeline_table()
        ctx = BuildContext(self.registry, base_dir, source, frozenset(self.config))
        present = [stage_kind[n] for n in stage_kind if _table(stage_kind[n]) in self.config]
        if not present:
            stages = ", ".join(f"[{_table(stage_kind[n])}]" for n in stage_kind)
            raise ConfigError(
                "", f"nothing to do: the config has none of the stage tables {stages}", source=source
            )
        self.stages = []
        for cls in sorted(present, key=lambda c: c.order):
            self.stages.extend(self._build(cls, ctx))

    def _build(self, cls: Any, ctx: BuildContext) -> list[Any]:
        """One stage instance per table; ``[[name]]`` arrays of a repeatable stage give several."""
        key = _table(cls)
        value = self.config[key]
        if not isinstance(value, list):
            return [cls.from_config(self.config, ctx)]
        stages = []
        for i, entry in enumerate(value):
            try:
                stages.append(cls.from_config({**self.config, key: entry}, ctx))
            except ConfigError as e:
                path = f"{key}[{i}]" + e.path[len(key) :] if e.path.startswith(key) else e.path
                raise ConfigError(path, e.problem, source=e.source) from None
        labels = [_label(s) for s in stages]
        dup = next((lab for lab in labels if labels.count(lab) > 1), None)
        if dup is not None:
            i = labels.index(dup, labels.index(dup) + 1)
            raise ConfigError(
                f"{key}[{i}].name",
                f"repeated [[{key}]] tables need distinct names, '{dup}' is used twice",
                source=self.source,
            )
        return stages

    def _check_pipeline_table(self) -> None:
        table = self.config.get("pipeline", {})
        allowed = {"name", "description"}
        for k, v in table.items():
            if k not in allowed:
                raise ConfigError(
                    f"pipeline.{k}",
                    f"unknown key; expected one of {', '.join(sorted(allowed))}",
                    source=self.source,
                )
            if not isinstance(v, str):
                raise ConfigError(f"pipeline.{k}", f"expected a string, got {v!r}", source=self.source)

    @property
    def name(self) -> str:
        return self.config.get("pipeline", {}).get("name", Path(self.source or "pipeline").stem)

    def run(
        self,
        out: str | Path | None,
        *,
        resume: bool = False,
        overwrite: bool = False,
        quiet: bool = False,
        no_cache: bool = False,
    ) -> PipelineResult:
        """Run every stage; outputs appear in ``out`` only if all succeed (None: no files).

        ``resume`` continues the same config's killed run from its checkpoints; ``overwrite``
        replaces the outputs of an earlier knitframe run in ``out`` (and nothing else); ``no_cache``
        makes the stages' executors compute every job afresh, without reading or keeping results.
        """
        if out is None:
            import tempfile

            with tempfile.TemporaryDirectory(prefix="knitframe-") as tmp:
                ctx = RunContext(
                    self.registry,
                    Path(tmp),
                    checkpoints=Path(tmp) / ".checkpoints",
                    quiet=quiet,
                    no_cache=no_cache,
                )
                summary = self._run_stages(ctx)
                return PipelineResult(None, ctx.responses, ctx.models, ctx.results, summary, ctx.objects)
        with OutputDir(
            out, command="run", fingerprint=fingerprint(self.config), resume=resume, overwrite=overwrite
        ) as od:
            ctx = RunContext(
                self.registry,
                od.staging,
                checkpoints=od.checkpoints,
                resume=resume,
                quiet=quiet,
                no_cache=no_cache,
            )
            summary = od.commit(self._run_stages(ctx))
        return PipelineResult(od.out, ctx.responses, ctx.models, ctx.results, summary, ctx.objects)

    def _run_stages(self, ctx: RunContext) -> dict[str, Any]:
        """Run the stages into ``ctx.out``; returns the summary (without its list of outputs)."""
        t_start = time.perf_counter()
        timings = []
        notes: list[str] = []
        with warnings.catch_warnings():
            warnings.simplefilter("always", KnitframeWarning)
            show = warnings.showwarning

            def keep(message, category, *args, **kwargs):  # shown as usual, and kept for the summary
                if issubclass(category, KnitframeWarning):
                    notes.append(str(message))
                show(message, category, *args, **kwargs)

            warnings.showwarning = keep
            for stage in self.stages:
                t0 = time.perf_counter()
                stage.run(ctx)
                timings.append({"stage": _label(stage), "seconds": round(time.perf_counter() - t0, 6)})
        missing = sorted(
            set(ctx.outputs) - {str(p.relative_to(ctx.out)) for p in ctx.out.rglob("*") if p.is_file()}
        )
        if missing:
            raise RuntimeError(f"stages declared outputs they did not write: {missing}")
        return {
            "knitframe": __version__,
            "pipeline": self.name,
            "config": self.source,
            "stages": timings,
            "plugins": dict(sorted(ctx.plugins.items())),
            "results": _jsonable(ctx.results),
            "warnings": notes,
            "wall_time_s": round(time.perf_counter() - t_start, 6),
            "python": sys.version.split()[0],
            "platform": platform.platform(),
        }


def _label(stage: Any) -> str:
    """A stage instance's name in timings and results: ``fit`` or, for named repeats, ``fit:measured``."""
    return declared(stage, Stage, "label")


def _table(stage: Any) -> str:
    """The top-level table a stage owns: its ``table`` ClassVar if it has one, else its name."""
    return declared(stage, Stage, "table") or stage.name


def _jsonable(obj: Any) -> Any:
    """Best-effort conversion of stage results to JSON-compatible data."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if attrs.has(type(obj)):
        return _jsonable(attrs.asdict(obj, recurse=False))
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    return str(obj)


def run(
    config: str | Path | Mapping[str, Any],
    out: str | Path | None = None,
    *,
    resume: bool = False,
    overwrite: bool = False,
    quiet: bool = True,
    registry: Registry | None = None,
    no_cache: bool = False,
) -> PipelineResult:
    """Run a pipeline from a TOML path or a config dict; the Python twin of ``knitframe run``.

    Parameters
    ----------
    config : path or mapping
        TOML file, or an already-parsed dict (relative paths then resolve against the cwd).
    out : path, optional
        Output directory. None runs without keeping files. An existing folder that holds anything
        is refused unless ``resume`` (the same config's run) or ``overwrite`` (replaces only an
        earlier knitframe run's outputs) is given.
    no_cache : bool
        Compute every executor job afresh: cached results are neither read nor written.
    """
    if isinstance(config, Mapping):
        pipeline = Pipeline(config, base_dir=Path.cwd(), registry=registry)
    else:
        path = Path(config)
        pipeline = Pipeline(
            load_toml(path), base_dir=path.resolve().parent, source=str(path), registry=registry
        )
    return pipeline.run(out, resume=resume, overwrite=overwrite, quiet=quiet, no_cache=no_cache)
