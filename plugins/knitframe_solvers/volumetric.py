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
   steps, each cut back adaptively on failure (:func:`knitframe.numerics.continuation.continuation`).

Each increment is solved by the shared Newton driver (:func:`knitframe.numerics.newton.minimise`) with a
linear-solver plugin, whose wall time is kept next to the assembly times (provenance
``timings_s``). The yarn's tangent is indefinite where fibres are compressed, so by default
(``tangent = "projected"``) Newton uses the tangent projected to its PSD part at every
quadrature point (IPC's projected Newton), and an iterate whose Newton step moves no node more
than ``step_tolerance``·r is converged (``"adaptive"`` switches between the exact and the
projected tangent; ``"exact"`` keeps the exact one).
Every converged step is checkpointed; a call with the same inputs and checkpoint directory
resumes after the last saved step. The run is :class:`knitframe_solvers.volumetric_run.VolumetricRun`
on the unit-cell run skeleton :class:`knitframe.numerics.cellrun.CellRun`; the discrete problem is
:class:`knitframe_solvers.volumetric_model.VolumetricModel`.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path
from typing import Any, ClassVar, Literal

import attrs
import numpy as np

from knitframe import get_registry, hookimpl
from knitframe import validators as v
from knitframe.config import instantiate
from knitframe.errors import ConfigError, FieldError
from knitframe.geometry import unit_cell
from knitframe.numerics.cellrun import checkpoint_key
from knitframe.numerics.memory import retain_freed_memory
from knitframe.numerics.newton import NewtonOptions
from knitframe.numerics.periodic import Lattice, periodic_transform
from knitframe.numerics.settings import settings_field
from knitframe.records import Fabric, Response, Scene
from knitframe.yarn import yarn_model
from knitframe_solvers.newton_settings import VolumetricNewton
from knitframe_solvers.volumetric_material import SolidForms, YarnLaw
from knitframe_solvers.volumetric_model import VolumetricModel, contact_surface
from knitframe_solvers.volumetric_run import VolumetricRun, VolumetricSetup

__all__ = ["VolumetricSolver", "EXTRA"]

#: what installs the modules the volumetric solver needs beyond the core: gmsh (the yarn meshes) and ipctk
#: (the ``ipc`` contact law)
EXTRA = 'pip install "knitframe[volumetric]"'


def _importable(name: str) -> bool:
    """Whether ``import name`` would find the module, without importing it."""
    if name in sys.modules:
        return sys.modules[name] is not None
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


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
    #: simulate takes checkpoint_dir (every converged step, for --resume) and output_dir (VTU files)
    checkpoints: ClassVar[bool] = True
    writes_vtu: ClassVar[bool] = True
    #: minutes per run: the conformance kit does not simulate it
    conformance_simulate: ClassVar[bool] = False

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
        """Checkpoint key: the inputs, the solver options and the resolved contact law (with its defaults)."""
        resolved = None if law is None else [type(law).__name__, attrs.asdict(law)]
        return checkpoint_key(fabric, scene, attrs.asdict(self), resolved)

    def check_extra(self, scene: Scene) -> None:
        """Refuse in one line (ConfigError naming ``solver.kind``) when a module of the ``volumetric`` extra
        that this scene needs is not installed: gmsh (the yarn meshes) always, ipctk with contact by the
        ``ipc`` law; the message says :data:`EXTRA`."""
        law = self.contact_law if isinstance(self.contact_law, str) else self.contact_law.get("kind")
        needed = ["gmsh"] + (["ipctk"] if "contact" in scene.effects and law == "ipc" else [])
        missing = [name for name in needed if not _importable(name)]
        if missing:
            raise ConfigError("solver.kind", f"the volumetric solver needs {' and '.join(missing)}: {EXTRA}")

    def setup(self, fabric: Fabric, scene: Scene, registry=None) -> VolumetricModel:
        """Mesh, material forms, periodic map and contact of a fabric's cell for the effects of a scene."""
        from knitframe.numerics.mesh import cell_mesh

        self.check_extra(scene)
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
        model.barrier = law is not None and law.barrier
        model.hold_candidates = self.holds_candidates(law)
        return model

    def validate(self, fabric: Fabric, scene: Scene, registry=None) -> None:
        """The checks that need no mesh, made while the config is validated; ConfigErrors name the key.

        The modules of the ``volumetric`` extra (:meth:`check_extra`), the linear solver and the
        solid contact law by name with their options (the law even when the scene has no contact: a
        wrong name is wrong either way), the yarn's model with its
        numbers, ``max_step`` against the contact reach, ``contact_modulus`` and the law's penalty
        within :data:`~knitframe.validators.OVERRIDE_FACTOR` of the yarn's transverse modulus and of
        the law's default penalty for this yarn and seed, and the cell's clearance
        (:meth:`check_clearance`): everything :meth:`simulate` builds or refuses before its first step.
        """
        self.check_extra(scene)
        registry = registry or get_registry()
        instantiate(registry, "linear_solver", self.linear_solver, "solver.linear_solver")
        yarn_model(registry, fabric.yarn)
        law = self.make_contact_law(registry)
        self.holds_candidates(law if "contact" in scene.effects else None)
        try:
            v.near_own("contact_modulus", self.contact_modulus, fabric.yarn.E_transverse, "MPa")
            # the penalty the run will use, against the law's default for this yarn
            h = self.seed * 0.5 * fabric.yarn.dk
            key = "stiffness" if law.stiffness is not None else "factor"
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
        """Refuse a knitted cell whose closest centerlines the mesh or first step cannot take (ConfigError).

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
        limit = law.finishes_strain
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
        if law.discretisation != "solid":
            raise ConfigError(
                "solver.contact_law",
                f"contact law '{law.name}' is for '{law.discretisation}', not solid meshes",
            )
        return law

    def holds_candidates(self, law: Any) -> bool:
        """Whether the contact candidates are held through each Newton iteration's line search.

        They are with ``contact_search = "iteration"`` and a law that takes them (its
        ``holds_candidates`` flag); then ``max_step`` must be at most half the reach (ConfigError
        otherwise): two nodes each moving max_step could close a gap wider than the reach within
        one step.
        """
        held = self.newton.contact_search == "iteration" and law is not None and law.holds_candidates
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
        """Newton options of the knitted state and load steps, and the looser ones of the intermediate
        pre-stress.

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
        model = self.setup(fabric, scene, get_registry())
        opts, loose = self.newton_options(fabric, model.cm.radius, model.barrier)
        key = self._key(fabric, scene, model.law) if checkpoint_dir is not None else None
        return VolumetricRun(
            VolumetricSetup(self, model, opts, loose, key, t_start),
            fabric,
            scene,
            progress=progress,
            output_dir=output_dir,
            checkpoint_dir=checkpoint_dir,
            trace=trace,
        )()


@hookimpl
def register_solvers(register):
    register(VolumetricSolver)
