"""Newton's method on an energy: the options, the result and the driver's entry point.

Shared by the unit-cell solvers. A problem is a function ``fun(x, order)`` returning
``(E, g, H, info)``: the energy E (N·mm), and for ``order >= 1`` its gradient g (n,), for
``order == 2`` its sparse Hessian H (n, n); ``info`` is a dict of diagnostics (the rod solver
reports the number of active contacts there). An energy of ``inf`` marks an inadmissible state
(for example yarns pushed through a contact barrier); the line search backs off from it.

:func:`minimise` solves g_f(x) = 0 on the free DOFs by Newton steps H_ff·dx = −g_f through a
linear-solver plugin, with

* a backtracking Armijo line search on E: E(x + α dx) ≤ E(x) + c·α·g·dx. Where the energy
  is only piecewise smooth (a contact pairing switches facets inside the step) or flat to
  round-off, no α may pass that test although the step is good; the search then falls back to
  the residual, accepting the longest α with |g_f(x + α dx)|₂ ≤ (1 − c·α)·|g_f(x)|₂ (the
  merit function of residual-based line searches in implicit FE codes);
* a Levenberg shift μ·mean|diag H| added to H_ff when the factorisation fails or dx is not a
  descent direction (μ = 0, 1e-8, 1e-7, … up to 1e-8·10^(k−1), k = ``max_shift_increases``;
  from there the iteration fails), and (the rigid-mode stabilisation) while ``stabilise(info)`` is true.
  Convergence is always tested on the unshifted gradient, so the shift changes the path, not
  the converged answer;
* an optional cap on the step size (``step_norm(dx) <= max_step``), which keeps contacts from
  being jumped over in one step;
* optionally (``projection``), a positive semi-definite Hessian from ``fun(x, 2, projected=True)``
  (the projected Newton method of barrier contact; the volumetric solid projects its tangent at
  every quadrature point). ``"always"`` uses it throughout; ``"adaptive"`` switches to it for the
  rest of the increment when the exact Newton step is not a descent direction or exceeds the cap
  (negative curvature, for example compressed fibres, sends the exact step far off), and back to
  the exact Hessian once a projected step is within ``release_step``·``max_step``, so that the
  last iterations converge quadratically on the exact tangent (with ``start_projected`` an
  increment starts on the projected Hessian);
* optionally (``cap_shift`` = c > 0), a step over c·``max_step`` raises the Levenberg shift and
  is solved again instead of being scaled down whole: where a near-singular mode (a yarn that
  only a few contacts hold) dominates dx, scaling would leave the rest of the step at nothing;
* an optional bound from continuous collision detection (``step_limit(x, dx)``, barrier
  contact): the line search starts from the largest crossing-free fraction α of the step, so
  no iterate passes through a barrier that only acts within a thin layer;
* optionally (``step_tol`` > 0), the step test of barrier-contact solvers (IPC): converged when
  the unshifted Newton step — exact, or projected while the projection is on, which is IPC's own
  test — is a descent direction with ``step_norm(dx)`` ≤ ``step_tol``. Many barrier pairs (stiff,
  each switching in and out of d̂) keep the residual bouncing long after the configuration has
  stopped moving;
* optionally (``chord``), chord steps (modified Newton): where the line search had to shorten a
  Newton step (α < 1: the CCD bound of barrier contact, where many pairs engage and each
  iteration moves only a fraction of the way), the next steps reuse that factorisation,
  dx = −H_k⁻¹·g(x), at the cost of a gradient and a back-substitution instead of a Hessian
  assembly and a factorisation. H_k is positive definite where the Newton step was a descent
  direction, so the chord step is one too; the same CCD bound and line search apply. Chord steps
  go on while their energy decrease per unit of work is at least the last Newton iteration's
  (work: the evaluations, factorisations and solves counted and weighted by
  :data:`knitframe.numerics.newton_driver.WORK_COST`, not wall seconds, so that the path does not
  depend on the machine's load), for at most ``max_chord`` in a row; then, or when a chord step
  fails, is within ``step_tol`` or is over twice the size of that Newton step (the kept
  factorisation no longer models the energy there), the Hessian is evaluated again. With
  ``chord_full`` they also follow full steps (α = 1): where projected Newton converges only linearly
  (its Hessian too stiff along a slow mode), a fresh Hessian buys little over the kept one, and the
  rate rule decides. A full step then
  counts as within reach of the step test when its size times its ratio to the last Newton step's
  (the observed rate) is within ``step_tol``, not at twice ``step_tol``. Where the first chord step after a
  Newton step is refused k times in a row, the next 2^k − 1 chances are skipped (stale factors
  refuse in streaks, and each refusal costs a gradient). A Newton step within twice
  ``step_tol`` starts no chord steps: the next Newton step may pass the step test. Convergence is tested as
  for any iterate, except the step test, which only a Newton step can pass. The linear solver must offer
  ``solve.factorize(A)`` (the ``direct`` plugin does); without it there are no chord steps;
* optionally (``extrapolate`` = a > 1), a longer step where a full step (α = 1) showed the Hessian
  too stiff along it: the minimum α* of the quadratic through E(0), g·dx and E(1), up to a (and
  the cap and the CCD bound), when it lowers E further. Projected Newton near a solution steps
  short along soft modes, and its full steps then converge only linearly;
* optionally (``halve_reversals``), a full step that reverses the last move where it moves most
  is halved when the midpoint's energy is lower: a node group flipping between two states across a
  kink of the energy (friction's stick-slip switch) passes the Armijo test on the rest of the
  step's decrease and would keep the step test from passing;
* optionally (``xtol`` > 0), the round-off test: converged when the unshifted Newton step moves no
  DOF by more than ``xtol``, tested before the line search. At the round-off floor of the gradient
  the energy no longer orders trial steps (differences of order ε·|E|), so a line search would
  only creep, and the order of the floating-point sums in the assembly decides whether it ends;
* besides the absolute test max|g_f| ≤ atol, the force-flux test of implicit FE codes (ABAQUS's
  R_n, C_n): when the problem reports the average nodal force flux q̃ = ``info["flux"]``, an
  iterate with max|g_f| ≤ R_n·q̃ whose last correction c satisfies
  ‖c‖ ≤ C_n·‖x − x_start‖ (both by ``step_norm``, else max-norm on the free DOFs) is
  converged. The residual is then small against the forces the structure carries, and the
  solution no longer moves; a contact energy that is only piecewise smooth can keep the
  absolute residual from falling further. From iteration I_P on the ratio R_P replaces R_n
  (ABAQUS's defaults: R_n = 0.005, C_n = 0.01, R_P = 0.02, I_P = 9);
* an optional early stop (``stall_iterations`` = K): when none of the last K residuals is below
  the smallest one before them, and that is still more than ``STALL_FACTOR`` = 10 times the
  tolerance (the absolute one or R·q̃), the increment is given up at once rather than after
  ``max_iter`` iterations, so that the continuation cuts back sooner (in the spirit of
  ABAQUS's divergence and rate-of-convergence checks).

Failure raises :class:`~knitframe.errors.NumericalError`, never NaN; its ``history`` attribute
holds the whole iteration history. The iteration itself is
:class:`~knitframe.numerics.newton_driver.Minimiser`; the line search and its refinements are in
:mod:`knitframe.numerics.newton_steps`; the records (:class:`NewtonOptions`, :class:`NewtonResult`,
:data:`Problem`) in :mod:`knitframe.numerics.newton_options`, from which this module exports them.
:func:`knitframe.numerics.continuation.continuation` follows a load parameter through targets
with these solves, cutting back on failure.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from knitframe.numerics.newton_driver import Minimiser
from knitframe.numerics.newton_options import NewtonOptions, NewtonResult, Problem

__all__ = ["NewtonOptions", "NewtonResult", "minimise", "Problem"]

#: the options of :func:`minimise` when it is given none
_DEFAULT_OPTIONS = NewtonOptions()


def minimise(
    fun: Problem,
    x0: np.ndarray,
    free: np.ndarray,
    *,
    solve: Callable[[Any, np.ndarray], np.ndarray],
    options: NewtonOptions = _DEFAULT_OPTIONS,
    stabilise: Callable[[dict], bool] | None = None,
    step_norm: Callable[[np.ndarray], float] | None = None,
    step_limit: Callable[[np.ndarray, np.ndarray], float] | None = None,
    on_iteration: Callable[[dict], None] | None = None,
) -> NewtonResult:
    """Minimise the energy of ``fun`` over the DOFs selected by the boolean mask ``free``.

    Parameters
    ----------
    fun : callable
        ``fun(x, order) -> (E, g, H, info)``, see the module docstring.
    x0 : (n,) array
        Start; the fixed DOFs keep their values.
    free : (n,) bool array
    solve : callable
        ``solve(A, b)`` from a linear-solver plugin.
    options : NewtonOptions
    stabilise : callable, optional
        ``stabilise(info) -> bool``: add the relative shift ``options.stabilisation`` to the
        Hessian while true (rigid modes not yet held by contact).
    step_norm : callable, optional
        Size of a full-length step dx (n,), compared with ``options.max_step``.
    step_limit : callable, optional
        ``step_limit(x, dx) -> α_max``: the largest admissible fraction of the step (continuous
        collision detection of barrier contact); the line search starts from min(1, α_max).
    on_iteration : callable, optional
        ``on_iteration(entry)`` with each iteration's history entry as it is completed (after its
        line search, or as the iterate converges or the iteration fails), ``wall_s`` and ``work``
        included: a trace of an increment that is killed or never converges.

    Returns
    -------
    NewtonResult
        Raises NumericalError when the iteration cannot make progress.
    """
    run = Minimiser(fun, x0, free, solve, options, stabilise, step_norm, step_limit, on_iteration)
    try:
        x, E, g, iterations, history, info = run.iterate()
    finally:
        run.release()
    return NewtonResult(x, E, g, iterations, True, history, info)
