"""Solver ``volumetric``: the paper's ABAQUS unit-cell model rebuilt on scikit-fem.

The high-fidelity rung of the accuracy ladder. Every yarn of the pattern's periodic 2x2 cell is
a swept tetrahedral tube (:mod:`knitframe.numerics.mesh`, P1 or isoparametric P2, seed r/3 by default)
made of the yarn model's hyperelastic law in total-Lagrangian large deformation, with the fibre
along the centerline (:mod:`knitframe_solvers.volumetric_material`). Yarns touch each other,
their periodic images under the current F̄ and (with ``self_contact``) distant parts of
themselves through a solid contact-law plugin: ``ipc`` (the default: barrier contact that admits
no interpenetration, the Newton line search bounded by continuous collision detection; it always
includes self-contact), ``mortar`` or ``penalty`` (penalty contact on signed gaps). With the
scene effect ``friction`` the contact pairs of the start of each increment are frozen (normal
force, master material point or tangent basis) and the law adds its regularised Coulomb
friction on the slip from there.

Periodicity is the shared macro-DOF mechanism of :mod:`knitframe.numerics.periodic`: the end faces of
each yarn at the course boundary are images of the start faces of their paired yarn,
u_end = u_start + (F̄ − I)·L1, folded into u = T·[u_independent, h]. The reaction conjugate to the
macro DOFs h divided by the cell area gives the course and wale tensions per unit width.

A run is

1. pre-stress (scene effect ``prestress``): the yarns start shrunk across the fibre to radius
   s₀·r — small enough that the knitted tubes do not overlap — and an eigenstrain
   Fθ = I + (s − 1)(I − a⊗a) with s growing from s₀ to 1 restores the knitted diameter dk at
   constant length, against contact (this resolves the geometry's initial interference);
2. the scene's load path (equibiaxial, uniaxial with a free side, or general) in the scene's
   steps, each cut back adaptively on failure (:func:`knitframe.numerics.newton.continuation`).

Each increment is solved by the shared Newton driver (:func:`knitframe.numerics.newton.minimise`) with a
linear-solver plugin, whose wall time is kept next to the assembly times (provenance
``timings_s``). The yarn's tangent is indefinite where fibres are compressed, so by default
(``tangent = "projected"``) Newton uses the tangent projected to its PSD part at every
quadrature point (IPC's projected Newton), and an iterate whose Newton step moves no node more
than ``step_tolerance``·r is converged (``"adaptive"`` switches between the exact and the
projected tangent; ``"exact"`` keeps the exact one).
Every converged step is checkpointed; a call with the same inputs and checkpoint directory
resumes after the last saved step.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import time
import warnings
from pathlib import Path
from typing import Any, ClassVar, Literal

import attrs
import numpy as np
import scipy.sparse as sp

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.config import instantiate
from knitframe.errors import ConfigError, FieldError, KnitframeWarning, NumericalError
from knitframe.geometry import unit_cell
from knitframe.numerics.contact_search import SegmentTopology
from knitframe.numerics.memory import retain_freed_memory
from knitframe.numerics.newton import NewtonOptions, StepCheckpoints, continuation, minimise
from knitframe.numerics.periodic import N_MACRO, Lattice, macro_index, periodic_transform
from knitframe.numerics.settings import settings_field
from knitframe.numerics.solid_contact import SolidSurface
from knitframe.numerics.stepfiles import StepSeries
from knitframe.plugins import get_registry
from knitframe.records import Fabric, Provenance, Response, Scene
from knitframe.yarns import yarn_model
from knitframe_solvers.newton_settings import VolumetricNewton
from knitframe_solvers.volumetric_material import SolidForms, YarnLaw

__all__ = ["VolumetricSolver", "contact_surface", "write_solid_vtu"]

#: a converged state whose residual exceeds this × the average nodal force flux gets a note in the Response's
#: provenance (the step test passed with large forces left: seen on the jammed SL10 cell, 29-800 × the flux;
#: the SL11 P2 r/3 runs end their steps at 0.7-6.6 ×, the coarse P1 run under 0.05 ×)
IMBALANCE_NOTE = 10.0
#: the warning of every P1 run that bends yarns (measured in docs/validation.md, "Is the reference converged?")
P1_LOCKING = (
    "volumetric order 1: linear tetrahedra lock in bending, so a knitted cell's P1 tensions are several "
    "times too high even at seed r/3; use order = 2 for numbers and P1 only for a quick look"
)


def contact_surface(cm: Any, lattice: Lattice | None, exclusion: float | None = None) -> SolidSurface:
    """Two-pass contact surface of a cell mesh: every lateral facet is both slave and master.

    Nodes get the strand bookkeeping of their yarn (position in its strand, arc unrolled along
    the strand), so pairs closer than ``exclusion`` (default π·dk) along one strand copy — a
    tube's own cross-section — are not contacts.
    """
    n_y = len(cm.names)
    nxt = {int(cm.node_body[end[0]]): int(cm.node_body[start[0]]) for end, start, _ in cm.end_pairs}
    periodic = len(nxt) == n_y
    st, seen = [], set()
    for i in range(n_y):  # strands: cycles of the end pairs (a handful of yarns)
        if i in seen:
            continue
        cyc = [i]
        while periodic and nxt[cyc[-1]] != i:
            cyc.append(nxt[cyc[-1]])
        seen.update(cyc)
        st.append(cyc)
    strand_of, pos, offset = np.zeros(n_y, np.int64), np.zeros(n_y, np.int64), np.zeros(n_y)
    cycle, length = np.zeros(len(st), np.int64), np.zeros(len(st))
    for k, cyc in enumerate(st):
        acc = 0.0
        for p, i in enumerate(cyc):
            strand_of[i], pos[i], offset[i] = k, p, acc
            acc += cm.lengths[i]
        cycle[k], length[k] = (len(cyc) if periodic else 0), acc
    b = cm.node_body
    topo = SegmentTopology(strand_of[b], pos[b], offset[b] + cm.node_arc, cycle, length)
    excl = np.pi * 2.0 * cm.radius if exclusion is None else float(exclusion)
    all_f = np.arange(len(cm.surface))
    # the tubes' end nodes stand for their matched start nodes: the seams are continued by the images
    identify = np.arange(cm.n_nodes)
    for end, start, _ in cm.end_pairs:
        identify[end] = start
    return SolidSurface.build(cm.nodes, cm.surface, all_f, all_f, topo, excl, lattice, identify)


def write_solid_vtu(path: Path, forms: SolidForms, u: np.ndarray, s: float, pressure: np.ndarray) -> Path:
    """VTU of the deformed solid: displacement and contact pressure (points), max principal stress (cells).

    The maximum principal Cauchy stress σ = J⁻¹ P Fᵀ (MPa) is averaged over each element's
    quadrature points. P2 meshes are written as VTK quadratic tetrahedra (same node order as
    scikit-fem's P2 element).
    """
    import meshio

    mesh = forms.mesh
    X = (mesh.doflocs if forms.edofs.shape[0] == 10 else mesh.p).T
    F = forms.deformation_gradient(u)
    P = forms.stress(u, s)
    J = np.linalg.det(np.moveaxis(F, (0, 1), (-2, -1)))
    sigma = np.einsum("iJeq,kJeq->ikeq", P, F) / J
    w = forms.dx / forms.dx.sum(axis=1, keepdims=True)
    sig_e = np.einsum("ikeq,eq->eik", sigma, w)
    smax = np.linalg.eigvalsh(0.5 * (sig_e + np.swapaxes(sig_e, 1, 2)))[:, -1]
    cell_type = "tetra10" if forms.edofs.shape[0] == 10 else "tetra"
    out = meshio.Mesh(
        X,
        [(cell_type, forms.edofs.T)],
        point_data={"displacement": u.reshape(-1, 3), "contact_pressure": pressure},
        cell_data={
            "max_principal_stress": [smax],
            "yarn": [np.asarray(getattr(forms, "element_body", np.zeros(len(smax))))],
        },
    )
    out.write(str(path))
    return Path(path)


@attrs.frozen
class VolumetricSolver:
    """Tetrahedral yarn solids (P1/P2) on the periodic 2x2 cell with solid contact and macro DOFs."""

    name: ClassVar[str] = "volumetric"
    description: ClassVar[str] = (
        "paper-fidelity unit-cell solver: P2 tetrahedral yarn solids, solid contact, pre-stress"
    )
    effects: ClassVar[frozenset[str]] = frozenset(
        {"large_deformation", "bending", "contact", "self_contact", "friction", "prestress", "anisotropy"}
    )
    loads: ClassVar[frozenset[str]] = frozenset(
        {"equibiaxial", "uniaxial-course", "uniaxial-wale", "general"}
    )

    #: polynomial order of the tetrahedra (1 or 2), -
    order: int = attrs.field(default=2, validator=v.in_range(1, 2))
    #: element size / yarn radius, -
    seed: float = attrs.field(default=1.0 / 3.0, validator=v.in_range(0.05, 1.5))
    #: solid contact-law plugin name or table with ``kind`` (ipc: barrier, the default; mortar, penalty), -
    contact_law: str | dict[str, Any] = "ipc"
    #: linear-solver plugin name or table with ``kind``
    linear_solver: str | dict[str, Any] = "direct"
    #: modulus scaling the penalty, MPa; default the yarn's E_transverse
    contact_modulus: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: same-strand pairs closer than this × dk along the yarn are the yarn itself (the ipc law: all pairs
    #: within 0.75 × this, none beyond it), -
    self_contact_exclusion: float = attrs.field(default=np.pi, validator=v.positive)
    #: steps of the radial pre-stress, -
    prestress_steps: int = attrs.field(default=8, validator=v.in_range(1, 1000))
    #: largest start radius of the pre-stress / r, -
    initial_radius: float = attrs.field(default=0.9, validator=v.in_range(0.05, 1.0))
    #: with pre-stress, closest centerline distance / r below which a cell is refused (the pre-stress starts
    #: at 0.95 of half of it; without pre-stress the limit is r), -
    min_clearance: float = attrs.field(default=0.25, validator=v.in_range(0.05, 2.0))
    #: Newton residual tolerance (largest nodal force) / (E_transverse r²), -
    tolerance: float = attrs.field(default=1e-3, validator=v.positive)
    #: also converged when the exact Newton step moves no node more than this × r (IPC's test; 0: off), -
    step_tolerance: float = attrs.field(default=0.01, validator=v.non_negative)
    #: Newton iterations per increment (default 40; 200 with barrier contact, whose CCD-bounded steps are
    #: short while contacts engage), -
    max_iterations: int | None = attrs.field(default=None, validator=v.optional(v.in_range(1, 10000)))
    #: quadrature order of the solid (2: 4 points), -
    intorder: int = attrs.field(default=2, validator=v.in_range(1, 6))
    #: "truncate" returns the converged steps (converged = false)
    on_failure: Literal["raise", "truncate"] = "raise"
    #: Newton and contact-search tuning: a preset ("default", "robust", "fast") or a table of keys, optionally
    #: with ``preset`` (see ``[solver.newton]`` of volumetric below)
    newton: str | dict[str, Any] = settings_field(VolumetricNewton)

    def _key(self, fabric: Fabric, scene: Scene, law: Any = None) -> str:
        """Checkpoint key: the inputs, the solver options and the resolved contact law (its defaults included)."""
        resolved = None if law is None else [type(law).__name__, attrs.asdict(law)]
        text = json.dumps(
            [fabric.to_dict(), scene.to_dict(), attrs.asdict(self), resolved], sort_keys=True, default=str
        )
        return hashlib.sha256(text.encode()).hexdigest()[:24]

    def setup(self, fabric: Fabric, scene: Scene, registry=None) -> VolumetricModel:
        """Mesh, material forms, periodic map and contact of a fabric's cell for the effects of a scene."""
        from knitframe.numerics.mesh import cell_mesh

        registry = registry or get_registry()
        cell = unit_cell(fabric, registry)
        t0 = time.perf_counter()
        # with the pre-stress the yarns start shrunk apart (radius s₀·r below half the closest centerline
        # distance), so centerlines closer than r (tight stitches) can be meshed and grown into contact
        limit = self.min_clearance * 0.5 * cell.dk if "prestress" in scene.effects else None
        cm = cell_mesh(cell, seed=self.seed, order=self.order, min_distance=limit)
        t_mesh = time.perf_counter() - t0
        forms = SolidForms(
            cm.mesh,
            YarnLaw.from_yarn(fabric.yarn, registry),
            cm.node_tangent,
            intorder=self.intorder,
            node_offset=cm.node_offset,
        )
        forms.element_body = cm.element_body
        forms.projection = self.newton.eigenvalue_filter
        lattice = Lattice(cell.L1, cell.L2)
        slave = np.concatenate([e for e, _, _ in cm.end_pairs])
        master = np.concatenate([s for _, s, _ in cm.end_pairs])
        images = np.tile([1, 0], (len(slave), 1))
        T, independent = periodic_transform(cm.n_nodes, slave, master, images, lattice)
        law, surface = None, None
        if "contact" in scene.effects:
            law = self.make_contact_law(registry)
            surface = contact_surface(cm, lattice, self.self_contact_exclusion * cell.dk)
            if "self_contact" not in scene.effects:
                surface = attrs.evolve(surface, exclusion=np.inf)
        modulus = self.contact_modulus or fabric.yarn.E_transverse
        h = self.seed * cm.radius
        stiffness = law.penalty(modulus, h) if law is not None else 0.0
        vol = float(forms.dx.sum())
        damping = self.newton.stabilisation * fabric.yarn.E_transverse / h**2 * vol / cm.n_nodes
        model = VolumetricModel(
            cell,
            cm,
            forms,
            lattice,
            T.tocsr(),
            independent,
            law,
            surface,
            stiffness,
            self.newton.reach * cm.radius,
            t_mesh,
            damping,
        )
        model.friction = law is not None and "friction" in scene.effects
        model.barrier = law is not None and hasattr(law, "step_limit")
        model.hold_candidates = self.holds_candidates(law)
        return model

    def validate(self, fabric: Fabric, scene: Scene, registry=None) -> None:
        """The checks that need no mesh, made while the config is validated; ConfigErrors name the key.

        The linear solver and the solid contact law by name with their options (the law even when
        the scene has no contact: a wrong name is wrong either way), the yarn's model with its
        numbers, ``max_step`` against the contact reach, ``contact_modulus`` and the law's penalty
        within :data:`~knitframe.validators.OVERRIDE_FACTOR` of the yarn's transverse modulus and of
        the law's default penalty for this yarn and seed, and the cell's clearance
        (:meth:`check_clearance`): everything :meth:`simulate` builds or refuses before its first step.
        """
        registry = registry or get_registry()
        instantiate(registry, "linear_solver", self.linear_solver, "solver.linear_solver")
        yarn_model(registry, fabric.yarn)
        law = self.make_contact_law(registry)
        self.holds_candidates(law if "contact" in scene.effects else None)
        try:
            v.near_own("contact_modulus", self.contact_modulus, fabric.yarn.E_transverse, "MPa")
            if hasattr(
                law, "penalty"
            ):  # the penalty the run will use, against the law's default for this yarn
                h = self.seed * 0.5 * fabric.yarn.dk
                key = "stiffness" if getattr(law, "stiffness", None) is not None else "factor"
                v.near_own(
                    f"contact_law.{key}",
                    law.penalty(self.contact_modulus or fabric.yarn.E_transverse, h),
                    type(law)().penalty(fabric.yarn.E_transverse, h),
                    "N/mm³ penalty",
                )
        except FieldError as e:
            raise ConfigError(f"solver.{e.field}", e.problem) from None
        self.check_law_reach(law, scene)
        self.check_clearance(unit_cell(fabric, registry), scene)

    def check_clearance(self, cell: Any, scene: Scene) -> None:
        """Refuse a knitted cell whose closest centerlines the mesh or the first step cannot take (ConfigError).

        With the pre-stress the tubes start shrunk, and centerlines closer than ``min_clearance``·r
        cross (``solver.min_clearance``); without it the knitted yarns must not overlap by more than
        2 % of r with contact (the run would start interpenetrated) nor come closer than r without
        (``scene.effects``). The same limits :meth:`setup` and :meth:`simulate` apply, found before
        anything is meshed.
        """
        from knitframe.geometry import clearance

        r = 0.5 * cell.dk
        clear = clearance(cell).minimum
        if "prestress" in scene.effects:
            if clear < self.min_clearance * r:
                raise ConfigError(
                    "solver.min_clearance",
                    f"the knitted centerlines come {clear:.4g} mm close, under "
                    f"min_clearance × r = {self.min_clearance * r:.4g} mm: the tubes cross; loosen the "
                    "stitch or lower min_clearance",
                )
        elif "contact" in scene.effects and 2.0 * r - clear > 0.02 * r:
            raise ConfigError(
                "scene.effects",
                f"the knitted yarns overlap by {2.0 * r - clear:.3g} mm (centerlines "
                f"{clear:.4g} mm apart, dk = {2 * r:.4g} mm); add 'prestress' to scene.effects",
            )
        elif clear < r:
            raise ConfigError(
                "scene.effects",
                f"the knitted centerlines come {clear:.4g} mm close, under the yarn "
                f"radius {r:.4g} mm: the tubes cross; add 'contact' and 'prestress' to scene.effects",
            )

    def check_law_reach(self, law: Any, scene: Scene) -> None:
        """Refuse, before any work, a load path past what a signed-gap law has been seen to finish.

        ``penalty`` and ``mortar`` measure a signed gap to a smoothed master surface; on knitted
        cells its pairing switches where yarns slide, and no run has finished past 10 % strain
        (the paths stall between 13 and 23 %; docs/validation.md). ``ipc`` has no such limit.
        """
        limit = getattr(law, "finishes_strain", None)
        if limit is None or "contact" not in scene.effects:
            return
        _, lam1, lam2 = scene.load.stretches()
        top = max(float(np.max(np.abs(np.asarray(x) - 1.0))) for x in (lam1, lam2) if x is not None)
        if top > limit + 1e-12:
            raise ConfigError(
                "solver.contact_law",
                f"'{law.name}' does not finish knitted cells past {100 * limit:g} % strain (the load "
                f"reaches {100 * top:.3g} %): use contact_law = 'ipc' (the default), or a shorter load path",
            )

    def make_contact_law(self, registry=None) -> Any:
        """The solid contact law named by ``contact_law``; ConfigError if it is unknown or not for solids."""
        law = instantiate(registry or get_registry(), "contact_law", self.contact_law, "solver.contact_law")
        if getattr(law, "discretisation", None) != "solid":
            raise ConfigError(
                "solver.contact_law",
                f"contact law '{law.name}' is for '{law.discretisation}', not solid meshes",
            )
        return law

    def holds_candidates(self, law: Any) -> bool:
        """Whether the contact candidates are held through each Newton iteration's line search.

        They are with ``newton.contact_search = "iteration"`` and a law that takes them; then
        ``newton.max_step`` must be at most half ``newton.reach`` (ConfigError otherwise): two nodes
        each moving max_step could close a gap wider than the reach within one step.
        """
        held = (
            self.newton.contact_search == "iteration"
            and law is not None
            and "candidates" in inspect.signature(law.evaluate).parameters
        )
        if held and self.newton.max_step > 0.5 * self.newton.reach:
            raise ConfigError(
                "solver.newton.max_step",
                f"{self.newton.max_step:g} is more than half the contact reach "
                f"({self.newton.reach:g}): with contact_search = 'iteration' a step could bring an unseen "
                "pair into contact; lower max_step or use contact_search = 'evaluation'",
            )
        return held

    def newton_options(
        self, fabric: Fabric, radius: float, barrier: bool
    ) -> tuple[NewtonOptions, NewtonOptions]:
        """Newton options of the knitted state and load steps, and the looser ones of the intermediate pre-stress.

        The residual tolerance is ``tolerance``·E_T·r² (the contact forces that resolve the pre-stress
        scale with the soft transverse modulus); the step test is ``step_tolerance`` (in units of r,
        as ``newton.max_step``); the safeguards are the ``newton`` settings. The intermediate pre-stress
        states are only a path to s = 1: their residual, flux and step tolerances are
        ``newton.path_tolerance_factor`` times larger, as in the rod solver.
        """
        r = radius
        nw = self.newton
        # few backtracks: where a step fails, a cut-back of the load step helps more than α → 0;
        # Levenberg shifts up to 1e-2 × the mean diagonal: where loops buckle or contact curvature makes the
        # Hessian indefinite the Newton direction climbs, and shifts of 1e-5 had been too small to turn it;
        # no residual-decrease fallback: the contact energy is continuous along a step (candidates held,
        # gaps continuous across facets), so a step must lower it (the fallback let the energy climb and
        # the iteration wander)
        max_iter = self.max_iterations or (200 if barrier else 40)
        opts = NewtonOptions(
            atol=self.tolerance * fabric.yarn.E_transverse * r * r,
            rtol=1e-10,
            max_iter=max_iter,
            max_step=nw.max_step,
            xtol=1e-10 * r,
            max_backtracks=12,
            residual_backtracks=0,
            max_shift_increases=7,
            flux_rtol=nw.flux_tolerance,
            correction_rtol=nw.correction_tolerance,
            late_flux_rtol=nw.late_flux_tolerance,
            stall_iterations=0 if barrier else nw.stall_iterations,
            cap_shift=nw.cap_shift,
            projection={"exact": "off", "projected": "always"}.get(nw.tangent, nw.tangent),
            step_tol=self.step_tolerance,
            start_projected=nw.start_projected,
            chord=nw.chord and barrier,
            extrapolate=nw.extrapolation,
            halve_reversals=nw.halve_reversals,
            chord_full=nw.chord_after_full_steps,
        )
        f = nw.path_tolerance_factor
        loose = attrs.evolve(
            opts,
            atol=f * opts.atol,
            flux_rtol=f * opts.flux_rtol,
            late_flux_rtol=f * opts.late_flux_rtol,
            step_tol=f * opts.step_tol,
        )
        return opts, loose

    def simulate(
        self,
        fabric: Fabric,
        scene: Scene,
        *,
        progress=None,
        output_dir: str | Path | None = None,
        checkpoint_dir: str | Path | None = None,
        trace=None,
    ) -> Response:
        """Pre-stress (if asked) and follow the scene's load path; returns tensions per unit width.

        Parameters
        ----------
        fabric, scene : the fabric to simulate and what to simulate.
        progress : callable, optional
            ``progress(done, total, message)`` after every converged step.
        output_dir : path, optional
            ``solid-NNNN.vtu`` per converged step plus ``solid.pvd`` when the scene's outputs
            include ``"vtu"``.
        checkpoint_dir : path, optional
            Converged steps are saved there; a later call with the same inputs resumes after
            the last saved step.
        trace : callable, optional
            ``trace(record)`` after every Newton solve, converged or not: a dict with
            ``record = "solve"``, the phase ("prestress" or "load"), the load parameter t,
            ``converged``, the wall time, the iteration history (energy, residual, flux,
            line-search α, shift, wall time) and, on failure, the diagnostic. Before it, one
            ``record = "iteration"`` dict per Newton iteration as it completes (phase, t and that
            iteration's history entry), so a solve that is killed or never ends leaves its
            iterations. For reproducible convergence studies.
        """
        t_start = time.perf_counter()
        if self.newton.retain_freed_memory:
            retain_freed_memory()
        registry = get_registry()
        model = self.setup(fabric, scene, registry)
        backend = instantiate(registry, "linear_solver", self.linear_solver, "solver.linear_solver")

        def timed(fn, count: bool):
            """fn with its wall time added to the linear-solve time (and, with ``count``, counted as a solve)."""

            def wrapper(*args):
                t0 = time.perf_counter()
                try:
                    return fn(*args)
                finally:
                    model.timings["linear_solve"] += time.perf_counter() - t0
                    model.evaluations["linear_solves"] += int(count)

            return wrapper

        solve = timed(backend, True)
        if (
            self.newton.chord
            and model.barrier
            and not model.hold_candidates
            and hasattr(backend, "factorize")
        ):
            # chord steps reuse a factorisation: each back-substitution counts as a linear solve, the
            # factorisation's time goes with them
            def factorize(A):
                kept = timed(backend.factorize, False)(A)
                apply = timed(kept, True)
                apply.free = getattr(kept, "free", lambda: None)
                return apply

            solve.factorize = factorize

        t_load, lam1, lam2 = scene.load.stretches()
        n_load = len(t_load)
        prestress = "prestress" in scene.effects
        total = n_load + (self.prestress_steps if prestress else 0)
        report = progress or (lambda done, tot, msg: None)
        r = model.cm.radius
        opts, loose = self.newton_options(fabric, r, model.barrier)
        n_ind = 3 * len(model.independent)
        base_free = np.ones(n_ind + N_MACRO, bool)
        base_free[:3] = False  # pin one node: the cell's free translation
        vtu = "vtu" in scene.outputs and output_dir is not None
        ckpt = (
            StepCheckpoints(checkpoint_dir, self._key(fabric, scene, model.law))
            if checkpoint_dir is not None
            else None
        )
        lat = model.lattice

        def step_norm(dx: np.ndarray) -> float:
            du = model.T @ dx
            return max(float(np.max(np.abs(du))), float(np.max(np.abs(dx[n_ind:]))) * model.L_max) / r

        residuals: list[float] = []
        penetrations: list[float] = []
        shares: list[float] = []

        def stab_share(res) -> float:
            """The foundation's share of the increment's energy (ABAQUS compares ALLSD with ALLIE)."""
            e = float(res.info.get("stabilisation_energy", 0.0))
            return e / abs(res.energy) if res.energy else 0.0

        def newton(
            q0: np.ndarray,
            free: np.ndarray,
            anchor: np.ndarray | None = None,
            options: NewtonOptions = opts,
            where: tuple[str, float] = ("prestress", 0.0),
            anchored: bool = False,
        ):
            if not anchored:
                model.anchor(q0 if anchor is None else anchor)
            t0 = time.perf_counter()
            each = None
            if trace is not None:
                last = model.counters()

                def each(entry: dict) -> None:
                    # with the iteration's share of the wall time per part, and its evaluations and linear solves
                    now = model.counters()
                    split = {k: now[k] - last[k] for k in now}
                    last.update(now)
                    trace({"record": "iteration", "phase": where[0], "t": where[1], **entry, **split})

            try:
                res = minimise(
                    model,
                    q0,
                    free,
                    solve=solve,
                    options=options,
                    step_norm=step_norm,
                    step_limit=model.step_limit if model.barrier else None,
                    on_iteration=each,
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
                        "max_penetration_over_r": float(res.info.get("max_penetration", 0.0)) / r,
                        "stabilisation_share": stab_share(res),
                    }
                )
            if options is opts:
                shares.append(stab_share(res))
                residuals.append(float(np.max(np.abs(res.gradient[free]), initial=0.0)))
                flux = float(res.info.get("flux", 0.0))
                if flux > 0 and residuals[-1] > IMBALANCE_NOTE * flux:
                    # the step test (a Newton step under step_tolerance) can pass where barrier pairs deep inside
                    # d̂ make the Hessian so stiff that a tiny step leaves forces far above the flux: say so
                    notes.append(
                        f"{where[0]} {where[1]:g} converged with a residual of "
                        f"{residuals[-1]:.3g} N, {residuals[-1] / flux:.3g} × the force flux "
                        "(its tensions carry that imbalance)"
                    )
                penetrations.append(float(res.info.get("max_penetration", 0.0)))
            return res

        s0 = 1.0
        if prestress:
            d_min = model.cm.clearance.minimum if model.cm.clearance is not None else 2.0 * r
            s0 = min(self.initial_radius, 0.95 * d_min / (2.0 * r))
        q = model.shrunk(s0)
        rows: list[tuple[float, float, float, float]] = []
        start_phase, start_index = "prestress", -1
        next_checkpoint = 0
        if ckpt is not None and (saved := ckpt.latest()) is not None:
            last, arrays, meta = saved
            next_checkpoint = last + 1
            q = arrays["q"]
            rows = [tuple(x) for x in arrays["rows"].tolist()]
            start_phase, start_index = meta["phase"], int(meta["target"])
            s0 = float(meta["s0"])
            ckpt.announce(last, total)
        series = StepSeries(output_dir, "solid", next_checkpoint) if vtu else None
        notes: list[str] = []
        if self.order == 1 and "bending" in scene.effects:
            message = P1_LOCKING
            notes.append(message)
            warnings.warn(message, KnitframeWarning, stacklevel=2)
        converged = True
        step_counter = [next_checkpoint]

        def write_step(path: Path, qv: np.ndarray) -> None:
            _, _, _, info = model(qv, 0)
            write_solid_vtu(
                path, model.forms, model.T @ qv, model.s, info.get("pressure", np.zeros(model.cm.n_nodes))
            )

        def after(phase: str, index: int, qv: np.ndarray, message: str, done: int) -> None:
            if series is not None:  # before the checkpoint: every checkpointed step has its file
                series.write(step_counter[0], lambda path: write_step(path, qv))
            if ckpt is not None:
                ckpt.save(
                    step_counter[0],
                    {"q": qv, "rows": np.array(rows, dtype=np.float64).reshape(-1, 4)},
                    {"phase": phase, "target": index, "s0": s0},
                )
            step_counter[0] += 1
            report(done, total, message)

        try:
            if prestress and start_phase == "prestress":
                free = base_free.copy()
                free[n_ind:] = False
                t_first = (start_index + 1) / self.prestress_steps
                targets = [k / self.prestress_steps for k in range(start_index + 2, self.prestress_steps + 1)]

                s_done = [
                    s0 + t_first * (1.0 - s0)
                ]  # the radius factor of the last converged state (not of a failed try)

                def solve_prestress(t: float, q0: np.ndarray):
                    s_new = s0 + t * (1.0 - s0)
                    q1 = model.grow(q0, s_done[0], s_new)
                    res = newton(
                        q1,
                        free,
                        anchor=q0,
                        options=loose if t < 1.0 - 1e-12 else opts,
                        where=("prestress", t),
                    )
                    s_done[0] = s_new
                    return res

                def on_prestress(i: int, t: float, res) -> None:
                    nonlocal q
                    q = res.x
                    idx = int(round(t * self.prestress_steps)) - 1
                    after("prestress", idx, q, f"pre-stress {idx + 1}/{self.prestress_steps}", idx + 1)

                if (
                    start_index < 0
                ):  # equilibrium of the shrunk state (curvature makes it not quite stress-free)
                    model.s = s0
                    q = newton(q, free, options=loose).x
                continuation(
                    solve_prestress,
                    q,
                    targets,
                    t0=t_first,
                    min_fraction=self.newton.min_step_fraction,
                    on_target=on_prestress,
                )
                start_phase, start_index = "load", -1
            model.s = 1.0
            if start_phase == "prestress":
                clear = model.cm.clearance
                overlap = 0.0 if clear is None or model.law is None else 2.0 * r - clear.minimum
                if overlap > 0.02 * r:
                    raise NumericalError(
                        f"volumetric: the knitted yarns overlap by {overlap:.3g} mm (centerlines {clear.minimum:.4g} mm "
                        f"apart, dk = {2 * r:.4g} mm); add 'prestress' to scene.effects"
                    )
                start_phase, start_index = "load", -1

            lam1_path = None if lam1 is None else np.concatenate([[1.0], lam1])
            lam2_path = None if lam2 is None else np.concatenate([[1.0], lam2])
            offset = total - n_load

            path: list[tuple[float, np.ndarray]] = []  # the last two converged load states (τ, q)

            def fluctuation(qv: np.ndarray) -> np.ndarray:
                """w = u − (F̄ − I)·X of the independent nodes."""
                return qv[:n_ind] - lat.affine(model.X_ind, qv[n_ind:]).ravel()

            def solve_load(tau: float, q0: np.ndarray):
                l1 = None if lam1_path is None else float(np.interp(tau, np.arange(n_load + 1), lam1_path))
                l2 = None if lam2_path is None else float(np.interp(tau, np.arange(n_load + 1), lam2_path))
                pres, vals = lat.constraints(l1, l2)
                qs = q0.copy()
                qs[n_ind:][pres] = vals[pres]
                secant = self.newton.predictor == "secant" and len(path) == 2 and path[-1][1] is q0
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
                    dq[:n_ind] = ratio * (fluctuation(q0) - fluctuation(q_prev))
                    dq = model.crossing_free(qs, dq)
                    model.anchor(q0)
                    e_affine = model(qs, 0)[0]
                    for _ in range(4):
                        if model(qs + dq, 0)[0] < e_affine:
                            qs += dq
                            break
                        dq *= 0.5
                free = base_free.copy()
                free[n_ind:] = ~pres
                # (anchored already when the secant was tried: anchoring again would repeat the friction pairing)
                res = newton(qs, free, anchor=q0, where=("load", tau), anchored=secant)
                path[:] = [*path[-1:], (tau, res.x)]
                return res

            def on_load(i: int, tau: float, res) -> None:
                nonlocal q
                q = res.x
                T1, T2 = lat.tensions(res.gradient[n_ind:])
                hm = q[n_ind:]
                rows.append((1.0 + hm[macro_index(0, 0)], 1.0 + hm[macro_index(1, 1)], T1, T2))
                k = int(round(tau))
                after("load", k - 1, q, f"load step {k}/{n_load}", offset + k)

            first = start_index + 1
            path.append((float(first), q))
            continuation(
                solve_load,
                q,
                list(np.arange(first + 1, n_load + 1, dtype=float)),
                t0=float(first),
                min_fraction=self.newton.min_step_fraction,
                on_target=on_load,
            )
        except NumericalError as e:
            if self.on_failure == "raise" or not rows:
                raise NumericalError(
                    f"volumetric solver ({fabric.pattern}, {fabric.yarn.name}): {e}"
                ) from None
            converged = False
            notes.append(f"stopped after {len(rows)} of {n_load} load steps: {e}")
        arr = np.array(rows, dtype=np.float64).reshape(-1, 4)
        load = scene.load
        key = load.response_kind
        sl = fabric.stitch_length if fabric.stitch_length is not None else fabric.arc_length
        prov = Provenance(
            kind="simulation",
            source=f"volumetric {fabric.pattern}",
            solver=self.name,
            mesh=model.cm.summary(),
            wall_time=time.perf_counter() - t_start,
            converged=converged,
            notes="; ".join(notes),
            extra={
                "timings_s": {k: round(v_, 3) for k, v_ in model.timings.items()},
                "newton_evaluations": model.evaluations,
                "tolerance_N": opts.atol,
                "max_final_residual_N": max(residuals, default=0.0),
                "max_penetration_over_r": max(penetrations, default=0.0) / r,
                "max_stabilisation_share": max(shares, default=0.0),
                "prestress_start_radius_over_r": s0,
                "penalty_N_per_mm3": model.stiffness,
                "dk_mm": model.cell.dk,
                "L1_mm": lat.L1.tolist(),
                "L2_mm": lat.L2.tolist(),
                "effects": sorted(scene.effects),
                "options": attrs.asdict(self),
            },
        )
        return Response(
            arr[:, 0],
            arr[:, 1],
            arr[:, 2],
            arr[:, 3],
            load=key,
            label=f"volumetric {fabric.pattern} SL{sl:g} {fabric.yarn.name}",
            provenance=prov,
        )


