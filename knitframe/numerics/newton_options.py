"""The options, the result and the problem of Newton's method (:func:`knitframe.numerics.newton.minimise`).

The records the iteration (:mod:`knitframe.numerics.newton_driver`) and its steps
(:mod:`knitframe.numerics.newton_steps`) read; :mod:`knitframe.numerics.newton` describes the
method, each option's role and the equations, and is where callers import them from.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import attrs
import numpy as np

__all__ = ["NewtonOptions", "NewtonResult", "Problem"]

#: ``fun(x, order) -> (E, g | None, H | None, info)``
Problem = Callable[[np.ndarray, int], tuple[float, Any, Any, dict]]


@attrs.frozen
class NewtonOptions:
    """Tolerances and safeguards of :func:`minimise`."""

    #: absolute tolerance on max |g_free|, in the units of the gradient (N)
    atol: float = 1e-9
    #: tolerance relative to max |g_free| at the start
    rtol: float = 1e-9
    max_iter: int = 60
    #: sufficient-decrease constant c
    armijo: float = 1e-4
    max_backtracks: int = 40
    #: trials of the residual-decrease fallback when no step lowers the energy (0: off)
    residual_backtracks: int = 6
    #: relative Hessian shift while stabilise(info) is true
    stabilisation: float = 1e-6
    max_shift_increases: int = 12
    #: cap on step_norm(dx)
    max_step: float = math.inf
    #: also converged when the unshifted Newton step (before the line search) moves no DOF more than this
    #: (the round-off floor, where energy differences no longer order trial steps)
    xtol: float = 0.0
    #: R_n: also converged when max|g_f| ≤ R_n·q̃, q̃ = info["flux"] (0: off)
    flux_rtol: float = 0.0
    #: C_n: ... and the last correction ≤ C_n × the increment's largest displacement
    correction_rtol: float = 1e-2
    #: R_P: the flux ratio from iteration ``late_iteration`` on (0: R_n throughout)
    late_flux_rtol: float = 0.0
    #: I_P: iterations after which R_P replaces R_n
    late_iteration: int = 9
    #: give up when the smallest residual has not improved in this many iterations (0: off)
    stall_iterations: int = 0
    #: raise the Levenberg shift (instead of scaling the step) while step_norm(dx) > this × max_step (0: off)
    cap_shift: float = 0.0
    #: Hessian: exact ("off"), PSD-projected ("always", fun(x, 2, projected=True)) or projected while exact
    #: steps fail ("adaptive")
    projection: str = attrs.field(
        default="off", validator=attrs.validators.in_(("off", "adaptive", "always"))
    )
    #: also converged when an unshifted Newton step (exact, or projected while projecting) has step_norm(dx) ≤
    #: this (IPC's criterion; 0: off)
    step_tol: float = 0.0
    #: "adaptive": back to the exact Hessian after a projected step ≤ this × max_step
    release_step: float = 0.5
    #: "adaptive": start on the projected Hessian (saves the exact factorisation of a first step that would
    #: fail)
    start_projected: bool = False
    #: after a Newton step the line search shortened (α < 1), reuse its factorisation for chord steps
    #: −H_k⁻¹·g(x) while they lower E at least as fast per unit of counted work as that Newton step (needs
    #: ``solve.factorize``)
    chord: bool = False
    #: with ``chord``, chord steps also after a full Newton step (α = 1): where full steps converge only
    #: linearly (a Hessian too stiff along a slow mode) a chord step gains about as much for a gradient and a
    #: back-substitution
    chord_full: bool = False
    #: chord steps in a row at most before the Hessian is evaluated and factorised again
    max_chord: int = 12
    #: a full Newton step that reverses the last one where it moves most (a 2-cycle across a kink of the
    #: energy, e.g. friction's stick-slip switch) is halved when that lowers E further
    halve_reversals: bool = False
    #: after a full step (α = 1) the energy's curvature along it says the model was too stiff: try α up to
    #: this, at the minimum of the quadratic through E(0), g·dx and E(1) (1: off)
    extrapolate: float = 1.0


@attrs.frozen
class NewtonResult:
    """Outcome of :func:`minimise`."""

    x: np.ndarray
    energy: float
    gradient: np.ndarray
    iterations: int
    converged: bool
    #: per iteration: energy, residual, alpha, shift, step_energy (E at the accepted step, as the line search
    #: evaluated it), step (size of the Newton step / max_step, before the cap; the size itself without a
    #: cap), alpha0 (the line search's first α: 1 or the CCD bound), wall_s (the iteration's wall time: its
    #: iterate's evaluation, factorisations, line search), work (the same counted and weighted by
    #: ``newton_driver.WORK_COST``, in gradient evaluations: what the chord rule compares)
    history: tuple[dict, ...]
    info: dict
