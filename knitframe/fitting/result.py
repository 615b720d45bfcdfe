"""A finished fit: the result record (:class:`FitResult`), the fitters' unit box and start design,
the parameters that ended at a bound, and :func:`finish`, which builds the record from a fitter's
best point.
"""

from __future__ import annotations

import math
import time
import warnings
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError, KnitframeWarning, NumericalError
from knitframe.fitting.params import _is_angle, finite_json, params_from_json, params_to_json
from knitframe.fitting.problem import FitProblem

#: A fitted parameter within this fraction of its range (in the fitters' unit box) is "at a bound".
AT_BOUND = 1e-4


@attrs.frozen(eq=False)
class FitResult:
    """A fitted reduced model: the model, its parameters (radians inside) and how well it fits."""

    #: the homogenizer instance (with its options)
    model: Any
    #: ordered as param_names
    params: np.ndarray = attrs.field(converter=lambda p: np.array(p, dtype=np.float64))
    #: tension NRMSE: course, wale, overall
    nrmse: dict[str, float] = attrs.Factory(dict)
    #: transverse-strain NRMSE (lateral models)
    nrmse_transverse: dict[str, float] = attrs.Factory(dict)
    objective: float = 0.0
    #: objective evaluations
    n_evals: int = 0
    #: seconds
    wall_time: float = 0.0
    fitter: str = ""
    converged: bool = True
    message: str = ""
    #: labels of the fitted Responses
    labels: tuple[str, ...] = ()
    diagnostics: dict[str, Any] = attrs.Factory(dict)
    #: parameters (as named in params.json) that ended at a bound of the model's box
    at_bound: tuple[str, ...] = ()
    #: why the result is suspect: unit conversions of its data, parameters at a bound
    warnings: tuple[str, ...] = ()

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(self.model.param_names)

    def stress(self, lam1, lam2):
        """The fitted model's (P1, P2), N/mm."""
        return self.model.stress(self.params, lam1, lam2)

    def solve_uniaxial(self, lam, direction="course"):
        """The fitted model under uniaxial load with a free side: ``(lam_free, P_loaded)``."""
        return self.model.solve_uniaxial(self.params, lam, direction)

    def to_json(self) -> dict[str, Any]:
        """Plain data: every parameter (θ as ``theta_deg``), ``nrmse``, run metadata, ``at_bound`` and
        ``warnings``.

        Never holds NaN or Infinity: a non-finite number is written as null, its key listed in
        ``non_finite``, and a line added to ``warnings`` (see :func:`finite_json`).
        """
        options = attrs.asdict(self.model) if attrs.has(type(self.model)) else {}
        out: dict[str, Any] = {"model": self.model.name, "options": options}
        out.update(params_to_json(self.param_names, self.params))
        out["nrmse"] = dict(self.nrmse)
        if self.nrmse_transverse:
            out["nrmse_transverse"] = dict(self.nrmse_transverse)
        out.update(
            {
                "fitter": self.fitter,
                "objective": self.objective,
                "n_evals": self.n_evals,
                "wall_time_s": round(self.wall_time, 6),
                "converged": self.converged,
                "message": self.message,
                "responses": list(self.labels),
                "diagnostics": self.diagnostics,
                "at_bound": list(self.at_bound),
                "warnings": list(self.warnings),
            }
        )
        out, bad = finite_json(out)
        if bad:
            out["non_finite"] = bad
            out["warnings"].append(f"non-finite values written as null: {', '.join(bad)}")
        return out

    @classmethod
    def from_json(cls, data: dict[str, Any], registry=None, path: str = "params") -> FitResult:
        """Rebuild from :meth:`to_json` output (the model is looked up in the registry)."""
        from knitframe.config import instantiate
        from knitframe.plugins import get_registry

        if "model" not in data:
            raise ConfigError(f"{path}.model", "required key is missing")
        spec = {"kind": data["model"], **data.get("options", {})}
        model = instantiate(registry or get_registry(), "homogenizer", spec, f"{path}.model")
        keys = {f"{n}_deg" if _is_angle(n) else n for n in model.param_names}
        params = params_from_json(model.param_names, {k: v for k, v in data.items() if k in keys}, path)
        return cls(
            model,
            params,
            nrmse=data.get("nrmse", {}),
            nrmse_transverse=data.get("nrmse_transverse", {}),
            objective=data.get("objective", 0.0),
            n_evals=data.get("n_evals", 0),
            wall_time=data.get("wall_time_s", 0.0),
            fitter=data.get("fitter", ""),
            converged=data.get("converged", True),
            message=data.get("message", ""),
            labels=tuple(data.get("responses", ())),
            diagnostics=data.get("diagnostics", {}),
            at_bound=tuple(data.get("at_bound", ())),
            warnings=tuple(data.get("warnings", ())),
        )

    def headline(self) -> str:
        """One line: model, fitter and NRMSE in percent."""
        parts = ", ".join(f"{k} {100 * v:.1f} %" for k, v in self.nrmse.items() if k != "overall")
        overall = 100 * self.nrmse.get("overall", float("nan"))
        line = f"{self.model.name} by {self.fitter}: NRMSE {overall:.1f} % ({parts})"
        if self.nrmse_transverse:
            line += f", transverse {100 * self.nrmse_transverse.get('overall', float('nan')):.1f} %"
        return line


