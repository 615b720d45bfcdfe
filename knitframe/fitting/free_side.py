"""The free side of a uniaxial test: the stretch at which a reduced model's free-side tension is
zero (P_free = 0), solved by a bracketed Newton iteration, its implicit derivative with respect
to the parameters, and the message when a model has no such stretch.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from knitframe.errors import NumericalError

#: Smallest free-side stretch the uniaxial solve considers; a model without lateral stiffness
#: (the paper's hgo beyond λ = 1/cos θ) "collapses" onto it.
FREE_MIN = 1e-3

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
    """One line: why a free-side curve of a model without lateral stiffness is zero up to loaded
    stretch ``top``.

    ``slack`` is the stretch where the model starts to carry tension (1/cos θ for the paper's
    hgo loaded along the course, 1/sin θ along the wale).
    """
    trig = "cos" if direction_index(direction) == 0 else "sin"
    return (
        f"'{model}' with a free side gives zero tension at every loaded stretch up to {top:.4g}: "
        f"P_free = 0 forces I4 = 1 until stretch 1/{trig}(theta) = {slack:.4g}; use 'hgo2m', which "
        "predicts the free side, or a fixed lateral side"
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
