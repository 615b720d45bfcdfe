"""The iteration of :func:`knitframe.numerics.newton.minimise`: its state and one step at a time.

:class:`Minimiser` holds what one call of ``minimise`` carries from iteration to iteration (the
iterate and its evaluation, the Levenberg shift, the projection switch, the kept factorisation
of the chord steps and their back-off) and splits an iteration into its stages: the convergence
tests, a chord step, the Newton step under rising shifts and the move to the new iterate. The
method, its options and the equations are described in :mod:`knitframe.numerics.newton`; the
line search and its refinements are in :mod:`knitframe.numerics.newton_steps`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp

from knitframe.errors import NumericalError
from knitframe.numerics.newton_options import NewtonOptions, Problem
from knitframe.numerics.newton_steps import (
    CHORD_SIZE_FACTOR,
    STALL_FACTOR,
    capped_step,
    chord_step,
    diag_scale,
    extrapolated,
    halved_reversal,
    history_summary,
    line_search,
    newton_failure,
    report_iteration,
    step_ratio,
)

__all__ = ["Minimiser", "free_block"]


def free_block(H: sp.spmatrix, free: np.ndarray, fmt: str = "csc") -> sp.spmatrix:
    """The free–free block ``H[free][:, free]`` of a sparse Hessian, in the format ``fmt`` ("csr" or "csc").

    Entry for entry (order of the stored entries included) what ``H[free][:, free].tocsc()`` and its
    conversion back to CSR give, without the conversions a solver does not need: a CSR ``H`` with sorted
    indices keeps them sorted under the row and column selection, so its CSR block is returned as
    sliced; otherwise it goes through CSC as before.
    """
    free = np.asarray(free, bool)
    Hf = sp.csr_matrix(H)[free][:, free]
    if fmt == "csc":
        return Hf.tocsc()
    if fmt != "csr":
        raise ValueError(f"free_block: format must be 'csr' or 'csc', got {fmt!r}")
    if H.format == "csr" and H.has_sorted_indices:
        Hf.has_sorted_indices = True
        return Hf
    return Hf.tocsc().tocsr()


def solver_format(solve: Callable[..., Any], n: int) -> str:
    """The sparse format a linear solver takes its n × n matrices in: its ``matrix_format(n)`` when it
    offers one ("csr" or "csc"), else "csc"."""
    fmt = getattr(solve, "matrix_format", None)
    return fmt(n) if callable(fmt) else "csc"


#: a converged state: x, E, g, the iteration count, the history and the last info
Converged = tuple[np.ndarray, float, np.ndarray, int, tuple[dict, ...], dict]

#: the chord rule's clock: the work of an evaluation of the problem (by order: energy, gradient, Hessian), of
#: a factorisation and of a solve (back-substitution, refined), in gradient evaluations. Chord steps continue
#: while they lower E per unit of this work at least as fast as the Newton step before them. A count, not
#: wall seconds, so that the path (and the result) does not depend on the machine's load. Measured on the
#: volumetric cell (jersey cotton SL12, seed r, all effects, one step 0 -> 5 %, medians, relative to a
#: gradient): P1 (2 589 free unknowns, SuperLU) energy 0.84, Hessian 7.3, factorisation 3.0, solve 0.08;
#: P2 (14 253, PARDISO) energy 1.9 (its line-search trials include most broad-phase searches), Hessian 4.2,
#: factorisation 5.3, solve 2.4 (PARDISO with its refinement: the linear solver's time less the
#: factorisations', per solve). A Newton iteration's fixed work (Hessian, factorisation, solve) is 11 here
#: against 10.5 (P1) and 11.9 (P2) measured, a chord step's (gradient, solve) 3 against 1.1 and 3.4: the
#: weights follow the P2 cell, where the chord steps' time matters.
WORK_COST: dict[int | str, float] = {0: 1.0, 1: 1.0, 2: 4.0, "factorisation": 5.0, "solve": 2.0}


class Minimiser:
    """The state of one :func:`minimise` call: the iterate, its evaluation, the shift and the chord steps.

    :meth:`iterate` runs the iterations; each is a record of the iterate (:meth:`_record`), the
    convergence tests (:meth:`_converged`, :meth:`_check_stall`), a chord step where one is due
    (:meth:`_chord_iteration`) or a Newton step (:meth:`_newton_step`: Levenberg shifts
    :meth:`_shifted_step` until a step is accepted), and the move to the new iterate (:meth:`_advance`).
    """

    def __init__(
        self,
        fun: Problem,
        x0: np.ndarray,
        free: np.ndarray,
        solve: Callable[[Any, np.ndarray], np.ndarray],
        options: NewtonOptions,
        stabilise: Callable[[dict], bool] | None,
        step_norm: Callable[[np.ndarray], float] | None,
        step_limit: Callable[[np.ndarray, np.ndarray], float] | None,
        on_iteration: Callable[[dict], None] | None,
    ):
        """The state at x0 (its evaluation; NumericalError if inadmissible); the arguments are
        :func:`~knitframe.numerics.newton.minimise`'s."""
        self.solve, self.options = solve, options
        # the chord rule's clock: work done, counted in energy evaluations (WORK_COST), not wall seconds
        self.work = 0.0
        self.work_start = 0.0
        self.problem = fun
        self.fun = self._counted
        self.stabilise, self.step_norm, self.step_limit = stabilise, step_norm, step_limit
        self.on_iteration = on_iteration
        self.x = np.array(x0, dtype=np.float64, copy=True)
        self.free = free = np.asarray(free, bool)
        self.projecting = options.projection == "always" or (
            options.projection == "adaptive" and options.start_projected
        )
        self._start_work()
        self.E, self.g, self.H, self.info = self.evaluate(self.x)
        if not np.isfinite(self.E):
            raise NumericalError(
                f"Newton: the starting state is inadmissible (energy {self.E}); "
                f"{self.info.get('diagnostic', '')}".strip()
            )
        r0 = float(np.max(np.abs(self.g[free]), initial=0.0))
        self.tol = max(options.atol, options.rtol * r0)
        self.history: list[dict] = []
        self.shift_rel = 0.0
        self.x_start = self.x.copy()
        self.measure = (
            step_norm if step_norm is not None else (lambda d: float(np.max(np.abs(d[free]), initial=0.0)))
        )
        self.correction = math.inf
        # the largest shift: the max_shift_increases-th value of 0, 1e-8, 1e-7, … (a shift carried over from
        # the last iteration starts higher, and without this cap iterations that each needed the largest shift
        # ratcheted it up to 1e6 × the diagonal: steps too short to matter, dozens of line searches each)
        self.max_shift = 1e-8 * 10.0 ** max(options.max_shift_increases - 1, 0)
        # chord steps: the last Newton iteration's factorisation, kept while it pays (options.chord)
        self.factorize = getattr(solve, "factorize", None) if options.chord else None
        self.kept = None
        self.chord_next = False
        self.newton_rate = 0.0
        self.newton_size = math.nan
        self.last_size = math.nan  # the last Newton step's size (options.chord_full)
        self.n_chord = self.n_chord_total = 0
        self.refused = self.skip = 0  # first chord steps refused in a row, and chord starts still to skip
        self.last_move = None  # the last accepted move x_new − x (options.halve_reversals)

    def _counted(self, x: np.ndarray, order: int, **kwargs) -> tuple[float, Any, Any, dict]:
        """The problem's evaluation of ``order`` at x, its cost (:data:`WORK_COST`) added to the work done."""
        self.work += WORK_COST[order]
        return self.problem(x, order, **kwargs)

    def _start_work(self) -> None:
        """Start the work count of the next iteration (as ``t_it`` starts its wall time)."""
        self.t_it = time.perf_counter()
        self.work_start = self.work

    def _iteration_work(self) -> float:
        """The work of the iteration just reported, in energy evaluations; also its history's ``work``."""
        work = self.work - self.work_start
        self.history[-1]["work"] = work
        return max(work, 1e-9)

    def evaluate(self, x: np.ndarray) -> tuple[float, Any, Any, dict]:
        """E, g, H and info at x, with the projected Hessian while projecting."""
        return self.fun(x, 2, projected=True) if self.projecting else self.fun(x, 2)

    def release(self) -> None:
        """Free the kept factorisation, if any."""
        if self.kept is not None:
            getattr(self.kept, "free", lambda: None)()
            self.kept = None

    def _result(self, it: int) -> Converged:
        """The converged state at iteration ``it``, after reporting its history entry."""
        self._iteration_work()
        report_iteration(self.on_iteration, self.history, self.t_it)
        return self.x, float(self.E), self.g, it, tuple(self.history), self.info

    def iterate(self) -> Converged:
        """Iterate until converged: ``(x, E, g, iterations, history, info)``; NumericalError (with
        ``history``) when there is no progress or no convergence."""
        options = self.options
        for it in range(options.max_iter * (1 + options.max_chord) + 1):
            res = self._record(it)
            ratio = (
                options.late_flux_rtol
                if options.late_flux_rtol > 0 and it >= options.late_iteration
                else options.flux_rtol
            )
            if self._converged(it, res, ratio):
                return self._result(it)
            if it - self.n_chord_total == options.max_iter:  # chord steps do not count against max_iter
                break
            self._check_stall(it, ratio)
            if self.chord_next and self._chord_iteration():
                continue
            done = self._newton_step(it, res)
            if done is not None:
                return done
        report_iteration(self.on_iteration, self.history, self.t_it)
        raise newton_failure(
            f"Newton: no convergence in {options.max_iter} iterations (residual "
            f"{self.history[-1]['residual']:.3g} > tol {self.tol:.3g}); {history_summary(self.history)}",
            self.history,
        )

    def _record(self, it: int) -> float:
        """Start the history entry of iteration ``it``; its residual max|g_f| (NumericalError if not
        finite)."""
        res = float(np.max(np.abs(self.g[self.free]), initial=0.0))
        if not np.isfinite(res):
            raise NumericalError(
                f"Newton: non-finite gradient at iteration {it}; {history_summary(self.history)}"
            )
        self.history.append({"it": it, "energy": float(self.E), "residual": res, "shift": self.shift_rel})
        for key in ("flux", "active"):
            if key in self.info:
                self.history[-1][key] = float(self.info[key])
        return res

    def _converged(self, it: int, res: float, ratio: float) -> bool:
        """The absolute test res ≤ tol, or the force-flux test at flux ratio ``ratio`` with a small
        correction."""
        if res <= self.tol:
            return True
        if ratio > 0 and it > 0 and res <= ratio * float(self.info.get("flux", 0.0)):
            return self.correction <= self.options.correction_rtol * self.measure(self.x - self.x_start)
        return False

    def _check_stall(self, it: int, ratio: float) -> None:
        """Give up (NumericalError) when no residual of the last ``stall_iterations`` beat the best before."""
        k = self.options.stall_iterations
        if not (k and it >= k):
            return
        history = self.history
        window = [h["residual"] for h in history[-k:]]
        best_before = min(h["residual"] for h in history[:-k])
        target = max(self.tol, ratio * float(self.info.get("flux", 0.0)))
        if min(window) >= best_before and best_before > STALL_FACTOR * target:
            report_iteration(self.on_iteration, history, self.t_it)
            raise newton_failure(
                f"Newton: stalled, no residual below {best_before:.3g} in the last {k} "
                f"iterations (tol {self.tol:.3g}); {history_summary(history)}",
                history,
            )

    def _chord_iteration(self) -> bool:
        """Try a chord step on the kept factorisation; True if taken (the next iterate is evaluated), else
        False with the Hessian evaluated at the iterate for a Newton step."""
        self.chord_next = False
        if self.projecting:  # the kept factorisation is of the projected Hessian
            self.history[-1]["projected"] = True
        self.work += WORK_COST["solve"]
        chord = chord_step(
            self.fun,
            self.x,
            self.E,
            self.g,
            self.kept,
            self.free,
            self.options,
            self.step_norm,
            self.step_limit,
            self.history[-1],
            max_size=CHORD_SIZE_FACTOR * self.newton_size,
        )
        if chord is None and self.n_chord == 0:
            # the first chord step after a Newton step refused: back off, 2^k − 1 chances skipped after
            # the k-th such refusal in a row (stale factors refuse them in streaks, each a wasted gradient)
            self.refused += 1
            self.skip = 2**self.refused - 1
        if chord is None:
            # no chord step (it failed, or it is within step_tol, which only a Newton step may test): the
            # Hessian
            self.E, self.g, self.H, self.info = self.evaluate(self.x)
            return False
        self.refused = 0
        alpha, x_new, E_new = chord
        rate = (self.E - E_new) / self._iteration_work()
        report_iteration(self.on_iteration, self.history, self.t_it)
        self.n_chord += 1
        self.n_chord_total += 1
        self.chord_next = rate >= self.newton_rate and self.n_chord < self.options.max_chord
        self._start_work()
        self.correction = self.measure(x_new - self.x)
        self.last_move = x_new - self.x
        self.x = x_new
        self.E, self.g, self.H, self.info = self.fun(self.x, 1) if self.chord_next else self.evaluate(self.x)
        return True

    def _newton_step(self, it: int, res: float) -> Converged | None:
        """A Newton iteration: the converged result if the step test passes, else None after moving."""
        Hff = self._free_block()
        base = (
            self.options.stabilisation if (self.stabilise is not None and self.stabilise(self.info)) else 0.0
        )
        self.shift_rel = self.shift_rel * 0.1 if self.shift_rel * 0.1 > max(base, 1e-10) else base
        self.shift_rel = min(self.shift_rel, self.max_shift)
        if self.projecting:
            self.history[-1]["projected"] = True
        step = self._shifted_step(it, res, Hff)
        if step is None:  # converged by the step test
            return self._result(it)
        return self._advance(it, *step)

    def _free_block(self) -> sp.spmatrix:
        """The free–free block of the Hessian in the format the linear solver takes (:func:`free_block`)."""
        n = int(np.count_nonzero(self.free))
        return free_block(self.H, self.free, solver_format(self.solve, n))

    def _solve_shifted(self, Hff: sp.spmatrix, gf: np.ndarray, scale: float) -> np.ndarray | None:
        """dx_f = −(H_ff + shift·scale·I)⁻¹·g_f (the factorisation kept for chord steps), None on failure."""
        shift_rel = self.shift_rel
        A = Hff + sp.identity(Hff.shape[0], format=Hff.format) * (shift_rel * scale) if shift_rel > 0 else Hff
        try:
            with np.errstate(all="ignore"):
                self.work += WORK_COST["factorisation"] + WORK_COST["solve"]
                if self.factorize is not None:  # kept for chord steps
                    self.release()
                    self.kept = self.factorize(A)
                    return np.atleast_1d(np.asarray(self.kept(-gf), dtype=np.float64))
                return np.atleast_1d(np.asarray(self.solve(A, -gf), dtype=np.float64))
        except (RuntimeError, np.linalg.LinAlgError, NumericalError, ValueError):
            return None

    def _shifted_step(self, it: int, res: float, Hff: sp.spmatrix) -> tuple | None:
        """Raise the Levenberg shift until a descent step passes the line search.

        Returns ``(alpha, x_new, E_new, dx, size)``, or None when the unshifted step is within
        ``step_tol`` (converged); NumericalError when no shift up to the largest gives a step.
        """
        options, free, x, entry = self.options, self.free, self.x, self.history[-1]
        gf = self.g[free]
        scale = diag_scale(Hff)
        tried = 0.0
        for _ in range(options.max_shift_increases + 2):
            if self.shift_rel > self.max_shift * (1.0 + 1e-9):
                break
            tried = self.shift_rel
            size = math.nan
            dx_f = self._solve_shifted(Hff, gf, scale)
            slope = float(gf @ dx_f) if dx_f is not None and np.all(np.isfinite(dx_f)) else math.nan
            descent = dx_f is not None and np.isfinite(slope) and slope < 0
            if descent:
                dx = np.zeros_like(x)
                dx[free] = dx_f
                if self.step_norm is not None and (np.isfinite(options.max_step) or options.step_tol > 0):
                    size = self.step_norm(dx)
            if (
                options.projection == "adaptive"
                and not self.projecting
                and (not descent or (np.isfinite(size) and size > options.max_step))
            ):
                # the exact Hessian sends the step uphill or far off: projected Newton for the rest of the
                # increment
                self.projecting = True
                entry["projected"] = True
                self.H = self.fun(x, 2, projected=True)[2]
                Hff = self._free_block()
                scale = diag_scale(Hff)
                continue
            if (
                descent
                and options.xtol > 0
                and self.shift_rel == 0.0
                and float(np.max(np.abs(dx_f), initial=0.0)) <= options.xtol
            ):
                # the unshifted Newton step moves no DOF more than xtol: x is the solution to round-off, where
                # the energy no longer orders trial steps and the line search may only creep (taken whole, the
                # step would pass the same test after it)
                entry["xtol"] = True
                return None
            if (
                descent
                and options.step_tol > 0
                and self.shift_rel == 0.0
                and np.isfinite(size)
                and size <= options.step_tol
            ):
                # the Newton step would move nothing by more than step_tol: x is the solution to that accuracy
                # (a projected step is H_p⁻¹g with H_p ⪰ the exact curvature's positive part: IPC's criterion)
                entry["step"] = step_ratio(size, options)
                entry["step_converged"] = True
                return None
            if descent:
                step = self._searched(dx, slope, size)
                if step is _SHIFT:
                    continue
                if step is not None:
                    alpha, x_new, E_new, dx = step
                    return alpha, x_new, E_new, dx, size
            self.shift_rel = max(10.0 * self.shift_rel, 1e-8)
        report_iteration(self.on_iteration, self.history, self.t_it)
        raise newton_failure(
            f"Newton: no descent step at iteration {it} (residual {res:.3g} > tol {self.tol:.3g}, "
            f"shift up to {tried:.2g}); {history_summary(self.history)}",
            self.history,
        )

    def _searched(self, dx: np.ndarray, slope: float, size: float):
        """The step taken along the descent direction dx of size ``size`` and slope g·dx.

        ``(alpha, x_new, E_new, dx)`` with dx as capped, after the line search, the extrapolation and
        (``halve_reversals``) the halving of a reversal; None when the line search finds no α;
        ``_SHIFT`` when dx is over ``cap_shift``·``max_step`` and the shift is raised instead.
        """
        options, entry = self.options, self.history[-1]
        if (
            options.cap_shift
            and np.isfinite(size)
            and size > options.cap_shift * options.max_step
            and max(10.0 * self.shift_rel, 1e-8) <= self.max_shift * (1.0 + 1e-9)
        ):
            # far outside the cap: a near-singular mode dominates dx, and scaling the whole step
            # down would leave the rest of it at nothing; damp that mode with a shift instead
            self.shift_rel = max(10.0 * self.shift_rel, 1e-8)
            return _SHIFT
        if np.isfinite(size):
            entry["step"] = step_ratio(size, options)
        x, fun = self.x, self.fun
        dx, slope, alpha0 = capped_step(x, dx, slope, size, options, self.step_limit)
        entry["alpha0"] = alpha0
        step = (
            line_search(fun, x, self.E, self.g, dx, slope, options, self.free, alpha0) if alpha0 > 0 else None
        )
        step = extrapolated(fun, x, self.E, dx, slope, size, step, options, self.step_limit, entry)
        if options.halve_reversals:
            step = halved_reversal(fun, x, dx, step, self.last_move, self.free, entry)
        return None if step is None else (*step, dx)

    def _advance(
        self, it: int, alpha: float, x_new: np.ndarray, E_new: float, dx: np.ndarray, size: float
    ) -> Converged | None:
        """Move to the accepted Newton step's iterate and evaluate it; the result if the xtol test passes."""
        options, entry = self.options, self.history[-1]
        entry["alpha"] = alpha
        entry["step_energy"] = float(E_new)  # as the line search saw it: the next entry's energy may differ
        # wall_s and work: this iteration's evaluations, factorisations, line search
        work = self._iteration_work()
        report_iteration(self.on_iteration, self.history, self.t_it)
        self._plan_chord(alpha, E_new, size, work)
        self._start_work()
        self.correction = self.measure(x_new - self.x)
        self.last_move = x_new - self.x
        self.x = x_new
        if (
            self.projecting
            and options.projection == "adaptive"
            and np.isfinite(size)
            and size <= options.release_step * options.max_step
        ):
            self.projecting = False  # in the basin: the exact tangent converges quadratically
        self.E, self.g, self.H, self.info = self.fun(self.x, 1) if self.chord_next else self.evaluate(self.x)
        if alpha == 1.0 and self.shift_rel == 0.0 and float(np.max(np.abs(dx), initial=0.0)) <= options.xtol:
            res = float(np.max(np.abs(self.g[self.free]), initial=0.0))
            self.history.append(
                {"it": it + 1, "energy": float(self.E), "residual": res, "shift": 0.0, "xtol": True}
            )
            return self._result(it + 1)
        return None

    def _plan_chord(self, alpha: float, E_new: float, size: float, work: float) -> None:
        """After a Newton step of length α and size ``size`` that took ``work`` (:data:`WORK_COST`): whether
        chord steps follow on its factorisation."""
        options = self.options
        near = options.step_tol > 0 and np.isfinite(size) and size <= CHORD_SIZE_FACTOR * options.step_tol
        if (
            near
            and options.chord_full
            and alpha >= 1.0
            and np.isfinite(self.last_size)
            and self.last_size > 0
        ):
            # a full step: the next Newton step is expected at size·ρ, ρ = this step / the last one (under
            # linear convergence ρ ≈ 1, and a step twice the test is many iterations from passing it)
            near = size * min(1.0, size / self.last_size) <= options.step_tol
        self.last_size = size
        if (
            options.chord
            and self.kept is not None
            and (alpha < 1.0 or options.chord_full)
            and self.shift_rel == 0.0
            and not near
            and not self.history[-1].get("halved")
        ):
            # a shortened step (or with chord_full any step): chord steps on this factorisation while they
            # gain energy at least this fast (not when the step was nearly within step_tol: the next Newton
            # step may end the iteration)
            self.newton_rate = (self.E - E_new) / work
            self.newton_size = size
            self.chord_next, self.n_chord = self.skip == 0, 0
            self.skip = max(self.skip - 1, 0)


#: :meth:`Minimiser._searched`'s answer when the step is over ``cap_shift`` × the cap: raise the shift
_SHIFT = object()