class VolumetricModel:
    """The discrete problem: ``model(q, order) -> (E, g, H, info)`` over q = [u_independent, h].

    E is the strain energy of the yarns at the current pre-stress parameter ``s`` plus the
    contact energy plus a weak foundation ½ c |u − u₀|² on the increment from the start u₀ of the
    current load increment (the stabilisation of ABAQUS's *STATIC, STABILIZE: it holds the rigid
    modes of yarns that no contact holds yet; its share of the energy is reported). g and H are
    pulled back to q through the periodic map u = T q. Wall time is accumulated per part in
    ``timings`` (material assembly, contact, transforms).

    Contact search (``hold_candidates``): a Hessian evaluation (order 2, one per Newton iterate)
    runs the broad-phase contact search and keeps its candidate master elements; energy and
    gradient evaluations (order 0 and 1: the line search between two iterates) choose each
    point's pair among them (the laws' ``candidates``), which saves the KD-tree search there. The
    gap is the same function as with a fresh search, as the step cannot bring a pair from out of
    the reach into contact. Implicit FE codes likewise search contact once per iteration.
    """

    def __init__(
        self, cell, cm, forms, lattice, T, independent, law, surface, stiffness, reach, t_mesh, damping=0.0
    ):
        self.cell, self.cm, self.forms, self.lattice = cell, cm, forms, lattice
        self.T, self.independent = T, independent
        self.law, self.surface, self.stiffness, self.reach = law, surface, stiffness, reach
        n = 3 * cm.n_nodes
        # q → [u (3N), h (6)] for the contact terms, which also depend on h through the images
        self.Q = sp.vstack(
            [T, sp.hstack([sp.csr_matrix((N_MACRO, T.shape[1] - N_MACRO)), sp.identity(N_MACRO)])]
        ).tocsr()
        self.QT = self.Q.T.tocsr()
        self.TT = T.T.tocsr()
        self.n = n
        self.s = 1.0
        self.L_max = float(max(np.linalg.norm(lattice.L1), np.linalg.norm(lattice.L2)))
        self.X_ind = cm.nodes[independent]
        self.damping = float(damping)
        self.u0 = np.zeros(n)
        self._pull_back = (
            None  # (K's indptr and indices, M, K's diagonal positions, H's indices, indptr, shape)
        )
        self.timings = {
            "mesh": t_mesh,
            "material": 0.0,
            "contact": 0.0,
            "transform": 0.0,
            "linear_solve": 0.0,
        }
        self.friction = False  # lagged Coulomb friction (scene effect "friction")
        self.friction_state = None
        self.normals = None  # nodal normals of the smoothed P1 master surface, frozen per increment (anchor)
        self.hold_candidates = (
            False  # broad-phase contact search at order-2 evaluations only, held for order 0 and 1
        )
        self.held = None
        self.barrier = (
            False  # a barrier contact law: the line search is bounded by continuous collision detection
        )
        self.evaluations = {"energy": 0, "gradient": 0, "hessian": 0, "linear_solves": 0}

    def pull_back(self, K: sp.csr_matrix) -> sp.csr_matrix:
        """Tᵀ (K + c I) T (c the foundation's ``damping``) for a K on the material's fixed pattern.

        Each entry of H = Tᵀ K T is Σ T_ia K_ij T_jb over the entries of K, linear in K's data: with the
        pattern fixed, H.data = M·(K.data + c·[diagonal entries]) with a constant sparse M (built once,
        about one entry per entry of K since most rows of T hold a single 1). A sparse matrix–vector
        product instead of two sparse matrix products per Hessian (0.1 s against 0.4–1.4 s at P2 r/3).
        A K on another pattern gets its own map, built again.
        """
        cached = self._pull_back
        # the same pattern: the same index arrays, or equal ones (scipy may copy them when it builds K)
        same = cached is not None and (
            cached[0] is K.indptr
            and cached[1] is K.indices
            or (
                cached[0].shape == K.indptr.shape
                and cached[1].shape == K.indices.shape
                and np.array_equal(cached[0], K.indptr)
                and np.array_equal(cached[1], K.indices)
            )
        )
        if not same:
            if not K.has_sorted_indices:
                K.sort_indices()
            cached = self._pull_back = (K.indptr, K.indices, *_pull_back_map(K, self.T))
        _, _, M, diag, indices, indptr, shape = cached
        v = K.data
        if self.damping != 0.0:
            v = v.copy()
            v[diag] += self.damping
        H = sp.csr_matrix((M @ v, indices, indptr), shape=shape, copy=False)
        H.has_sorted_indices = True
        return H

    def counters(self) -> dict[str, float]:
        """Wall time so far per part (``material_s``, ``contact_s``, ``transform_s``, ``linear_solve_s``) and
        the numbers of evaluations and linear solves (``n_energy``, ``n_gradient``, ``n_hessian``, ``n_linear_solves``)."""
        out = {f"{k}_s": v for k, v in self.timings.items() if k != "mesh"}
        out.update({f"n_{k}": float(n) for k, n in self.evaluations.items()})
        return out

    def shrunk(self, s0: float) -> np.ndarray:
        """q of the yarns shrunk across the fibre to s0·r: u = (s0 − 1)·(transverse offset)."""
        q = np.zeros(self.T.shape[1])
        u = (s0 - 1.0) * self.cm.node_offset[self.independent]
        q[: 3 * len(self.independent)] = u.ravel()
        return q

    def grow(self, q0: np.ndarray, s_from: float, s_to: float) -> np.ndarray:
        """Pre-stress predictor from q0 (at radius factor s_from) to the stress-free radius s_to·r; sets ``s``.

        The free growth of the tubes, q0 + shrunk(s_to) − shrunk(s_from), exact away from contacts;
        with a barrier law only 0.9 of the crossing-free fraction of it (CCD), as a barrier admits
        no crossing.
        """
        step = self.crossing_free(q0, self.shrunk(s_to) - self.shrunk(s_from))
        self.s = s_to
        return q0 + step

    def crossing_free(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """A predictor's move dq from q as a barrier admits it: 0.9 of its crossing-free fraction (CCD); as is
        without a barrier law."""
        return dq * (0.9 * self.step_limit(q, dq)) if self.barrier else dq

    def anchor(self, q0: np.ndarray) -> None:
        """Start a load increment at q0: the foundation pulls towards this state, and with friction the
        contact pairs of q0 (normal forces, master points) are frozen for the increment's slip."""
        self.u0 = self.T @ q0
        self.friction_state = None
        self.held = None
        x = self.cm.nodes + self.u0.reshape(-1, 3)
        # laws without a smoothed master surface (or without the method, from other packages) get none
        frozen = getattr(self.law, "master_normals", None)
        self.normals = None if frozen is None else frozen(self.surface, x)
        if self.friction:
            self.friction_state = self.law.friction_state(
                self.surface, x, q0[-N_MACRO:], stiffness=self.stiffness, reach=self.reach, **self._normals()
            )

    def step_limit(self, q: np.ndarray, dq: np.ndarray) -> float:
        """Largest fraction α ≤ 1 of the step dq from q along which no yarn surfaces cross (the law's CCD)."""
        t0 = time.perf_counter()
        x = self.cm.nodes + (self.T @ q).reshape(-1, 3)
        dx = (self.T @ dq).reshape(-1, 3)
        try:
            return self.law.step_limit(
                self.surface, x, q[-N_MACRO:], dx, dq[-N_MACRO:], stiffness=self.stiffness
            )
        finally:
            self.timings["contact"] += time.perf_counter() - t0

    def _normals(self) -> dict[str, np.ndarray]:
        return {} if self.normals is None else {"normals": self.normals}

    def force_flux(self, gc: np.ndarray | None) -> float:
        """Average nodal force flux q̃ (N) of the last gradient evaluation.

        q̃ = mean over the loaded nodes of |f_a|, f_a = Σ_e |R_e,a| + |g_contact,a| (3-vectors of
        absolute element and contact nodal forces): the force level through the mesh, which does
        not cancel at equilibrium. ABAQUS tests residuals against 0.005 of its time average.
        """
        f = np.zeros(self.n) if self.forms.flux is None else self.forms.flux.copy()
        if gc is not None:
            f += np.abs(np.asarray(gc)[: self.n])
        node = np.linalg.norm(f.reshape(-1, 3), axis=1)
        loaded = node[node > 0]
        return float(loaded.mean()) if loaded.size else 0.0

    def __call__(self, q: np.ndarray, order: int, projected: bool = False) -> tuple[float, Any, Any, dict]:
        """(E, g, H, info) at q; with ``projected`` the solid's tangent is PSD-projected per quadrature point."""
        self.evaluations[("energy", "gradient", "hessian")[order]] += 1
        t0 = time.perf_counter()
        u = self.T @ q
        h = q[-N_MACRO:]
        self.timings["transform"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        try:
            E, R, K = self.forms.evaluate(u, self.s, order, project=projected)
        except NumericalError as e:  # an inverted element: inadmissible, the line search backs off
            self.timings["material"] += time.perf_counter() - t0
            return np.inf, None, None, {"diagnostic": str(e)}
        if not np.isfinite(E):
            self.timings["material"] += time.perf_counter() - t0
            return np.inf, None, None, {"diagnostic": "an element is inverted"}
        self.timings["material"] += time.perf_counter() - t0
        info: dict[str, Any] = {"active": 0, "max_penetration": 0.0}
        gc = Hc = None
        if self.law is not None:
            t0 = time.perf_counter()
            x = self.cm.nodes + u.reshape(-1, 3)
            kw = {"friction_state": self.friction_state} if self.friction_state is not None else {}
            kw.update(self._normals())
            if self.hold_candidates and order < 2 and self.held is not None:
                kw["candidates"] = self.held
            Ec, gc, Hc, info = self.law.evaluate(
                self.surface, x, h, order, stiffness=self.stiffness, reach=self.reach, **kw
            )
            if self.hold_candidates and order == 2:
                self.held = info.get("candidates")
            info.pop("candidates", None)
            E += Ec
            self.timings["contact"] += time.perf_counter() - t0
        du = u - self.u0
        E_stab = 0.5 * self.damping * float(du @ du)
        E += E_stab
        info["stabilisation_energy"] = E_stab
        if order == 0:
            return E, None, None, info
        info["flux"] = self.force_flux(gc)
        t0 = time.perf_counter()
        g = self.TT @ (R + self.damping * du)
        if gc is not None:
            g = g + self.QT @ gc
        H = None
        if order == 2:
            H = self.pull_back(K)
            if Hc is not None and Hc.nnz:
                H = H + self.QT @ Hc @ self.Q
            H = H.tocsr()
        self.timings["transform"] += time.perf_counter() - t0
        if not np.all(np.isfinite(g)):
            raise NumericalError("volumetric: non-finite residual")
        return E, g, H, info


def _pull_back_map(K: sp.csr_matrix, T: sp.csr_matrix):
    """M with (Tᵀ K T).data = M @ K.data for every K on K's pattern, the positions of K's diagonal, and the
    pattern (indices, indptr, shape) of Tᵀ K T in sorted CSR order."""
    T = sp.csr_matrix(T)
    nk = K.nnz
    I = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    J = K.indices.astype(np.int64)
    cnt = np.diff(T.indptr)

    def expand(p, rows):  # every (entry p, T's entry in row rows[p]): p repeated, T's column and value
        c = cnt[rows]
        pe = np.repeat(p, c)
        start = np.repeat(T.indptr[rows], c)
        k = np.arange(pe.size) - np.repeat(np.cumsum(c) - c, c)
        return pe, T.indices[start + k].astype(np.int64), T.data[start + k]

    p1, a, ta = expand(np.arange(nk), I)
    p2, b, tb = expand(np.arange(p1.size), J[p1])
    p, a, w = p1[p2], a[p2], ta[p2] * tb
    n = T.shape[1]
    key, row = np.unique(a * n + b, return_inverse=True)  # row-major sorted: CSR order
    M = sp.csr_matrix((w, (row, p)), shape=(key.size, nk))
    rows_h = key // n
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows_h, minlength=n))])
    idx = np.int32 if max(n, key.size) < 2**31 else np.int64
    diag = np.flatnonzero(I == J)
    return M, diag, (key % n).astype(idx), indptr.astype(idx), (n, n)


@hookimpl
def register_solvers(register):
    register(VolumetricSolver)
