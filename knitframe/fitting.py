r"""Fitting reduced fabric models to Responses: the objective, its gradient and the result record.

A reduced model (a :class:`~knitframe.interfaces.Homogenizer`) used here also offers
``bounds()``, ``x0()``, ``log_scale``, ``predicts_lateral``, ``stress_grad(params, λ1, λ2)`` →
``(P1, P2, ∂P1/∂p, ∂P2/∂p)`` and ``tangent(params, λ1, λ2)`` → ``(∂P1/∂λ1, ∂P1/∂λ2, ∂P2/∂λ2)``.

How each Response enters the fit (:class:`FitProblem`):

* ``equibiaxial`` / ``general``: both stretches are imposed; P1 is compared with T1 and P2 with T2.
* ``uniaxial-course`` / ``uniaxial-wale`` (free sides): the loaded tension is compared. A model
  that cannot predict the free side (``predicts_lateral = False``, the paper's ``hgo``) is
  evaluated at the *measured* free-side stretch; its free-side tension, which should be zero, is
  reported as the diagnostic ``free_side_tension`` (max |P_free| / max |T_loaded|). A model that
  can (``predicts_lateral = True``) gets its free-side stretch from P_free = 0
  (:func:`solve_free_side`); the difference to the measured transverse strain is a second
  residual group.

Score and objective. Residuals are grouped by direction (course, wale) and kind (tension,
transverse strain). ``NRMSE_g = sqrt(mean_g r²) / max_g |measured|`` — normalised by the maximum
measured tension of that direction (transverse: maximum |transverse strain|), and ``overall``
over all tension residuals by the overall maximum. The fitters minimise

.. math:: J(p) = \sum_{g \in \text{tension}} \mathrm{NRMSE}_g^2
               + w_t \sum_{g \in \text{transverse}} \mathrm{NRMSE}_g^2

which is the paper's least-squares objective Σ‖S − P‖² with each direction weighted by its own
scale, so a stiff and a soft direction count equally. Its gradient is exact: stress derivatives
from the model, and for a solved free side the implicit derivative
``∂λf/∂p = −(∂P_f/∂p) / (∂P_f/∂λf)``.
"""

from __future__ import annotations

import json
import math
import textwrap
import time
import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError, KnitframeWarning, NumericalError
from knitframe.records import Provenance, Response

__all__ = [
    "direction_index",
    "solve_free_side",
    "bracketed_newton",
    "free_side_grad",
    "params_to_json",
    "params_from_json",
    "FitProblem",
    "FitResult",
    "UnitBox",
    "start_design",
    "predict",
    "write_fit_outputs",
    "plot_fit",
    "at_bound",
    "finite_json",
    "free_side_zero_message",
]

#: Smallest free-side stretch the uniaxial solve considers; a model without lateral stiffness
#: (the paper's hgo beyond λ = 1/cos θ) "collapses" onto it.
FREE_MIN = 1e-3
#: Scaled residuals are clipped here so that squares and sums stay finite far outside the data.
RESIDUAL_CLIP = 1e100
#: A fitted parameter within this fraction of its range (in the fitters' unit box) is "at a bound".
AT_BOUND = 1e-4
DIRECTIONS = ("course", "wale")


def direction_index(direction: str | int) -> int:
    """0 for the course (``"course"``, ``"x"``, 0), 1 for the wale (``"wale"``, ``"y"``, 1)."""
    key = str(direction).strip().lower()
    if key in ("course", "x", "0"):
        return 0
    if key in ("wale", "y", "1"):
        return 1
    raise ValueError(f"direction must be 'course' or 'wale', got {direction!r}")


def _pair(d: int, lam_load, lam_free):
    return (lam_load, lam_free) if d == 0 else (lam_free, lam_load)


