"""Solver ``rod``: discrete elastic rods on the periodic 2x2 unit cell, with yarn-yarn contact.

The fast rung of the accuracy ladder. Each yarn centerline of the pattern's cell is a chain of
straight segments no longer than dk/2 by default (:mod:`knitframe_solvers.rod_model`) with
stretching EA and bending EI from the yarn model (straight rest shape, no twist: see
:mod:`knitframe_solvers.rod_terms`). Yarns touch each other, their periodic images under the
current F̄ and (with ``self_contact``) themselves through a rod contact-law plugin, whose energy
density is integrated over both centerlines (:mod:`knitframe_solvers.rod_contact`) and scaled
so that two parallel yarns have the yarn model's transverse line-contact stiffness
(:func:`rod_stiffness`). F̄ enters through the macro DOFs of :mod:`knitframe.periodic`; the
course and wale tensions per unit width are the macro reactions divided by the cell area.

A run is

1. pre-stress (scene effect ``prestress``): the contact distance grows geometrically from an
   undersized value — small enough that the knitted centerlines do not overlap — to dk, at
   F̄ = I and constant yarn length (rest lengths are those of the geometry). The yarn is
   straight at rest throughout (``prestress_start = "straight"``), or starts stress-free in its
   knitted shape, like the paper's volumetric cell, whose rest curvature is released linearly to
   straight over the same steps (``"knitted"``); ``"auto"`` tries the first and falls back to the
   second. Intermediate steps are solved to 1000× the tolerance (they are a path); the last
   one, at dk with the straight yarn, to the full tolerance;
2. with ``relax``, the course and wale stretches are freed until both tensions vanish: springs
   holding them are released decade by decade, so the cell follows the nearest branch of
   equilibria. The stretches of the load path are measured from this relaxed lattice;
3. the scene's load path: equibiaxial, uniaxial with the other side free (its macro DOF is
   solved for, so its tension is zero) or a general λ1(t), λ2(t), in the scene's steps, each cut
   back adaptively on failure (:func:`knitframe.newton.continuation`); each increment starts
   from the previous state mapped affinely by the change of F̄.

Every step is solved by Newton with an Armijo line search (:func:`knitframe.newton.minimise`);
the rigid modes of yarns that no contact holds yet are stabilised by a Hessian shift, which does
not change the converged state. One node is pinned to remove the cell's free translation.
Every converged step (pre-stress, relaxed lattice, load) is checkpointed with what a resumed
run needs to retrace the same path; the provenance reports the relaxed lattice and its energy.

Stiff yarns in tight cells can be multistable: different pre-stress paths may relax to
different states (compare ``relaxed_energy_Nmm`` and ``relaxed_stretch``).
"""

from __future__ import annotations

import hashlib
import json
import time
import warnings
from pathlib import Path
from typing import Any, ClassVar, Literal

import attrs
import numpy as np
import scipy.sparse as sp

from knitframe.stepfiles import StepSeries
from knitframe.geometry import unit_cell
from knitframe import hookimpl, validators as v
from knitframe.config import instantiate
from knitframe.errors import KnitframeWarning, ConfigError, FieldError, NumericalError
from knitframe.newton import NewtonOptions, StepCheckpoints, continuation, minimise
from knitframe.periodic import macro_index
from knitframe.plugins import get_registry
from knitframe.records import Fabric, Provenance, Response, Scene
from knitframe.yarns import yarn_model

from knitframe_solvers.rod_contact import line_energy
from knitframe_solvers.rod_model import RodEnergy, RodModel, from_cell

__all__ = ["RodSolver", "rod_stiffness", "write_rod_vtu"]

#: decades over which the springs holding the lattice are released in the relaxation
RELAX_DECADES = 6


