"""The fit's objective (:class:`FitProblem`): the Responses as residual blocks, the scaled
residuals, the objective J(p) and its exact gradient (see :mod:`knitframe.fitting`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError, NumericalError
from knitframe.fitting.free_side import DIRECTIONS, free_side_grad, solve_free_side
from knitframe.records import Response

#: Scaled residuals are clipped here so that squares and sums stay finite far outside the data.
RESIDUAL_CLIP = 1e100


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
        self.lateral = bool(model.predicts_lateral)
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
        """``(tension, transverse)`` NRMSE by direction plus ``overall``; transverse is empty for
        hgo-like models."""
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
