"""Newton's method on an energy.

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
  go on while their energy decrease per second of wall time is at least the last Newton
  iteration's, for at most ``max_chord`` in a row; then, or when a chord step fails, is within
  ``step_tol`` or is over twice the size of that Newton step (the kept factorisation no longer
  models the energy there), the Hessian is evaluated again. With ``chord_full`` they also follow full
  steps (α = 1): where projected Newton converges only linearly (its Hessian too stiff along a slow
  mode), a fresh Hessian buys little over the kept one, and the rate rule decides. A full step then
  counts as within reach of the step test when its size times its ratio to the last Newton step's
  (the observed rate) is within ``step_tol``, not at twice ``step_tol``. Where the first chord step after a
  Newton step is refused k times in a row, the next 2^k − 1 chances are skipped (stale factors
  refuse in streaks, and each refusal costs a gradient). A Newton step within twice
  ``step_tol`` starts no chord steps: the next Newton step may pass the step test. Convergence is tested as for any iterate,
  except the step test, which only a Newton step can pass. The linear solver must offer
  ``solve.factorize(A)`` (the ``direct`` plugin does); without it there are no chord steps;
* optionally (``extrapolate`` = a > 1), a longer step where a full step (α = 1) showed the Hessian
  too stiff along it: the minimum α* of the quadratic through E(0), g·dx and E(1), up to a (and
  the cap and the CCD bound), when it lowers E further. Projected Newton near a solution steps
  short along soft modes, and its full steps then converge only linearly;
* optionally (``halve_reversals``), a full step that reverses the last move where it moves most
  is halved when the midpoint's energy is lower: a node group flipping between two states across a
  kink of the energy (friction's stick-slip switch) passes the Armijo test on the rest of the
  step's decrease and would keep the step test from passing;
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
holds the whole iteration history.
:func:`knitframe.numerics.continuation.continuation` follows a load parameter through targets
with these solves, cutting back on failure.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import Any

import attrs
import numpy as np
import scipy.sparse as sp

from knitframe.errors import NumericalError

__all__ = ["NewtonOptions", "NewtonResult", "minimise", "Problem"]

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
    #: also converged when an unshifted full Newton step moves no DOF more than this (round-off floor)
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
    #: −H_k⁻¹·g(x) while they lower E at least as fast per second as that Newton step (needs
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
    #: iterate's evaluation, factorisations, line search)
    history: tuple[dict, ...]
    info: dict


def _diag_scale(A: sp.spmatrix) -> float:
    d = np.abs(A.diagonal())
    return float(d.mean()) if d.size and d.mean() > 0 else 1.0


def _fmt(history: Sequence[dict], last: int = 6) -> str:
    rows = [
        f"it {h['it']}: E={h['energy']:.6g} |g|={h['residual']:.3g} alpha={h.get('alpha', 0):.3g} "
        f"shift={h.get('shift', 0):.2g}"
        for h in history[-last:]
    ]
    return "; ".join(rows)


def minimise(
    fun: Problem,
    x0: np.ndarray,
    free: np.ndarray,
    *,
    solve: Callable[[Any, np.ndarray], np.ndarray],
    options: NewtonOptions = NewtonOptions(),
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
        line search, or as the iterate converges or the iteration fails), ``wall_s`` included: a
        trace of an increment that is killed or never converges.

    Returns
    -------
    NewtonResult
        Raises NumericalError when the iteration cannot make progress.
    """
    x = np.array(x0, dtype=np.float64, copy=True)
    free = np.asarray(free, bool)
    projecting = options.projection == "always" or (
        options.projection == "adaptive" and options.start_projected
    )

    def evaluate(x: np.ndarray) -> tuple[float, Any, Any, dict]:
        return fun(x, 2, projected=True) if projecting else fun(x, 2)

    t_it = time.perf_counter()
    E, g, H, info = evaluate(x)
    if not np.isfinite(E):
        raise NumericalError(
            f"Newton: the starting state is inadmissible (energy {E}); {info.get('diagnostic', '')}".strip()
        )
    r0 = float(np.max(np.abs(g[free]), initial=0.0))
    tol = max(options.atol, options.rtol * r0)
    history: list[dict] = []
    shift_rel = 0.0
    x_start = x.copy()
    measure = step_norm if step_norm is not None else (lambda d: float(np.max(np.abs(d[free]), initial=0.0)))
    correction = math.inf
    # the largest shift: the max_shift_increases-th value of 0, 1e-8, 1e-7, … (a shift carried over from
    # the last iteration starts higher, and without this cap iterations that each needed the largest shift
    # ratcheted it up to 1e6 × the diagonal: steps too short to matter, dozens of line searches each)
    max_shift = 1e-8 * 10.0 ** max(options.max_shift_increases - 1, 0)
    # chord steps: the last Newton iteration's factorisation, kept while it pays (options.chord)
    factorize = getattr(solve, "factorize", None) if options.chord else None
    kept = None
    chord_next = False
    newton_rate = 0.0
    newton_size = math.nan
    last_size = math.nan  # the last Newton step's size (options.chord_full)
    n_chord = n_chord_total = 0
    refused = skip = 0  # first chord steps refused in a row, and chord starts still to skip (back-off)
    last_move = None  # the last accepted move x_new − x (options.halve_reversals)

    def release() -> None:
        nonlocal kept
        if kept is not None:
            getattr(kept, "free", lambda: None)()
            kept = None

    try:
        for it in range(options.max_iter * (1 + options.max_chord) + 1):
            res = float(np.max(np.abs(g[free]), initial=0.0))
            if not np.isfinite(res):
                raise NumericalError(f"Newton: non-finite gradient at iteration {it}; {_fmt(history)}")
            history.append({"it": it, "energy": float(E), "residual": res, "shift": shift_rel})
            for key in ("flux", "active"):
                if key in info:
                    history[-1][key] = float(info[key])
            if res <= tol:
                _report(on_iteration, history, t_it)
                return NewtonResult(x, float(E), g, it, True, tuple(history), info)
            ratio = (
                options.late_flux_rtol
                if options.late_flux_rtol > 0 and it >= options.late_iteration
                else options.flux_rtol
            )
            if ratio > 0 and it > 0 and res <= ratio * float(info.get("flux", 0.0)):
                if correction <= options.correction_rtol * measure(x - x_start):
                    _report(on_iteration, history, t_it)
                    return NewtonResult(x, float(E), g, it, True, tuple(history), info)
            if it - n_chord_total == options.max_iter:  # chord steps do not count against max_iter
                break
            if options.stall_iterations and it >= options.stall_iterations:
                window = [h["residual"] for h in history[-options.stall_iterations :]]
                best_before = min(h["residual"] for h in history[: -options.stall_iterations])
                target = max(tol, ratio * float(info.get("flux", 0.0)))
                if min(window) >= best_before and best_before > STALL_FACTOR * target:
                    _report(on_iteration, history, t_it)
                    raise _failure(
                        f"Newton: stalled, no residual below {best_before:.3g} in the last {options.stall_iterations} "
                        f"iterations (tol {tol:.3g}); {_fmt(history)}",
                        history,
                    )
            if chord_next:
                chord_next = False
                if projecting:  # the kept factorisation is of the projected Hessian
                    history[-1]["projected"] = True
                chord = _chord_step(
                    fun,
                    x,
                    E,
                    g,
                    kept,
                    free,
                    options,
                    step_norm,
                    step_limit,
                    history[-1],
                    max_size=CHORD_SIZE_FACTOR * newton_size,
                )
                if chord is None and n_chord == 0:
                    # the first chord step after a Newton step refused: back off, 2^k − 1 chances skipped after
                    # the k-th such refusal in a row (stale factors refuse them in streaks, each a wasted gradient)
                    refused += 1
                    skip = 2**refused - 1
                if chord is not None:
                    refused = 0
                    alpha, x_new, E_new = chord
                    _report(on_iteration, history, t_it)
                    n_chord += 1
                    n_chord_total += 1
                    rate = (E - E_new) / max(history[-1]["wall_s"], 1e-9)
                    chord_next = rate >= newton_rate and n_chord < options.max_chord
                    t_it = time.perf_counter()
                    correction = measure(x_new - x)
                    last_move = x_new - x
                    x = x_new
                    E, g, H, info = fun(x, 1) if chord_next else evaluate(x)
                    continue
                # no chord step (it failed, or it is within step_tol, which only a Newton step may test): the Hessian
                E, g, H, info = evaluate(x)
            Hff = H[free][:, free].tocsc()
            gf = g[free]
            scale = _diag_scale(Hff)
            base = options.stabilisation if (stabilise is not None and stabilise(info)) else 0.0
            shift_rel = shift_rel * 0.1 if shift_rel * 0.1 > max(base, 1e-10) else base
            shift_rel = min(shift_rel, max_shift)
            accepted = False
            tried = 0.0
            size = math.nan
            if projecting:
                history[-1]["projected"] = True
            for _ in range(options.max_shift_increases + 2):
                if shift_rel > max_shift * (1.0 + 1e-9):
                    break
                tried = shift_rel
                size = math.nan
                A = (
                    Hff + sp.identity(Hff.shape[0], format="csc") * (shift_rel * scale)
                    if shift_rel > 0
                    else Hff
                )
                dx_f = None
                try:
                    with np.errstate(all="ignore"):
                        if factorize is not None:  # kept for chord steps
                            release()
                            kept = factorize(A)
                            dx_f = np.atleast_1d(np.asarray(kept(-gf), dtype=np.float64))
                        else:
                            dx_f = np.atleast_1d(np.asarray(solve(A, -gf), dtype=np.float64))
                except (RuntimeError, np.linalg.LinAlgError, NumericalError, ValueError):
                    dx_f = None
                slope = float(gf @ dx_f) if dx_f is not None and np.all(np.isfinite(dx_f)) else math.nan
                descent = dx_f is not None and np.isfinite(slope) and slope < 0
                if descent:
                    dx = np.zeros_like(x)
                    dx[free] = dx_f
                    if step_norm is not None and (np.isfinite(options.max_step) or options.step_tol > 0):
                        size = step_norm(dx)
                if (
                    options.projection == "adaptive"
                    and not projecting
                    and (not descent or (np.isfinite(size) and size > options.max_step))
                ):
                    # the exact Hessian sends the step uphill or far off: projected Newton for the rest of the increment
                    projecting = True
                    history[-1]["projected"] = True
                    H = fun(x, 2, projected=True)[2]
                    Hff = H[free][:, free].tocsc()
                    scale = _diag_scale(Hff)
                    continue
                if (
                    descent
                    and options.step_tol > 0
                    and shift_rel == 0.0
                    and np.isfinite(size)
                    and size <= options.step_tol
                ):
                    # the Newton step would move nothing by more than step_tol: x is the solution to that accuracy
                    # (a projected step is H_p⁻¹g with H_p ⪰ the exact curvature's positive part: IPC's criterion)
                    history[-1]["step"] = _step_ratio(size, options)
                    history[-1]["step_converged"] = True
                    _report(on_iteration, history, t_it)
                    return NewtonResult(x, float(E), g, it, True, tuple(history), info)
                if descent:
                    if (
                        options.cap_shift
                        and np.isfinite(size)
                        and size > options.cap_shift * options.max_step
                        and max(10.0 * shift_rel, 1e-8) <= max_shift * (1.0 + 1e-9)
                    ):
                        # far outside the cap: a near-singular mode dominates dx, and scaling the whole step
                        # down would leave the rest of it at nothing; damp that mode with a shift instead
                        shift_rel = max(10.0 * shift_rel, 1e-8)
                        continue
                    if np.isfinite(size):
                        history[-1]["step"] = _step_ratio(size, options)
                    dx, slope, alpha0 = _capped(x, dx, slope, size, options, step_limit)
                    history[-1]["alpha0"] = alpha0
                    step = (
                        _line_search(fun, x, E, g, dx, slope, options, free, alpha0) if alpha0 > 0 else None
                    )
                    step = _extrapolated(fun, x, E, dx, slope, size, step, options, step_limit, history[-1])
                    if options.halve_reversals:
                        step = _halved_reversal(fun, x, dx, step, last_move, free, history[-1])
                    if step is not None:
                        alpha, x_new, E_new = step
                        accepted = True
                        break
                shift_rel = max(10.0 * shift_rel, 1e-8)
            if not accepted:
                _report(on_iteration, history, t_it)
                raise _failure(
                    f"Newton: no descent step at iteration {it} (residual {res:.3g} > tol {tol:.3g}, shift up to "
                    f"{tried:.2g}); {_fmt(history)}",
                    history,
                )
            history[-1]["alpha"] = alpha
            history[-1]["step_energy"] = float(
                E_new
            )  # as the line search saw it: the next entry's energy may differ
            _report(
                on_iteration, history, t_it
            )  # wall_s: this iteration's evaluations, factorisations, line search
            near = options.step_tol > 0 and np.isfinite(size) and size <= CHORD_SIZE_FACTOR * options.step_tol
            if near and options.chord_full and alpha >= 1.0 and np.isfinite(last_size) and last_size > 0:
                # a full step: the next Newton step is expected at size·ρ, ρ = this step / the last one (under
                # linear convergence ρ ≈ 1, and a step twice the test is many iterations from passing it)
                near = size * min(1.0, size / last_size) <= options.step_tol
            last_size = size
            if (
                options.chord
                and kept is not None
                and (alpha < 1.0 or options.chord_full)
                and shift_rel == 0.0
                and not near
                and not history[-1].get("halved")
            ):
                # a shortened step (or with chord_full any step): chord steps on this factorisation while they gain
                # energy at least this fast (not when the step was nearly within step_tol: the next Newton step
                # may end the iteration)
                newton_rate = (E - E_new) / max(history[-1]["wall_s"], 1e-9)
                newton_size = size
                chord_next, n_chord = skip == 0, 0
                skip = max(skip - 1, 0)
            t_it = time.perf_counter()
            correction = measure(x_new - x)
            last_move = x_new - x
            x = x_new
            if (
                projecting
                and options.projection == "adaptive"
                and np.isfinite(size)
                and size <= options.release_step * options.max_step
            ):
                projecting = False  # in the basin: the exact tangent converges quadratically
            E, g, H, info = fun(x, 1) if chord_next else evaluate(x)
            if alpha == 1.0 and shift_rel == 0.0 and float(np.max(np.abs(dx), initial=0.0)) <= options.xtol:
                res = float(np.max(np.abs(g[free]), initial=0.0))
                history.append(
                    {"it": it + 1, "energy": float(E), "residual": res, "shift": 0.0, "xtol": True}
                )
                _report(on_iteration, history, t_it)
                return NewtonResult(x, float(E), g, it + 1, True, tuple(history), info)
        _report(on_iteration, history, t_it)
        raise _failure(
            f"Newton: no convergence in {options.max_iter} iterations (residual {history[-1]['residual']:.3g} > "
            f"tol {tol:.3g}); {_fmt(history)}",
            history,
        )
    finally:
        release()