def rod_stiffness(yarn, registry=None, law=None, line_stiffness: float | None = None) -> dict[str, float]:
    """EA (N), EI (N·mm²) and the contact stiffnesses of a yarn, from its yarn model.

    ``k_line`` (N/mm²) is the yarn model's tangent line-contact stiffness (Hertz line contact
    with the transverse modulus) at the line load that flattens a pair of parallel yarns by 5 %
    of dk, unless ``line_stiffness`` overrides it. Given a rod contact ``law``, its energy
    density φ is scaled so that two parallel yarns reproduce it: ``k_contact`` (N/mm³) makes
    ψ″(0.95 dk) = k_line, with ψ(d) = ∫ φ(√(d² + τ²)) dτ
    (:func:`knitframe_solvers.rod_contact.line_energy`). The core (barrier) of the packed fibres
    gets ``k_core`` (N/mm³), which makes the line stiffness E_axial halfway through the
    barrier's band.
    """
    registry = registry or get_registry()
    model = registry["yarn_model"][yarn.model].from_yarn(yarn)
    if line_stiffness is None:
        f_ref = float(np.asarray(model.contact_load(np.array([0.05 * yarn.dk])))[0])
        line_stiffness = float(np.asarray(model.contact_stiffness(np.array([f_ref])))[0])
    out = {"EA": float(model.EA), "EI": float(model.EI), "k_line": float(line_stiffness)}
    if law is not None:
        dk = yarn.dk
        out["k_contact"] = line_stiffness / line_energy(law, 0.95 * dk, dk, 1.0, 0.0, derivative=2)
        core = float(getattr(law, "core", 0.0))
        y_mid = 0.5 * (core + 0.5 * (1.0 + core))
        out["k_core"] = (float(yarn.E_axial) / line_energy(law, y_mid * dk, dk, 0.0, 1.0, derivative=2)
                         if core > 0 else 0.0)
    return out


def write_rod_vtu(path: Path, model: RodModel, q: np.ndarray, radius: float, cell_data: dict | None = None) -> Path:
    """Deformed centerlines as VTU line cells; segments crossing the cell boundary get their own end point."""
    import meshio

    x = model.positions(q)
    p0, p1 = model.segments(q)
    n = model.n_nodes
    cross = np.any(model.edge_images[:, 1] != 0, axis=1)
    extra = p1[cross]
    pts = np.vstack([x, extra])
    cells = model.edges.copy()
    cells[cross, 1] = n + np.arange(int(cross.sum()))
    yarn = np.concatenate([model.yarn, model.yarn[model.edges[cross, 0]]])
    disp = pts - np.vstack([model.X, model.X[model.edges[cross, 1]]])
    meshio.write(path, meshio.Mesh(
        pts, [("line", cells)],
        point_data={"yarn": yarn.astype(np.float64), "displacement": disp, "radius": np.full(len(pts), radius)},
        cell_data={k: [np.asarray(v_, dtype=np.float64)] for k, v_ in (cell_data or {}).items()},
    ))
    return path


