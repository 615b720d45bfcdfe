"""Solver ``rod``: discrete elastic rods on the periodic 2x2 unit cell, with yarn-yarn contact.

The fast rung of the accuracy ladder. Each yarn centerline of the pattern's cell is a chain of
straight segments no longer than dk/2 by default (:mod:`knitframe_solvers.rod_model`) with
stretching EA and bending EI from the yarn model (straight rest shape, no twist: see
:mod:`knitframe_solvers.rod_terms`); option ``shear`` chooses how the yarn's axial shear enters:
one effective EI, or every segment's section turning on its own (a shear-deformable rod). Yarns
touch each other, their periodic images under the current F̄ and (with ``self_contact``)
themselves through a rod contact-law plugin, whose energy density is integrated over both
centerlines (:mod:`knitframe_solvers.rod_contact`) and scaled so that two parallel yarns have the
yarn model's transverse line-contact stiffness (:func:`rod_stiffness`). F̄ enters through the
macro DOFs of :mod:`knitframe.numerics.periodic`; the course and wale tensions per unit width are
the macro reactions divided by the cell area.

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
   back adaptively on failure (:func:`knitframe.numerics.continuation.continuation`); each
   increment starts from the previous state mapped affinely by the change of F̄.

Every step is solved by Newton with an Armijo line search (:func:`knitframe.numerics.newton.minimise`);
the rigid modes of yarns that no contact holds yet are stabilised by a Hessian shift, which does
not change the converged state. One node is pinned to remove the cell's free translation.
Every converged step (pre-stress, relaxed lattice, load) is checkpointed with what a resumed
run needs to retrace the same path; the provenance reports the relaxed lattice and its energy.

Stiff yarns in tight cells can be multistable: different pre-stress paths relax to different states.
The solver therefore explores a small documented set of starts
(:data:`~knitframe_solvers.rod_starts.START_SET`, option ``starts``): each is pre-stressed and
relaxed, and the load path continues from the one of lowest relaxed energy E = Σ (stretching +
bending + contact) at zero tension. A start whose pre-stress fails is recorded with its reason; if
that is the nominal one (from every rest shape of ``prestress_start``), the other starts are tried
all the same (``starts = "auto"``: all of the set), the run continues from the lowest that
converged and warns so, and only when none converges does it fail, naming each start's reason.
If the chosen start's load path fails (a NumericalError that would end or truncate the run), the
path is followed again from the next converged start in order of E
(:func:`~knitframe_solvers.rod_starts.fallback_order`; a start within
:data:`~knitframe_solvers.rod_starts.SAME_ENERGY` of a failed one is the same state and is passed
over, :func:`~knitframe_solvers.rod_starts.next_start`), and so on: the first start whose path
finishes is the answer, with one warning naming the start that failed, why, and how much higher the
used start's E is. Only when every start fails does the run fail, or, with ``on_failure =
"truncate"``, keep the rows of the start that got furthest (the lower E of a tie). On a fallback the
steps from the relaxed lattice on are rewritten for the new start (checkpoints and VTU files alike),
and every checkpoint carries all starts' relaxed states, so a resumed run continues from the start
recorded in it and can still fall back. Every start, its energy, whether it converged and, if its
load path failed, ``load_error`` (one line) and ``load_steps`` (the load steps it reached) are in
``provenance.extra['starts']``, the start the rows come from in
``provenance.extra['start_chosen']``. Under a uniaxial load a step whose free side jumps
(:func:`~knitframe_solvers.rod_branches.branch_jumps`) is cut back (option ``follow_branch``), so
the path follows its branch to where it ends, whatever the step count; a jump that survives the
smallest increment is a real snap, and where Newton fails at the fold ending the followed branch the
step may jump once from its last converged state; either is flagged with the loaded stretch where it
happened. The run is :class:`knitframe_solvers.rod_run.RodRun` on the unit-cell run skeleton
:class:`knitframe.numerics.cellrun.CellRun`.
"""

from __future__ import annotations

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
from knitframe.numerics.settings import settings_field
from knitframe.records import Fabric, Response, Scene
from knitframe.yarn import effective_bending, shear_stiffness, yarn_model
from knitframe_solvers.newton_settings import RodNewton
from knitframe_solvers.rod_contact import line_energy
from knitframe_solvers.rod_geometry import RodModel, from_cell, with_directors
from knitframe_solvers.rod_model import RodEnergy, knitted_overlap
from knitframe_solvers.rod_run import RodRun, RodSetup
from knitframe_solvers.rod_starts import start_count