def solve_free_side(
    model: Any,
    params: np.ndarray,
    lam: np.ndarray,
    direction: str | int = "course",
    *,
    guess: np.ndarray | None = None,
):
    """Uniaxial load with a free side: the free stretch λf with ``P_free(λ, λf) = 0``.

    The root is bracketed from the reference λf = 1: if P_free(λ, 1) > 0 the bracket is
    [FREE_MIN, 1], otherwise [1, hi] with hi doubled until P_free(hi) > 0. Inside the bracket a
    vectorised Newton iteration on the model's tangent ∂P_free/∂λf falls back to bisection
    whenever a step would leave the bracket, so it converges for any continuous P_free (and
    quadratically near the root, 4–6 iterations in practice). Where P_free(FREE_MIN) >= 0
    already (a model with no lateral stiffness, e.g. the paper's hgo beyond λ = 1/cos θ) the free
    side collapses: λf = FREE_MIN.

    Parameters
    ----------
    model : reduced model with ``stress(params, lam1, lam2)`` and ``stress_tangent(params, lam1, lam2)``
    params : (k,) parameters
    lam : (n,) loaded stretch, -
    direction : ``"course"`` or ``"wale"``
    guess : (n,) optional start for the iteration (e.g. the previous solution during a fit); it is
        used only where it lies inside the bracket

    Returns
    -------
    lam_free, P_loaded : (n,) free-side stretch (-) and loaded tension (N/mm)
    """
    d = direction_index(direction)
    lam = np.atleast_1d(np.asarray(lam, dtype=np.float64))
    shape = lam.shape
    lam = lam.ravel()

    def f(lf):
        return model.stress(params, *_pair(d, lam, lf))[1 - d]

    def fdf(lf):
        P1, P2, K11, _, K22 = model.stress_tangent(params, *_pair(d, lam, lf))  # one evaluation, not two
        return (P2, K22) if d == 0 else (P1, K11)

    one = np.ones_like(lam)
    f1 = f(one)
    lo = np.where(f1 > 0, FREE_MIN, 1.0)
    hi = np.where(f1 > 0, 1.0, 2.0)
    collapse = (f1 > 0) & (f(lo) >= 0)
    for _ in range(60):
        bad = (f1 < 0) & (f(hi) <= 0)
        if not bad.any():
            break
        hi = np.where(bad, 2.0 * hi, hi)
    else:
        i = int(np.flatnonzero(bad)[0])
        raise NumericalError(
            f"free-side solve: P_free stays <= 0 up to stretch {hi[i]:.3g} at loaded stretch {lam[i]:.6g}; "
            "the model has no lateral stiffness in tension"
        )
    fixed = np.where(collapse, FREE_MIN, 1.0)  # collapsed points and exact roots at 1 need no iteration
    done = collapse | (f1 == 0)
    lo, hi = np.where(done, fixed, lo), np.where(done, fixed, hi)
    x0 = fixed if guess is None else np.clip(np.asarray(guess, dtype=np.float64).ravel(), lo, hi)
    root = bracketed_newton(fdf, lo, hi, x0, increasing=True)
    P = model.stress(params, *_pair(d, lam, root))[d]
    return root.reshape(shape), np.asarray(P).reshape(shape)


def free_side_zero_message(model: str, top: float, slack: float, direction: str | int = "course") -> str:
    """One line: why a free-side curve of a model without lateral stiffness is zero up to loaded stretch ``top``.

    ``slack`` is the stretch where the model starts to carry tension (1/cos θ for the paper's
    hgo loaded along the course, 1/sin θ along the wale).
    """
    trig = "cos" if direction_index(direction) == 0 else "sin"
    return (
        f"'{model}' with a free side gives zero tension at every loaded stretch up to {top:.4g}: P_free = 0 "
        f"forces I4 = 1 until stretch 1/{trig}(theta) = {slack:.4g}; use 'hgo2m', which predicts the free side, "
        "or a fixed lateral side"
    )


