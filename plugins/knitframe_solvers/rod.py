"""Solver ``rod``: discrete elastic rods on the periodic 2x2 unit cell, with yarn-yarn contact.

The fast rung of the accuracy ladder. Each yarn centerline of the pattern's cell is a chain of
straight segments no longer than dk/2 by default (:mod:`knitframe_solvers.rod_model`) with
stretching EA and bending EI from the yarn model (straight rest shape, no twist: see
:mod:`knitframe_solvers.rod_terms`). Yarns touch each other, their periodic images under the
current F̄ and (with ``self_contact``) themselves through a rod contact-law plugin, whose energy
density is integrated over both centerlines (:mod:`knitframe_solvers.rod_contact`) and scaled
so that two parallel yarns have the yarn model's transverse line-contact stiffness
(:func:`rod_stiffness`). F̄ enters through the macro DOFs of :mod:`knitframe.numerics.periodic`; the
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
   back adaptively on failure (:func:`knitframe.numerics.newton.continuation`); each increment starts
   from the previous state mapped affinely by the change of F̄.

Every step is solved by Newton with an Armijo line search (:func:`knitframe.numerics.newton.minimise`);
the rigid modes of yarns that no contact holds yet are stabilised by a Hessian shift, which does
not change the converged state. One node is pinned to remove the cell's free translation.
Every converged step (pre-stress, relaxed lattice, load) is checkpointed with what a resumed
run needs to retrace the same path; the provenance reports the relaxed lattice and its energy.

Stiff yarns in tight cells can be multistable: different pre-stress paths relax to different
states. The solver therefore explores a small documented set of starts (:data:`START_SET`,
option ``starts``): each is pre-stressed and relaxed, and the load path continues from the one
of lowest relaxed energy E = Σ (stretching + bending + contact) at zero tension. If that start's
load path fails (a NumericalError that would end or truncate the run), the path is followed again
from the next converged start in order of E (:func:`fallback_order`; a start within
:data:`SAME_ENERGY` of a failed one is the same state and is passed over, :func:`next_start`),
and so on: the first start whose path finishes is the answer, with one warning naming the start
that failed, why, and how much higher the used start's E is. Only when every start fails does the
run fail, or, with ``on_failure = "truncate"``, keep the rows of the start that got furthest (the
lower E of a tie). On a fallback the steps from the relaxed lattice on are rewritten for the new
start (checkpoints and VTU files alike), and every checkpoint carries all starts' relaxed states,
so a resumed run continues from the start recorded in it and can still fall back. Every start, its
energy, whether it converged and, if its load path failed, ``load_error`` (one line) and
``load_steps`` (the load steps it reached) are in ``provenance.extra['starts']``, the start the
rows come from in ``provenance.extra['start_chosen']``. Under a uniaxial load a step whose free
side jumps (:func:`branch_jumps`) is cut back (option ``follow_branch``), so the path follows its
branch to where it ends, whatever the step count; a jump that survives the smallest increment is
a real snap, and where Newton fails at the fold ending the followed branch the step may jump once
from its last converged state; either is flagged with the loaded stretch where it happened.
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

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.config import instantiate
from knitframe.errors import ConfigError, FieldError, KnitframeWarning, NumericalError
from knitframe.geometry import unit_cell
from knitframe.numerics.newton import NewtonOptions, StepCheckpoints, continuation, minimise
from knitframe.numerics.periodic import macro_index
from knitframe.numerics.settings import settings_field
from knitframe.numerics.stepfiles import StepSeries
from knitframe.plugins import get_registry
from knitframe.records import Fabric, Provenance, Response, Scene
from knitframe.yarns import yarn_model
from knitframe_solvers.newton_settings import RodNewton
from knitframe_solvers.rod_contact import line_energy
from knitframe_solvers.rod_model import RodEnergy, RodModel, from_cell

__all__ = ["RodSolver", "rod_stiffness", "write_rod_vtu"]

#: decades over which the springs holding the lattice are released in the relaxation
RELAX_DECADES = 6
#: a load step's free stretch jumps when it changes by more than JUMP_RATIO × the loaded stretch's change and JUMP_FLOOR
JUMP_RATIO, JUMP_FLOOR = 3.0, 0.02
#: with no free side, a step whose stretch grows while its tension falls by more than this fraction of
#: the tension before it, and by more than DROP_FLOOR × the path's largest |tension|, is a snap
DROP_FRACTION, DROP_FLOOR = 0.10, 0.01
#: with ``follow_branch`` an increment is cut back already when the free change passes CUT_RATIO × the loaded one
#: (and JUMP_FLOOR): a smooth path passes once the increment is small enough, a snap never does
CUT_RATIO = 1.0


@attrs.frozen
class Start:
    """One start of the pre-stress: a rest shape, a number of pre-stress steps and a loop depth.

    ``rest``: ``"option"`` is the rest shape of the ``prestress_start`` option (for ``"auto"``: straight,
    knitted if that fails); ``"other"`` is the other of straight and knitted. ``steps`` multiplies
    ``prestress_steps``. ``amplitude`` a scales the out-of-plane loop depth of the knitted
    centerlines about the cell's mid-plane: z ↦ z̄ + a (z − z̄), with the rest lengths unchanged.
    """

    name: str
    rest: Literal["option", "other"] = "option"
    steps: float = 1.0
    amplitude: float = 1.0


#: The documented starts, in the order they are tried; ``starts = n`` uses the first n. Each
#: reaches another relaxed state on at least one of jersey, garter, rib and seed SL11 cotton
#: (docs/notes/2026-11-26-rod-multistart.md).
START_SET: tuple[Start, ...] = (
    Start("nominal"),
    Start("other rest shape", rest="other"),
    Start("slower pre-stress", steps=1.5),
    Start("flatter loops", amplitude=0.5),
    Start("deeper loops", amplitude=1.5),
)
#: the number of starts of ``starts = "auto"``: the three that found the lowest state of jersey and rib
AUTO_STARTS = 3
#: the starts after the nominal one give up sooner: their smallest pre-stress increment, of a step
EXTRA_START_MIN_FRACTION = 1.0 / 8
#: a later start replaces the best so far only if its energy is lower by more than this, relative
SAME_ENERGY = 1e-4


def loop_depth_start(model: RodModel, amplitude: float) -> np.ndarray:
    """State q whose centerlines have the loop depth scaled by ``amplitude``: u_z = (a − 1)(z − z̄), no macro strain."""
    q = np.zeros(model.n_dof)
    z = model.X[:, 2]
    q[2 : 3 * model.n_nodes : 3] = (amplitude - 1.0) * (z - z.mean())
    return q


def start_count(instance, attribute, value) -> None:
    """``starts`` is "auto" or a whole number of starts from 1 to len(START_SET)."""
    if value == "auto":
        return
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer))
        or not 1 <= value <= len(START_SET)
    ):
        raise FieldError(
            attribute.name,
            f'must be "auto" or a whole number from 1 to {len(START_SET)}, got {v.shown(value)}',
        )


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
        out["k_core"] = (
            float(yarn.E_axial) / line_energy(law, y_mid * dk, dk, 0.0, 1.0, derivative=2)
            if core > 0
            else 0.0
        )
    return out


def write_rod_vtu(
    path: Path, model: RodModel, q: np.ndarray, radius: float, cell_data: dict | None = None
) -> Path:
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
    meshio.write(
        path,
        meshio.Mesh(
            pts,
            [("line", cells)],
            point_data={
                "yarn": yarn.astype(np.float64),
                "displacement": disp,
                "radius": np.full(len(pts), radius),
            },
            cell_data={k: [np.asarray(v_, dtype=np.float64)] for k, v_ in (cell_data or {}).items()},
        ),
    )
    return path


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

    #: rod segments per stitch of yarn; unset: segments no longer than dk/2 (at least 16), -
    segments_per_stitch: int | None = attrs.field(default=None, validator=v.optional(v.in_range(4, 1000)))
    #: linear-solver plugin name or table with ``kind``
    linear_solver: str | dict[str, Any] = "direct"
    #: rod contact-law plugin name or table with ``kind``
    contact_law: str | dict[str, Any] = "rod_penalty"
    #: steps growing the contact radius, -
    prestress_steps: int = attrs.field(default=8, validator=v.in_range(1, 1000))
    #: yarn rest shape during the pre-stress: straight throughout, or the knitted shape released to straight;
    #: "auto" tries straight, then knitted
    prestress_start: Literal["auto", "straight", "knitted"] = "auto"
    #: pre-stress starts explored, the first n of nominal, other rest shape (straight/knitted), 1.5x the
    #: pre-stress steps, loop depth x0.5, x1.5; the load continues from the lowest relaxed energy, or from the
    #: next if that load path fails; "auto": the first 3
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
            for key, value in (
                ("contact_stiffness", self.contact_stiffness),
                ("contact_law.stiffness", getattr(law, "stiffness", None)),
            ):
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
        return (
            f"rod: the knitted centerlines overlap (closest centre distance {d_min:.4g} mm < "
            f"{getattr(energy.law, 'core', 0) * cell.dk:.4g} mm); add 'prestress' to scene.effects"
        )

    def make_contact_law(self, registry=None) -> Any:
        """The rod contact law named by ``contact_law``; ConfigError if it is unknown or not for rods."""
        law = instantiate(registry or get_registry(), "contact_law", self.contact_law, "solver.contact_law")
        if getattr(law, "discretisation", None) != "rod":
            raise ConfigError(
                "solver.contact_law", f"contact law '{law.name}' is for '{law.discretisation}', not rods"
            )
        return law

    def setup(self, fabric: Fabric, scene: Scene, registry=None) -> tuple[RodModel, RodEnergy, Any]:
        """Rod model, energy and unit cell for a fabric and the effects of a scene."""
        registry = registry or get_registry()
        cell = unit_cell(fabric, registry)
        model = from_cell(cell, self.segments(cell))
        law = self.make_contact_law(registry) if "contact" in scene.effects else None
        stiff = rod_stiffness(
            fabric.yarn,
            registry,
            law,
            line_stiffness=self.contact_stiffness or getattr(law, "stiffness", None),
        )
        energy = RodEnergy(
            model,
            self.EA or stiff["EA"],
            self.EI or stiff["EI"],
            bending="bending" in scene.effects,
            law=law,
            dk=cell.dk,
            dk_full=cell.dk,
            k_contact=stiff.get("k_contact", 0.0),
            k_core=stiff.get("k_core"),
            self_contact="self_contact" in scene.effects,
            exclusion=self.self_contact_exclusion * cell.dk,
            friction="friction" in scene.effects,
            quadrature=self.contact_quadrature,
            k_line=stiff["k_line"],
        )
        return model, energy, cell

    def segments(self, cell) -> int:
        """Segments per stitch: the option, or the smallest multiple of 4 (at least 16) with segments ≤ dk/2."""
        if self.segments_per_stitch is not None:
            return self.segments_per_stitch
        return max(16, 4 * int(np.ceil(cell.arc_length_per_stitch / (0.5 * cell.dk) / 4.0)))

    def _key(self, fabric: Fabric, scene: Scene) -> str:
        text = json.dumps(
            [fabric.to_dict(), scene.to_dict(), attrs.asdict(self)], sort_keys=True, default=str
        )
        return hashlib.sha256(text.encode()).hexdigest()[:24]

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
        opts = NewtonOptions(
            atol=self.tolerance * energy.EA,
            rtol=1e-10,
            max_iter=self.max_iterations,
            stabilisation=self.newton.stabilisation,
            max_step=self.newton.max_step,
            xtol=1e-12 * float(np.linalg.norm(lat.L1) + np.linalg.norm(lat.L2)),
        )
        L_max = float(max(np.linalg.norm(lat.L1), np.linalg.norm(lat.L2)))

        def step_norm(dx: np.ndarray) -> float:
            # in units of the current contact distance, which is small early in the pre-stress
            return max(
                float(np.max(np.linalg.norm(dx[: 3 * n].reshape(-1, 3), axis=1))),
                float(np.max(np.abs(dx[3 * n :]))) * L_max,
            ) / max(energy.dk, 0.5 * cell.dk)

        n_strands = model.n_strands

        def stabilise(info: dict) -> bool:
            return info.get("strands_in_contact", 0) < n_strands

        base_free = np.ones(model.n_dof, bool)
        base_free[:3] = False  # pin node 0: the cell's free translation
        vtu = "vtu" in scene.outputs and output_dir is not None
        ckpt = (
            StepCheckpoints(checkpoint_dir, self._key(fabric, scene)) if checkpoint_dir is not None else None
        )

        def newton(q0: np.ndarray, free: np.ndarray, options: NewtonOptions = opts):
            if energy.friction and energy.law is not None:
                energy.update_lag(q0)
            return minimise(
                energy, q0, free, solve=solve, options=options, stabilise=stabilise, step_norm=step_norm
            )

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

                x = minimise(
                    fun,
                    x,
                    free,
                    solve=solve,
                    options=attrs.evolve(opts, max_iter=4 * self.max_iterations),
                    stabilise=stabilise,
                    step_norm=step_norm,
                ).x
            return x

        rows: list[tuple[float, float, float, float]] = []
        q = np.zeros(model.n_dof)
        kappa_knitted = model.curvature(q)
        dk_full = cell.dk
        # what a checkpoint carries besides q, rows and the starts' relaxed states, so a resumed run
        # retraces the same path: relaxed_step is the step index of the relaxed lattice (a fallback to
        # another start rewrites the steps from there); snaps are the jumps the load path kept
        state: dict[str, Any] = {
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
        }
        # the relaxed state of every start (row i: state["starts"][i]; NaN where it did not converge)
        start_states = np.zeros((0, model.n_dof))
        step_counter = [0]
        if ckpt is not None and (saved := ckpt.latest()) is not None:
            index, arrays, meta = saved
            q = arrays["q"]
            rows = [tuple(r) for r in arrays["rows"].tolist()]
            start_states = arrays.get("starts_q", start_states)
            state.update({k: meta.get(k) for k in state})
            state["snaps"] = state["snaps"] or []
            energy.dk = float(meta["dk"])
            step_counter[0] = index + 1
            ckpt.announce(index, total)
        snaps: list[dict[str, Any]] = state["snaps"]  # jumps left at the smallest load increment
        series = StepSeries(output_dir, "rod", step_counter[0]) if vtu else None
        notes: list[str] = []
        converged = True

        def after(phase: str, index: int, qv: np.ndarray, message: str, done: int) -> None:
            state.update(phase=phase, target=index, dk=energy.dk)
            if series is not None:  # before the checkpoint: every checkpointed step has its file
                series.write(step_counter[0], lambda path: write_rod_vtu(path, model, qv, 0.5 * energy.dk))
            if ckpt is not None:
                ckpt.save(
                    step_counter[0],
                    {
                        "q": qv,
                        "rows": np.array(rows, dtype=np.float64).reshape(-1, 4),
                        "starts_q": start_states,
                    },
                    state,
                )
            step_counter[0] += 1
            report(done, total, message)

        def rewind(step: int) -> None:
            """Drop the checkpoints and VTU files after step ``step``; the next step written is ``step``.

            Checkpoints go first, the latest first, so a run killed on the way resumes from a
            checkpoint whose files are all there; the file of ``step`` itself is rewritten next.
            """
            nonlocal series
            if ckpt is not None:
                ckpt.discard_after(step)
            if series is not None:
                series = StepSeries(output_dir, "rod", step + 1)
            step_counter[0] = step

        def initial_distance(q0: np.ndarray) -> float:
            """Where the pre-stress from state q0 starts: small enough that no two centerlines overlap."""
            energy.dk = dk_full
            d_min = float(energy.pairs(q0).distance.min(initial=dk_full))
            return min(self.initial_radius * dk_full, 0.95 * d_min)

        def run_prestress(
            start: str,
            q0: np.ndarray,
            first: int,
            dk0: float,
            n_steps: int,
            label: str | None = None,
            min_fraction: float | None = None,
        ) -> np.ndarray:
            """Grow the contact distance dk0 → dk geometrically at F̄ = I, from pre-stress step ``first`` of ``n_steps``.

            With a ``label`` (a start other than the nominal one) the steps are reported as progress
            but neither checkpointed nor written: only the chosen start's relaxed state is.
            """
            free = base_free.copy()
            free[3 * n :] = False
            t_first = first / n_steps
            targets = [k / n_steps for k in range(first + 1, n_steps + 1)]
            loose = attrs.evolve(opts, atol=1e3 * opts.atol, max_iter=2 * self.max_iterations)
            record = label is None
            if label is None:
                label = "" if self.prestress_start == "straight" else f" ({start} start)"

            def solve_prestress(t: float, x0: np.ndarray):
                energy.dk = dk0 * (dk_full / dk0) ** t
                if start == "knitted":
                    energy.kappa0 = (1.0 - t) * kappa_knitted
                # the intermediate states are only a path to t = 1; where contacts barely touch, the
                # smooth onset of the law makes Newton converge linearly, so they get a looser tolerance
                return newton(x0, free, loose if t < 1.0 - 1e-12 else opts)

            def on_prestress(i: int, t: float, res) -> None:
                idx = int(round(t * n_steps)) - 1
                message = f"pre-stress{label} {idx + 1}/{n_steps}"
                if record:
                    after("prestress", idx, res.x, message, idx + 1)
                else:
                    report(self.prestress_steps, total, message)

            try:
                out = continuation(
                    solve_prestress,
                    q0,
                    targets,
                    t0=t_first,
                    min_fraction=min_fraction or self.newton.min_step_fraction,
                    on_target=on_prestress,
                )
            except NumericalError as e:
                raise NumericalError(
                    f"pre-stress{label} (contact distance {energy.dk:.4g} of {dk_full:.4g} mm): {e}"
                ) from None
            finally:
                energy.kappa0 = None
                energy.dk = dk_full
            return out[-1].x if out else q0

        relax_free = base_free.copy()
        relax_free[3 * n :] = ~lat.constraints(None, None)[0]

        def relaxed(qv: np.ndarray) -> np.ndarray:
            """The state the load path starts from: with ``relax``, the lattice at zero tension."""
            return relax_lattice(qv, relax_free) if self.relax else qv

        def stretch_of(qv: np.ndarray) -> list[float]:
            return [1.0 + float(qv[3 * n + macro_index(0, 0)]), 1.0 + float(qv[3 * n + macro_index(1, 1)])]

        def explore_starts(q_nominal: np.ndarray) -> np.ndarray:
            """Pre-stress and relax the other starts of :data:`START_SET`; the state of lowest energy E.

            Records every start (rest shape, pre-stress steps, loop depth, converged, E, relaxed
            stretches) in ``state["starts"]`` and the chosen one in ``state["start_chosen"]``. A
            start replaces the best so far only if its energy is lower by more than
            :data:`SAME_ENERGY` relative, so one state reached twice keeps the earlier start. The
            relaxed states go to ``start_states`` (checkpointed with every later step), from which
            a failed load path falls back to the next start (:func:`fallback_order`).
            """
            nonlocal start_states
            count = AUTO_STARTS if self.starts == "auto" else int(self.starts)
            chosen, q_best = 0, q_nominal
            best = float(energy(q_nominal, 0)[0])
            start_states = np.full((count, model.n_dof), np.nan)
            start_states[0] = q_nominal
            entries = [
                {
                    "name": START_SET[0].name,
                    "rest": state["start"],
                    "prestress_steps": self.prestress_steps,
                    "amplitude": 1.0,
                    "converged": True,
                    "energy_Nmm": best,
                    "relaxed_stretch": stretch_of(q_nominal),
                }
            ]
            for k, st in enumerate(START_SET[1:count], start=1):
                rest = (
                    state["start"]
                    if st.rest == "option"
                    else ("knitted" if state["start"] == "straight" else "straight")
                )
                steps = max(1, int(round(st.steps * self.prestress_steps)))
                entry = {"name": st.name, "rest": rest, "prestress_steps": steps, "amplitude": st.amplitude}
                t0 = time.perf_counter()
                try:
                    q0 = loop_depth_start(model, st.amplitude)
                    qk = relaxed(
                        run_prestress(
                            rest,
                            q0,
                            0,
                            initial_distance(q0),
                            steps,
                            label=f" start {k + 1}/{count} ({st.name})",
                            min_fraction=max(self.newton.min_step_fraction, EXTRA_START_MIN_FRACTION),
                        )
                    )
                    E = float(energy(qk, 0)[0])
                    if not np.isfinite(E):
                        raise NumericalError(f"non-finite energy {E} at the relaxed state")
                except NumericalError as e:
                    entry.update(converged=False, energy_Nmm=None, relaxed_stretch=None, error=str(e))
                else:
                    entry.update(converged=True, energy_Nmm=E, relaxed_stretch=stretch_of(qk))
                    start_states[k] = qk
                    if E < best - SAME_ENERGY * abs(best):
                        chosen, q_best, best = k, qk, E
                finally:
                    energy.dk = dk_full
                entries.append({**entry, "wall_time_s": time.perf_counter() - t0})
            state.update(starts=entries, start_chosen=entries[chosen]["name"])
            return q_best

        try:
            # ---- pre-stress: grow the contact distance at F̄ = I and constant yarn length
            if prestress and state["phase"] == "prestress":
                if state["start"] is not None:  # resuming
                    starts = [state["start"]]
                else:
                    state["dk0"] = initial_distance(q)
                    starts = (
                        ["straight", "knitted"] if self.prestress_start == "auto" else [self.prestress_start]
                    )
                for k, start in enumerate(starts):
                    state["start"] = start
                    try:
                        q = run_prestress(
                            start, q, int(state["target"]) + 1, state["dk0"], self.prestress_steps
                        )
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
                q = relaxed(q)
                if prestress:
                    q = explore_starts(q)
                state.update(
                    lam_ref=stretch_of(q), relaxed_energy=float(energy(q, 0)[0]), relaxed_step=step_counter[0]
                )
                after("load", -1, q, "relaxed lattice" if self.relax else "start of the load path", offset)
            lam_ref = state["lam_ref"]

            # ---- load path
            lam1_path = None if lam1 is None else np.concatenate([[1.0], lam1])
            lam2_path = None if lam2 is None else np.concatenate([[1.0], lam2])

            def prescribed(tau: float):
                l1 = None if lam1_path is None else float(np.interp(tau, np.arange(n_load + 1), lam1_path))
                l2 = None if lam2_path is None else float(np.interp(tau, np.arange(n_load + 1), lam2_path))
                return lat.constraints(
                    None if l1 is None else l1 * lam_ref[0], None if l2 is None else l2 * lam_ref[1]
                )

            # the free side of a uniaxial path is watched for jumps to another branch (follow_branch)
            watch = self.follow_branch and scene.load.kind == "uniaxial"
            k_load = 0 if scene.load.direction == "course" else 1
            loaded_path = lam1_path if k_load == 0 else lam2_path
            # the smallest increment continuation tries, in loaded stretch
            smallest = (
                self.newton.min_step_fraction * float(np.abs(np.diff(loaded_path)).min()) if watch else 0.0
            )
            # cut: an increment of this load step was cut back for a jump; last: the last converged (tau, q);
            # lenient: load steps up to this tau may jump (following their branch failed at its fold)
            follow: dict[str, Any] = {"cut": False, "last": None, "lenient": -1.0}

            def solve_load(tau: float, q0: np.ndarray):
                pres, vals = prescribed(tau)
                qs = q0.copy()
                qs[3 * n :][pres] = vals[pres]
                # predictor: carry the cell content along with the lattice (about the pinned node 0)
                A = lat.F(qs[3 * n :]) @ np.linalg.inv(lat.F(q0[3 * n :]))
                x = model.positions(q0)
                qs[: 3 * n] = (x[0] + (x - x[0]) @ A.T - model.X).reshape(-1)
                free = base_free.copy()
                free[3 * n :] = ~pres
                res = newton(qs, free)
                if watch:
                    a, b = np.divide(stretch_of(q0), lam_ref), np.divide(stretch_of(res.x), lam_ref)
                    d_load, d_free = abs(b[k_load] - a[k_load]), b[1 - k_load] - a[1 - k_load]
                    if is_jump(d_load, d_free, CUT_RATIO):
                        lenient = tau <= follow["lenient"] + 1e-12
                        if not lenient and d_load > smallest * (
                            1.0 + 1e-6
                        ):  # continuation can still halve it
                            follow["cut"] = True
                            raise NumericalError(
                                f"the free stretch jumped {a[1 - k_load]:.3f} -> {b[1 - k_load]:.3f} "
                                f"over a loaded increment of {d_load:.3g} (another branch)"
                            )
                        snaps.append(
                            {
                                "loaded": [float(a[k_load]), float(b[k_load])],
                                "free": [float(a[1 - k_load]), float(b[1 - k_load])],
                                "how": "fold not converged" if lenient else "smallest increment",
                            }
                        )
                follow["last"] = (tau, res.x)
                return res

            def on_load(i: int, tau: float, res) -> None:
                nonlocal q
                q = res.x
                T1, T2 = lat.tensions(res.gradient[3 * n :])
                h = q[3 * n :]
                # stretches relative to the relaxed lattice; tensions per unit relaxed width
                l1, l2 = 1.0 + h[macro_index(0, 0)], 1.0 + h[macro_index(1, 1)]
                rows.append((l1 / lam_ref[0], l2 / lam_ref[1], T1 / lam_ref[1], T2 / lam_ref[0]))
                k = int(round(tau))
                follow["cut"] = False
                path_states.append(q)
                after("load", k - 1, q, f"load step {k}/{n_load}", offset + k)

            def follow_load(t_at: float, q_at: np.ndarray) -> None:
                """The load path from load time ``t_at`` and state ``q_at`` to its end; NumericalError if it fails."""
                while True:
                    try:
                        continuation(
                            solve_load,
                            q_at,
                            list(np.arange(np.floor(t_at) + 1, n_load + 1, dtype=float)),
                            t0=t_at,
                            min_fraction=self.newton.min_step_fraction,
                            on_target=on_load,
                        )
                        return
                    except NumericalError:
                        last = follow["last"]
                        # the branch was followed to its fold, where Newton fails (after a cut-back for a jump,
                        # or with no jump seen, the followed branch ending inside the step): from the last
                        # converged state this load step may jump (it is flagged with where); once per step
                        if not (watch and last is not None and follow["lenient"] < np.floor(last[0]) + 1):
                            raise
                        t_at, q_at = last
                        follow.update(cut=False, lenient=float(np.floor(t_at) + 1))

            def switch_to(k: int) -> np.ndarray:
                """Start k's relaxed state begins the load path: the steps from the relaxed lattice on are rewritten."""
                nonlocal lam_ref
                entry = state["starts"][k]
                qk = start_states[k].copy()
                rewind(state["relaxed_step"])
                rows.clear()
                snaps.clear()
                path_states.clear()
                follow.update(cut=False, last=None, lenient=-1.0)
                state.update(
                    lam_ref=stretch_of(qk),
                    relaxed_energy=float(entry["energy_Nmm"]),
                    start_chosen=entry["name"],
                )
                lam_ref = state["lam_ref"]
                after("load", -1, qk, f"relaxed lattice (start '{entry['name']}')", offset)
                return qk

            # ---- fallback: a start whose load path fails gives way to the next in order of relaxed energy
            entries = state["starts"]
            names = [e["name"] for e in entries]
            order = fallback_order(entries)
            # a fallback needs the starts' relaxed states (a checkpoint of an older version has none)
            can_fall_back = (
                len(order) > 1
                and state["relaxed_step"] is not None
                and len(start_states) == len(entries)
                and state["start_chosen"] in names
            )
            path_states: list[
                np.ndarray
            ] = []  # q of each converged load step of this path since this run began
            tried: dict[int, tuple[list, list, list]] = {}  # start -> its failed path (rows, states, snaps)
            all_failed = False
            t_at = float(start_index + 1)
            while True:
                try:
                    follow_load(t_at, q)
                    break
                except NumericalError as e:
                    if not can_fall_back:
                        raise
                    error = e
                current = names.index(state["start_chosen"])
                entries[current].update(
                    load_error=f"after {len(rows)} of {n_load} load steps: {first_clause(str(error))}",
                    load_steps=len(rows),
                )
                if len(path_states) == len(rows):  # the whole path is in memory (not resumed midway)
                    tried[current] = (list(rows), list(path_states), [dict(sn) for sn in snaps])
                nxt = next_start(entries, order)
                if nxt is None:
                    all_failed = True
                    break
                q, t_at = switch_to(nxt), 0.0
            if all_failed:
                summary = "; ".join(f"'{entries[k]['name']}' {entries[k]['load_error']}" for k in order)
                furthest = max(order, key=lambda k: (entries[k].get("load_steps", 0), -order.index(k)))
                if self.on_failure == "truncate" and entries[furthest].get("load_steps", 0) > 0:
                    # keep the rows of the start that got furthest (the lower energy of a tie)
                    if names[furthest] != state["start_chosen"]:
                        q = switch_to(furthest)
                        if furthest in tried:  # replayed from memory: no solve
                            kept_rows, kept_states, kept_snaps = tried[furthest]
                            snaps.extend(kept_snaps)
                            for k, (row, qv) in enumerate(zip(kept_rows, kept_states), start=1):
                                rows.append(row)
                                q = qv
                                after("load", k - 1, qv, f"load step {k}/{n_load}", offset + k)
                        else:  # tried before a resume: its path is followed again to where it fails
                            try:
                                follow_load(0.0, q)
                            except NumericalError:
                                pass
                    summary += f"; kept the rows of '{names[furthest]}', which got furthest"
                raise NumericalError(f"no start could follow the load path: {summary}")
            if can_fall_back and state["start_chosen"] != names[order[0]]:  # fell back
                first, used = entries[order[0]], entries[names.index(state["start_chosen"])]
                others = "".join(
                    f"; nor could '{entries[k]['name']}' ({entries[k]['load_error']})"
                    for k in order[1:]
                    if "load_steps" in entries[k]
                )
                message = (
                    f"rod solver ({fabric.pattern}, {fabric.yarn.name}): the lowest-energy start '{first['name']}' "
                    f"could not follow the load path ({first['load_error']}){others}; continued from "
                    f"'{used['name']}' (energy {used['energy_Nmm'] - first['energy_Nmm']:.4g} N·mm higher)"
                )
                notes.append(message)
                warnings.warn(message, KnitframeWarning, stacklevel=2)
        except NumericalError as e:
            if self.on_failure == "raise" or not rows:
                raise NumericalError(f"rod solver ({fabric.pattern}, {fabric.yarn.name}): {e}") from None
            converged = False
            notes.append(f"stopped after {len(rows)} of {n_load} load steps: {e}")
        arr = np.array(rows, dtype=np.float64).reshape(-1, 4)
        load = scene.load
        jumps = locate_jumps(branch_jumps(arr, load), snaps, arr, load)
        drops = tension_drops(arr, load)
        for j in drops:
            message = (
                f"rod solver ({fabric.pattern}, {fabric.yarn.name}): load step {j['step']} snapped to another "
                f"equilibrium state: the {j['direction']} tension fell {j['from']:.4g} -> {j['to']:.4g} N/mm "
                f"while its stretch grew; the curve after it is another state"
            )
            notes.append(message)
            warnings.warn(message, KnitframeWarning, stacklevel=2)
        jumps = sorted(jumps + drops, key=lambda j: j["step"])
        for j in (j for j in jumps if "free" in j):
            where = (
                ""
                if "at_loaded_stretch" not in j
                else " (between loaded stretch {:.4f} and {:.4f}, {})".format(
                    *j["at_loaded_stretch"], j["how"]
                )
            )
            message = (
                f"rod solver ({fabric.pattern}, {fabric.yarn.name}): load step {j['step']} jumped to another "
                f"equilibrium branch{where}: the free {j['free']} stretch went {j['from']:.3f} -> {j['to']:.3f} "
                f"while the loaded stretch changed by {j['loaded_change']:.3f}; the curve after it is another state"
            )
            notes.append(message)
            warnings.warn(message, KnitframeWarning, stacklevel=2)
        key = load.response_kind
        size = (
            f"SL{fabric.stitch_length:g}"
            if fabric.stitch_length is not None
            else f"{fabric.arc_length:g} mm/stitch"
        )
        prov = Provenance(
            kind="simulation",
            source=f"rod {fabric.pattern}",
            solver=self.name,
            mesh=f"{model.n_nodes} nodes, {len(model.edges)} segments ({self.segments(cell)}/stitch)",
            wall_time=time.perf_counter() - t_start,
            converged=converged,
            notes="; ".join(notes),
            extra={
                "EA_N": energy.EA,
                "EI_Nmm2": energy.EI,
                "k_line_N_per_mm2": energy.k_line,
                "dk_mm": cell.dk,
                "L1_mm": lat.L1.tolist(),
                "L2_mm": lat.L2.tolist(),
                "effects": sorted(scene.effects),
                "options": attrs.asdict(self),
                "prestress_start": state["start"],
                "relaxed_stretch": state["lam_ref"],
                "branch_jumps": jumps,
                "relaxed_energy_Nmm": state["relaxed_energy"],
                "starts": state["starts"],
                "start_chosen": state["start_chosen"],
            },
        )
        return Response(
            arr[:, 0],
            arr[:, 1],
            arr[:, 2],
            arr[:, 3],
            load=key,
            label=f"rod {fabric.pattern} {size} {fabric.yarn.name}",
            provenance=prov,
        )


