"""Stage ``[design]``: a compression sleeve from a limb and a fabric library.

::

    [design]
    limb = "example"                 # the built-in arm; or a scan ("arm.stl", .obj, .ply); or measurements:
    # limb = { positions_mm = [0, 100, 250, 420], circumferences_mm = [160, 250, 240, 310], ellipticity = 0.85 }
    library = "builtin"              # or a library.json (knitframe library build, a sweep)
    objective = { kind = "pressure_profile", target_mmHg = 30, ratios = [1.0, 0.6] }
    method = "optimal"               # or "paper" (the paper's per-element procedure, tube.mode = "paper")
    pressure = "equivalent"          # the Laplace radius the objective uses: C/2π, or "local" curvature
    min_courses = 10                 # each region at least this many courses
    # max_fabrics = 3                # at most this many distinct fabrics

    [design.tube]
    mode = "knitting"                # or "paper": a cylinder of wrist circumference mapped element for element
    # needles = 120                  # stitches per course (knitting; searched when not given)

Writes ``design.json``, ``knit-map.csv``, ``knit-map.png``, ``pressure.png`` and ``design.vtu``.
The same as ``knitframe design`` and :func:`knitframe.design`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar, Literal

import attrs

from knitframe import hookimpl, validators as v
from knitframe.config import PluginSpec, instantiate
from knitframe.errors import ConfigError, FieldError
from knitframe.schema import build


@attrs.frozen
class TubeTable:
    """Schema of ``[design.tube]``."""

    mode: Literal["paper", "knitting"] = "knitting"  #: "paper": wrist cylinder mapped element for element; "knitting": needles × courses
    circumference: float | None = attrs.field(default=None, validator=v.optional(v.positive))  #: paper mode: tube circumference, mm (default: the wrist's)
    length: float | None = attrs.field(default=None, validator=v.optional(v.positive))  #: paper mode: tube length, mm (default: the limb's)
    needles: int | None = attrs.field(default=None, validator=v.optional(v.in_range(4, 10000)))  #: knitting mode: stitches per course (default: searched)
    axial_stretch: float = attrs.field(default=1.0, validator=v.in_range(0.5, 2.0))  #: knitting mode: target wale stretch on the limb


@attrs.frozen
class DesignTable:
    """Schema of the ``[design]`` table."""

    limb: str | dict[str, Any] = "example"  #: "example", a scan file (STL, OBJ, PLY), or {positions_mm, circumferences_mm, ellipticity}
    library: str = "builtin"  #: "builtin" or a library.json file
    objective: str | dict[str, Any] = "pressure_profile"  #: objective plugin name, or a table with kind and options
    method: Literal["optimal", "paper"] = "optimal"  #: exact course bands, or the paper's per-element procedure
    pressure: Literal["equivalent", "local"] = "equivalent"  #: the radius the pressure objectives use
    min_courses: float = attrs.field(default=10.0, validator=v.in_range(0.0, 1e5))  #: least courses in each region
    max_fabrics: int | None = attrs.field(default=None, validator=v.optional(v.in_range(1, 1000)))  #: at most this many distinct fabrics
    base: str | None = None  #: the single fabric to compare with (default: the library's first cotton)
    stations: int = attrs.field(default=41, validator=v.in_range(3, 2000))  #: stations along the limb
    around: int = attrs.field(default=64, validator=v.in_range(8, 2000))  #: points around each section
    axis: list[float] | None = None  #: a scan's axis direction (default: its longest principal axis)
    tube: TubeTable = attrs.Factory(TubeTable)  #: how the tube is made

    def __attrs_post_init__(self) -> None:
        if self.axis is not None and len(self.axis) != 3:
            raise FieldError("axis", f"must be 3 numbers, got {len(self.axis)}")


def load_limb(value: Any, ctx: Any, table: DesignTable) -> Any:
    """The Limb a ``limb`` value names (errors name ``design.limb``)."""
    from knitframe.garment.limb import Limb, example_arm

    if value == "example":
        return example_arm(n_stations=table.stations, n_around=table.around)
    if isinstance(value, dict):
        allowed = {"positions_mm", "circumferences_mm", "ellipticity", "name"}
        extra = sorted(set(value) - allowed)
        if extra:
            raise ConfigError(f"design.limb.{extra[0]}", f"unknown key; expected one of {', '.join(sorted(allowed))}",
                              source=ctx.source)
        for key in ("positions_mm", "circumferences_mm"):
            if key not in value:
                raise ConfigError(f"design.limb.{key}", "required key is missing", source=ctx.source)
        try:
            return Limb.from_measurements(value["positions_mm"], value["circumferences_mm"],
                                          ellipticity=value.get("ellipticity", 1.0), n_stations=table.stations,
                                          n_around=table.around, name=value.get("name", "limb"))
        except (ValueError, TypeError, FieldError) as e:
            field = getattr(e, "field", "")
            raise ConfigError(f"design.limb{'.' + field if field else ''}", getattr(e, "problem", str(e)),
                              source=ctx.source) from None
    path = ctx.path(value, "design.limb")
    return Limb.from_scan(path, axis=table.axis, n_stations=table.stations, n_around=table.around)


def load_library(value: str, ctx: Any) -> Any:
    from knitframe.garment.library import FabricLibrary, builtin_library

    if value == "builtin":
        return builtin_library()
    return FabricLibrary.load(ctx.path(value, "design.library"))


@attrs.frozen
class DesignStage:
    """Design a sleeve for a limb from a fabric library."""

    name: ClassVar[str] = "design"
    description: ClassVar[str] = "design a compression sleeve: fabrics per region of a tube on a limb"
    order: ClassVar[int] = 70
    uses: ClassVar[tuple[str, ...]] = ()
    schema: ClassVar[type] = DesignTable

    options: DesignTable
    limb: Any
    library: Any
    objective: Any
    objective_name: str

    @classmethod
    def from_config(cls, config, ctx) -> "DesignStage":
        from knitframe.garment.tube import Tube

        table = build(DesignTable, config["design"], "design", source=ctx.source)
        objective = instantiate(ctx.registry, "design_objective", table.objective, "design.objective",
                                source=ctx.source)
        library = load_library(table.library, ctx)
        if table.base is not None and table.base not in library.names:
            raise ConfigError("design.base", f"no fabric '{table.base}' in library '{library.name}'; it has "
                              f"{', '.join(library.names)}", source=ctx.source)
        if table.method == "paper" and table.tube.mode != "paper":
            raise ConfigError("design.method", "the paper's per-element method needs design.tube.mode = 'paper'",
                              source=ctx.source)
        limb = load_limb(table.limb, ctx, table)
        Tube(**attrs.asdict(table.tube))
        return cls(table, limb, library, objective, PluginSpec.parse(table.objective, "design.objective").kind)

    def run(self, ctx) -> None:
        from knitframe.garment.core import design
        from knitframe.garment.outputs import write_design
        from knitframe.garment.tube import Tube

        ctx.used("stage", self.name)
        ctx.used("design_objective", self.objective_name)
        t = self.options
        d = design(self.limb, self.library, self.objective, tube=Tube(**attrs.asdict(t.tube)), method=t.method,
                   pressure=t.pressure, min_courses=t.min_courses, max_fabrics=t.max_fabrics, base=t.base)
        for name in write_design(d, ctx.out):
            ctx.outputs.append(name)
        ctx.objects[self.name] = d
        pe = d.standard_positions()
        ctx.results[self.name] = {
            "objective": self.objective_name, "value": d.value, "regions": len(d.regions()),
            "limits_respected": d.limits_respected, "stress_cv": d.stress_cv(),
            "baseline_stress_cv": d.baseline["stress_cv"], "guarantee": d.guarantee,
            "headline": (f"{len(d.regions())} regions, {self.objective_name} {d.value:.4g}; pressure "
                         f"{pe['distal']['pressure_equivalent_mmHg']:.1f} mmHg distal, "
                         f"{pe['top']['pressure_equivalent_mmHg']:.1f} mmHg top; stress CV "
                         f"{d.stress_cv():.3f} (one fabric: {d.baseline['stress_cv']:.3f}); "
                         f"limits {'respected' if d.limits_respected else 'EXCEEDED'}"),
        }


@hookimpl
def register_stages(register):
    register(DesignStage)