class UnitBox:
    """Maps the model's parameter box to [0, 1]^k (log scale where the model asks for it)."""

    def __init__(self, model: Any):
        lo, hi = (np.asarray(v, dtype=np.float64) for v in model.bounds())
        self.lo, self.hi = lo, hi
        self.log = np.asarray(model.log_scale, dtype=bool)
        if np.any(self.log & (lo <= 0)):
            raise ValueError("log-scaled parameters need a positive lower bound")
        self.span = np.array(
            [math.log(h / l) if g else h - l for l, h, g in zip(lo, hi, self.log, strict=False)]
        )

    def to_params(self, u: np.ndarray) -> np.ndarray:
        u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
        return np.where(self.log, self.lo * np.exp(u * self.span), self.lo + u * self.span)

    def to_unit(self, p: np.ndarray) -> np.ndarray:
        p = np.clip(np.asarray(p, dtype=np.float64), self.lo, self.hi)
        u = [math.log(x / l) if g else x - l for x, l, g in zip(p, self.lo, self.log, strict=False)]
        return np.clip(np.asarray(u) / self.span, 0.0, 1.0)

    def dparams(self, u: np.ndarray) -> np.ndarray:
        """∂p/∂u, elementwise."""
        return np.where(self.log, self.to_params(u) * self.span, self.span)


def start_design(problem: FitProblem, box: UnitBox, n_screen: int = 64) -> list[tuple[float, np.ndarray]]:
    """Deterministic start design: the model's ``x0`` plus the first ``n_screen`` points of an
    unscrambled Halton sequence in the unit box (its origin skipped), sorted by objective.

    Returns ``[(J, u), …]`` best first; the same data always gives the same starts.
    """
    from scipy.stats import qmc

    k = len(box.lo)
    pts = [box.to_unit(problem.model.x0())]
    if n_screen > 0:
        pts += list(qmc.Halton(k, scramble=False).random(n_screen + 1)[1:])
    scored = []
    for u in pts:
        try:
            f = problem.objective(box.to_params(u))
        except NumericalError:
            continue
        scored.append((f, np.asarray(u)))
    if not scored:
        raise NumericalError("no start point gives a finite objective")
    scored.sort(key=lambda t: t[0])
    return scored


def at_bound(model: Any, params: np.ndarray) -> tuple[tuple[str, ...], str]:
    """Parameters at a bound of the model's box (params.json names) and a one-line description of them.

    A parameter counts when it lies within :data:`AT_BOUND` of its range (log range for
    log-scaled ones) from either end: the optimum may lie outside the box, so the data do not
    determine it. Bounds a model declares as symmetry planes (``symmetric_bounds``, e.g. the
    fibre angle of hgo at 0 and 90°, where I4 is symmetric) are not counted: a fit ending there
    is at a true stationary point, not cut off. Returns ``((), "")`` when none is.
    """
    box = UnitBox(model)
    u = box.to_unit(params)
    lo, hi = model.bounds()
    shown = params_to_json(model.param_names, params)
    symmetric = model.symmetric_bounds
    names, parts = [], []
    for k, (n, key) in enumerate(zip(model.param_names, shown, strict=False)):
        side = "lower" if u[k] <= AT_BOUND else "upper" if u[k] >= 1.0 - AT_BOUND else None
        if symmetric[k]:
            continue
        if side:
            edge = params_to_json([n], [(lo if side == "lower" else hi)[k]])[key]
            names.append(key)
            parts.append(f"{key} = {shown[key]:.4g} (its {side} bound is {edge:.4g})")
    if not names:
        return (), ""
    return tuple(names), (
        f"{model.name} fit: {'; '.join(parts)}: the data do not determine "
        f"{'this parameter' if len(names) == 1 else 'these parameters'} inside the model's range "
        "(check the data's units and strain range)"
    )


def finish(
    problem: FitProblem,
    params: np.ndarray,
    *,
    fitter: str,
    t0: float,
    converged: bool,
    message: str,
    diagnostics: dict[str, Any] | None = None,
) -> FitResult:
    """Build the :class:`FitResult` of a finished optimisation (NRMSE, wall time, evaluations).

    Non-finite parameters are a NumericalError. Parameters at a bound of the model's box are
    listed in ``at_bound`` and reported by a :class:`~knitframe.errors.KnitframeWarning`; the
    result's ``warnings`` also carry the unit conversions made while reading its data.
    """
    params = np.asarray(params, dtype=np.float64)
    if not np.all(np.isfinite(params)):
        raise NumericalError(f"fitter '{fitter}' ended at non-finite parameters {params.tolist()}")
    ten, tra = problem.nrmse(params)
    diag = dict(diagnostics or {})
    fst = problem.free_side_tension(params)
    if fst is not None:
        diag["free_side_tension"] = fst
    n_evals = problem.n_evals
    objective = problem.objective(params)
    notes = [w for r in problem.responses for w in r.provenance.extra.get("warnings", ())]
    names, bound = at_bound(problem.model, params)
    if bound:
        warnings.warn(bound, KnitframeWarning, stacklevel=2)
        notes.append(bound)
    return FitResult(
        problem.model,
        params,
        ten,
        tra,
        objective,
        n_evals,
        time.perf_counter() - t0,
        fitter,
        converged,
        message,
        tuple(r.label for r in problem.responses),
        diag,
        names,
        tuple(dict.fromkeys(notes)),
    )
