"""The step helpers of :func:`knitframe.numerics.newton.minimise`: the line search and its refinements.

What one Newton iteration does with a solved direction dx: cap it (:func:`capped_step`), search along
it (:func:`line_search`: Armijo on the energy, then a residual-decrease fallback), lengthen a
full step the energy shows was too short (:func:`extrapolated`), halve a full step that reverses
the last one (:func:`halved_reversal`), and the chord steps on a kept factorisation
(:func:`chord_step`). Also the bookkeeping shared by the driver: the history's step ratio, its
one-line summary, reporting an iteration and the failure that carries the history. The equations
are in each function's docstring and in the module docstring of :mod:`knitframe.numerics.newton`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence

import numpy as np
import scipy.sparse as sp

from knitframe.errors import NumericalError
from knitframe.numerics.newton_options import NewtonOptions, Problem

__all__ = [
    "CHORD_SIZE_FACTOR",
    "EXTRAPOLATE_MIN",
    "REVERSAL_COS",
    "EXTRAPOLATE_TRIALS",
    "STALL_FACTOR",
    "diag_scale",
    "history_summary",
    "capped_step",
    "halved_reversal",
    "extrapolated",
    "chord_step",
    "report_iteration",
    "step_ratio",
    "newton_failure",
    "line_search",
]


#: chord steps: none after a Newton step within this × step_tol, and none larger than this × that Newton step
CHORD_SIZE_FACTOR = 2.0

#: extrapolation (``NewtonOptions.extrapolate``) only to α of at least this: a shorter gain is not worth its
#: evaluation
EXTRAPOLATE_MIN = 1.5
#: a full step whose cosine with the last move (where it moves most) is below this is a reversal
REVERSAL_COS = -0.5
#: energy evaluations of an extrapolation at most
EXTRAPOLATE_TRIALS = 3

#: an iteration counts as stalled only while its best residual is this many times the tolerance
STALL_FACTOR = 10.0


def diag_scale(A: sp.spmatrix) -> float:
    """The mean |diagonal| of A, the scale of the Levenberg shift μ·mean|diag H| (1 for a zero diagonal)."""
    d = np.abs(A.diagonal())
    return float(d.mean()) if d.size and d.mean() > 0 else 1.0


def history_summary(history: Sequence[dict], last: int = 6) -> str:
    """The ``last`` iterations of ``history`` in one line (energy, residual, α, shift), for error messages."""
    rows = [
        f"it {h['it']}: E={h['energy']:.6g} |g|={h['residual']:.3g} alpha={h.get('alpha', 0):.3g} "
        f"shift={h.get('shift', 0):.2g}"
        for h in history[-last:]
    ]
    return "; ".join(rows)


def capped_step(
    x: np.ndarray,
    dx: np.ndarray,
    slope: float,
    size: float,
    options: NewtonOptions,
    step_limit: Callable[[np.ndarray, np.ndarray], float] | None,
) -> tuple[np.ndarray, float, float]:
    """A step of size ``size`` scaled down to ``options.max_step`` (dx and its slope g·dx), and the line
    search's first α: 1, or the crossing-free fraction ``step_limit(x, dx)`` when smaller."""
    if np.isfinite(size) and size > options.max_step:
        dx = dx * (options.max_step / size)
        slope *= options.max_step / size
    return dx, slope, 1.0 if step_limit is None else min(1.0, float(step_limit(x, dx)))


def halved_reversal(
    fun: Problem,
    x: np.ndarray,
    dx: np.ndarray,
    step: tuple[float, np.ndarray, float] | None,
    last_move: np.ndarray | None,
    free: np.ndarray,
    entry: dict,
) -> tuple[float, np.ndarray, float] | None:
    """A full step that reverses the last move where it is largest, halved if that lowers the energy further.

    Where the energy has a kink (IPC friction's mollifier is only C¹ at the stick-slip switch), a
    group of nodes can flip between two states at every full Newton step: in the P2 r/3 pre-stress,
    60 nodes moved 0.033 r per step, each step at cos −0.76 to −0.995 to the last, from iteration 13 to 32,
    while the
    rest of the cell had converged and the Armijo test, satisfied by the rest, accepted every step.
    The step is compared with the last move on the DOFs where it moves at least half its largest
    move; at cos < ``REVERSAL_COS`` the midpoint x + dx/2 (the 2-cycle's centre) is evaluated and
    taken when its energy is below the full step's. Records ``halved`` in ``entry``.
    """
    if step is None or step[0] != 1.0 or last_move is None:
        return step
    d = dx[free]
    big = np.abs(d) >= 0.5 * float(np.max(np.abs(d), initial=0.0))
    a, b = d[big], last_move[free][big]
    denom = float(np.linalg.norm(a) * np.linalg.norm(b))
    if denom == 0.0 or float(a @ b) / denom >= REVERSAL_COS:
        return step
    x_h = x + 0.5 * dx
    E_h = fun(x_h, 0)[0]
    if np.isfinite(E_h) and E_h < step[2]:
        entry["halved"] = True
        return 0.5, x_h, E_h
    return step


