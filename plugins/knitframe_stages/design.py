"""Stage ``[design]``: a compression sleeve from a limb and a fabric library.

::

    [design]
    limb = "example"                 # the built-in arm; or a scan ("arm.stl", .obj, .ply); or measurements:
    # limb = { positions_mm = [0, 100, 250, 420], circumferences_mm = [160, 250, 240, 310],
    #          ellipticity = 0.85 }
    library = "builtin"              # or a library.json (knitframe library build, a sweep)
    objective = { kind = "pressure_profile", target_mmHg = 30, ratios = [1.0, 0.6] }
    method = "optimal"               # or "paper" (the paper's per-element procedure, tube.mode = "paper")
    pressure = "equivalent"          # the Laplace radius the objective uses: C/2π, or "local" curvature
    min_courses = 10                 # each region at least this many courses
    # max_fabrics = 3                # at most this many distinct fabrics

    [design.tube]
    mode = "knitting"                # or "paper": a wrist-circumference cylinder mapped element for element
    # needles = 120                  # stitches per course (knitting; searched when not given)

    [design.machine]                 # optional: also knit it on a V-bed machine (docs/machine-output.md)
    machine = "SWG091N2"
    gauge = 15
    # width = 540                    # needles per bed the program may use
    # carriers = { acrylic = 3 }     # yarn -> carrier (default 1, 2, ... in the order the tube uses them)
    # stitch_numbers = { "11" = 5, default = 5 }   # stitch length -> x-stitch-number, over the defaults
    # dat = true                     # also sleeve.dat (Shima DAT) through knitout-to-dat-python

Writes ``design.json``, ``knit-map.csv``, ``knit-map.png``, ``pressure.png`` and ``design.vtu``;
with ``[design.machine]`` also ``sleeve.k`` (knitout, checked by knitout-interpreter),
``sleeve-chart.png`` and, with ``dat``, ``sleeve.dat``. The same as ``knitframe design`` (then
``knitframe knitout``) and :func:`knitframe.design`.
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import attrs

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.config import PluginSpec, instantiate
from knitframe.errors import ConfigError, FieldError
from knitframe.interfaces import Stage
from knitframe.schema import build


@attrs.frozen
class TubeTable:
    """Schema of ``[design.tube]``."""

    #: "paper": wrist cylinder mapped element for element; "knitting": needles × courses
    mode: Literal["paper", "knitting"] = "knitting"
    #: paper mode: tube circumference, mm (default: the wrist's)
    circumference: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: paper mode: tube length, mm (default: the limb's)
    length: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: knitting mode: stitches per course (default: searched)
    needles: int | None = attrs.field(default=None, validator=v.optional(v.in_range(4, 10000)))
    #: knitting mode: target wale stretch on the limb
    axial_stretch: float = attrs.field(default=1.0, validator=v.in_range(0.5, 2.0))
    #: knitting mode: shape the tube (the needle count follows the limb); false: one count throughout
    shaping: bool = True


@attrs.frozen
class MachineTable:
    """Schema of ``[design.machine]``: knit the sleeve on a V-bed machine (knitframe.garment.knitout)."""

    #: knitout ;;Machine: (the model knitout-interpreter simulates)
    machine: str = "SWG091N2"
    #: needles per inch of the machine; the tube is knitted at half gauge
    gauge: int = 15
    #: needles per bed the program may use (default: the machine's, 540)
    width: int | None = None
    #: yarn -> carrier number (default: the lowest free, in the order the tube uses the yarns)
    carriers: dict[str, int] = attrs.Factory(dict)
    #: stitch length ("11") or "default" -> x-stitch-number, over the built-in table
    stitch_numbers: dict[str, int] = attrs.Factory(dict)
    #: also write sleeve.dat (Shima DAT) through knitout-to-dat-python
    dat: bool = False
    #: run sleeve.k through knitout-interpreter before writing it (about 25 s for the example)
    check: bool = True
    #: write the machine program (false: only use the shaping rules below for the design)
    knitout: bool = True
    #: shaping: most stitches added or removed on one shaping course (both edges together)
    max_change: int = 2
    #: shaping: least courses from one shaping course to the next
    every: int = 2
    #: fewest stitches per course
    min_needles: int = 8
    #: most stitches per course (default: the bed width)
    max_needles: int | None = None

    def __attrs_post_init__(self) -> None:
        self.spec()  # every field checked; a FieldError names it
        self.rules()

    def rules(self) -> Any:
        """The :class:`~knitframe.garment.shaping.MachineRules` of this table."""
        from knitframe.garment.shaping import MachineRules

        top = self.max_needles if self.max_needles is not None else self.spec().bed_width
        return MachineRules(self.max_change, self.every, self.min_needles, top)

    def spec(self) -> Any:
        """The :class:`~knitframe.garment.knitout.MachineSpec` of this table."""
        from knitframe.garment.knitout import MachineSpec

        return MachineSpec(
            self.machine, self.gauge, self.width, dict(self.carriers), dict(self.stitch_numbers), self.dat
        )


@attrs.frozen
class DesignTable:
    """Schema of the ``[design]`` table."""

    #: "example", a scan file (STL, OBJ, PLY), or {positions_mm, circumferences_mm, ellipticity}
    limb: str | dict[str, Any] = "example"
    #: "builtin" or a library.json file
    library: str = "builtin"
    #: objective plugin name, or a table with kind and options
    objective: str | dict[str, Any] = "pressure_profile"
    #: exact course bands, or the paper's per-element procedure
    method: Literal["optimal", "paper"] = "optimal"
    #: the radius the pressure objectives use
    pressure: Literal["equivalent", "local"] = "equivalent"
    #: least courses in each region
    min_courses: float = attrs.field(default=10.0, validator=v.in_range(0.0, 1e5))
    #: at most this many distinct fabrics
    max_fabrics: int | None = attrs.field(default=None, validator=v.optional(v.in_range(1, 1000)))
    #: the single fabric to compare with (default: the library's first cotton)
    base: str | None = None
    #: stations along the limb
    stations: int = attrs.field(default=41, validator=v.in_range(3, 2000))
    #: points around each section
    around: int = attrs.field(default=64, validator=v.in_range(8, 2000))
    #: a scan's axis direction (default: its longest principal axis)
    axis: list[float] | None = None
    #: how the tube is made
    tube: TubeTable = attrs.Factory(TubeTable)
    #: knit it on a V-bed machine: sleeve.k, sleeve-chart.png (and sleeve.dat); its shaping rules
    machine: MachineTable | None = None
    #: no station's mean pressure may exceed this, mmHg
    ceiling_mmHg: float = attrs.field(default=60.0, validator=v.in_range(1.0, 300.0))
    #: relative change of the limb's circumference the pressure band is reported for (0.03 = ±3 %)
    limb_tolerance: float = attrs.field(default=0.03, validator=v.in_range(0.0, 0.49))
    #: design for the worst case over the limb ± limb_tolerance (and the other scans)
    robust: bool = False
    #: other scans of the same limb (relaxed, flexed, ...): designed for the worst case over all
    limbs: list[str] = attrs.Factory(list)
    #: relative error of the fabrics' relaxed course pitch the pressure band is reported for
    pitch_error: float = attrs.field(default=0.05, validator=v.in_range(0.0, 0.49))
    #: warn where a local pressure peak exceeds this multiple of its station's mean
    peak_ratio: float = attrs.field(default=2.0, validator=v.in_range(1.0, 100.0))
    #: knitter's gauge of library fabrics: name -> [stitches, courses] per 10 cm of a relaxed swatch
    gauge: dict[str, list[float]] = attrs.Factory(dict)

    def __attrs_post_init__(self) -> None:
        if self.axis is not None and len(self.axis) != 3:
            raise FieldError("axis", f"must be 3 numbers, got {len(self.axis)}")


def load_limb(value: Any, ctx: Any, table: DesignTable, field: str = "design.limb") -> Any:
    """The Limb a ``limb`` value names (errors name ``field``)."""
    from knitframe.garment.limb import Limb, example_arm

    if value == "example":
        return example_arm(n_stations=table.stations, n_around=table.around)
    if isinstance(value, dict):
        allowed = {"positions_mm", "circumferences_mm", "ellipticity", "name"}
        extra = sorted(set(value) - allowed)
        if extra:
            raise ConfigError(
                f"{field}.{extra[0]}",
                f"unknown key; expected one of {', '.join(sorted(allowed))}",
                source=ctx.source,
            )
        for key in ("positions_mm", "circumferences_mm"):
            if key not in value:
                raise ConfigError(f"{field}.{key}", "required key is missing", source=ctx.source)
        try:
            return Limb.from_measurements(
                value["positions_mm"],
                value["circumferences_mm"],
                ellipticity=value.get("ellipticity", 1.0),
                n_stations=table.stations,
                n_around=table.around,
                name=value.get("name", "limb"),
            )
        except (ValueError, TypeError, FieldError) as e:
            sub = getattr(e, "field", "")
            raise ConfigError(
                f"{field}{'.' + sub if sub else ''}", getattr(e, "problem", str(e)), source=ctx.source
            ) from None
    path = ctx.path(value, field)
    return Limb.from_scan(path, axis=table.axis, n_stations=table.stations, n_around=table.around)


def load_library(value: str, ctx: Any) -> Any:
    from knitframe.garment.library import FabricLibrary, builtin_library

    if value == "builtin":
        return builtin_library()
    return FabricLibrary.load(ctx.path(value, "design.library"))


@attrs.frozen
class DesignStage(Stage):
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
    others: tuple = ()

    @classmethod
    def from_config(cls, config, ctx) -> DesignStage:
        from knitframe.garment.tube import Tube

        table = build(DesignTable, config["design"], "design", source=ctx.source)
        objective = instantiate(
            ctx.registry, "design_objective", table.objective, "design.objective", source=ctx.source
        )
        library = load_library(table.library, ctx)
        if table.base is not None and table.base not in library.names:
            raise ConfigError(
                "design.base",
                f"no fabric '{table.base}' in library '{library.name}'; it has {', '.join(library.names)}",
                source=ctx.source,
            )
        if table.method == "paper" and table.tube.mode != "paper":
            raise ConfigError(
                "design.method",
                "the paper's per-element method needs design.tube.mode = 'paper'",
                source=ctx.source,
            )
        if table.gauge:
            library = library.with_gauges({k: tuple(g) for k, g in table.gauge.items()}, field="design.gauge")
        if table.machine is not None and table.machine.knitout:
            library = check_machine(table, library, ctx)
        limb = load_limb(table.limb, ctx, table)
        others = tuple(load_limb(x, ctx, table, f"design.limbs[{k}]") for k, x in enumerate(table.limbs))
        Tube(**attrs.asdict(table.tube))
        return cls(
            table,
            limb,
            library,
            objective,
            PluginSpec.parse(table.objective, "design.objective").kind,
            others,
        )

    def run(self, ctx) -> None:
        from knitframe.garment.core import design
        from knitframe.garment.outputs import write_design
        from knitframe.garment.tube import Tube

        ctx.used("stage", self.name)
        ctx.used("design_objective", self.objective_name)
        t = self.options
        d = design(
            self.limb,
            self.library,
            self.objective,
            tube=Tube(**attrs.asdict(t.tube)),
            method=t.method,
            pressure=t.pressure,
            min_courses=t.min_courses,
            max_fabrics=t.max_fabrics,
            base=t.base,
            rules=t.machine.rules() if t.machine is not None else None,
            ceiling=t.ceiling_mmHg,
            tolerance=t.limb_tolerance,
            robust=t.robust or bool(self.others),
            limbs=list(self.others),
            pitch_error=t.pitch_error,
            peak_ratio=t.peak_ratio,
        )
        for name in write_design(d, ctx.out):
            ctx.outputs.append(name)
        machine = self._machine_outputs(d, ctx) if t.machine is not None and t.machine.knitout else None
        ctx.objects[self.name] = d
        ctx.results[self.name] = {
            "objective": self.objective_name,
            "value": d.value,
            "regions": len(d.regions()),
            "limits_respected": d.limits_respected,
            "stress_cv": d.stress_cv(),
            "baseline_stress_cv": d.baseline["stress_cv"],
            "guarantee": d.guarantee,
            "headline": headline(d, self.objective_name),
        }
        if machine is not None:
            ctx.results[self.name]["machine"] = machine
            per = machine.get("needles_per_course") or [machine["needles"]]
            span = f"{min(per)}–{max(per)}" if min(per) != max(per) else f"{per[0]}"
            ctx.results[self.name]["headline"] += (
                f"; sleeve.k: {span} stitches × {machine['courses']} courses, "
                + (f"checked by {machine['check']['interpreter']}" if machine["check"] else "not checked")
            )

    def _machine_outputs(self, d: Any, ctx: Any) -> dict[str, Any]:
        """sleeve.k, sleeve-chart.png (and sleeve.dat) of the design, checked by knitout-interpreter."""
        from knitframe.garment.knitout import KnitMap, plan, program, write_machine_outputs

        m = self.options.machine
        try:
            kmap = KnitMap.from_design(d)
            spec = m.spec()  # carriers of library yarns this design does not use are not needed
            p = plan(
                kmap, attrs.evolve(spec, carriers={y: c for y, c in spec.carriers.items() if y in kmap.yarns})
            )
        except FieldError as e:
            where = {
                "tube": "design.tube.mode",
                "pattern": "design.machine",
                "tube.needles_per_course": "design.machine.max_change",
            }.get(e.field, f"design.machine.{e.field}")
            raise ConfigError(where, e.problem) from None
        lines, report = program(p, check=m.check)
        names, info = write_machine_outputs(p, lines, ctx.out, dat=m.dat)
        ctx.outputs.extend(names)
        return {**info, "check": report}


def headline(d: Any, objective_name: str) -> str:
    """One line on a design: regions and needles, the pressures, the prescription, the limits."""
    pe = d.standard_positions()
    tube = ""
    if d.row_needles is not None:
        lo, hi = int(d.row_needles.min()), int(d.row_needles.max())
        tube = f" on {lo}–{hi} stitches per course" if lo != hi else f" on {lo} stitches per course"
    n = len(d.regions())
    text = (
        f"{n} region{'s' if n != 1 else ''}{tube}, {objective_name} {d.value:.4g}; pressure "
        f"{pe['distal']['pressure_equivalent_mmHg']:.1f} mmHg distal, "
        f"{pe['top']['pressure_equivalent_mmHg']:.1f} mmHg top"
    )
    rx = d.prescription()
    if rx is not None:
        a = rx["all"]
        text += (
            f"; prescription: {a['stations_inside']} of {a['stations']} stations within "
            f"±{100 * rx['tolerance']:.0f} % (RMS {100 * a['rms_error']:.1f} %), "
            + {True: "falls steadily", False: "does NOT fall steadily", None: "flat target"}[
                rx["falls_steadily"]
            ]
        )
    else:
        text += f"; stress CV {d.stress_cv():.3f} (one fabric: {d.baseline['stress_cv']:.3f})"
    return text + f"; limits {'respected' if d.limits_respected else 'EXCEEDED'}"


def check_machine(table: DesignTable, library: Any, ctx: Any) -> Any:
    """Every check of ``[design.machine]`` the config allows, before any work; returns the library to design
    from: without the fabrics whose pattern the machine output cannot knit (with a warning naming them)."""
    import warnings

    from knitframe.errors import KnitframeWarning
    from knitframe.garment.knitout import PAPER_MODE, PATTERNS, missing

    m = table.machine
    if table.tube.mode != "knitting":
        raise ConfigError("design.tube.mode", PAPER_MODE, source=ctx.source)
    for key, problem in (("check", missing(check=m.check)), ("dat", missing(check=False, dat=m.dat))):
        if problem:
            raise ConfigError(f"design.machine.{key}", problem, source=ctx.source)
    spec = m.spec()
    if table.tube.needles is not None and table.tube.needles > spec.bed_width:
        raise ConfigError(
            "design.machine.width",
            f"the tube needs {table.tube.needles} needles per bed (half gauge: "
            f"one per stitch of the course, design.tube.needles) but the machine width is "
            f"{spec.bed_width}",
            source=ctx.source,
        )
    kept = [e for e in library.entries if e.pattern in PATTERNS]
    if not kept:
        raise ConfigError(
            "design.library",
            f"no fabric of library '{library.name}' can be knitted by the machine "
            f"output (patterns {', '.join(PATTERNS)})",
            source=ctx.source,
        )
    left_out = [e.name for e in library.entries if e.pattern not in PATTERNS]
    if left_out:
        if table.base in left_out:
            raise ConfigError(
                "design.base",
                f"fabric '{table.base}' cannot be knitted by the machine output (its "
                f"pattern is not one of {', '.join(PATTERNS)})",
                source=ctx.source,
            )
        warnings.warn(
            f"design.machine: fabrics {', '.join(left_out)} are left out of the library: the machine "
            f"output knits only {', '.join(PATTERNS)}",
            KnitframeWarning,
            stacklevel=2,
        )
        library = attrs.evolve(library, entries=kept)
    yarns = list(dict.fromkeys(e.yarn for e in kept))
    for yarn in spec.carriers:
        if yarn not in yarns:
            raise ConfigError(
                f"design.machine.carriers.{yarn}",
                f"library '{library.name}' has no yarn '{yarn}'; it has {', '.join(yarns)}",
                source=ctx.source,
            )
    for e in kept:
        try:
            spec.stitch_number(e.stitch_length, e.name)
        except FieldError as err:
            raise ConfigError(f"design.machine.{err.field}", err.problem, source=ctx.source) from None
    return library


@hookimpl
def register_stages(register):
    register(DesignStage)