@attrs.frozen
class RodSolver:
    """Discrete elastic rods (EA, EI) on the periodic 2x2 cell with penalty contact and macro DOFs."""

    name: ClassVar[str] = "rod"
    description: ClassVar[str] = "fast unit-cell solver: discrete elastic rods, penalty contact with periodic images"
    effects: ClassVar[frozenset[str]] = frozenset(
        {"large_deformation", "bending", "contact", "self_contact", "friction", "prestress"})
    loads: ClassVar[frozenset[str]] = frozenset({"equibiaxial", "uniaxial-course", "uniaxial-wale", "general"})

    segments_per_stitch: int | None = attrs.field(default=None, validator=v.optional(v.in_range(4, 1000)))  #: rod segments per stitch of yarn; unset: segments no longer than dk/2 (at least 16), -
    linear_solver: str | dict[str, Any] = "direct"  #: linear-solver plugin name or table with ``kind``
    contact_law: str | dict[str, Any] = "rod_penalty"  #: rod contact-law plugin name or table with ``kind``
    prestress_steps: int = attrs.field(default=8, validator=v.in_range(1, 1000))  #: steps growing the contact radius, -
    prestress_start: Literal["auto", "straight", "knitted"] = "auto"  #: yarn rest shape during the pre-stress: straight throughout, or the knitted shape released to straight; "auto" tries straight, then knitted
    initial_radius: float = attrs.field(default=0.7, validator=v.in_range(0.0, 1.0, lo_open=True))  #: largest start of the pre-stress radius / (dk/2), -
    self_contact_exclusion: float = attrs.field(default=np.pi, validator=v.positive)  #: same-strand pairs closer than this × dk along the yarn are neighbours, -
    tolerance: float = attrs.field(default=1e-9, validator=v.positive)  #: Newton residual tolerance / EA, -
    stabilisation: float = attrs.field(default=1e-6, validator=v.non_negative)  #: relative Hessian shift while a strand has no contact, -
    max_step: float = attrs.field(default=0.2, validator=v.positive)  #: largest node move per Newton step / max(current contact distance, dk/2), -
    min_step_fraction: float = attrs.field(default=1.0 / 64, validator=v.in_range(0.0, 1.0, lo_open=True))  #: smallest cut-back increment / load step, -
    max_iterations: int = attrs.field(default=100, validator=v.in_range(1, 10000))  #: Newton iterations per increment, -
    relax: bool = True  #: after pre-stress, let the lattice contract or expand to zero tension and load from there
    on_failure: Literal["raise", "truncate"] = "raise"  #: "truncate" returns the converged steps (converged = false)
    EA: float | None = attrs.field(default=None, validator=v.optional(v.positive))  #: override axial stiffness, N
    EI: float | None = attrs.field(default=None, validator=v.optional(v.positive))  #: override bending stiffness, N·mm²
    contact_stiffness: float | None = attrs.field(default=None, validator=v.optional(v.positive))  #: override the line contact stiffness at 5 % flattening, N/mm²
    contact_quadrature: int = attrs.field(default=4, validator=v.in_range(1, 16))  #: Gauss points per segment (each way) of the contact integral, -

    # ------------------------------------------------------------------------------------- setup
    def validate(self, fabric: Fabric, scene: Scene, registry=None) -> None:
        """The checks that need no geometry, made while the config is validated; ConfigErrors name the key.

        The linear solver and the rod contact law by name with their options (the law even when the
        scene has no contact: a wrong name is wrong either way), the yarn's model with its numbers,
        the stiffness overrides (``EA``, ``EI``, the contact stiffness) within
        :data:`~knitframe.validators.OVERRIDE_FACTOR` of the yarn's own, and, with contact but no
        pre-stress, the knitted cell's overlap (:meth:`knitted_overlap`): everything
        :meth:`simulate` builds or refuses before its first step.
        """
        registry = registry or get_registry()
        instantiate(registry, "linear_solver", self.linear_solver, "solver.linear_solver")
        yarn_model(registry, fabric.yarn)
        law = self.make_contact_law(registry)
        own = rod_stiffness(fabric.yarn, registry)
        try:
            v.near_own("EA", self.EA, own["EA"], "N")
            v.near_own("EI", self.EI, own["EI"], "N·mm²")
            for key, value in (("contact_stiffness", self.contact_stiffness),
                               ("contact_law.stiffness", getattr(law, "stiffness", None))):
                v.near_own(key, value, own["k_line"], "N/mm²")
        except FieldError as e:
            raise ConfigError(f"solver.{e.field}", e.problem) from None
        if "contact" in scene.effects and "prestress" not in scene.effects:
            model, energy, cell = self.setup(fabric, scene, registry)
            problem = self.knitted_overlap(energy, cell, np.zeros(model.n_dof))
            if problem is not None:
                raise ConfigError("scene.effects", problem.removeprefix("rod: "))

    @staticmethod
    def knitted_overlap(energy: RodEnergy, cell: Any, q: np.ndarray) -> str | None:
        """Why state ``q`` cannot start a run without the pre-stress (centerlines inside the contact core), or None."""
        with np.errstate(all="ignore"):
            E0 = energy(q, 0)[0]
        if np.isfinite(E0):
            return None
        d_min = float(energy.pairs(q).distance.min(initial=cell.dk))
        return (f"rod: the knitted centerlines overlap (closest centre distance {d_min:.4g} mm < "
                f"{getattr(energy.law, 'core', 0) * cell.dk:.4g} mm); add 'prestress' to scene.effects")

    def make_contact_law(self, registry=None) -> Any:
        """The rod contact law named by ``contact_law``; ConfigError if it is unknown or not for rods."""
        law = instantiate(registry or get_registry(), "contact_law", self.contact_law, "solver.contact_law")
        if getattr(law, "discretisation", None) != "rod":
            raise ConfigError("solver.contact_law", f"contact law '{law.name}' is for '{law.discretisation}', not rods")
        return law

    def setup(self, fabric: Fabric, scene: Scene, registry=None) -> tuple[RodModel, RodEnergy, Any]:
        """Rod model, energy and unit cell for a fabric and the effects of a scene."""
        registry = registry or get_registry()
        cell = unit_cell(fabric, registry)
        model = from_cell(cell, self.segments(cell))
        law = self.make_contact_law(registry) if "contact" in scene.effects else None
        stiff = rod_stiffness(fabric.yarn, registry, law,
                              line_stiffness=self.contact_stiffness or getattr(law, "stiffness", None))
        energy = RodEnergy(
            model, self.EA or stiff["EA"], self.EI or stiff["EI"], bending="bending" in scene.effects, law=law,
            dk=cell.dk, dk_full=cell.dk, k_contact=stiff.get("k_contact", 0.0), k_core=stiff.get("k_core"),
            self_contact="self_contact" in scene.effects, exclusion=self.self_contact_exclusion * cell.dk,
            friction="friction" in scene.effects, quadrature=self.contact_quadrature, k_line=stiff["k_line"],
        )
        return model, energy, cell

    def segments(self, cell) -> int:
        """Segments per stitch: the option, or the smallest multiple of 4 (at least 16) with segments ≤ dk/2."""
        if self.segments_per_stitch is not None:
            return self.segments_per_stitch
        return max(16, 4 * int(np.ceil(cell.arc_length_per_stitch / (0.5 * cell.dk) / 4.0)))

    def _key(self, fabric: Fabric, scene: Scene) -> str:
        text = json.dumps([fabric.to_dict(), scene.to_dict(), attrs.asdict(self)], sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:24]

    # ---------------------------------------------------------------------------------- simulate
    def simulate(self, fabric: Fabric, scene: Scene, *, progress=None, output_dir: str | Path | None = None,
                 checkpoint_dir: str | Path | None = None) -> Response:
        """Pre-stress (if asked) and follow the scene's load path; returns tensions per unit width.

        Parameters
        ----------
        fabric, scene : the fabric to simulate and what to simulate.
        progress : callable, optional
            ``progress(done, total, message)`` after every converged step.
        output_dir : path, optional
            Where the deformed geometry of every step goes as ``rod-NNNN.vtu`` (plus
            ``rod.pvd``) when the scene's outputs include ``"vtu"``.
        checkpoint_dir : path, optional
            Converged steps are saved there; a later call with the same inputs resumes after
            the last saved step.
        """
        t_start = time.perf_counter()
        registry = get_registry()
        model, energy, cell = self.setup(fabric, scene, registry)
        lat = model.lattice
        n = model.n_nodes
        solve = instantiate(registry, "linear_solver", self.linear_solver, "solver.linear_solver")
        t_load, lam1, lam2 = scene.load.stretches()
        n_load = len(t_load)
        prestress = "prestress" in scene.effects and energy.law is not None
        total = n_load + (self.prestress_steps if prestress else 0) + 1  # + the relaxed lattice
        report = progress or (lambda done, tot, msg: None)
        opts = NewtonOptions(atol=self.tolerance * energy.EA, rtol=1e-10, max_iter=self.max_iterations,
                             stabilisation=self.stabilisation, max_step=self.max_step,
                             xtol=1e-12 * float(np.linalg.norm(lat.L1) + np.linalg.norm(lat.L2)))
        L_max = float(max(np.linalg.norm(lat.L1), np.linalg.norm(lat.L2)))

        def step_norm(dx: np.ndarray) -> float:
            # in units of the current contact distance, which is small early in the pre-stress
            return max(float(np.max(np.linalg.norm(dx[: 3 * n].reshape(-1, 3), axis=1))),
                       float(np.max(np.abs(dx[3 * n:]))) * L_max) / max(energy.dk, 0.5 * cell.dk)

        n_strands = model.n_strands

        def stabilise(info: dict) -> bool:
            return info.get("strands_in_contact", 0) < n_strands

        base_free = np.ones(model.n_dof, bool)
        base_free[:3] = False  # pin node 0: the cell's free translation
        vtu = "vtu" in scene.outputs and output_dir is not None
        ckpt = StepCheckpoints(checkpoint_dir, self._key(fabric, scene)) if checkpoint_dir is not None else None

        def newton(q0: np.ndarray, free: np.ndarray, options: NewtonOptions = opts):
            if energy.friction and energy.law is not None:
                energy.update_lag(q0)
            return minimise(energy, q0, free, solve=solve, options=options, stabilise=stabilise, step_norm=step_norm)

        def relax_lattice(q0: np.ndarray, free: np.ndarray) -> np.ndarray:
            # Springs on the course and wale stretch tie the lattice to where the pre-stress left
            # it and are released in decades: the cell follows the nearest branch of equilibria
            # to zero tension instead of jumping in one long solve to whichever basin it meets.
            idx = 3 * n + np.array([macro_index(0, 0), macro_index(1, 1)])
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
                x = minimise(fun, x, free, solve=solve, options=attrs.evolve(opts, max_iter=4 * self.max_iterations),
                             stabilise=stabilise, step_norm=step_norm).x
            return x

        rows: list[tuple[float, float, float, float]] = []
        q = np.zeros(model.n_dof)
        kappa_knitted = model.curvature(q)
        dk_full = cell.dk
        # what a checkpoint carries besides q and rows, so a resumed run retraces the same path
        state: dict[str, Any] = {"phase": "prestress", "target": -1, "dk": energy.dk, "dk0": None, "lam_ref": None,
                                 "start": None, "relaxed_energy": None}
        step_counter = [0]
        if ckpt is not None and (saved := ckpt.latest()) is not None:
            index, arrays, meta = saved
            q = arrays["q"]
            rows = [tuple(r) for r in arrays["rows"].tolist()]
            state.update({k: meta.get(k) for k in state})
            energy.dk = float(meta["dk"])
            step_counter[0] = index + 1
            ckpt.announce(index, total)
        series = StepSeries(output_dir, "rod", step_counter[0]) if vtu else None
        notes: list[str] = []
        converged = True

        def after(phase: str, index: int, qv: np.ndarray, message: str, done: int) -> None:
            state.update(phase=phase, target=index, dk=energy.dk)
            if series is not None:  # before the checkpoint: every checkpointed step has its file
                series.write(step_counter[0], lambda path: write_rod_vtu(path, model, qv, 0.5 * energy.dk))
            if ckpt is not None:
                ckpt.save(step_counter[0], {"q": qv, "rows": np.array(rows, dtype=np.float64).reshape(-1, 4)}, state)
            step_counter[0] += 1
            report(done, total, message)

        def run_prestress(start: str, q0: np.ndarray, first: int) -> np.ndarray:
            """Grow the contact distance dk0 → dk geometrically at F̄ = I, from pre-stress step ``first``."""
            free = base_free.copy()
            free[3 * n:] = False
            t_first = first / self.prestress_steps
            targets = [k / self.prestress_steps for k in range(first + 1, self.prestress_steps + 1)]
            dk0 = state["dk0"]
            loose = attrs.evolve(opts, atol=1e3 * opts.atol, max_iter=2 * self.max_iterations)
            label = "" if self.prestress_start == "straight" else f" ({start} start)"

            def solve_prestress(t: float, x0: np.ndarray):
                energy.dk = dk0 * (dk_full / dk0) ** t
                if start == "knitted":
                    energy.kappa0 = (1.0 - t) * kappa_knitted
                # the intermediate states are only a path to t = 1; where contacts barely touch, the
                # smooth onset of the law makes Newton converge linearly, so they get a looser tolerance
                return newton(x0, free, loose if t < 1.0 - 1e-12 else opts)

            def on_prestress(i: int, t: float, res) -> None:
                idx = int(round(t * self.prestress_steps)) - 1
                after("prestress", idx, res.x, f"pre-stress{label} {idx + 1}/{self.prestress_steps}", idx + 1)

            try:
                out = continuation(solve_prestress, q0, targets, t0=t_first, min_fraction=self.min_step_fraction,
                                   on_target=on_prestress)
            except NumericalError as e:
                raise NumericalError(f"pre-stress{label} (contact distance {energy.dk:.4g} of {dk_full:.4g} mm): {e}"
                                     ) from None
            finally:
                energy.kappa0 = None
            energy.dk = dk_full
            return out[-1].x if out else q0

        try:
            # ---- pre-stress: grow the contact distance at F̄ = I and constant yarn length
            if prestress and state["phase"] == "prestress":
                if state["start"] is not None:  # resuming
                    starts = [state["start"]]
                else:
                    energy.dk = dk_full
                    d_min = float(energy.pairs(q).distance.min(initial=dk_full))
                    state["dk0"] = min(self.initial_radius * dk_full, 0.95 * d_min)
                    starts = ["straight", "knitted"] if self.prestress_start == "auto" else [self.prestress_start]
                for k, start in enumerate(starts):
                    state["start"] = start
                    try:
                        q = run_prestress(start, q, int(state["target"]) + 1)
                        break
                    except NumericalError as e:
                        if k + 1 == len(starts):
                            raise NumericalError("; after that ".join(notes + [str(e)])) from None
                        notes.append(str(e))
                        q, state["target"] = np.zeros(model.n_dof), -1
                if notes:
                    notes[-1] = f"{notes[-1]}; converged from the knitted shape instead"
                state.update(phase="load", target=-1)
            elif energy.law is not None and state["phase"] == "prestress":
                problem = self.knitted_overlap(energy, cell, q)
                if problem is not None:
                    raise NumericalError(problem)
                state.update(phase="load", target=-1)
            start_index = int(state["target"])

            # ---- relaxation: the course and wale stretches are free (zero tension), shear stays zero
            offset = total - n_load
            if state["lam_ref"] is None:  # the lattice the stretches are measured from
                if self.relax:
                    free = base_free.copy()
                    pres, _ = lat.constraints(None, None)
                    free[3 * n:] = ~pres
                    q = relax_lattice(q, free)
                state["lam_ref"] = [1.0 + q[3 * n + macro_index(0, 0)], 1.0 + q[3 * n + macro_index(1, 1)]]
                state["relaxed_energy"] = float(energy(q, 0)[0])
                after("load", -1, q, "relaxed lattice" if self.relax else "start of the load path", offset)
            lam_ref = state["lam_ref"]

            # ---- load path
            lam1_path = None if lam1 is None else np.concatenate([[1.0], lam1])
            lam2_path = None if lam2 is None else np.concatenate([[1.0], lam2])

            def prescribed(tau: float):
                l1 = None if lam1_path is None else float(np.interp(tau, np.arange(n_load + 1), lam1_path))
                l2 = None if lam2_path is None else float(np.interp(tau, np.arange(n_load + 1), lam2_path))
                return lat.constraints(None if l1 is None else l1 * lam_ref[0], None if l2 is None else l2 * lam_ref[1])

            def solve_load(tau: float, q0: np.ndarray):
                pres, vals = prescribed(tau)
                qs = q0.copy()
                qs[3 * n:][pres] = vals[pres]
                # predictor: carry the cell content along with the lattice (about the pinned node 0)
                A = lat.F(qs[3 * n:]) @ np.linalg.inv(lat.F(q0[3 * n:]))
                x = model.positions(q0)
                qs[: 3 * n] = (x[0] + (x - x[0]) @ A.T - model.X).reshape(-1)
                free = base_free.copy()
                free[3 * n:] = ~pres
                return newton(qs, free)

            def on_load(i: int, tau: float, res) -> None:
                nonlocal q
                q = res.x
                T1, T2 = lat.tensions(res.gradient[3 * n:])
                h = q[3 * n:]
                # stretches relative to the relaxed lattice; tensions per unit relaxed width
                l1, l2 = 1.0 + h[macro_index(0, 0)], 1.0 + h[macro_index(1, 1)]
                rows.append((l1 / lam_ref[0], l2 / lam_ref[1], T1 / lam_ref[1], T2 / lam_ref[0]))
                k = int(round(tau))
                after("load", k - 1, q, f"load step {k}/{n_load}", offset + k)

            first = start_index + 1
            continuation(solve_load, q, list(np.arange(first + 1, n_load + 1, dtype=float)), t0=float(first),
                         min_fraction=self.min_step_fraction, on_target=on_load)
        except NumericalError as e:
            if self.on_failure == "raise" or not rows:
                raise NumericalError(f"rod solver ({fabric.pattern}, {fabric.yarn.name}): {e}") from None
            converged = False
            notes.append(f"stopped after {len(rows)} of {n_load} load steps: {e}")
        arr = np.array(rows, dtype=np.float64).reshape(-1, 4)
        load = scene.load
        jumps = branch_jumps(arr, load)
        for j in jumps:
            message = (f"rod solver ({fabric.pattern}, {fabric.yarn.name}): load step {j['step']} jumped to another "
                       f"equilibrium branch: the free {j['free']} stretch went {j['from']:.3f} -> {j['to']:.3f} while "
                       f"the loaded stretch changed by {j['loaded_change']:.3f}; the curve after it is another state")
            notes.append(message)
            warnings.warn(message, KnitframeWarning, stacklevel=2)
        key = load.response_kind
        size = f"SL{fabric.stitch_length:g}" if fabric.stitch_length is not None else f"{fabric.arc_length:g} mm/stitch"
        prov = Provenance(
            kind="simulation", source=f"rod {fabric.pattern}", solver=self.name,
            mesh=f"{model.n_nodes} nodes, {len(model.edges)} segments ({self.segments(cell)}/stitch)",
            wall_time=time.perf_counter() - t_start, converged=converged, notes="; ".join(notes),
            extra={"EA_N": energy.EA, "EI_Nmm2": energy.EI, "k_line_N_per_mm2": energy.k_line,
                   "dk_mm": cell.dk, "L1_mm": lat.L1.tolist(), "L2_mm": lat.L2.tolist(),
                   "effects": sorted(scene.effects), "options": attrs.asdict(self),
                   "prestress_start": state["start"], "relaxed_stretch": state["lam_ref"], "branch_jumps": jumps,
                   "relaxed_energy_Nmm": state["relaxed_energy"]},
        )
        return Response(arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3], load=key,
                        label=f"rod {fabric.pattern} {size} {fabric.yarn.name}", provenance=prov)