def bracketed_newton(
    fdf,
    lo: np.ndarray,
    hi: np.ndarray,
    x0: np.ndarray,
    *,
    xtol: float = 1e-13,
    xscale: float = 1.0,
    maxiter: int = 200,
    increasing: bool | None = None,
) -> np.ndarray:
    """Vectorised safeguarded Newton: a root of ``f`` in [lo, hi] for every element.

    ``fdf(x) -> (f, df)``. Needs sign(f(lo)) != sign(f(hi)) (or a zero at an end); ``increasing``
    states f(lo) <= 0 <= f(hi), saving the evaluation at ``lo`` that would find out. Each step is
    Newton's unless it leaves the current bracket or ``df`` is not finite and non-zero, then it
    bisects; the bracket shrinks on every step, so the iteration cannot diverge. Converged when
    the step (or the bracket) is below ``xtol·max(xscale, |x|)``; not converging in ``maxiter``
    steps raises NumericalError.
    """
    lo, hi = np.array(lo, dtype=np.float64), np.array(hi, dtype=np.float64)
    x = np.clip(np.asarray(x0, dtype=np.float64), lo, hi)
    rising = fdf(lo)[0] < 0 if increasing is None else increasing  # orientation of the bracket
    for _ in range(maxiter):
        fx, dfx = fdf(x)
        below = (fx < 0) == rising
        lo = np.where(below, x, lo)
        hi = np.where(below, hi, x)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            xn = x - fx / dfx
        bad = ~np.isfinite(xn) | ~np.isfinite(dfx) | (dfx == 0) | (xn < lo) | (xn > hi)
        xn = np.where(bad, 0.5 * (lo + hi), xn)
        xn = np.where(fx == 0, x, xn)
        step = np.abs(xn - x)
        x = xn
        tol = xtol * np.maximum(xscale, np.abs(x))
        if np.all((step <= tol) | (hi - lo <= tol)):
            return x
    raise NumericalError(
        f"bracketed Newton did not converge in {maxiter} steps (widest bracket {np.max(hi - lo):.3g})"
    )


def free_side_grad(
    model: Any,
    params: np.ndarray,
    lam: np.ndarray,
    direction: str | int = "course",
    *,
    guess: np.ndarray | None = None,
):
    """:func:`solve_free_side` plus parameter derivatives.

    Returns ``(lam_free, P_loaded, dlam_free (n, k), dP_loaded (n, k))``. The implicit
    derivative ``∂λf/∂p = −(∂P_f/∂p)/(∂P_f/∂λf)`` holds at an interior root; a collapsed
    free side (λf = FREE_MIN) or a vanishing ∂P_f/∂λf gives ``∂λf/∂p = 0``.
    """
    d = direction_index(direction)
    lf, _ = solve_free_side(model, params, lam, d, guess=guess)
    lam = np.asarray(lam, dtype=np.float64).reshape(lf.shape)
    l1, l2 = _pair(d, lam, lf)
    P1, P2, dP1, dP2 = model.stress_grad(params, l1, l2)
    K11, K12, K22 = model.tangent(params, l1, l2)
    Kff, Klf = (K22, K12) if d == 0 else (K11, K12)
    dPf, dPl = (dP2, dP1) if d == 0 else (dP1, dP2)
    interior = (lf > FREE_MIN) & (np.abs(Kff) > 0)
    dlf = np.where(interior[..., None], -dPf / np.where(interior, Kff, 1.0)[..., None], 0.0)
    return lf, (P1, P2)[d], dlf, dPl + Klf[..., None] * dlf


def _is_angle(name: str) -> bool:
    return name.startswith("theta")


def params_to_json(names: Sequence[str], params: Sequence[float]) -> dict[str, float]:
    """Parameters by name; angles (``theta*``) become ``<name>_deg`` in degrees."""
    out = {}
    for n, p in zip(names, params):
        out[f"{n}_deg" if _is_angle(n) else n] = float(math.degrees(p)) if _is_angle(n) else float(p)
    return out


