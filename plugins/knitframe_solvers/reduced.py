"""Solver ``reduced``: a fitted reduced model (homogenizer) under a Scene's load path.

The cheapest rung of the accuracy ladder: no geometry, no mesh, microseconds per point. The
fabric is already encoded in the model's parameters, so ``simulate`` ignores the Fabric.

::

    [solver]
    kind = "reduced"
    model = "hgo2m"                      # or { kind = "hgo", compression_fibre = false }
    params_file = "fit-out/params.json"   # written by the [fit] stage / `knitframe fit`
    # or: params = { a = 0.26, b = 15.9, theta_deg = 53.7 }

Load paths: ``equibiaxial`` and ``general`` impose both stretches; ``uniaxial`` solves the free
side from P_free = 0 (:func:`knitframe.fitting.solve_free_side`). The paper's ``hgo`` has no
lateral stiffness, so under free sides it carries no tension until the loaded stretch passes
1/cos θ (course) or 1/sin θ (wale), after which the free side collapses; the Response notes it.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any, ClassVar

import attrs
import numpy as np

from knitframe import get_registry, hookimpl
from knitframe.effects import require_effects
from knitframe.errors import ConfigError, FieldError, NumericalError
from knitframe.fitting import FREE_MIN, FitResult, params_from_json, params_to_json, within_model_bounds
from knitframe.records import Provenance, Response


@attrs.frozen
class ReducedSolver:
    """Evaluate a parameterised reduced model along the scene's load path (Response kind "model")."""

    name: ClassVar[str] = "reduced"
    description: ClassVar[str] = (
        "fitted reduced model (hgo, hgo2m, ...) along the load path; no geometry, instant"
    )
    effects: ClassVar[frozenset[str]] = frozenset({"large_deformation", "anisotropy"})
    loads: ClassVar[frozenset[str]] = frozenset(
        {"equibiaxial", "uniaxial-course", "uniaxial-wale", "general"}
    )
    #: cheap enough for the conformance kit to simulate with default options
    conformance_simulate: ClassVar[bool] = True
    #: one evaluation: nothing to checkpoint, no VTU files
    checkpoints: ClassVar[bool] = False
    writes_vtu: ClassVar[bool] = False

    #: homogenizer name, or a table with ``kind`` and its options
    model: str | dict[str, Any] = "hgo"
    #: parameters by name, angles as ``<name>_deg``; empty: the model's defaults
    params: dict[str, float] = attrs.Factory(dict)
    #: params.json of a fit (relative to the working directory); overrides ``model``/``params``
    params_file: str | None = None

    def __attrs_post_init__(self) -> None:
        self.resolved("")  # fail at configuration time, not in the middle of a run (paths below [solver])

    @classmethod
    def from_fit(cls, result: FitResult) -> ReducedSolver:
        """The solver for a fitted model."""
        options = attrs.asdict(result.model) if attrs.has(type(result.model)) else {}
        return cls({"kind": result.model.name, **options}, params_to_json(result.param_names, result.params))

    def resolved(self, table: str = "solver") -> tuple[Any, np.ndarray]:
        """The homogenizer instance and its parameter array (radians), inside the model's own bounds.

        ConfigErrors name the key below ``table``, the config table of the solver ("" for paths
        relative to it, as the schema wants while it builds the solver).
        """
        from knitframe.config import instantiate

        def at(key: str) -> str:
            return f"{table}.{key}" if table else key

        if self.params_file is not None:
            p = Path(self.params_file)
            try:
                data = json.loads(p.read_text(encoding="utf-8"))
            except (OSError, ValueError, RecursionError) as e:
                raise ConfigError(at("params_file"), f"cannot read {p}: {e}") from None
            if not isinstance(data, dict) or not isinstance(data.get("options", {}), dict):
                raise ConfigError(
                    at("params_file"),
                    f"{p} is not a params.json of a fit (a table with 'model' and the parameters)",
                )
            fit = FitResult.from_json(data, path=at("params_file"))
            model, params, where = fit.model, fit.params, at("params_file")
        else:
            model = instantiate(get_registry(), "homogenizer", self.model, at("model"))
            where = at("params")
            params = (
                params_from_json(model.param_names, self.params, where)
                if self.params
                else np.asarray(model.x0(), dtype=np.float64)
            )
        try:
            within_model_bounds(model, params)
        except FieldError as e:
            raise ConfigError(f"{where}.{e.field}", e.problem) from None
        return model, params

    def validate(self, fabric: Any, scene, registry=None) -> None:
        """Nothing to check for a fabric and scene: the model has no geometry, contact law or yarn law."""

    def simulate(self, fabric: Any, scene, *, progress=None) -> Response:
        t0 = time.perf_counter()
        require_effects(scene, self, get_registry())
        model, params = self.resolved()
        load = scene.load
        _, lam1, lam2 = load.stretches()
        notes = ""
        if load.kind == "uniaxial":
            lam = lam1 if load.direction == "course" else lam2
            lf, P = model.solve_uniaxial(params, lam, load.direction)
            zero = np.zeros_like(P)
            if np.any(lf <= FREE_MIN):
                notes = (
                    f"free side collapsed (no lateral stiffness) beyond loaded stretch "
                    f"{lam[np.argmax(lf <= FREE_MIN)]:.4g}"
                )
            if load.direction == "course":
                lam1, lam2, P1, P2, kind = lam, lf, P, zero, "uniaxial-course"
            else:
                lam1, lam2, P1, P2, kind = lf, lam, zero, P, "uniaxial-wale"
        else:
            P1, P2 = model.stress(params, lam1, lam2)
            kind = load.kind
        if not (np.all(np.isfinite(P1)) and np.all(np.isfinite(P2))):
            raise NumericalError(
                f"reduced model '{model.name}' gave non-finite tension with params {params.tolist()}"
            )
        if progress is not None:
            progress(1.0, 1.0, "reduced model evaluated")
        prov = Provenance(
            kind="model",
            source=model.name,
            solver=self.name,
            wall_time=time.perf_counter() - t0,
            converged=True,
            notes=notes,
            extra={"params": params_to_json(model.param_names, params)},
        )
        return Response(lam1, lam2, P1, P2, load=kind, label=f"{model.name} ({load.kind})", provenance=prov)


@hookimpl
def register_solvers(register):
    register(ReducedSolver)
