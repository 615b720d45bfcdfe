"""Stage ``[patchwork]``: combine fabric regions in parallel, in series or in a grid.

::

    [patchwork]
    mode = "series"            # series | parallel | grid
    direction = "course"       # load direction for model regions
    lateral = "free"           # model regions: free (P = 0) or fixed (λ = 1) lateral side
    max_strain = 0.4
    steps = 40

    [[patchwork.regions]]
    name = "jersey"
    source = "fit"             # last fitted model; "fit:0" the first; "response:<label>"; "file:params.json"
    length = 30.0              # mm along the load (series, grid)
    width = 20.0               # mm across the load (parallel)

    # grid only: rows across the load (row_widths), region names along the load
    # layout = [["jersey", "rib"], ["rib", "jersey"]]
    # row_widths = [10.0, 10.0]

Writes ``patchwork.csv`` and ``patchwork.png``, and adds the patchwork's Response to the run.

With ``lateral = "free"`` (the default) every model region must predict its free side, as
``hgo2m`` does. The paper's ``hgo`` (also the ``[fit]`` default) cannot: P_free = 0 forces
I4 = 1, so it carries no tension up to λ = 1/cos θ and then collapses laterally. Such a config is
refused in one line before any work; fit ``hgo2m`` or set ``lateral = "fixed"``.
"""

from __future__ import annotations

import csv
import json
from typing import ClassVar, Literal

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.config import PluginSpec
from knitframe.errors import ConfigError, FieldError, KnitframeError
from knitframe.fitting import FitResult
from knitframe.interfaces import Stage
from knitframe.patchwork import grid
from knitframe.records import Response
from knitframe.report import plot_responses
from knitframe.schema import build


@attrs.frozen
class Region:
    """One region of the patchwork."""

    name: str
    #: "fit", "fit:<i>", "response:<label>" or "file:<params.json>"
    source: str
    #: along the load, mm
    length: float = attrs.field(default=1.0, validator=v.positive)
    #: across the load, mm
    width: float = attrs.field(default=1.0, validator=v.positive)

    def __attrs_post_init__(self) -> None:
        kind = self.source.split(":", 1)[0]
        if kind not in ("fit", "response", "file"):
            raise FieldError(
                "source",
                f"must be 'fit', 'fit:<index>', 'response:<label>' or 'file:<params.json>', "
                f"got {self.source!r}",
            )
        if kind == "fit" and ":" in self.source and not self.source.split(":", 1)[1].lstrip("-").isdigit():
            raise FieldError("source", f"'fit:<index>' needs an integer index, got {self.source!r}")


@attrs.frozen
class PatchworkTable:
    """Schema of the ``[patchwork]`` table."""

    #: tables with name, source ("fit", "fit:<i>", "response:<label>", "file:<params.json>"), length and width
    #: in mm
    regions: list[Region]
    #: how the regions are combined
    mode: Literal["series", "parallel", "grid"] = "series"
    #: load direction for model regions
    direction: Literal["course", "wale"] = "course"
    #: model regions: free side (P = 0) or fixed (λ = 1)
    lateral: Literal["free", "fixed"] = "free"
    #: engineering strain of the whole patchwork, -
    max_strain: float = attrs.field(default=0.3, validator=v.strain_limit)
    #: load steps
    steps: int = attrs.field(default=30, validator=v.in_range(1, 100000))
    #: grid: region names, rows across the load
    layout: list[list[str]] = attrs.Factory(list)
    #: grid: width of each row, mm
    row_widths: list[float] = attrs.Factory(list)

    def __attrs_post_init__(self) -> None:
        if not self.regions:
            raise FieldError("regions", "must list at least one region")
        names = [r.name for r in self.regions]
        if len(set(names)) != len(names):
            raise FieldError("regions", f"region names must be unique, got {names}")
        if self.mode == "grid":
            if not self.layout:
                raise FieldError("layout", "grid mode needs a layout (rows of region names)")
            for i, row in enumerate(self.layout):
                for name in row:
                    if name not in names:
                        raise FieldError(
                            f"layout[{i}]", f"unknown region {name!r}; regions are {', '.join(names)}"
                        )
            if len(self.row_widths) != len(self.layout) or any(w <= 0 for w in self.row_widths):
                raise FieldError("row_widths", f"needs {len(self.layout)} widths > 0, one per layout row")


