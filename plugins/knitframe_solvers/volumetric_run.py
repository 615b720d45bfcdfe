"""One run of the volumetric solver on the unit-cell run skeleton: radial pre-stress, then the load path.

:class:`VolumetricRun` is what :meth:`knitframe_solvers.volumetric.VolumetricSolver.simulate`
does (the run is described in :mod:`knitframe_solvers.volumetric`). The steps, checkpoints and
resume, VTU files, rows, notes, truncate on failure and the Response are
:class:`knitframe.numerics.cellrun.CellRun`'s; this module supplies the solid model's phase hooks:
the Newton solve with its trace and statistics, the pre-stress growth of the tubes, the load
predictor (affine, or secant) and the rows.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe import get_registry
from knitframe.config import instantiate
from knitframe.errors import NumericalError
from knitframe.numerics.cellrun import CellRun
from knitframe.numerics.continuation import StepCheckpoints
from knitframe.numerics.newton import NewtonOptions, NewtonResult, minimise
from knitframe.numerics.periodic import N_MACRO, macro_index
from knitframe.records import Fabric, Response, Scene
from knitframe_solvers.volumetric_model import VolumetricModel, section_summary, write_solid_vtu

__all__ = ["IMBALANCE_NOTE", "P1_LOCKING", "VolumetricRun", "VolumetricSetup"]

#: a converged state whose residual exceeds this × the average nodal force flux gets a note in the Response's
#: provenance (the step test passed with large forces left: seen on the jammed SL10 cell, 29-800 × the flux;
#: the SL11 P2 r/3 runs end their steps at 0.7-6.6 ×, the coarse P1 run under 0.05 ×)
IMBALANCE_NOTE = 10.0
#: the warning of every P1 run that bends yarns (measured in docs/validation.md, "Is the reference
#: converged?")
P1_LOCKING = (
    "volumetric order 1: linear tetrahedra lock in bending, so a knitted cell's P1 tensions are too high "
    "even at seed r/3; use order = 2 for numbers and P1 only for a quick look"
)


@attrs.frozen
class VolumetricSetup:
    """What a run takes from its solver, once, before it starts; the run calls nothing of the solver."""

    #: the solver, whose options (its attrs fields, its tuning ``newton``) the run reads
    solver: Any
    #: the cell's discrete problem (``VolumetricSolver.setup``)
    model: VolumetricModel
    #: Newton options of the knitted state and the load steps
    opts: NewtonOptions
    #: the looser Newton options of the intermediate pre-stress states
    loose: NewtonOptions
    #: what identifies the run's checkpoints (None: none are kept)
    key: str | None
    #: when the run began (``time.perf_counter()``), before the set-up: its wall time includes the meshing
    t_start: float


class VolumetricRun:
    """The state of one :meth:`VolumetricSolver.simulate` call and its phases.

    The phases read the solver's options from ``self.solver`` (its tuning from ``self.solver.newton``).
    """

    def __init__(
        self,
        setup: VolumetricSetup,
        fabric: Fabric,
        scene: Scene,
        *,
        progress=None,
        output_dir: str | Path | None = None,
        checkpoint_dir: str | Path | None = None,
        trace=None,
    ):
        self.solver, self.fabric, self.scene, self.trace = setup.solver, fabric, scene, trace
        registry = get_registry()
        self.model = model = setup.model
        backend = instantiate(registry, "linear_solver", self.solver.linear_solver, "solver.linear_solver")
        self.solve = self.timed_solver(backend)
        self.with_prestress = "prestress" in scene.effects
        self.r = r = model.cm.radius
        self.opts, self.loose = setup.opts, setup.loose
        self.n_ind = 3 * len(model.independent)
        self.base_free = np.ones(self.n_ind + N_MACRO, bool)
        self.base_free[:3] = False  # pin one node: the cell's free translation
        ckpt = StepCheckpoints(checkpoint_dir, setup.key) if checkpoint_dir is not None else None
        self.lat = model.lattice
        self.residuals: list[float] = []
        self.penetrations: list[float] = []
        #: the section ratio det F/|F a| at each full-tolerance state (the end of the pre-stress, the load
        #: steps): phase, stretches, volume-weighted median, 5 % quantile and smallest value
        self.sections: list[dict[str, Any]] = []
        self.shares: list[float] = []
        s0 = 1.0
        if self.with_prestress:
            d_min = model.cm.clearance.minimum if model.cm.clearance is not None else 2.0 * r
            s0 = min(self.solver.initial_radius, 0.95 * d_min / (2.0 * r))
        self.state: dict[str, Any] = {"phase": "prestress", "target": -1, "s0": s0}
        self.run = CellRun(
            self.solver.name,
            fabric,
            scene,
            n_prestress=self.solver.prestress_steps if self.with_prestress else 0,
            state=self.state,
            checkpoints=ckpt,
            output_dir=output_dir,
            prefix="solid",
            write_vtu=self.write_step,
            progress=progress,
            on_failure=self.solver.on_failure,
            t_start=setup.t_start,
        )
        self.path: list[tuple[float, np.ndarray]] = []  # the last two converged load states (τ, q)

    def timed_solver(self, backend: Any) -> Any:
        """The linear solver with its wall time added to the model's ``linear_solve`` time."""
        model = self.model

        def timed(fn, count: bool):
            """fn with its wall time added to the linear-solve time (with ``count``, counted as a solve)."""

            def wrapper(*args):
                t0 = time.perf_counter()
                try:
                    return fn(*args)
                finally:
                    model.timings["linear_solve"] += time.perf_counter() - t0
                    model.evaluations["linear_solves"] += int(count)

            return wrapper

        solve = timed(backend, True)
        # the format the backend takes its matrices in: the Newton driver hands it the Hessian's free block so
        solve.matrix_format = getattr(backend, "matrix_format", None)
        if (
            self.solver.newton.chord
            and model.barrier
            and not model.hold_candidates
            and backend.factorize is not None
        ):
            # chord steps reuse a factorisation: each back-substitution counts as a linear solve, the
            # factorisation's time goes with them
            def factorize(A):
                kept = timed(backend.factorize, False)(A)
                apply = timed(kept, True)
                apply.free = kept.free
                return apply

            solve.factorize = factorize
        return solve

    # ---------------------------------------------------------------------------------- the run
    def __call__(self) -> Response:
        """Pre-stress (if asked) and follow the load path (truncated on failure if asked); the Response."""
        model, state = self.model, self.state
        q = model.shrunk(state["s0"])
        arrays = self.run.open()
        if arrays is not None:
            q = arrays["q"]
            state["s0"] = float(state["s0"])
        if self.solver.order == 1 and "bending" in self.scene.effects:
            self.run.warn(P1_LOCKING, stacklevel=3)
        with self.run.truncating():
            start_index = int(state["target"])
            if state["phase"] == "prestress":
                q = self.prestress_phase(q, start_index) if self.with_prestress else self.check_overlap(q)
                start_index = -1
            model.s = 1.0
            first = start_index + 1
            self.path.append((float(first), q))
            self.run.load(
                self.solve_load,
                q,
                float(first),
                row=self.row,
                min_fraction=self.solver.newton.min_step_fraction,
            )
        return self.response()

    # ---------------------------------------------------------------------------------- Newton
    def step_norm(self, dx: np.ndarray) -> float:
        du = self.model.T @ dx
        return (
            max(float(np.max(np.abs(du))), float(np.max(np.abs(dx[self.n_ind :]))) * self.model.L_max)
            / self.r
        )

    @staticmethod
    def stab_share(res: NewtonResult) -> float:
        """The foundation's share of the increment's energy (ABAQUS compares ALLSD with ALLIE)."""
        e = float(res.info.get("stabilisation_energy", 0.0))
        return e / abs(res.energy) if res.energy else 0.0

    def newton_solve(
        self,
        q0: np.ndarray,
        free: np.ndarray,
        anchor: np.ndarray | None = None,
        options: NewtonOptions | None = None,
        where: tuple[str, float] = ("prestress", 0.0),
        anchored: bool = False,
    ) -> NewtonResult:
        """Newton from q0 on the DOFs ``free``, the foundation anchored at ``anchor`` (default q0); traced."""
        model, trace = self.model, self.trace
        options = self.opts if options is None else options
        if not anchored:
            model.anchor(q0 if anchor is None else anchor)
        t0 = time.perf_counter()
        try:
            res = minimise(
                model,
                q0,
                free,
                solve=self.solve,
                options=options,
                step_norm=self.step_norm,
                step_limit=model.step_limit if model.barrier else None,
                on_iteration=self.iteration_trace(where),
            )
        except NumericalError as e:
            if trace is not None:
                trace(
                    {
                        "record": "solve",
                        "phase": where[0],
                        "t": where[1],
                        "converged": False,
                        "wall_s": time.perf_counter() - t0,
                        "history": list(getattr(e, "history", ())),
                        "diagnostic": str(e),
                    }
                )
            raise
        if trace is not None:
            trace(
                {
                    "record": "solve",
                    "phase": where[0],
                    "t": where[1],
                    "converged": True,
                    "wall_s": time.perf_counter() - t0,
                    "iterations": res.iterations,
                    "history": list(res.history),
                    "max_penetration_over_r": float(res.info.get("max_penetration", 0.0)) / self.r,
                    "stabilisation_share": self.stab_share(res),
                }
            )
        if options is self.opts:
            self.record(res, free, where)
        return res

    def iteration_trace(self, where: tuple[str, float]):
        """``on_iteration`` of a traced solve: a ``record = "iteration"`` per Newton iteration; or None."""
        if self.trace is None:
            return None
        model, trace = self.model, self.trace
        last = model.counters()

        def each(entry: dict) -> None:
            # with the iteration's share of the wall time per part, and its evaluations and linear solves
            now = model.counters()
            split = {k: now[k] - last[k] for k in now}
            last.update(now)
            trace({"record": "iteration", "phase": where[0], "t": where[1], **entry, **split})

        return each

    def record(self, res: NewtonResult, free: np.ndarray, where: tuple[str, float]) -> None:
        """The statistics of a converged state at full tolerance (residual, penetration, stabilisation)."""
        self.shares.append(self.stab_share(res))
        self.residuals.append(float(np.max(np.abs(res.gradient[free]), initial=0.0)))
        flux = float(res.info.get("flux", 0.0))
        if flux > 0 and self.residuals[-1] > IMBALANCE_NOTE * flux:
            # the step test (a Newton step under step_tolerance) can pass where barrier pairs deep inside
            # d̂ make the Hessian so stiff that a tiny step leaves forces far above the flux: say so
            self.run.notes.append(
                f"{where[0]} {where[1]:g} converged with a residual of "
                f"{self.residuals[-1]:.3g} N, {self.residuals[-1] / flux:.3g} × the force flux "
                "(its tensions carry that imbalance)"
            )
        self.penetrations.append(float(res.info.get("max_penetration", 0.0)))
        # full-tolerance states only: the end of the pre-stress (s = 1, where the section ratio is the
        # elastic one the barrier limits) and the load steps
        model = self.model
        hm = res.x[self.n_ind :]
        self.sections.append(
            {
                "phase": where[0],
                "lambda1": 1.0 + float(hm[macro_index(0, 0)]),
                "lambda2": 1.0 + float(hm[macro_index(1, 1)]),
                **section_summary(model.forms, model.T @ res.x),
            }
        )

    # ------------------------------------------------------------------------------- pre-stress
    def prestress_phase(self, q: np.ndarray, start_index: int) -> np.ndarray:
        """Grow the tubes from radius s₀·r to r (s = s₀ + t (1 − s₀)) at F̄ = I, after pre-stress step
        ``start_index``; the last state."""
        model, s0, n = self.model, self.state["s0"], self.solver.prestress_steps
        free = self.base_free.copy()
        free[self.n_ind :] = False
        # the radius factor of the last converged state (not of a failed try)
        s_done = [s0 + (start_index + 1) / n * (1.0 - s0)]

        def solve_prestress(t: float, q0: np.ndarray) -> NewtonResult:
            s_new = s0 + t * (1.0 - s0)
            q1 = model.grow(q0, s_done[0], s_new)
            res = self.newton_solve(
                q1,
                free,
                anchor=q0,
                options=self.loose if t < 1.0 - 1e-12 else self.opts,
                where=("prestress", t),
            )
            s_done[0] = s_new
            return res

        if start_index < 0:  # equilibrium of the shrunk state (curvature makes it not quite stress-free)
            model.s = s0
            q = self.newton_solve(q, free, options=self.loose).x
        return self.run.prestress(
            solve_prestress, q, first=start_index + 1, min_fraction=self.solver.newton.min_step_fraction
        )

    def check_overlap(self, q: np.ndarray) -> np.ndarray:
        """Without the pre-stress, the knitted yarns must not overlap (NumericalError); q as it is."""
        r, clear = self.r, self.model.cm.clearance
        overlap = 0.0 if clear is None or self.model.law is None else 2.0 * r - clear.minimum
        if overlap > 0.02 * r:
            raise NumericalError(
                f"volumetric: the knitted yarns overlap by {overlap:.3g} mm (centerlines "
                f"{clear.minimum:.4g} mm apart, dk = {2 * r:.4g} mm); add 'prestress' to scene.effects"
            )
        return q

    # -------------------------------------------------------------------------------- load path
    def fluctuation(self, qv: np.ndarray) -> np.ndarray:
        """w = u − (F̄ − I)·X of the independent nodes."""
        n_ind = self.n_ind
        return qv[:n_ind] - self.lat.affine(self.model.X_ind, qv[n_ind:]).ravel()

    def solve_load(self, tau: float, q0: np.ndarray) -> NewtonResult:
        """The load step at τ from q0: the predictor, then Newton anchored at q0."""
        pres, vals = self.lat.constraints(*self.run.stretches(tau))
        qs, secant = self.predict(tau, q0, pres, vals)
        free = self.base_free.copy()
        free[self.n_ind :] = ~pres
        # (anchored already when the secant was tried: anchoring again would repeat the friction pairing)
        res = self.newton_solve(qs, free, anchor=q0, where=("load", tau), anchored=secant)
        self.path[:] = [*self.path[-1:], (tau, res.x)]
        return res

    def predict(
        self, tau: float, q0: np.ndarray, pres: np.ndarray, vals: np.ndarray
    ) -> tuple[np.ndarray, bool]:
        """The start of the load step at τ from q0, and whether the secant was tried (model anchored)."""
        model, lat, n_ind, path = self.model, self.lat, self.n_ind, self.path
        qs = q0.copy()
        qs[n_ind:][pres] = vals[pres]
        secant = self.solver.newton.predictor == "secant" and len(path) == 2 and path[-1][1] is q0
        if secant:
            # the free macro DOFs (a free side's contraction) extrapolated from the last two converged states
            (t_prev, q_prev), (t_now, _) = path
            ratio = (tau - t_now) / (t_now - t_prev)
            qs[n_ind:][~pres] += ratio * (q0[n_ind:] - q_prev[n_ind:])[~pres]
        if model.barrier:
            # predictor: the whole current configuration mapped by F̄_new·F̄_old⁻¹ (with the images):
            # an affine map keeps a configuration free of crossings, as a barrier needs
            M = lat.F(qs[n_ind:]) @ np.linalg.inv(lat.F(q0[n_ind:])) - np.eye(3)
            x_ind = model.X_ind + q0[:n_ind].reshape(-1, 3)
            qs[:n_ind] += (x_ind @ M.T).ravel()
        else:
            # predictor: the affine increment (F̄ − I)·X of the macro step on every node
            qs[:n_ind] += lat.affine(model.X_ind, qs[n_ind:] - q0[n_ind:]).ravel()
        if secant:
            # and the yarns' fluctuation, w ≈ w_n + ratio·(w_n − w_{n−1}); with a barrier only 0.9 of its
            # crossing-free part. It is a guess: taken (or half of it, a quarter, …) only where it admits
            # no inverted element and lowers the energy below the affine start's, else the affine start
            dq = np.zeros_like(qs)
            dq[:n_ind] = ratio * (self.fluctuation(q0) - self.fluctuation(q_prev))
            dq = model.crossing_free(qs, dq)
            model.anchor(q0)
            e_affine = model(qs, 0)[0]
            for _ in range(4):
                if model(qs + dq, 0)[0] < e_affine:
                    qs += dq
                    break
                dq *= 0.5
        return qs, secant

    def row(self, tau: float, res: NewtonResult) -> tuple[float, float, float, float]:
        """(λ1, λ2, T1, T2) of a converged load step: the macro stretches and the tensions per unit width."""
        T1, T2 = self.lat.tensions(res.gradient[self.n_ind :])
        hm = res.x[self.n_ind :]
        return (1.0 + hm[macro_index(0, 0)], 1.0 + hm[macro_index(1, 1)], T1, T2)

    def write_step(self, path: Path, qv: np.ndarray) -> None:
        """The VTU file of state qv, with its contact pressure."""
        model = self.model
        _, _, _, info = model(qv, 0)
        write_solid_vtu(
            path, model.forms, model.T @ qv, model.s, info.get("pressure", np.zeros(model.cm.n_nodes))
        )

    # --------------------------------------------------------------------------------- response
    def response(self) -> Response:
        """The Response, with the volumetric run's provenance (timings, residuals, penetration, …)."""
        fabric, model, lat, r = self.fabric, self.model, self.lat, self.r
        tightest = min((sec["min"] for sec in self.sections), default=1.0)
        if tightest < fabric.yarn.compaction:
            self.run.notes.append(
                f"the yarn was compacted to {tightest:.3g} of its section, past its limit "
                f"J_min = {fabric.yarn.compaction:.3g}"
            )
        sl = fabric.stitch_length if fabric.stitch_length is not None else fabric.arc_length
        return self.run.response(
            source=f"volumetric {fabric.pattern}",
            mesh=model.cm.summary(),
            label=f"volumetric {fabric.pattern} SL{sl:g} {fabric.yarn.name}",
            extra={
                "timings_s": {k: round(v_, 3) for k, v_ in model.timings.items()},
                "newton_evaluations": model.evaluations,
                "tolerance_N": self.opts.atol,
                "max_final_residual_N": max(self.residuals, default=0.0),
                "max_penetration_over_r": max(self.penetrations, default=0.0) / r,
                "max_stabilisation_share": max(self.shares, default=0.0),
                "min_section_ratio": tightest,
                "section_ratio": self.sections,
                "compaction_limit": fabric.yarn.compaction,
                "prestress_start_radius_over_r": self.state["s0"],
                "penalty_N_per_mm3": model.stiffness,
                "dk_mm": model.cell.dk,
                "L1_mm": lat.L1.tolist(),
                "L2_mm": lat.L2.tolist(),
                "effects": sorted(self.scene.effects),
                "options": attrs.asdict(self.solver),
            },
        )