def _capped(
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


def _halved_reversal(
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
    60 nodes moved 0.033 r per step, each step at cos −0.76 to −0.995 to the last, from iteration 13 to 32, while the
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


def _extrapolated(
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
    """The line search's ``step``, or a longer one along dx where the full step's energy says the model was too stiff.

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


def _chord_step(
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
    dx, slope, alpha0 = _capped(x, dx, slope, size, options, step_limit)
    step = _line_search(fun, x, E, g, dx, slope, options, free, alpha0) if alpha0 > 0 else None
    step = _extrapolated(fun, x, E, dx, slope, size, step, options, step_limit, entry)
    if step is None:
        return None
    entry["chord"] = True
    if np.isfinite(size):
        entry["step"] = _step_ratio(size, options)
    entry.update(alpha0=alpha0, alpha=step[0], step_energy=float(step[2]))
    return step


def _report(on_iteration: Callable[[dict], None] | None, history: Sequence[dict], t_start: float) -> None:
    """Close the last history entry (its wall time since ``t_start``) and pass a copy to ``on_iteration``."""
    history[-1]["wall_s"] = time.perf_counter() - t_start
    if on_iteration is not None:
        on_iteration(dict(history[-1]))


def _step_ratio(size: float, options: NewtonOptions) -> float:
    """A Newton step's size for the history: over the cap when there is one, else as is."""
    return size / options.max_step if np.isfinite(options.max_step) else size


#: chord steps: none after a Newton step within this × step_tol, and none larger than this × that Newton step
CHORD_SIZE_FACTOR = 2.0

#: extrapolation (``NewtonOptions.extrapolate``) only to α of at least this: a shorter gain is not worth its evaluation
EXTRAPOLATE_MIN = 1.5
#: a full step whose cosine with the last move (where it moves most) is below this is a reversal
REVERSAL_COS = -0.5
#: energy evaluations of an extrapolation at most
EXTRAPOLATE_TRIALS = 3

#: an iteration counts as stalled only while its best residual is this many times the tolerance
STALL_FACTOR = 10.0


def _failure(message: str, history: Sequence[dict]) -> NumericalError:
    """A NumericalError that carries the whole iteration history as ``error.history``."""
    err = NumericalError(message)
    err.history = tuple(history)
    return err


def _line_search(
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
    """Backtracking Armijo search on E from α = ``alpha0``, then (if no step lowers E) a residual-decrease fallback.

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