@attrs.frozen
class PatchworkStage(Stage):
    """Series, parallel and grid combinations of fitted models and Responses."""

    name: ClassVar[str] = "patchwork"
    description: ClassVar[str] = "combine regions (fitted models or Responses) in series, parallel or a grid"
    order: ClassVar[int] = 60
    uses: ClassVar[tuple[str, ...]] = ()
    schema: ClassVar[type] = PatchworkTable

    spec: PatchworkTable
    #: regions read from params.json files, by region name
    files: dict[str, FitResult]
    source: str | None = None

    @classmethod
    def from_config(cls, config, ctx) -> PatchworkStage:
        table = build(PatchworkTable, config["patchwork"], "patchwork", source=ctx.source)
        files = {}
        for i, r in enumerate(table.regions):
            key = f"patchwork.regions[{i}].source"
            if r.source.startswith("file:"):
                path = ctx.path(r.source[5:], key)
                try:
                    data = json.loads(path.read_text())
                except (OSError, json.JSONDecodeError) as e:
                    raise ConfigError(key, f"cannot read {path.name}: {e}", source=ctx.source) from None
                files[r.name] = FitResult.from_json(data, ctx.registry, key)
            elif r.source.startswith("fit") and "fit" not in ctx.tables:
                raise ConfigError(
                    key, "refers to a fitted model but the config has no [fit] table", source=ctx.source
                )
        if table.lateral == "free":
            _check_free_side(table, files, config, ctx)
        return cls(table, files, ctx.source)

    def _resolve(self, region: Region, ctx, i: int):
        key = f"patchwork.regions[{i}].source"
        kind, _, arg = region.source.partition(":")
        if kind == "file":
            return self.files[region.name]
        if kind == "fit":
            idx = int(arg) if arg else -1
            if not -len(ctx.models) <= idx < len(ctx.models):
                raise ConfigError(
                    key, f"no fitted model {idx}; the run has {len(ctx.models)}", source=self.source
                )
            return ctx.models[idx]
        for r in ctx.responses:
            if r.label == arg:
                return r
        have = ", ".join(r.label for r in ctx.responses) or "none"
        raise ConfigError(key, f"no Response labelled {arg!r}; have {have}", source=self.source)

    def run(self, ctx) -> None:
        ctx.used("stage", self.name)
        t = self.spec
        by_name = {r.name: (i, r) for i, r in enumerate(t.regions)}
        src = {r.name: self._resolve(r, ctx, i) for i, r in enumerate(t.regions)}
        if t.mode == "grid":
            names = t.layout
            widths = t.row_widths
        elif t.mode == "series":
            names = [[r.name for r in t.regions]]
            widths = [max(r.width for r in t.regions)]
        else:
            names = [[r.name] for r in t.regions]
            widths = [r.width for r in t.regions]
        lengths = [[by_name[n][1].length for n in row] for row in names]
        if t.mode == "parallel":
            lengths = [[1.0] for _ in names]
        strain = np.linspace(0.0, t.max_strain, t.steps + 1)
        try:
            res = grid(
                [[src[n] for n in row] for row in names],
                widths,
                lengths,
                strain,
                direction=t.direction,
                lateral=t.lateral,
                mode=t.mode,
            )
        except ValueError as e:
            raise ConfigError("patchwork", str(e), source=self.source) from None
        response = res.to_response(t.direction, label=f"patchwork ({t.mode})")
        ctx.responses.append(response)
        self._write_csv(ctx.output("patchwork.csv"), res, names)
        curves = [r for r in src.values() if isinstance(r, Response)]
        plot_responses(ctx.output("patchwork.png"), [*curves, response], title=f"patchwork ({t.mode})")
        ctx.results[self.name] = {
            "mode": t.mode,
            "regions": [r.name for r in t.regions],
            "max_tension_N_per_mm": float(res.tension.max()),
            "max_force_N": float(res.force.max()),
            "headline": f"{t.mode} patchwork of {len(t.regions)} regions: {res.tension.max():.4g} N/mm at "
            f"{100 * t.max_strain:.0f} % strain",
        }

    @staticmethod
    def _write_csv(path, res, names) -> None:
        cols = ["strain", "tension_N_per_mm", "force_N"]
        cols += [f"row{i}_tension_N_per_mm" for i in range(len(names))]
        cols += [f"row{i}_{n}_stretch" for i, row in enumerate(names) for n in row]
        cols += [
            f"row{i}_interface{j}_displacement_mm" for i, row in enumerate(names) for j in range(len(row) - 1)
        ]
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(cols)
            for k in range(len(res.strain)):
                vals = [res.strain[k], res.tension[k], res.force[k], *res.row_tension[k]]
                vals += [res.stretch[k, i, j] for i, row in enumerate(names) for j in range(len(row))]
                vals += [
                    res.interface_displacement[k, i, j]
                    for i, row in enumerate(names)
                    for j in range(len(row) - 1)
                ]
                w.writerow([f"{x:.10g}" for x in vals])


def _fit_models(config) -> list[tuple[str, bool]]:
    """``(model kind, is the default)`` of each [fit] table, in run order."""
    from knitframe_stages.fit import FitTable

    fits = config.get("fit", [])
    out = []
    for f in fits if isinstance(fits, list) else [fits]:
        spec = f.get("model") if isinstance(f, dict) else None
        if spec is None:
            out.append((str(attrs.fields(FitTable).model.default), True))
        else:
            out.append((PluginSpec.parse(spec, "fit.model").kind, False))
    return out


def _check_free_side(table: PatchworkTable, files: dict[str, FitResult], config, ctx) -> None:
    """A model region with a free side needs a model that predicts it; name the first that does not."""
    fits = _fit_models(config)
    for r in table.regions:
        kind, _, arg = r.source.partition(":")
        if kind == "file":
            name, default, model = files[r.name].model.name, False, files[r.name].model
        elif kind == "fit" and fits:
            idx = int(arg) if arg else -1
            if not -len(fits) <= idx < len(fits):
                continue  # reported when the stage runs, with the number of fits made
            name, default = fits[idx]
            try:
                model = ctx.registry["homogenizer"][name]
            except KnitframeError:
                continue  # the [fit] stage names an unknown model itself
        else:
            continue
        if not model.predicts_lateral:
            origin = " (the [fit] default)" if default else ""
            raise ConfigError(
                "patchwork.lateral",
                f"'free' needs models that predict their free side, but region "
                f"'{r.name}' uses '{name}'{origin}: with a free side P_free = 0 forces I4 = 1, so it "
                "carries no tension up to stretch 1/cos(theta) and then collapses; fit 'hgo2m' or set "
                'lateral = "fixed"',
                source=ctx.source,
            )


@hookimpl
def register_stages(register):
    register(PatchworkStage)