def extrapolated(
    fun: Problem,
    x: np.ndarray,
    E: float,
    dx: np.ndarray,
    slope: float,
    size: float,
    step: tuple[float, np.ndarray, float] | None,
    options: NewtonOptions,
    step_limit: Callable[[np.ndarray, np.ndarray], float] | None,
    entry: dict,
) -> tuple[float, np.ndarray, float] | None:
    """The line search's ``step``, or a longer one along dx where the full step's energy says the model was
    too stiff.

    After a full step (α = 1) was accepted, the quadratic through φ(0) = E, φ'(0) = g·dx and
    φ(1) = E(x + dx) has its curvature c = 2·(φ(1) − φ(0) − φ'(0)) and its minimum at
    α* = −φ'(0)/c (α* = ∞ where c ≤ 0). Where the Hessian overestimates the curvature along dx
    (projected Newton near a solution: the clamped negative eigenvalues of compressed fibres and
    the barrier's dropped curvature stiffen soft modes) α* ≫ 1 and full steps converge only
    linearly (in the coarse SL11 cell, steps shrinking by 8 % per iteration with α* = 6–50).
    The first trial is α_e = min(α*, ``options.extrapolate``, ``max_step``/|dx|, the CCD bound of
    α_e·dx); the energy grows faster than quadratically beyond α = 1 (barrier pairs close), so
    where E(α_e) is not below φ(1), the minimum of the quadratic through φ(0), φ'(0) and
    φ(α_e), kept within [α_e/4, α_e/2], is tried next (no new CCD query: the segment to α_e is
    crossing-free), until α < ``EXTRAPOLATE_MIN``. The longest trial below φ(1) (and passing the
    Armijo test) is taken. Costs: a CCD query and up to ``EXTRAPOLATE_TRIALS`` energy evaluations.
    Records ``alpha_star`` and, when taken, ``extrapolated`` = α in ``entry``.
    """
    if step is None or step[0] != 1.0 or options.extrapolate <= EXTRAPOLATE_MIN:
        return step
    E1 = step[2]
    c = 2.0 * (E1 - E - slope)
    entry["alpha_star"] = math.inf if c <= 0 else float(-slope / c)
    a = min(options.extrapolate, entry["alpha_star"])
    if np.isfinite(size) and np.isfinite(options.max_step) and size > 0:
        a = min(a, options.max_step / min(size, options.max_step))
    if not a >= EXTRAPOLATE_MIN:
        return step
    if step_limit is not None:
        a *= min(1.0, float(step_limit(x, a * dx)))
    for _ in range(EXTRAPOLATE_TRIALS):
        if not a >= EXTRAPOLATE_MIN:
            break
        x_e = x + a * dx
        E_e = fun(x_e, 0)[0]
        if np.isfinite(E_e) and E_e < E1 and E_e <= E + options.armijo * a * slope:
            entry["extrapolated"] = float(a)
            return a, x_e, E_e
        curvature = 2.0 * (E_e - E - slope * a) / (a * a) if np.isfinite(E_e) else math.inf
        a = min(max(-slope / curvature, 0.25 * a), 0.5 * a) if curvature > 0 else 0.5 * a
    return step