def fallback_order(starts: list[dict[str, Any]]) -> list[int]:
    """The converged starts in the order a failed load path falls back in: the chosen one, then the rest by relaxed energy.

    The chosen start is the one :func:`RodSolver.simulate` loads first: a start replaces the best
    so far only if its energy E is lower by more than :data:`SAME_ENERGY` relative. The others
    follow by E (the earlier start of a tie).
    """
    ok = [k for k, s in enumerate(starts) if s.get("converged") and s.get("energy_Nmm") is not None]
    if not ok:
        return []
    first = ok[0]
    for k in ok[1:]:
        if starts[k]["energy_Nmm"] < starts[first]["energy_Nmm"] - SAME_ENERGY * abs(
            starts[first]["energy_Nmm"]
        ):
            first = k
    return [first] + sorted((k for k in ok if k != first), key=lambda k: (starts[k]["energy_Nmm"], k))


def next_start(starts: list[dict[str, Any]], order: list[int]) -> int | None:
    """The next start to follow the load path from after a failure, or None when none is left.

    Starts whose path failed carry ``load_error``. A start whose relaxed energy is within
    :data:`SAME_ENERGY` (relative) of a failed one is the same state and would fail the same
    way: it is marked as not tried, with the failed start's name, and passed over.
    """
    failed = [k for k in order if "load_error" in starts[k]]
    for k in order:
        if "load_error" in starts[k]:
            continue
        E = starts[k]["energy_Nmm"]
        same = [
            j
            for j in failed
            if abs(E - starts[j]["energy_Nmm"]) <= SAME_ENERGY * abs(starts[j]["energy_Nmm"])
        ]
        if same:
            starts[k]["load_error"] = f"not tried: the same relaxed state as '{starts[same[0]]['name']}'"
            continue
        return k
    return None