def params_from_json(names: Sequence[str], data: dict[str, Any], path: str = "params") -> np.ndarray:
    """Inverse of :func:`params_to_json`; a missing or non-numeric parameter is a ConfigError at ``path``."""
    out = []
    for n in names:
        key = f"{n}_deg" if _is_angle(n) else n
        if key not in data:
            raise ConfigError(
                f"{path}.{key}", f"required parameter is missing (model needs {', '.join(names)})"
            )
        v = data[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"{path}.{key}", f"expected a finite number, got {v!r}")
        out.append(math.radians(v) if _is_angle(n) else float(v))
    extra = sorted(set(data) - {f"{n}_deg" if _is_angle(n) else n for n in names})
    if extra:
        raise ConfigError(f"{path}.{extra[0]}", f"unknown parameter; the model has {', '.join(names)}")
    return np.array(out)


@attrs.frozen(eq=False)
class _Block:
    """How one Response enters the fit."""

    index: int
    uniaxial: bool
    direction: int  # loaded direction for uniaxial blocks
    lam1: np.ndarray
    lam2: np.ndarray
    measured: tuple[np.ndarray, ...]  # tensions compared (1 for uniaxial, 2 otherwise)
    lam_free: np.ndarray | None  # measured free-side stretch to compare (lateral models only)


_GROUPS = ("course", "wale", "course_transverse", "wale_transverse")