def chord_step(
    fun: Problem,
    x: np.ndarray,
    E: float,
    g: np.ndarray,
    factor: Callable[[np.ndarray], np.ndarray],
    free: np.ndarray,
    options: NewtonOptions,
    step_norm: Callable[[np.ndarray], float] | None,
    step_limit: Callable[[np.ndarray, np.ndarray], float] | None,
    entry: dict,
    max_size: float = math.nan,
) -> tuple[float, np.ndarray, float] | None:
    """A chord step dx = −H_k⁻¹·g(x) on a kept factorisation, capped and bounded as a Newton step; None if it
    is no descent direction, is within ``step_tol`` (only a Newton step may end the iteration), is larger than
    ``max_size`` (the kept factorisation no longer models the energy here) or finds no α.
    Records ``chord``, ``step``, ``alpha0``, ``alpha`` and ``step_energy`` in ``entry``."""
    gf = g[free]
    try:
        with np.errstate(all="ignore"):
            dx_f = np.atleast_1d(np.asarray(factor(-gf), dtype=np.float64))
    except (RuntimeError, np.linalg.LinAlgError, NumericalError, ValueError):
        return None
    slope = float(gf @ dx_f) if np.all(np.isfinite(dx_f)) else math.nan
    if not (np.isfinite(slope) and slope < 0):
        return None
    dx = np.zeros_like(x)
    dx[free] = dx_f
    size = (
        step_norm(dx)
        if step_norm is not None and (np.isfinite(options.max_step) or options.step_tol > 0)
        else math.nan
    )
    if options.step_tol > 0 and np.isfinite(size) and size <= options.step_tol:
        return None
    if np.isfinite(size) and np.isfinite(max_size) and size > max_size:
        return None
    dx, slope, alpha0 = capped_step(x, dx, slope, size, options, step_limit)
    step = line_search(fun, x, E, g, dx, slope, options, free, alpha0) if alpha0 > 0 else None
    step = extrapolated(fun, x, E, dx, slope, size, step, options, step_limit, entry)
    if step is None:
        return None
    entry["chord"] = True
    if np.isfinite(size):
        entry["step"] = step_ratio(size, options)
    entry.update(alpha0=alpha0, alpha=step[0], step_energy=float(step[2]))
    return step


def report_iteration(
    on_iteration: Callable[[dict], None] | None, history: Sequence[dict], t_start: float
) -> None:
    """Close the last history entry (its wall time since ``t_start``) and pass a copy to ``on_iteration``."""
    history[-1]["wall_s"] = time.perf_counter() - t_start
    if on_iteration is not None:
        on_iteration(dict(history[-1]))


def step_ratio(size: float, options: NewtonOptions) -> float:
    """A Newton step's size for the history: over the cap when there is one, else as is."""
    return size / options.max_step if np.isfinite(options.max_step) else size


def newton_failure(message: str, history: Sequence[dict]) -> NumericalError:
    """A NumericalError that carries the whole iteration history as ``error.history``."""
    err = NumericalError(message)
    err.history = tuple(history)
    return err


def line_search(
    fun: Problem,
    x: np.ndarray,
    E: float,
    g: np.ndarray,
    dx: np.ndarray,
    slope: float,
    options: NewtonOptions,
    free: np.ndarray | None = None,
    alpha0: float = 1.0,
) -> tuple[float, np.ndarray, float] | None:
    """Backtracking Armijo search on E from α = ``alpha0``, then (if no step lowers E) a residual-decrease
    fallback.

    Near round-off level a step that lowers |g| is accepted directly. The fallback tries
    α = α0, α0/2, … (``options.residual_backtracks`` values) and accepts the first admissible one with
    |g_f(x + α dx)|₂ ≤ (1 − c·α)|g_f(x)|₂, c = ``options.armijo``.
    """
    alpha = alpha0
    g_norm = float(np.linalg.norm(g))
    for _ in range(options.max_backtracks):
        x_new = x + alpha * dx
        E_new = fun(x_new, 0)[0]
        if np.isfinite(E_new):
            if E_new <= E + options.armijo * alpha * slope:
                return alpha, x_new, E_new
            # the energy change is below round-off: judge the step by the gradient instead
            if abs(alpha * slope) < 1e-12 * max(abs(E), 1e-300) * 1e3:
                g_new = fun(x_new, 1)[1]
                if np.linalg.norm(g_new) < g_norm:
                    return alpha, x_new, E_new
        alpha *= 0.5
    mask = slice(None) if free is None else free
    gf_norm = float(np.linalg.norm(g[mask]))
    alpha = alpha0
    for _ in range(options.residual_backtracks):
        x_new = x + alpha * dx
        E_new, g_new, _, _ = fun(x_new, 1)
        if np.isfinite(E_new) and g_new is not None and np.all(np.isfinite(g_new[mask])):
            if float(np.linalg.norm(g_new[mask])) <= (1.0 - options.armijo * alpha) * gf_norm:
                return alpha, x_new, E_new
        alpha *= 0.5
    return None