def first_clause(message: str) -> str:
    """A NumericalError's message up to its first "; " (the Newton trace after it is left out)."""
    return message.split("; ", 1)[0]


def is_jump(d_load: Any, d_free: Any, ratio: float = JUMP_RATIO, floor: float = JUMP_FLOOR) -> Any:
    r"""Whether a free-stretch change is a jump: :math:`|\Delta\lambda_{free}| > \max(\mathrm{ratio}\,|\Delta\lambda_{load}|, \mathrm{floor})`."""
    return np.abs(d_free) > np.maximum(ratio * np.abs(d_load), floor)


def branch_jumps(
    rows: np.ndarray, load: Any, *, ratio: float = JUMP_RATIO, floor: float = JUMP_FLOOR
) -> list[dict[str, Any]]:
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
    for k in np.flatnonzero(is_jump(d_load, d_free, ratio, floor)):
        out.append(
            {
                "step": int(k) + 1,
                "free": "wale" if k_free else "course",
                "from": float(lam[k, k_free]),
                "to": float(lam[k + 1, k_free]),
                "loaded_change": float(d_load[k]),
            }
        )
    return out


def tension_drops(
    rows: np.ndarray, load: Any, *, fraction: float = DROP_FRACTION, floor: float = DROP_FLOOR
) -> list[dict[str, Any]]:
    r"""Load steps of a path with no free side (equibiaxial, general) where a tension falls.

    ``rows`` holds (λ1, λ2, T1, T2) per converged load step. Along a direction d whose stretch
    grows in step k (Δλ_d > 0), the step is a snap to another equilibrium state when its tension
    falls by more than ``fraction`` of the tension before it and by more than ``floor`` times
    the path's largest |T|:
    :math:`T_d^{k-1} - T_d^{k} > \max(\mathrm{fraction}\,|T_d^{k-1}|, \mathrm{floor}\,\max|T|)`.
    A cell that stays on one branch stiffens or softens smoothly under a growing stretch; its
    tension does not fall. Uniaxial paths are checked by :func:`branch_jumps` instead.
    """
    if getattr(load, "kind", None) == "uniaxial" or len(rows) == 0:
        return []
    lam = np.vstack([[1.0, 1.0], rows[:, :2]])
    T = np.vstack([[0.0, 0.0], rows[:, 2:4]])
    scale = floor * float(np.max(np.abs(T)))
    out = []
    for d, name in ((0, "course"), (1, "wale")):
        grows = np.diff(lam[:, d]) > 0
        fall = T[:-1, d] - T[1:, d]
        for k in np.flatnonzero(grows & (fall > np.maximum(fraction * np.abs(T[:-1, d]), scale))):
            out.append(
                {
                    "step": int(k) + 1,
                    "direction": name,
                    "from": float(T[k, d]),
                    "to": float(T[k + 1, d]),
                    "kind": "tension drop",
                }
            )
    return sorted(out, key=lambda j: (j["step"], j["direction"]))