class FitProblem:
    """The joint least-squares problem of one model over several Responses.

    Parameters
    ----------
    model : reduced model (see module docstring)
    responses : Responses fitted jointly (course and wale, any number of samples each)
    transverse_weight : weight ``w_t`` of the transverse-strain groups (lateral models only)
    """

    def __init__(self, model: Any, responses: Iterable[Response], *, transverse_weight: float = 1.0):
        self.model = model
        self.responses = list(responses)
        if not self.responses:
            raise ConfigError("fit", "no responses to fit")
        self.transverse_weight = float(transverse_weight)
        self.lateral = bool(getattr(model, "predicts_lateral", False))
        self.n_evals = 0
        self._guess: dict[int, np.ndarray] = {}
        self.blocks = [self._block(i, r) for i, r in enumerate(self.responses)]
        # group id of every residual, in block order
        gid = []
        for b in self.blocks:
            n = len(b.lam1)
            if b.uniaxial:
                gid.append(np.full(n, b.direction))
                if b.lam_free is not None:
                    gid.append(np.full(n, 2 + b.direction))
            else:
                gid += [np.zeros(n, int), np.ones(n, int)]
        self.gid = np.concatenate(gid)
        meas = np.concatenate([self._measured(b) for b in self.blocks])
        self.present = [g for g in range(4) if np.any(self.gid == g)]
        self.norm = np.ones(4)
        self.count = np.ones(4)
        for g in self.present:
            m = np.abs(meas[self.gid == g]).max()
            self.count[g] = np.sum(self.gid == g)
            if g < 2 and m == 0:
                raise NumericalError(f"NRMSE undefined: every measured {_GROUPS[g]} tension is zero")
            self.norm[g] = m if m > 0 else 1.0
        # transverse groups with no measured contraction cannot be normalised: they are left out
        self.present = [g for g in self.present if g < 2 or np.abs(meas[self.gid == g]).max() > 0]
        weight = np.array([1.0, 1.0, self.transverse_weight, self.transverse_weight])
        w = np.array([weight[g] if g in self.present else 0.0 for g in range(4)])
        self.scale = np.sqrt(w / self.count) / self.norm  # residual → scaled residual
        self.tension_max = np.abs(meas[self.gid < 2]).max()

    def _block(self, i: int, r: Response) -> _Block:
        d = r.loaded_direction
        if d is None:
            return _Block(i, False, -1, r.lambda1, r.lambda2, (r.T1, r.T2), None)
        measured = (r.T1, r.T2)[d]
        free = (r.lambda1, r.lambda2)[1 - d]
        measured_free = r.provenance.extra.get("transverse_measured", True)
        lam_free = free if (self.lateral and measured_free) else None
        return _Block(i, True, d, r.lambda1, r.lambda2, (measured,), lam_free)

    @staticmethod
    def _measured(b: _Block) -> np.ndarray:
        parts = list(b.measured)
        if b.lam_free is not None:
            parts.append(b.lam_free - 1.0)
        return np.concatenate(parts)

    # -- model evaluation -------------------------------------------------------------------
    def _evaluate(self, params: np.ndarray, grad: bool):
        """Residuals (model − data) in group order, with their Jacobian (m, k) if ``grad``."""
        rs, js = [], []
        m = self.model
        for b in self.blocks:
            if b.uniaxial and b.lam_free is not None:
                lam_load = (b.lam1, b.lam2)[b.direction]
                guess = self._guess.get(b.index)  # warm start: parameters move little between evaluations
                if grad:
                    lf, P, dlf, dP = free_side_grad(m, params, lam_load, b.direction, guess=guess)
                    js += [dP, dlf]
                else:
                    lf, P = solve_free_side(m, params, lam_load, b.direction, guess=guess)
                self._guess[b.index] = lf
                rs += [P - b.measured[0], lf - b.lam_free]
                continue
            if grad:
                P1, P2, dP1, dP2 = m.stress_grad(params, b.lam1, b.lam2)
            else:
                P1, P2 = m.stress(params, b.lam1, b.lam2)
            if b.uniaxial:
                rs.append((P1, P2)[b.direction] - b.measured[0])
                if grad:
                    js.append((dP1, dP2)[b.direction])
            else:
                rs += [P1 - b.measured[0], P2 - b.measured[1]]
                if grad:
                    js += [dP1, dP2]
        r = np.concatenate(rs)
        return r, (np.concatenate(js) if grad else None)

    def objective(self, params: np.ndarray, grad: bool = False):
        """J(p) (and ∂J/∂p if ``grad``); finite for any parameters inside the model's bounds."""
        self.n_evals += 1
        r, jac = self._evaluate(np.asarray(params, dtype=np.float64), grad)
        s = self.scale[self.gid]
        rs = np.clip(r * s, -RESIDUAL_CLIP, RESIDUAL_CLIP)
        f = float(rs @ rs)
        if not math.isfinite(f):
            raise NumericalError(f"fit objective is not finite at parameters {np.asarray(params).tolist()}")
        if not grad:
            return f
        inside = np.abs(r * s) < RESIDUAL_CLIP
        g = 2.0 * ((rs * inside * s) @ jac)
        return f, np.nan_to_num(g, nan=0.0, posinf=RESIDUAL_CLIP, neginf=-RESIDUAL_CLIP)

    def nrmse(self, params: np.ndarray) -> tuple[dict[str, float], dict[str, float]]:
        """``(tension, transverse)`` NRMSE by direction plus ``overall``; transverse is empty for hgo-like models."""
        r, _ = self._evaluate(np.asarray(params, dtype=np.float64), False)
        ten, tra = {}, {}
        for g in self.present:
            rms = float(np.sqrt(np.mean(r[self.gid == g] ** 2)) / self.norm[g])
            (ten if g < 2 else tra)[DIRECTIONS[g % 2]] = rms
        t = self.gid < 2
        ten["overall"] = float(np.sqrt(np.mean(r[t] ** 2)) / self.tension_max)
        tg = [g for g in self.present if g >= 2]
        if tg:
            mask = np.isin(self.gid, tg)
            norm = max(self.norm[g] for g in tg)
            tra["overall"] = float(np.sqrt(np.mean(r[mask] ** 2)) / norm)
        return ten, tra

    def free_side_tension(self, params: np.ndarray) -> float | None:
        """max |P_free| / max |T_loaded| over the uniaxial tests evaluated at the measured free side."""
        worst = None
        for b in self.blocks:
            if b.uniaxial and b.lam_free is None:
                P = self.model.stress(params, b.lam1, b.lam2)[1 - b.direction]
                v = float(np.abs(P).max() / self.tension_max)
                worst = v if worst is None else max(worst, v)
        return worst


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
        """Plain data: every parameter (θ as ``theta_deg``), ``nrmse``, run metadata, ``at_bound`` and ``warnings``.

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
        line = f"{self.model.name} by {self.fitter}: NRMSE {100 * self.nrmse.get('overall', float('nan')):.1f} % ({parts})"
        if self.nrmse_transverse:
            line += f", transverse {100 * self.nrmse_transverse.get('overall', float('nan')):.1f} %"
        return line


class UnitBox:
    """Maps the model's parameter box to [0, 1]^k (log scale where the model asks for it)."""

    def __init__(self, model: Any):
        lo, hi = (np.asarray(v, dtype=np.float64) for v in model.bounds())
        self.lo, self.hi = lo, hi
        self.log = np.asarray(getattr(model, "log_scale", (False,) * len(lo)), dtype=bool)
        if np.any(self.log & (lo <= 0)):
            raise ValueError("log-scaled parameters need a positive lower bound")
        self.span = np.array([math.log(h / l) if g else h - l for l, h, g in zip(lo, hi, self.log)])

    def to_params(self, u: np.ndarray) -> np.ndarray:
        u = np.clip(np.asarray(u, dtype=np.float64), 0.0, 1.0)
        return np.where(self.log, self.lo * np.exp(u * self.span), self.lo + u * self.span)

    def to_unit(self, p: np.ndarray) -> np.ndarray:
        p = np.clip(np.asarray(p, dtype=np.float64), self.lo, self.hi)
        u = [math.log(x / l) if g else x - l for x, l, g in zip(p, self.lo, self.log)]
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


