"""One run of the rod solver on the unit-cell run skeleton: pre-stress, starts, relaxed lattice, load path.

:class:`RodRun` is what :meth:`knitframe_solvers.rod.RodSolver.simulate` does (the run is
described there). The steps, checkpoints and resume, VTU files, rows, notes, truncate on failure
and the Response are :class:`knitframe.numerics.cellrun.CellRun`'s; this module supplies the rod
model's phase hooks and what is rod-specific: the pre-stress from its two rest shapes
(:mod:`knitframe_solvers.rod_prestress`), the relaxation of the lattice, the exploration of the
starts (:mod:`knitframe_solvers.rod_starts`), following the branch of a uniaxial path and the
fallback to another start when a load path fails (:mod:`knitframe_solvers.rod_branches`), and
the Response with the rod's provenance (:mod:`knitframe_solvers.rod_report`). This module holds
the run's state, its Newton solves, the relaxation and the load path.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import attrs
import numpy as np
import scipy.sparse as sp

from knitframe import get_registry
from knitframe.config import instantiate
from knitframe.errors import NumericalError
from knitframe.numerics.cellrun import CellRun
from knitframe.numerics.continuation import StepCheckpoints, continuation
from knitframe.numerics.newton import NewtonOptions, NewtonResult, minimise
from knitframe.numerics.periodic import macro_index
from knitframe.records import Fabric, Response, Scene
from knitframe_solvers.rod_branches import CUT_RATIO, is_jump
from knitframe_solvers.rod_geometry import RodModel, write_rod_vtu
from knitframe_solvers.rod_model import RodEnergy
from knitframe_solvers.rod_prestress import RodPrestress
from knitframe_solvers.rod_report import RodReport
from knitframe_solvers.rod_starts import MultiStart

__all__ = ["RodRun", "RodSetup"]

#: decades over which the springs holding the lattice are released in the relaxation
RELAX_DECADES = 6


@attrs.frozen
class RodSetup:
    """What a run takes from its solver, once, before it starts; the run calls nothing of the solver."""

    #: the solver, whose options (its attrs fields, its tuning ``newton``) the run reads
    solver: Any
    #: the rods of the cell (``RodSolver.setup``)
    model: RodModel
    #: their energy
    energy: RodEnergy
    #: the knitted unit cell they discretise
    cell: Any
    #: rod segments per stitch
    segments: int
    #: what identifies the run's checkpoints (None: none are kept)
    key: str | None
    #: when the run began (``time.perf_counter()``), before the set-up
    t_start: float


class RodRun(RodPrestress, MultiStart, RodReport):
    """The state of one :meth:`RodSolver.simulate` call and its phases.

    The phases read the solver's options from ``self.solver`` (its tuning from ``self.solver.newton``).
    """

    def __init__(
        self,
        setup: RodSetup,
        fabric: Fabric,
        scene: Scene,
        *,
        progress=None,
        output_dir: str | Path | None = None,
        checkpoint_dir: str | Path | None = None,
    ):
        registry = get_registry()
        self.solver, self.fabric, self.scene = setup.solver, fabric, scene
        self.model, self.energy, self.cell = model, energy, cell = setup.model, setup.energy, setup.cell
        self.segments = setup.segments
        self.lat = lat = model.lattice
        self.n = model.n_nodes
        #: where the macro DOFs start in q (after the nodes and any directors)
        self.m0 = m0 = 3 * model.n_points
        self.solve = instantiate(registry, "linear_solver", self.solver.linear_solver, "solver.linear_solver")
        self.with_prestress = "prestress" in scene.effects and energy.law is not None
        self.opts = NewtonOptions(
            atol=self.solver.tolerance * energy.EA,
            rtol=1e-10,
            max_iter=self.solver.max_iterations,
            stabilisation=self.solver.newton.stabilisation,
            max_step=self.solver.newton.max_step,
            xtol=1e-12 * float(np.linalg.norm(lat.L1) + np.linalg.norm(lat.L2)),
        )
        self.L_max = float(max(np.linalg.norm(lat.L1), np.linalg.norm(lat.L2)))
        self.l_mean = float(model.l0.mean())
        self.base_free = np.ones(model.n_dof, bool)
        self.base_free[:3] = False  # pin node 0: the cell's free translation
        self.relax_free = self.base_free.copy()
        self.relax_free[m0:] = ~lat.constraints(None, None)[0]
        self.kappa_knitted = model.curvature(np.zeros(model.n_dof))
        self.dk_full = float(energy.dk_full or cell.dk)
        # what a checkpoint carries besides q, rows and the starts' relaxed states, so a resumed run
        # retraces the same path: relaxed_step is the step index of the relaxed lattice (a fallback to
        # another start rewrites the steps from there); snaps are the jumps the load path kept
        self.state: dict[str, Any] = {
            "phase": "prestress",
            "target": -1,
            "dk": energy.dk,
            "dk0": None,
            "lam_ref": None,
            "start": None,
            "relaxed_energy": None,
            "starts": [],
            "start_chosen": None,
            "relaxed_step": None,
            "snaps": [],
            "shear_deg": [],  # the largest shear angle of each load step (with directors)
            "nominal_error": None,  # why the nominal start failed (then the other starts are tried)
            "nominal_rests": [],  # the rest shapes it failed from
        }
        # the relaxed state of every start (row i: state["starts"][i]; NaN where it did not converge)
        self.start_states = np.zeros((0, model.n_dof))
        ckpt = StepCheckpoints(checkpoint_dir, setup.key) if checkpoint_dir is not None else None
        self.run = CellRun(
            self.solver.name,
            fabric,
            scene,
            n_prestress=self.solver.prestress_steps if self.with_prestress else 0,
            extra_steps=1,  # the relaxed lattice
            state=self.state,
            checkpoints=ckpt,
            output_dir=output_dir,
            prefix="rod",
            write_vtu=lambda path, q: write_rod_vtu(path, model, q, 0.5 * energy.dk),
            arrays=lambda: {"starts_q": self.start_states},
            meta=lambda: {"dk": energy.dk},
            progress=progress,
            on_failure=self.solver.on_failure,
            t_start=setup.t_start,
        )
        self.init_load_path()
        self.warn_long_shear_length()

    def init_load_path(self) -> None:
        """The load path's bookkeeping: reference lattice, kept jumps, states, and the branch watch."""
        # the load path: its reference lattice, the jumps it kept (snaps) and the states of this path
        self.lam_ref: list[float] | None = None
        self.snaps: list[dict[str, Any]] = self.state["snaps"]
        self.path_states: list[np.ndarray] = []
        # cut: an increment of this load step was cut back for a jump; last: the last converged (tau, q);
        # lenient: load steps up to this tau may jump (following their branch failed at its fold)
        self.follow: dict[str, Any] = {"cut": False, "last": None, "lenient": -1.0}
        # the free side of a uniaxial path is watched for jumps to another branch (follow_branch)
        self.watch = self.solver.follow_branch and self.scene.load.kind == "uniaxial"
        self.k_load = 0 if self.scene.load.direction == "course" else 1
        loaded_path = self.run.stretch_paths[self.k_load]
        # the smallest increment continuation tries, in loaded stretch
        self.smallest = (
            self.solver.newton.min_step_fraction * float(np.abs(np.diff(loaded_path)).min())
            if self.watch
            else 0.0
        )

    # ---------------------------------------------------------------------------------- the run
    def __call__(self) -> Response:
        """Pre-stress, relax and follow the load path (truncated on failure if asked); the Response."""
        q = np.zeros(self.model.n_dof)
        arrays = self.run.open()
        if arrays is not None:
            q = arrays["q"]
            self.start_states = arrays.get("starts_q", self.start_states)
            self.state["snaps"] = self.state["snaps"] or []
            self.energy.dk = float(self.state["dk"])
        self.snaps = self.state["snaps"]  # jumps left at the smallest load increment
        with self.run.truncating():
            q = self.prestress_phase(q)
            start_index = int(self.state["target"])
            q = self.relax_phase(q)
            self.load_phase(q, start_index)
        return self.response()

    def accept(self, phase: str, index: int, q: np.ndarray, message: str, done: int) -> None:
        if phase == "load":
            self.record_shear(index, q)
        self.run.accept(phase, index, q, message, done)

    # ---------------------------------------------------------------------------------- Newton
    def step_norm(self, dx: np.ndarray) -> float:
        # in units of the current contact distance, which is small early in the pre-stress
        n, m0 = self.n, self.m0
        return max(
            float(np.max(np.linalg.norm(dx[: 3 * n].reshape(-1, 3), axis=1))),
            float(np.max(np.abs(dx[m0:]))) * self.L_max,
            # a director turned by Δd moves the end of its edge by about |Δd|·l0
            float(np.max(np.abs(dx[3 * n : m0]), initial=0.0)) * self.l_mean,
        ) / max(self.energy.dk, 0.5 * self.cell.dk)

    def stabilise(self, info: dict) -> bool:
        return info.get("strands_in_contact", 0) < self.model.n_strands

    def newton_solve(
        self, q0: np.ndarray, free: np.ndarray, options: NewtonOptions | None = None
    ) -> NewtonResult:
        energy = self.energy
        if energy.friction and energy.law is not None:
            energy.update_lag(q0)
        return minimise(
            energy,
            q0,
            free,
            solve=self.solve,
            options=self.opts if options is None else options,
            stabilise=self.stabilise,
            step_norm=self.step_norm,
        )

    # ------------------------------------------------------------------------------- relaxation
    def relax_lattice(self, q0: np.ndarray, free: np.ndarray) -> np.ndarray:
        # Springs on the course and wale stretch tie the lattice to where the pre-stress left
        # it and are released in decades: the cell follows the nearest branch of equilibria
        # to zero tension instead of jumping in one long solve to whichever basin it meets.
        energy = self.energy
        idx = self.m0 + np.array([macro_index(0, 0), macro_index(1, 1)])
        h0 = q0[idx].copy()
        K0 = 10.0 * float(np.abs(energy(q0, 2)[2].diagonal()[idx]).max())
        x = q0
        for K in [K0 * 10.0**-k for k in range(RELAX_DECADES)] + [0.0]:

            def fun(qv: np.ndarray, order: int = 2, K: float = K):
                E, g, H, info = energy(qv, order)
                dh = qv[idx] - h0
                E += 0.5 * K * float(dh @ dh)
                if order >= 1:
                    g = g.copy()
                    g[idx] += K * dh
                if order >= 2:
                    H = H + sp.csr_matrix((np.full(2, K), (idx, idx)), shape=H.shape)
                return E, g, H, info

            x = minimise(
                fun,
                x,
                free,
                solve=self.solve,
                options=attrs.evolve(self.opts, max_iter=4 * self.solver.max_iterations),
                stabilise=self.stabilise,
                step_norm=self.step_norm,
            ).x
        return x

    def relaxed(self, qv: np.ndarray) -> np.ndarray:
        """The state the load path starts from: with ``relax``, the lattice at zero tension."""
        return self.relax_lattice(qv, self.relax_free) if self.solver.relax else qv

    def stretch_of(self, qv: np.ndarray) -> list[float]:
        m0 = self.m0
        return [1.0 + float(qv[m0 + macro_index(0, 0)]), 1.0 + float(qv[m0 + macro_index(1, 1)])]

    def relax_phase(self, q: np.ndarray) -> np.ndarray:
        """The relaxed lattice (course and wale stretches free, shear zero), of the start of lowest energy."""
        state = self.state
        if state["lam_ref"] is None:  # the lattice the stretches are measured from
            if state["nominal_error"] is None:
                try:
                    q = self.relaxed(q)
                except NumericalError as e:
                    if not self.with_prestress or self.start_total() == 1:
                        raise
                    state.update(nominal_error=f"relaxing the lattice: {e}", nominal_rests=[state["start"]])
            if self.with_prestress:
                q = self.explore_starts(None if state["nominal_error"] else q)
            state.update(
                lam_ref=self.stretch_of(q),
                relaxed_energy=float(self.energy(q, 0)[0]),
                relaxed_step=self.run.step,
            )
            message = "relaxed lattice" if self.solver.relax else "start of the load path"
            self.accept("load", -1, q, message, self.run.offset)
        self.lam_ref = state["lam_ref"]
        return q

    # -------------------------------------------------------------------------------- load path
    def prescribed(self, tau: float):
        """The macro DOFs prescribed at τ and their values (stretches of the relaxed lattice)."""
        l1, l2 = self.run.stretches(tau)
        lam_ref = self.lam_ref
        return self.lat.constraints(
            None if l1 is None else l1 * lam_ref[0], None if l2 is None else l2 * lam_ref[1]
        )

    def solve_load(self, tau: float, q0: np.ndarray) -> NewtonResult:
        """The load step at τ from q0: the affine predictor, Newton, and the branch watch."""
        lat, n, m0, model = self.lat, self.n, self.m0, self.model
        pres, vals = self.prescribed(tau)
        qs = q0.copy()
        qs[m0:][pres] = vals[pres]
        # predictor: carry the cell content along with the lattice (about the pinned node 0)
        A = lat.F(qs[m0:]) @ np.linalg.inv(lat.F(q0[m0:]))
        x = model.positions(q0)
        qs[: 3 * n] = (x[0] + (x - x[0]) @ A.T - model.X).reshape(-1)
        if model.directors is not None:  # directors turn with the lattice, keeping their length
            d = model.director_vectors(q0)
            dA = d @ A.T
            dA *= (np.linalg.norm(d, axis=1) / np.linalg.norm(dA, axis=1))[:, None]
            qs[3 * n : m0] = (dA - model.directors).reshape(-1)
        free = self.base_free.copy()
        free[m0:] = ~pres
        res = self.newton_solve(qs, free)
        if self.watch:
            self.watch_branch(tau, q0, res.x)
        self.follow["last"] = (tau, res.x)
        return res

    def watch_branch(self, tau: float, q0: np.ndarray, x: np.ndarray) -> None:
        """Cut back (NumericalError) an increment whose free side jumps, or keep the jump as a snap."""
        k_load, lam_ref = self.k_load, self.lam_ref
        a, b = np.divide(self.stretch_of(q0), lam_ref), np.divide(self.stretch_of(x), lam_ref)
        d_load, d_free = abs(b[k_load] - a[k_load]), b[1 - k_load] - a[1 - k_load]
        if not is_jump(d_load, d_free, CUT_RATIO):
            return
        lenient = tau <= self.follow["lenient"] + 1e-12
        if not lenient and d_load > self.smallest * (1.0 + 1e-6):  # continuation can still halve it
            self.follow["cut"] = True
            raise NumericalError(
                f"the free stretch jumped {a[1 - k_load]:.3f} -> {b[1 - k_load]:.3f} "
                f"over a loaded increment of {d_load:.3g} (another branch)"
            )
        self.snaps.append(
            {
                "loaded": [float(a[k_load]), float(b[k_load])],
                "free": [float(a[1 - k_load]), float(b[1 - k_load])],
                "how": "fold not converged" if lenient else "smallest increment",
            }
        )

    def row(self, tau: float, res: NewtonResult) -> tuple[float, float, float, float]:
        """(λ1, λ2, T1, T2): stretches relative to the relaxed lattice; tensions per unit relaxed width."""
        m0, lam_ref = self.m0, self.lam_ref
        T1, T2 = self.lat.tensions(res.gradient[m0:])
        h = res.x[m0:]
        l1, l2 = 1.0 + h[macro_index(0, 0)], 1.0 + h[macro_index(1, 1)]
        return (l1 / lam_ref[0], l2 / lam_ref[1], T1 / lam_ref[1], T2 / lam_ref[0])

    def on_load_step(self, k: int, res: NewtonResult) -> None:
        self.follow["cut"] = False
        self.path_states.append(res.x)
        self.record_shear(k - 1, res.x)  # before the step is accepted and checkpointed

    def follow_load(self, t_at: float, q_at: np.ndarray) -> None:
        """The load path from load time ``t_at`` and state ``q_at`` to its end; NumericalError if it fails."""
        follow = self.follow
        while True:
            try:
                self.run.load(
                    self.solve_load,
                    q_at,
                    t_at,
                    row=self.row,
                    min_fraction=self.solver.newton.min_step_fraction,
                    on_step=self.on_load_step,
                    follow=continuation,
                )
                return
            except NumericalError:
                last = follow["last"]
                # the branch was followed to its fold, where Newton fails (after a cut-back for a jump,
                # or with no jump seen, the followed branch ending inside the step): from the last
                # converged state this load step may jump (it is flagged with where); once per step
                if not (self.watch and last is not None and follow["lenient"] < np.floor(last[0]) + 1):
                    raise
                t_at, q_at = last
                follow.update(cut=False, lenient=float(np.floor(t_at) + 1))