__all__ = ["RodSolver", "rod_stiffness"]


def rod_stiffness(yarn, registry=None, law=None, line_stiffness: float | None = None) -> dict[str, float]:
    """EA (N), EI (N·mm²) and the contact stiffnesses of a yarn, from its yarn model.

    ``k_line`` (N/mm²) is the yarn model's tangent line-contact stiffness (Hertz line contact
    with the transverse modulus) at the line load that flattens a pair of parallel yarns by 5 %
    of dk, unless ``line_stiffness`` overrides it. Given a rod contact ``law``, its energy
    density φ is scaled so that two parallel yarns reproduce it: ``k_contact`` (N/mm³) makes
    ψ″(0.95 dk) = k_line, with ψ(d) = ∫ φ(√(d² + τ²)) dτ
    (:func:`knitframe_solvers.rod_contact.line_energy`). The core (barrier) of the packed fibres
    gets ``k_core`` (N/mm³), which makes the line stiffness the yarn's core modulus
    (``yarn.core_E``, E_axial unless measured) halfway through the barrier's band. A ``law``
    is first given what it reads from the yarn (``law.for_yarn(yarn)``: a ``core`` of None becomes
    the yarn's compaction limit). A law whose ``rigidity(yarn)`` is not None (``rod_shell``) takes
    k from the yarn's compression law, and ``k_line`` is then its line stiffness at 5 %
    flattening of its contact distance ``outer``.
    """
    registry = registry or get_registry()
    model = registry["yarn_model"][yarn.model].from_yarn(yarn)
    if line_stiffness is None:
        f_ref = float(np.asarray(model.contact_load(np.array([0.05 * yarn.dk])))[0])
        line_stiffness = float(np.asarray(model.contact_stiffness(np.array([f_ref])))[0])
    out = {"EA": float(model.EA), "EI": float(model.EI), "k_line": float(line_stiffness)}
    if law is None:
        return out
    law = law.for_yarn(yarn)
    rigidity = law.rigidity(yarn)
    if rigidity is not None:  # the yarn's own compression law
        D = float(law.outer or yarn.dk)
        out["k_contact"] = float(rigidity)
        out["k_line"] = line_energy(law, 0.95 * D, D, out["k_contact"], None, derivative=2)
    else:
        dk = yarn.dk
        out["k_contact"] = line_stiffness / line_energy(law, 0.95 * dk, dk, 1.0, 0.0, derivative=2)
        core = float(law.core or 0.0)
        y_mid = 0.5 * (core + 0.5 * (1.0 + core))
        out["k_core"] = (
            float(yarn.core_E) / line_energy(law, y_mid * dk, dk, 0.0, 1.0, derivative=2) if core > 0 else 0.0
        )
    return out


#: values of the rod's ``shear`` option
SHEAR_MODES = ("resolved", "effective", "none")


def _shear_mode(value: Any) -> Any:
    """``shear`` as one of :data:`SHEAR_MODES`; true and false (older configs) are "effective" and "none"."""
    if isinstance(value, bool):
        return "effective" if value else "none"
    return value


