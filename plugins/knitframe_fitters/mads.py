"""Fitter ``mads``: Mesh Adaptive Direct Search via NOMAD 4 (PyNomadBBO), the paper's optimiser.

MADS needs no gradient. It runs in the unit parameter box (log scale for a, b, μ) from the best
point of the same deterministic Halton screen the ``lbfgs`` fitter uses, with a fixed NOMAD seed,
until ``max_evals`` black-box evaluations or NOMAD's own mesh-size stop.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.errors import NumericalError, PluginError
from knitframe.fitting import FitProblem, FitResult, UnitBox, finish, start_design
from knitframe.records import Response


def _import_nomad():
    try:
        import PyNomad
    except ImportError:
        raise PluginError("fitter 'mads' needs NOMAD 4: pip install PyNomadBBO") from None
    return PyNomad


@attrs.frozen
class MADSFitter:
    """NOMAD 4 MADS on the joint NRMSE objective (derivative-free)."""

    name: ClassVar[str] = "mads"
    description: ClassVar[str] = "NOMAD 4 mesh adaptive direct search (PyNomadBBO), as in the paper"

    #: NOMAD MAX_BB_EVAL
    max_evals: int = attrs.field(default=1500, validator=v.in_range(1, 10**7))
    #: Halton points screened for the start
    screen: int = attrs.field(default=64, validator=v.in_range(0, 100000))
    #: NOMAD SEED
    seed: int = attrs.field(default=1, validator=v.in_range(0, 2**31 - 1))
    #: weight of transverse-strain NRMSE²
    transverse_weight: float = attrs.field(default=1.0, validator=v.non_negative)

    def fit(self, model, responses: Iterable[Response]) -> FitResult:
        PyNomad = _import_nomad()
        t0 = time.perf_counter()
        problem = FitProblem(model, responses, transverse_weight=self.transverse_weight)
        box = UnitBox(model)
        u0 = start_design(problem, box, self.screen)[0][1]
        k = len(u0)

        def blackbox(point) -> int:
            u = np.array([point.get_coord(i) for i in range(k)])
            try:
                f = problem.objective(box.to_params(u))
            except NumericalError:
                return 0  # NOMAD treats a failed evaluation as infeasible and moves on
            point.setBBO(repr(f).encode())
            return 1

        opts = [
            "BB_OUTPUT_TYPE OBJ",
            f"MAX_BB_EVAL {self.max_evals}",
            "DISPLAY_DEGREE 0",
            f"SEED {self.seed}",
        ]
        out = PyNomad.optimize(blackbox, list(map(float, u0)), [0.0] * k, [1.0] * k, opts)
        u = np.asarray(out.get("x_single_best") or u0, dtype=np.float64)
        # run_flag 1: NOMAD's mesh (or target) stop; 0: budget spent with a feasible point
        converged = int(out.get("run_flag", -1)) == 1
        return finish(
            problem,
            box.to_params(u),
            fitter=self.name,
            t0=t0,
            converged=converged,
            message=str(out.get("stop_reason", "")),
            diagnostics={"nomad_evals": int(out.get("nb_evals", 0)), "seed": self.seed},
        )


@hookimpl
def register_fitters(register):
    register(MADSFitter)
