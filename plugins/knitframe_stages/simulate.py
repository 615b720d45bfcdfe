"""Stage ``simulate``: run a unit-cell solver plugin on a fabric and a scene.

::

    [solver]
    kind = "rod"                 # solver plugin; the other keys are its options
    segments_per_stitch = 16

    [fabric]
    pattern = "jersey"
    stitch_length = 11
    yarn = "cotton"              # a yarn library name, or a table of Yarn fields

    [scene]
    effects = ["large_deformation", "bending", "contact", "prestress"]
    load = { kind = "equibiaxial", max_strain = 0.3, steps = 10 }

The scene's effects and load are checked against the solver before any work, the fabric's cell is
built once to refuse dimensions no stitch can have, and the solver's ``validate(fabric, scene,
registry)`` makes its own checks (plugins by name, yarn model) then too. Writes ``simulated.csv``,
``simulated.png`` and ``yarn.csv`` (what the solver read from the yarn record, each value marked
measured, estimate or derived, as ``knitframe yarn`` prints it), ``section.png`` when the solver
reports the yarn's section ratio (the volumetric solver: how far the yarn is squeezed across along
the path, against its compaction limit), and ``vtu/`` when the scene's
outputs include "vtu" and the solver ``writes_vtu``; a solver that declares ``checkpoints``
checkpoints every converged step, so ``knitframe run --resume`` continues a killed run.
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs

from knitframe import hookimpl
from knitframe.config import PluginSpec, instantiate
from knitframe.effects import require_effects
from knitframe.errors import ConfigError
from knitframe.geometry import checked_cell
from knitframe.interfaces import Stage
from knitframe.progress import ProgressBar
from knitframe.records import Fabric, Scene
from knitframe.report import compare, plot_comparison, plot_sections, write_responses_csv
from knitframe.schema import build
from knitframe.yarn import config_yarns, resolve_yarn


@attrs.frozen
class SolverTable:
    """Schema of the ``[solver]`` table: ``kind`` names the solver plugin; every other key is one of its
    options."""

    #: solver plugin name (see "Plugin options" → solver)
    kind: str = "rod"


@attrs.frozen
class SimulateStage(Stage):
    """Simulate a fabric's unit cell with a solver plugin and add the Response to the run."""

    name: ClassVar[str] = "simulate"
    table: ClassVar[str] = "solver"
    description: ClassVar[str] = "simulate the unit cell with a solver plugin ([solver] kind = ...)"
    order: ClassVar[int] = 20
    uses: ClassVar[tuple[str, ...]] = ("fabric", "scene", "yarns")
    schema: ClassVar[type] = SolverTable

    solver_name: str
    solver: Any
    fabric: Fabric
    #: the first (or only) scene
    scene: Scene
    #: every scene, one per load of ``scene.load = [...]``
    scenes: tuple[Scene, ...] = ()

    @classmethod
    def from_config(cls, config, ctx) -> SimulateStage:
        src = ctx.source
        spec = PluginSpec.parse(config["solver"], "solver")
        solver = instantiate(ctx.registry, "solver", config["solver"], "solver", source=src)
        if "fabric" not in config:
            raise ConfigError(
                "fabric", "required table is missing (pattern, stitch_length, yarn)", source=src
            )
        table = dict(config["fabric"])
        # an alias (stockinette) is recorded as the pattern it names (jersey)
        if isinstance(table.get("pattern"), str):
            table["pattern"] = ctx.registry["pattern"].canonical(table["pattern"])
        if "yarn" not in table:
            raise ConfigError("fabric.yarn", "required key is missing", source=src)
        try:
            own = config_yarns(ctx.registry, config.get("yarns", {}))
            value = table["yarn"]
            table["yarn"] = (
                own[value]
                if isinstance(value, str) and value in own
                else resolve_yarn(ctx.registry, value, "fabric.yarn")
            )
        except ConfigError as e:
            raise ConfigError(e.path, e.problem, source=src) from None
        fabric = build(Fabric, table, "fabric", source=src)
        try:
            # the pattern and its options, the stitch-length table, dimensions a stitch can have, and
            # whatever else the pattern refuses: the cell is built once here, cheaply, before any work
            checked_cell(fabric, ctx.registry)
        except ConfigError as e:
            raise ConfigError(e.path, e.problem, source=src) from None
        scenes = _scenes(config.get("scene", {}), src)
        for scene in scenes:
            require_effects(scene, solver, ctx.registry, name=spec.kind)
            try:  # the solver's own checks: plugins by name, yarn model ...
                solver.validate(fabric, scene, ctx.registry)
            except ConfigError as e:
                raise ConfigError(e.path, e.problem, source=src) from None
        return cls(spec.kind, solver, fabric, scenes[0], tuple(scenes))

    def run(self, ctx) -> None:
        ctx.used("solver", self.solver_name)
        ctx.used("stage", self.name)
        ctx.used("pattern", self.fabric.pattern)
        scenes = self.scenes or (self.scene,)
        responses = [self._simulate(ctx, scene, len(scenes) > 1) for scene in scenes]
        ctx.responses.extend(responses)
        write_responses_csv(ctx.output("simulated.csv"), responses)
        write_yarn_csv(ctx.output("yarn.csv"), self.fabric.yarn)
        measured = [r for r in ctx.responses if r.provenance.kind == "experiment"]
        ratios = compare(responses, measured)
        title = self.figure_title()
        plot_comparison(ctx.output("simulated.png"), responses, measured, title=title, ratios=ratios)
        if any(r.provenance.extra.get("section_ratio") for r in responses):
            plot_sections(ctx.output("section.png"), responses, title=f"{title}: squeezed across")
        headline = "; ".join(
            f"{r.label} {r.load}: {len(r)} steps, converged={r.provenance.converged}, "
            f"{r.provenance.wall_time or 0:.1f} s"
            for r in responses
        )
        if ratios:
            headline += "; simulated/measured tension " + ", ".join(
                f"{load} " + "/".join(f"{v:.2g}" for v in row.values()) + " at " + "/".join(row)
                for load, row in ratios.items()
            )
        first = responses[0]
        ctx.results[self.name] = {
            "solver": self.solver_name,
            "label": first.label,
            "load": first.load if len(responses) == 1 else [r.load for r in responses],
            "points": len(first) if len(responses) == 1 else [len(r) for r in responses],
            "converged": all(r.provenance.converged for r in responses),
            "wall_time_s": sum(r.provenance.wall_time or 0 for r in responses),
            "max_T1_N_per_mm": max(float(r.T1.max()) for r in responses),
            "max_T2_N_per_mm": max(float(r.T2.max()) for r in responses),
            "simulated_over_measured": ratios,
            "headline": headline,
        }

    def figure_title(self) -> str:
        """The figures' title, each thing once: ``rod solver: jersey, 11.28 mm per stitch, pearl-cotton
        yarn`` (a Response's label may start with the solver's name too)."""
        f = self.fabric
        size = f"SL{f.stitch_length:g}" if f.stitch_length is not None else f"{f.arc_length:g} mm per stitch"
        return f"{self.solver_name} solver: {f.pattern}, {size}, {f.yarn.name} yarn"

    def _simulate(self, ctx, scene: Scene, several: bool) -> Any:
        """One scene through the solver, with progress, checkpoints and VTU files where asked."""
        kwargs: dict[str, Any] = {}
        bar = None
        if not ctx.quiet:
            bar = ProgressBar(
                f"{self.solver_name} {self.fabric.pattern}"
                + (f" {scene.load.response_kind}" if several else "")
            )
            kwargs["progress"] = bar
        if self.solver.checkpoints:
            kwargs["checkpoint_dir"] = ctx.checkpoint_dir("simulate")  # keyed by fabric and scene
        vtu = "vtu" + (f"/{scene.load.response_kind}" if several else "")
        if "vtu" in scene.outputs and self.solver.writes_vtu:
            kwargs["output_dir"] = ctx.out / vtu
        try:
            response = self.solver.simulate(self.fabric, scene, **kwargs)
        finally:
            if bar is not None:
                bar.close()
        if "output_dir" in kwargs:
            ctx.outputs.extend(f"{vtu}/{p.name}" for p in sorted((ctx.out / vtu).glob("*")))
        return response