def finite_json(data: Any, path: str = "") -> tuple[Any, list[str]]:
    """``data`` with every non-finite float replaced by None, and the dotted keys where that happened."""
    if isinstance(data, dict):
        out, bad = {}, []
        for k, v in data.items():
            out[k], b = finite_json(v, f"{path}.{k}" if path else str(k))
            bad += b
        return out, bad
    if isinstance(data, (list, tuple)):
        pairs = [finite_json(v, f"{path}[{i}]") for i, v in enumerate(data)]
        return [v for v, _ in pairs], [b for _, bs in pairs for b in bs]
    if isinstance(data, (float, np.floating)) and not math.isfinite(data):
        return None, [path]
    return data, []


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
    symmetric = getattr(model, "symmetric_bounds", (False,) * len(u))
    names, parts = [], []
    for k, (n, key) in enumerate(zip(model.param_names, shown)):
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


def predict(result: FitResult, response: Response) -> Response:
    """The fitted model's Response at a measured Response's loaded stretches.

    Uniaxial tests: a lateral model solves its free side; otherwise the measured free-side
    stretch is used (as in the fit). Other loads: both stretches are imposed.
    """
    d = response.loaded_direction
    lam1, lam2 = response.lambda1, response.lambda2
    if d is not None and getattr(result.model, "predicts_lateral", False):
        lam_load = (lam1, lam2)[d]
        lf, _ = result.solve_uniaxial(lam_load, d)
        lam1, lam2 = _pair(d, lam_load, lf)
    P1, P2 = result.stress(lam1, lam2)
    if d is not None:  # the free side carries no load by definition of the test
        P1, P2 = (P1, np.zeros_like(P2)) if d == 0 else (np.zeros_like(P1), P2)
    return Response(
        lam1,
        lam2,
        P1,
        P2,
        load=response.load,
        label=f"{response.label} ({result.model.name})",
        provenance=Provenance(kind="model", source=result.model.name, notes=f"fitted by {result.fitter}"),
    )