def branch_jumps(rows: np.ndarray, load: Any, *, ratio: float = 3.0, floor: float = 0.02) -> list[dict[str, Any]]:
    r"""Load steps where the free side's stretch jumps: a snap to another equilibrium branch.

    ``rows`` holds (λ1, λ2, T1, T2) per converged load step, from the relaxed lattice (λ = 1).
    Under a uniaxial load a step k is a jump when the free stretch changes by more than ``ratio``
    times the loaded stretch's change and by more than ``floor``:
    :math:`|\Delta\lambda_{free}| > \max(\mathrm{ratio}\,|\Delta\lambda_{load}|, \mathrm{floor})`.
    A smooth lateral contraction stays well below that (knit Poisson ratios are of order one).
    Equibiaxial and general paths have no free side and are not checked here.
    """
    if getattr(load, "kind", None) != "uniaxial" or len(rows) == 0:
        return []
    k_load = 0 if load.direction == "course" else 1
    k_free = 1 - k_load
    lam = np.vstack([[1.0, 1.0], rows[:, :2]])
    d_load = np.abs(np.diff(lam[:, k_load]))
    d_free = np.diff(lam[:, k_free])
    out = []
    for k in np.flatnonzero(np.abs(d_free) > np.maximum(ratio * d_load, floor)):
        out.append({"step": int(k) + 1, "free": "wale" if k_free else "course", "from": float(lam[k, k_free]),
                    "to": float(lam[k + 1, k_free]), "loaded_change": float(d_load[k])})
    return out


@hookimpl
def register_solvers(register):
    register(RodSolver)