def write_yarn_csv(path, yarn) -> None:
    """The yarn record's quantities (``yarn_properties``) as CSV, with the record's source."""
    import csv

    from knitframe.yarn import yarn_properties

    with open(path, "w", newline="", encoding="utf-8") as fh:
        fh.write(f"# yarn: {yarn.name}\n")
        if yarn.source:
            fh.write(f"# source: {yarn.source}\n")
        w = csv.writer(fh)
        w.writerow(["quantity", "symbol", "value", "unit", "status", "how", "used_by"])
        for p in yarn_properties(yarn):
            w.writerow(
                [
                    p.name,
                    p.symbol,
                    "" if p.value is None else repr(p.value),
                    p.unit,
                    p.status,
                    p.how,
                    p.used_by,
                ]
            )


def _scenes(table: Any, source: str | None) -> list[Scene]:
    """One Scene per load: ``load`` may be a table or an array of tables (``[{...}, {...}]``)."""
    if not isinstance(table, dict) or not isinstance(table.get("load"), list):
        return [build(Scene, table, "scene", source=source)]
    loads = table["load"]
    if not loads:
        raise ConfigError("scene.load", "an array of loads needs at least one load table", source=source)
    scenes = []
    for i, load in enumerate(loads):
        try:
            scenes.append(build(Scene, {**table, "load": load}, "scene", source=source))
        except ConfigError as e:
            path = (
                e.path.replace("scene.load", f"scene.load[{i}]", 1)
                if e.path.startswith("scene.load")
                else e.path
            )
            raise ConfigError(path, e.problem, source=source) from None
    kinds = [s.load.response_kind for s in scenes]
    dup = next((k for k in kinds if kinds.count(k) > 1), None)
    if dup is not None:
        raise ConfigError(
            "scene.load", f"two loads of the same kind ({dup}); give each load once", source=source
        )
    return scenes


@hookimpl
def register_stages(register):
    register(SimulateStage)
