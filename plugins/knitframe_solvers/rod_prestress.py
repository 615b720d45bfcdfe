"""The rod run's pre-stress: the contact distance grown from where no centerlines overlap to dk.

The phase of :class:`knitframe_solvers.rod_run.RodRun` before the relaxed lattice (the run is
described in :mod:`knitframe_solvers.rod`): with the scene effect ``prestress`` the contact
distance grows geometrically, dk(t) = dk₀ (dk/dk₀)^t, at F̄ = I from a rest shape that is straight
throughout or the knitted shape released to straight (``prestress_start``; ``"auto"`` tries one,
then the other); without it the knitted state must not overlap
(:func:`~knitframe_solvers.rod_model.knitted_overlap`).
"""

from __future__ import annotations

import attrs
import numpy as np

from knitframe.errors import NumericalError
from knitframe.numerics.continuation import continuation
from knitframe.numerics.newton import NewtonResult
from knitframe_solvers.rod_model import knitted_overlap

__all__ = ["RodPrestress"]


class RodPrestress:
    """The pre-stress phase of a rod run, from the nominal start's rest shape (or the start resumed).

    A base of :class:`knitframe_solvers.rod_run.RodRun`, whose state and phases these methods use
    (``state``, ``run``, ``energy``, ``opts``, ``newton_solve``, ``start_total``, …).
    """

    def initial_distance(self, q0: np.ndarray) -> float:
        """Where the pre-stress from state q0 starts: small enough that no two centerlines overlap."""
        self.energy.dk = self.dk_full
        d_min = float(self.energy.pairs(q0).distance.min(initial=self.dk_full))
        return min(self.solver.initial_radius * self.dk_full, 0.95 * d_min)

    def run_prestress(
        self,
        start: str,
        q0: np.ndarray,
        first: int,
        dk0: float,
        n_steps: int,
        label: str | None = None,
        min_fraction: float | None = None,
    ) -> np.ndarray:
        """Grow the contact distance dk0 → dk geometrically at F̄ = I.

        From pre-stress step ``first`` of ``n_steps``.

        With a ``label`` (a start other than the nominal one) the steps are reported as progress
        but neither checkpointed nor written: only the chosen start's relaxed state is.
        """
        energy, dk_full, opts = self.energy, self.dk_full, self.opts
        free = self.base_free.copy()
        free[self.m0 :] = False
        loose = attrs.evolve(opts, atol=1e3 * opts.atol, max_iter=2 * self.solver.max_iterations)
        record = label is None
        if label is None:
            label = "" if self.solver.prestress_start == "straight" else f" ({start} start)"

        def solve_prestress(t: float, x0: np.ndarray) -> NewtonResult:
            energy.dk = dk0 * (dk_full / dk0) ** t
            if start == "knitted":
                energy.kappa0 = (1.0 - t) * self.kappa_knitted
            # the intermediate states are only a path to t = 1; where contacts barely touch, the
            # smooth onset of the law makes Newton converge linearly, so they get a looser tolerance
            return self.newton_solve(x0, free, loose if t < 1.0 - 1e-12 else opts)

        try:
            return self.run.prestress(
                solve_prestress,
                q0,
                first=first,
                n_steps=n_steps,
                min_fraction=min_fraction or self.solver.newton.min_step_fraction,
                label=label,
                record=record,
                follow=continuation,
            )
        except NumericalError as e:
            raise NumericalError(
                f"pre-stress{label} (contact distance {energy.dk:.4g} of {dk_full:.4g} mm): {e}"
            ) from None
        finally:
            energy.kappa0 = None
            energy.dk = dk_full

    def auto_order(self) -> list[str]:
        """The rest shapes ``prestress_start = "auto"`` tries, in order.

        Straight, then knitted; a shear-deformable rod starts knitted, because its directors,
        straight at rest, would first have to turn across whole loops at the first step.
        """
        return ["knitted", "straight"] if self.model.directors is not None else ["straight", "knitted"]

    def prestress_phase(self, q: np.ndarray) -> np.ndarray:
        """Pre-stress (grow the contact distance at F̄ = I and constant yarn length), or check the start."""
        state, notes = self.state, self.run.notes
        if self.with_prestress and state["phase"] == "prestress":
            if state["start"] is not None:  # resuming
                starts = [state["start"]]
            else:
                state["dk0"] = self.initial_distance(q)
                starts = (
                    self.auto_order()
                    if self.solver.prestress_start == "auto"
                    else [self.solver.prestress_start]
                )
            failures: list[str] = []
            for k, start in enumerate(starts):
                state["start"] = start
                try:
                    q = self.run_prestress(
                        start, q, int(state["target"]) + 1, state["dk0"], self.solver.prestress_steps
                    )
                    break
                except NumericalError as e:
                    failures.append(str(e))
                    q, state["target"] = np.zeros(self.model.n_dof), -1
                    if k + 1 < len(starts):
                        continue
                    message = "; after that ".join(failures)
                    if self.start_total() == 1:
                        raise NumericalError(message) from None
                    # the other starts of START_SET are tried before the run gives up (explore_starts)
                    state.update(nominal_error=message, nominal_rests=list(starts), start=starts[0])
                    failures = []
            if failures:
                notes.append(f"{'; '.join(failures)}; converged from the {state['start']} shape instead")
            state.update(phase="load", target=-1)
        elif self.energy.law is not None and state["phase"] == "prestress":
            problem = knitted_overlap(self.energy, q)
            if problem is not None:
                raise NumericalError(problem)
            state.update(phase="load", target=-1)
        return q