def plot_fit(path: Path, result: FitResult, responses: Sequence[Response], *, title: str = "") -> None:
    """Data (±1 sd band) against the fitted model; a second panel shows the transverse strain."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from knitframe.report import curve

    uni = [r for r in responses if r.loaded_direction is not None]
    fig, axes = plt.subplots(1, 2 if uni else 1, figsize=(11 if uni else 6.4, 4.4), dpi=110, squeeze=False)
    ax, colors = axes[0, 0], plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, r in enumerate(responses):
        c = colors[i % len(colors)]
        pred = predict(result, r)
        for (name, strain, T, sd), (_, _, P, _) in zip(curve(r), curve(pred)):
            ls = "-" if name == "course" else "--"
            o = np.argsort(strain)
            ax.plot(strain[o], T[o], ls, color=c, lw=1.2, alpha=0.9, label=f"{r.label or r.load} ({name})")
            if sd is not None:
                ax.fill_between(strain[o], (T - sd)[o], (T + sd)[o], color=c, alpha=0.2, lw=0)
            ax.plot(strain[o], P[o], ls, color="k", lw=1.0)
        d = r.loaded_direction
        if d is not None:
            bx = axes[0, 1]
            strain = (r.lambda1, r.lambda2)[d] - 1
            lat = (r.lambda1, r.lambda2)[1 - d] - 1
            sd = (r.lambda1_sd, r.lambda2_sd)[1 - d]
            o = np.argsort(strain)
            bx.plot(strain[o], lat[o], color=c, lw=1.2)
            if sd is not None:
                bx.fill_between(strain[o], (lat - sd)[o], (lat + sd)[o], color=c, alpha=0.2, lw=0)
            if getattr(result.model, "predicts_lateral", False):
                plat = (pred.lambda1, pred.lambda2)[1 - d] - 1
                bx.plot(strain[o], plat[o], "k-", lw=1.0)
    ax.plot([], [], "k-", lw=1.0, label=f"fitted {result.model.name}")
    ax.set_xlabel("engineering strain in the loaded direction, -")
    ax.set_ylabel("tension per unit width, N/mm")
    ax.set_title(title or result.headline(), fontsize=8)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    if uni:
        bx = axes[0, 1]
        bx.set_xlabel("engineering strain in the loaded direction, -")
        bx.set_ylabel("transverse strain, -")
        bx.set_title(
            "free side: measured"
            + (" vs model" if result.model.predicts_lateral else " (imposed in the fit)"),
            fontsize=8,
        )
        bx.grid(alpha=0.3)
    notes = result.to_json()["warnings"]
    if notes:  # suspect results say so on the figure, in red below the axes
        text = "\n".join(textwrap.fill(f"warning: {w}", 150 if uni else 95) for w in notes)
        rows = text.count("\n") + 1
        fig.set_size_inches(fig.get_figwidth(), fig.get_figheight() + 0.16 * rows)
        fig.text(0.01, 0.01, text, color="red", fontsize=7, va="bottom", ha="left")
        fig.tight_layout(rect=(0, (0.16 * rows + 0.05) / fig.get_figheight(), 1, 1))
    else:
        fig.tight_layout()
    fig.savefig(path, metadata={"Description": " | ".join(notes) or "no warnings"})
    plt.close(fig)


def write_fit_outputs(
    result: FitResult, responses: Sequence[Response], params_path: Path, plot_path: Path
) -> None:
    """Write ``params.json`` (parameters, θ in degrees, NRMSE, metadata, warnings) and the fit plot.

    The JSON is strict: NaN and Infinity cannot be written (see :meth:`FitResult.to_json`); a
    result that needed cleaning says so by a :class:`~knitframe.errors.KnitframeWarning`.
    """
    data = result.to_json()
    if data.get("non_finite"):
        warnings.warn(f"{Path(params_path).name}: {data['warnings'][-1]}", KnitframeWarning, stacklevel=2)
    Path(params_path).write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")
    plot_fit(Path(plot_path), result, responses)
