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
built once to refuse dimensions no stitch can have, and a solver with a ``validate(fabric, scene,
registry)`` method makes its own checks (plugins by name, yarn model) then too. Writes
``simulated.csv`` and ``simulated.png`` (and ``vtu/`` when the scene's outputs include "vtu");
every converged step is checkpointed so ``knitframe run --resume`` continues a killed run.
"""

from __future__ import annotations

import inspect
from typing import Any, ClassVar

import attrs

from knitframe import hookimpl
from knitframe.geometry import checked_cell
from knitframe.yarns import config_yarns, resolve_yarn
from knitframe.config import PluginSpec, instantiate
from knitframe.effects import require_effects
from knitframe.errors import ConfigError
from knitframe.progress import ProgressBar
from knitframe.records import Fabric, Scene
from knitframe.report import plot_responses, write_responses_csv
from knitframe.schema import build


@attrs.frozen
class SolverTable:
    """Schema of the ``[solver]`` table: ``kind`` names the solver plugin; every other key is one of its options."""

    kind: str = "rod"  #: solver plugin name (see "Plugin options" → solver)


def _accepts(fn, name: str) -> bool:
    try:
        return name in inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False


@attrs.frozen
class SimulateStage:
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
    scene: Scene

    @classmethod
    def from_config(cls, config, ctx) -> "SimulateStage":
        src = ctx.source
        spec = PluginSpec.parse(config["solver"], "solver")
        solver = instantiate(ctx.registry, "solver", config["solver"], "solver", source=src)
        if "fabric" not in config:
            raise ConfigError("fabric", "required table is missing (pattern, stitch_length, yarn)", source=src)
        table = dict(config["fabric"])
        if "yarn" not in table:
            raise ConfigError("fabric.yarn", "required key is missing", source=src)
        try:
            own = config_yarns(ctx.registry, config.get("yarns", {}))
            value = table["yarn"]
            table["yarn"] = own[value] if isinstance(value, str) and value in own else resolve_yarn(
                ctx.registry, value, "fabric.yarn")
        except ConfigError as e:
            raise ConfigError(e.path, e.problem, source=src) from None
        fabric = build(Fabric, table, "fabric", source=src)
        try:
            # the pattern and its options, the stitch-length table, dimensions a stitch can have, and
            # whatever else the pattern refuses: the cell is built once here, cheaply, before any work
            checked_cell(fabric, ctx.registry)
        except ConfigError as e:
            raise ConfigError(e.path, e.problem, source=src) from None
        scene = build(Scene, config.get("scene", {}), "scene", source=src)
        require_effects(scene, solver, ctx.registry, name=spec.kind)
        validate = getattr(solver, "validate", None)
        if validate is not None:
            try:
                validate(fabric, scene, ctx.registry)  # the solver's own checks: plugins by name, yarn model ...
            except ConfigError as e:
                raise ConfigError(e.path, e.problem, source=src) from None
        return cls(spec.kind, solver, fabric, scene)

    def run(self, ctx) -> None:
        ctx.used("solver", self.solver_name)
        ctx.used("stage", self.name)
        ctx.used("pattern", self.fabric.pattern)
        kwargs: dict[str, Any] = {}
        bar = None
        if not ctx.quiet:
            bar = ProgressBar(f"{self.solver_name} {self.fabric.pattern}")
            kwargs["progress"] = bar
        if _accepts(self.solver.simulate, "checkpoint_dir"):
            kwargs["checkpoint_dir"] = ctx.checkpoint_dir("simulate")
        if "vtu" in self.scene.outputs and _accepts(self.solver.simulate, "output_dir"):
            kwargs["output_dir"] = ctx.out / "vtu"
        try:
            response = self.solver.simulate(self.fabric, self.scene, **kwargs)
        finally:
            if bar is not None:
                bar.close()
        if "output_dir" in kwargs:
            ctx.outputs.extend(f"vtu/{p.name}" for p in sorted((ctx.out / "vtu").glob("*")))
        ctx.responses.append(response)
        write_responses_csv(ctx.output("simulated.csv"), [response])
        plot_responses(ctx.output("simulated.png"), [response], title=f"{self.solver_name}: {response.label}")
        prov = response.provenance
        ctx.results[self.name] = {
            "solver": self.solver_name,
            "label": response.label,
            "load": response.load,
            "points": len(response),
            "converged": prov.converged,
            "wall_time_s": prov.wall_time,
            "max_T1_N_per_mm": float(response.T1.max()),
            "max_T2_N_per_mm": float(response.T2.max()),
            "headline": f"{response.label}: {len(response)} steps, converged={prov.converged}, "
                        f"{prov.wall_time or 0:.1f} s",
        }


@hookimpl
def register_stages(register):
    register(SimulateStage)
