"""Stage ``[fit]``: fit a reduced model to the run's Responses.

::

    [fit]
    model = "hgo"                     # or { kind = "hgo2m", compression_fibre = false }
    fitter = "lbfgs"                  # or { kind = "mads", max_evals = 2000 }
    labels = []                       # Response labels to fit; empty: all of them
    kinds = []                        # provenance kinds to fit ("experiment", "simulation"); empty: all
    export = ["abaqus", "calculix"]   # material cards of the fitted model (also "calculix-deck", "febio")
    export_thickness = 1.0            # mm: reference thickness t0 of the solid the cards describe

Several fits in one run: give ``[[fit]]`` tables with distinct ``name`` keys; each writes
``<name>-params.json`` and ``<name>-fit.png``.

Writes ``params.json`` (every parameter, θ as ``theta_deg``, NRMSE per direction and overall,
wall time, evaluations) and ``fit.png`` (data ±1 sd against the fit), and appends the fitted
model (a :class:`~knitframe.fitting.FitResult`) to ``ctx.models``. Each format in ``export``
adds ``<prefix>params.<suffix>`` next to params.json (``params.abaqus.inp``,
``params.calculix.inp``, ``params.calculix-check.inp``, ``params.febio.xml``), made by
:func:`knitframe.export.export_card` from the params.json data exactly as ``knitframe export``
makes it; a model that cannot be written in a listed format is refused before any work.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import attrs

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.config import PluginSpec, instantiate
from knitframe.errors import ConfigError
from knitframe.export import FORMATS, card_refusal, export_card
from knitframe.fitting import write_fit_outputs
from knitframe.interfaces import Stage
from knitframe.schema import build


@attrs.frozen
class FitTable:
    """Schema of the ``[fit]`` table."""

    #: homogenizer name, or a table with ``kind`` and options
    model: str | dict[str, Any] = "hgo"
    #: fitter name, or a table with ``kind`` and options
    fitter: str | dict[str, Any] = "lbfgs"
    #: fit only these Responses (by label); empty: all
    labels: list[str] = attrs.Factory(list)
    #: fit only Responses of these provenance kinds; empty: all
    kinds: list[Literal["experiment", "simulation", "model"]] = attrs.Factory(list)
    #: name of this fit when several [[fit]] tables are given; prefixes its output files
    name: str = ""
    #: material cards of the fitted model to write next to params.json (docs/export.md)
    export: list[Literal["abaqus", "calculix", "calculix-deck", "febio"]] = attrs.Factory(list)
    #: reference thickness t0 (mm) of the solid the export cards describe: k1 = 2a/t0
    export_thickness: float = attrs.field(default=1.0, validator=v.positive)


@attrs.frozen
class FitStage(Stage):
    """Fit a reduced model to every (or the selected) Response of the run."""

    name: ClassVar[str] = "fit"
    description: ClassVar[str] = "fit a reduced model (homogenizer) to the run's Responses"
    order: ClassVar[int] = 50
    uses: ClassVar[tuple[str, ...]] = ()
    schema: ClassVar[type] = FitTable
    repeatable: ClassVar[bool] = True

    model: Any
    fitter: Any
    model_name: str
    fitter_name: str
    labels: tuple[str, ...]
    source: str | None = None
    kinds: tuple[str, ...] = ()
    fit_name: str = ""
    export: tuple[str, ...] = ()
    export_thickness: float = 1.0

    @property
    def label(self) -> str:
        """``fit``, or ``fit:<name>`` for a named fit."""
        return f"fit:{self.fit_name}" if self.fit_name else "fit"

    @classmethod
    def from_config(cls, config, ctx) -> FitStage:
        table = build(FitTable, config["fit"], "fit", source=ctx.source)
        model = instantiate(ctx.registry, "homogenizer", table.model, "fit.model", source=ctx.source)
        fitter = instantiate(ctx.registry, "fitter", table.fitter, "fit.fitter", source=ctx.source)
        if not (ctx.tables - {"fit", "patchwork", "pipeline"}):
            raise ConfigError(
                "fit",
                "nothing to fit: add a [data] table (or a stage that makes Responses)",
                source=ctx.source,
            )
        for i, fmt in enumerate(table.export):
            if fmt in table.export[:i]:
                raise ConfigError(f"fit.export[{i}]", f"{fmt!r} is listed twice", source=ctx.source)
            why = card_refusal(model, fmt)
            if why:
                raise ConfigError(f"fit.export[{i}]", why, source=ctx.source)
        return cls(
            model,
            fitter,
            PluginSpec.parse(table.model, "fit.model").kind,
            PluginSpec.parse(table.fitter, "fit.fitter").kind,
            tuple(table.labels),
            ctx.source,
            tuple(table.kinds),
            table.name,
            tuple(table.export),
            table.export_thickness,
        )

    def run(self, ctx) -> None:
        ctx.used("stage", self.name)
        ctx.used("homogenizer", self.model_name)
        ctx.used("fitter", self.fitter_name)
        responses = [
            r
            for r in ctx.responses
            if (not self.labels or r.label in self.labels)
            and (not self.kinds or r.provenance.kind in self.kinds)
        ]
        missing = sorted(set(self.labels) - {r.label for r in ctx.responses})
        if missing:
            raise ConfigError(
                "fit.labels",
                f"no Response labelled {missing[0]!r}; have "
                f"{', '.join(r.label for r in ctx.responses) or 'none'}",
                source=self.source,
            )
        if not responses:
            raise ConfigError(
                "fit", "no Responses to fit: an earlier stage must produce some", source=self.source
            )
        result = self.fitter.fit(self.model, responses)
        prefix = f"{self.fit_name}-" if self.fit_name else ""
        write_fit_outputs(
            result, responses, ctx.output(f"{prefix}params.json"), ctx.output(f"{prefix}fit.png")
        )
        data = result.to_json()
        cards = []
        for fmt in self.export:  # the same text as `knitframe export <prefix>params.json --format fmt`
            text = export_card(
                data,
                fmt,
                path=f"{prefix}params.json",
                registry=ctx.registry,
                options={"thickness": "fit.export_thickness", "format": "fit.export"},
                thickness=self.export_thickness,
            )
            name = f"{prefix}params.{FORMATS[fmt]}"
            ctx.output(name).write_text(text, encoding="utf-8")
            cards.append(name)
        ctx.models.append(result)
        ctx.results[self.label] = {
            **data,
            "headline": result.headline(),
            **({"cards": cards} if cards else {}),
        }


@hookimpl
def register_stages(register):
    register(FitStage)
