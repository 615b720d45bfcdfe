"""Fitter ``lbfgs``: scipy's L-BFGS-B with the analytic gradient, from several deterministic starts.

Start design (:func:`knitframe.fitting.start_design`): the objective is evaluated at the model's
default parameters and at the first ``screen`` points of an unscrambled Halton sequence in the
parameter box (log scale for a, b, μ); L-BFGS-B then runs from the ``starts`` best of them and
the best end point wins. The optimiser works in the unit box, so parameters spanning decades are
as easy to move as an angle. Same data, same result, on every machine.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.errors import NumericalError
from knitframe.fitting import FitProblem, FitResult, UnitBox, finish, one_blas_thread, start_design
from knitframe.records import Response


@attrs.frozen
class LBFGSFitter:
    """Multi-start L-BFGS-B with the exact gradient of the joint NRMSE objective."""

    name: ClassVar[str] = "lbfgs"
    description: ClassVar[str] = "scipy L-BFGS-B with analytic gradient, multi-start from a Halton screen"

    #: local runs from the best screened points
    starts: int = attrs.field(default=4, validator=v.in_range(1, 1000))
    #: Halton points screened for starts
    screen: int = attrs.field(default=64, validator=v.in_range(0, 100000))
    #: L-BFGS-B iterations per start
    max_iter: int = attrs.field(default=500, validator=v.in_range(1, 10**6))
    #: weight of transverse-strain NRMSE²
    transverse_weight: float = attrs.field(default=1.0, validator=v.non_negative)

    def fit(self, model, responses: Iterable[Response]) -> FitResult:
        from scipy.optimize import minimize

        t0 = time.perf_counter()
        problem = FitProblem(model, responses, transverse_weight=self.transverse_weight)
        box = UnitBox(model)

        def fun(u):
            try:
                f, g = problem.objective(box.to_params(u), grad=True)
            except NumericalError:
                return 1e200, np.zeros_like(u)  # e.g. no free-side root: steer the line search away
            return f, g * box.dparams(u)

        best = None
        with one_blas_thread():
            for _, u0 in start_design(problem, box, self.screen)[: self.starts]:
                res = minimize(
                    fun,
                    u0,
                    jac=True,
                    method="L-BFGS-B",
                    bounds=[(0.0, 1.0)] * len(u0),
                    options={"maxiter": self.max_iter, "ftol": 1e-12, "gtol": 1e-9},
                )
                if best is None or res.fun < best.fun:
                    best = res
        return finish(
            problem,
            box.to_params(best.x),
            fitter=self.name,
            t0=t0,
            converged=bool(best.success),
            message=str(best.message),
            diagnostics={"starts": self.starts, "screen": self.screen},
        )


@hookimpl
def register_fitters(register):
    register(LBFGSFitter)