@attrs.frozen
class RodSolver:
    """Discrete elastic rods (EA, EI) on the periodic 2x2 cell with penalty contact and macro DOFs."""

    name: ClassVar[str] = "rod"
    description: ClassVar[str] = (
        "fast unit-cell solver: discrete elastic rods, penalty contact with periodic images"
    )
    effects: ClassVar[frozenset[str]] = frozenset(
        {"large_deformation", "bending", "contact", "self_contact", "friction", "prestress"}
    )
    loads: ClassVar[frozenset[str]] = frozenset(
        {"equibiaxial", "uniaxial-course", "uniaxial-wale", "general"}
    )
    #: simulate takes checkpoint_dir (every converged step, for --resume) and output_dir (VTU files)
    checkpoints: ClassVar[bool] = True
    writes_vtu: ClassVar[bool] = True
    #: minutes per run: the conformance kit does not simulate it
    conformance_simulate: ClassVar[bool] = False
    #: the plugins an option set to "auto" may pick (the sweep's cache hashes them all)
    auto_plugins: ClassVar[dict[str, tuple[str, ...]]] = {"contact_law": ("rod_shell", "rod_penalty")}

    #: rod segments per stitch of yarn; unset: segments no longer than dk/2 (at least 16), -
    segments_per_stitch: int | None = attrs.field(default=None, validator=v.optional(v.in_range(4, 1000)))
    #: linear-solver plugin name or table with ``kind``
    linear_solver: str | dict[str, Any] = "direct"
    #: rod contact-law plugin name or table with ``kind``; "auto": ``rod_shell`` for a yarn whose record has a
    #: compression law (shell and core diameters, k, p), else ``rod_penalty``
    contact_law: str | dict[str, Any] = "auto"
    #: steps growing the contact radius, -
    prestress_steps: int = attrs.field(default=8, validator=v.in_range(1, 1000))
    #: yarn rest shape during the pre-stress: straight throughout, or the knitted shape released to straight;
    #: "auto" tries straight, then knitted (knitted first with shear = "resolved")
    prestress_start: Literal["auto", "straight", "knitted"] = "auto"
    #: pre-stress starts explored, the first n of nominal, other rest shape (straight/knitted), 1.5x the
    #: pre-stress steps, loop depth x0.5, x1.5; the load continues from the lowest relaxed energy, or from the
    #: next if that load path fails; "auto": the first 3, or all 5 if the nominal pre-stress fails
    starts: int | Literal["auto"] = attrs.field(default="auto", validator=start_count)
    #: under a uniaxial load, cut back a step whose free side jumps so the path follows its branch; a jump
    #: left at the smallest increment is flagged with where it happened
    follow_branch: bool = True
    #: largest start of the pre-stress radius / (dk/2), -
    initial_radius: float = attrs.field(default=0.7, validator=v.in_range(0.0, 1.0, lo_open=True))
    #: same-strand pairs closer than this × dk along the yarn are neighbours, -
    self_contact_exclusion: float = attrs.field(default=np.pi, validator=v.positive)
    #: Newton residual tolerance / EA, -
    tolerance: float = attrs.field(default=1e-9, validator=v.positive)
    #: Newton iterations per increment, -
    max_iterations: int = attrs.field(default=100, validator=v.in_range(1, 10000))
    #: after pre-stress, let the lattice contract or expand to zero tension and load from there
    relax: bool = True
    #: "truncate" returns the converged steps (converged = false)
    on_failure: Literal["raise", "truncate"] = "raise"
    #: Newton and cut-back tuning: a preset ("default", "robust", "fast") or a table of keys, optionally with
    #: ``preset`` (see ``[solver.newton]`` of rod below)
    newton: str | dict[str, Any] = settings_field(RodNewton)
    #: override axial stiffness, N
    EA: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: how the yarn's axial shear enters its bending: "resolved", every segment shears on its own (a
    #: Timoshenko–Reissner rod, EI of the solid section, κ G_A A in shear); "effective", one bending
    #: stiffness EI / (1 + EI k²/(κ G_A A)) at k = 2π/(yarn per stitch); "none", the solid section's EI.
    #: A yarn with a measured bending_stiffness bends with it, unsheared (true: "effective", false: "none")
    shear: Literal["resolved", "effective", "none"] | bool = attrs.field(
        default="effective", converter=_shear_mode, validator=attrs.validators.in_(SHEAR_MODES)
    )
    #: override bending stiffness, N·mm²
    EI: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: override the line contact stiffness at 5 % flattening, N/mm²
    contact_stiffness: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: Gauss points per segment (each way) of the contact integral, -
    contact_quadrature: int = attrs.field(default=4, validator=v.in_range(1, 16))

    # ------------------------------------------------------------------------------------- setup
    def validate(self, fabric: Fabric, scene: Scene, registry=None) -> None:
        """The checks that need no geometry, made while the config is validated; ConfigErrors name the key.

        The linear solver and the rod contact law by name with their options (the law even when the
        scene has no contact: a wrong name is wrong either way), the yarn's model with its numbers,
        the stiffness overrides (``EA``, ``EI``, the contact stiffness) within
        :data:`~knitframe.validators.OVERRIDE_FACTOR` of the yarn's own, and, with contact but no
        pre-stress, the knitted cell's overlap (:func:`~knitframe_solvers.rod_model.knitted_overlap`):
        everything :meth:`simulate` builds or refuses before its first step.
        """
        registry = registry or get_registry()
        instantiate(registry, "linear_solver", self.linear_solver, "solver.linear_solver")
        yarn_model(registry, fabric.yarn)
        law = self.make_contact_law(registry, fabric.yarn)
        if self.contact_stiffness is not None and law.rigidity(fabric.yarn) is not None:
            raise ConfigError(
                "solver.contact_stiffness",
                f"contact law '{law.name}' takes its stiffness from the yarn's compression law "
                "(compression_k); leave contact_stiffness unset, or set contact_law = 'rod_penalty'",
            )
        own = rod_stiffness(fabric.yarn, registry)
        try:
            v.near_own("EA", self.EA, own["EA"], "N")
            v.near_own("EI", self.EI, own["EI"], "N·mm²")
            for key, value in (
                ("contact_stiffness", self.contact_stiffness),
                ("contact_law.stiffness", law.stiffness),
            ):
                v.near_own(key, value, own["k_line"], "N/mm²")
        except FieldError as e:
            raise ConfigError(f"solver.{e.field}", e.problem) from None
        if "contact" in scene.effects and "prestress" not in scene.effects:
            model, energy, _ = self.setup(fabric, scene, registry)
            problem = knitted_overlap(energy, np.zeros(model.n_dof))
            if problem is not None:
                raise ConfigError("scene.effects", problem.removeprefix("rod: "))

    def make_contact_law(self, registry=None, yarn=None) -> Any:
        """The rod contact law named by ``contact_law``; ConfigError if it is unknown or not for rods.

        ``"auto"`` is ``rod_shell`` for a ``yarn`` whose record has a compression law, else
        ``rod_penalty``. Given a ``yarn``, the law comes with what it reads from it
        (``law.for_yarn(yarn)``).
        """
        name = self.contact_law
        if name == "auto":
            shell, penalty = self.auto_plugins["contact_law"]
            name = shell if yarn is not None and yarn.has_compression_law else penalty
        law = instantiate(registry or get_registry(), "contact_law", name, "solver.contact_law")
        if law.discretisation != "rod":
            raise ConfigError(
                "solver.contact_law", f"contact law '{law.name}' is for '{law.discretisation}', not rods"
            )
        return law if yarn is None else law.for_yarn(yarn)

    def setup(self, fabric: Fabric, scene: Scene, registry=None) -> tuple[RodModel, RodEnergy, Any]:
        """Rod model, energy and unit cell for a fabric and the effects of a scene."""
        registry = registry or get_registry()
        cell = unit_cell(fabric, registry)
        model = from_cell(cell, self.segments(cell))
        law = self.make_contact_law(registry, fabric.yarn) if "contact" in scene.effects else None
        stiff = rod_stiffness(
            fabric.yarn,
            registry,
            law,
            line_stiffness=self.contact_stiffness or (law.stiffness if law is not None else None),
        )
        # the contact distance: dk, or the shell diameter of a law that reads the yarn's compression law
        contact_dk = float((law.outer if law is not None else None) or cell.dk)
        EI, GA = stiff["EI"], 0.0
        if self.shear == "effective":
            EI = effective_bending(fabric.yarn, cell.arc_length_per_stitch)
        elif self.shear == "resolved" and fabric.yarn.bending_stiffness is None:
            model = with_directors(model)
            EI, GA = float(fabric.yarn.EI), shear_stiffness(fabric.yarn)
        energy = RodEnergy(
            model,
            self.EA or stiff["EA"],
            self.EI or EI,
            bending="bending" in scene.effects,
            law=law,
            dk=contact_dk,
            dk_full=contact_dk,
            k_contact=stiff.get("k_contact", 0.0),
            k_core=stiff.get("k_core"),
            self_contact="self_contact" in scene.effects,
            exclusion=self.self_contact_exclusion * cell.dk,
            friction="friction" in scene.effects,
            quadrature=self.contact_quadrature,
            k_line=stiff["k_line"],
            GA=GA,
        )
        return model, energy, cell

    def segments(self, cell) -> int:
        """Segments per stitch: the option, or the least multiple of 4 (at least 16) with segments ≤ dk/2."""
        if self.segments_per_stitch is not None:
            return self.segments_per_stitch
        return max(16, 4 * int(np.ceil(cell.arc_length_per_stitch / (0.5 * cell.dk) / 4.0)))

    def _key(self, fabric: Fabric, scene: Scene) -> str:
        return checkpoint_key(fabric, scene, attrs.asdict(self))

    # ---------------------------------------------------------------------------------- simulate
    def simulate(
        self,
        fabric: Fabric,
        scene: Scene,
        *,
        progress=None,
        output_dir: str | Path | None = None,
        checkpoint_dir: str | Path | None = None,
    ) -> Response:
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
        model, energy, cell = self.setup(fabric, scene, get_registry())
        key = self._key(fabric, scene) if checkpoint_dir is not None else None
        return RodRun(
            RodSetup(self, model, energy, cell, self.segments(cell), key, t_start),
            fabric,
            scene,
            progress=progress,
            output_dir=output_dir,
            checkpoint_dir=checkpoint_dir,
        )()


@hookimpl
def register_solvers(register):
    register(RodSolver)