def locate_jumps(
    jumps: list[dict[str, Any]], snaps: list[dict[str, list[float]]], rows: np.ndarray, load: Any
) -> list[dict[str, Any]]:
    """The load steps' jumps with where each happened: ``at_loaded_stretch`` [λa, λb] of its snap.

    ``snaps`` are the jumps the load path kept (``follow_branch``), each with its loaded and
    free stretches before and after and ``how``: at the smallest increment, or after Newton
    failed at the fold where the followed branch ends. A snap inside load step k (its
    loaded stretch between those of rows k−1 and k) is attached to that step's jump, or is
    reported as the step's jump when the whole step's change stays under :func:`branch_jumps`'s
    threshold.
    """
    if not snaps:
        return jumps
    k_load = 0 if load.direction == "course" else 1
    ends = np.concatenate([[1.0], rows[:, k_load]])
    out = {j["step"]: dict(j) for j in jumps}
    for snap in snaps:
        lo, hi = snap["loaded"]
        step = int(np.clip(np.searchsorted(ends, 0.5 * (lo + hi)), 1, len(rows)))  # loaded stretch rises
        jump = out.setdefault(
            step,
            {
                "step": step,
                "free": "wale" if k_load == 0 else "course",
                "from": snap["free"][0],
                "to": snap["free"][1],
                "loaded_change": float(abs(ends[step] - ends[step - 1])),
            },
        )
        jump.update(at_loaded_stretch=[lo, hi], how=snap["how"])
    return [out[k] for k in sorted(out)]


@hookimpl
def register_solvers(register):
    register(RodSolver)
