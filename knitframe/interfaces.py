"""The contracts each plugin kind honours.

Implementations are usually ``@attrs.frozen`` classes: their fields are the plugin's options,
so a config table ``[solver] kind = "rod"`` plus other keys becomes ``RodSolver(**keys)``
(see :func:`knitframe.config.instantiate`). Every implementation carries ``ClassVar`` fields
``name`` and ``description``.

Each protocol declares every attribute, method and keyword the core calls on a plugin of its
kind; the core calls them without asking whether they exist. A capability that not every plugin
has is declared as such: a ``ClassVar`` flag (a solid contact law's ``barrier``, a solver's
``checkpoints``) or a method whose body here is the safe default (a solver's ``validate`` checks
nothing). A plugin declares each member itself or inherits the defaults by subclassing its
protocol (``class MySolver(knitframe.interfaces.Solver)``). Two reader capabilities are small
protocols of their own (:class:`HeaderReader`, :class:`DispatchingReader`), so that a plain
reader stays a two-line class. :mod:`knitframe.testing` checks every declared member.
"""

from __future__ import annotations

import types
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from knitframe.pipeline import BuildContext, RunContext
    from knitframe.plugins import Registry
    from knitframe.records import Fabric, Response, Scene, Yarn

__all__ = [
    "Pattern",
    "YarnModel",
    "Solver",
    "ContactLaw",
    "RodContactLaw",
    "SolidContactLaw",
    "LinearSolverFactory",
    "LinearSolve",
    "Factors",
    "Homogenizer",
    "Fitter",
    "DesignObjective",
    "Executor",
    "Reader",
    "HeaderReader",
    "DispatchingReader",
    "Stage",
    "declared",
    "Progress",
]

#: ``progress(done, total, message)``: solvers report progress through this callback.
Progress = Callable[[float, float, str], None]


@runtime_checkable
class Pattern(Protocol):
    """A knit pattern: the 2x2 periodic unit cell of yarn centerlines for a given Fabric."""

    name: ClassVar[str]
    description: ClassVar[str]
    #: machine setting -> yarn length per stitch (mm), for fabrics given by ``stitch_length``; None:
    #: the pattern takes ``arc_length`` only (read through :func:`declared`)
    stitch_lengths: Mapping[str, float] | None = None

    def cell(self, fabric: Fabric) -> Any:
        """Unit cell (centerlines with exact tangents, lattice vectors, end pairing, layout)."""


@runtime_checkable
class YarnModel(Protocol):
    """A yarn's constitutive law for the solid solver plus the rod stiffnesses derived from it."""

    name: ClassVar[str]
    description: ClassVar[str]

    @classmethod
    def from_yarn(cls, yarn: Yarn) -> YarnModel:
        """Model parameterised by a Yarn record."""

    def evaluate(
        self, F: np.ndarray, fibre: np.ndarray | None = None, order: int = 2
    ) -> tuple[np.ndarray, Any, Any]:
        """Strain energy density Ψ (...), first Piola-Kirchhoff stress P (..., 3, 3) and tangent
        A_iJkL = ∂P_iJ/∂F_kL (..., 3, 3, 3, 3), MPa, at deformation gradients F (..., 3, 3) with unit
        reference fibre directions ``fibre`` (..., 3); ``order`` < 2 may leave A None, < 1 P too."""


@runtime_checkable
class Solver(Protocol):
    """Simulates a unit cell: ``simulate(fabric, scene) -> Response``.

    ``effects`` lists the :data:`~knitframe.records.EFFECTS` the solver can model; ``loads``
    the load-path kinds it can follow. A scene asking for anything else is refused before work.
    The simulate stage passes ``checkpoint_dir`` only to a solver that declares ``checkpoints``
    and ``output_dir`` only to one that declares ``writes_vtu``. A solver may take further
    keywords of its own (the volumetric solver's ``trace``); the core never passes them.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    effects: ClassVar[frozenset[str]]
    loads: ClassVar[frozenset[str]]
    #: ``simulate`` takes ``checkpoint_dir``: it checkpoints every converged step there and resumes
    #: from the checkpoints it finds
    checkpoints: ClassVar[bool] = False
    #: ``simulate`` takes ``output_dir`` and writes VTU files of its states there
    writes_vtu: ClassVar[bool] = False
    #: the conformance kit runs a short scene of each declared load with default options (only
    #: for solvers that take seconds)
    conformance_simulate: ClassVar[bool] = False

    def simulate(
        self,
        fabric: Fabric,
        scene: Scene,
        *,
        progress: Progress | None = None,
        output_dir: str | Path | None = None,
        checkpoint_dir: str | Path | None = None,
    ) -> Response:
        """Run the scene and return the tension-stretch Response."""

    def validate(self, fabric: Fabric, scene: Scene, registry: Registry | None = None) -> None:
        """The solver's own checks of a fabric and scene before any work (plugins it names, yarn
        model, option ranges); raises ConfigError naming the key. Default: nothing to check."""


@runtime_checkable
class ContactLaw(Protocol):
    """Yarn-yarn contact terms for one discretisation (``"rod"`` or ``"solid"``).

    The members a solver calls depend on the discretisation: :class:`RodContactLaw` and
    :class:`SolidContactLaw`.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    discretisation: ClassVar[str]


@runtime_checkable
class RodContactLaw(ContactLaw, Protocol):
    """Contact between yarn centerlines (``discretisation = "rod"``): an energy of the centre distance.

    ``stiffness`` (N/mm², None: from the yarn model) and ``core`` (the smallest centre distance the
    law admits, as a fraction of dk; 0: none; None: the yarn's compaction limit ``Yarn.compaction``)
    are read by the rod solver, after :meth:`for_yarn` has given the law what it reads from the
    yarn. Subclass this protocol to inherit the defaults of ``outer``, ``for_yarn`` and
    ``rigidity``.
    """

    stiffness: float | None
    core: float | None
    #: the contact distance (mm) the law takes from the yarn in :meth:`for_yarn` (``rod_shell``: the
    #: diameter of the yarn's shell); None: the knitted diameter dk
    outer: float | None = None

    def normal(
        self, d: np.ndarray, dk: float, k: float, k_core: float | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Energy e and its first and second derivatives in the centre distances d (m,), mm, for
        contact distance dk (mm), stiffness k and core stiffness k_core (default k); e is 0 for
        d >= dk."""

    def for_yarn(self, yarn: Yarn) -> RodContactLaw:
        """This law with what it reads from the yarn's record; the rod solver uses only what this returns.

        The default: a ``core`` of None becomes the yarn's compaction limit ``yarn.compaction``. A
        law that needs a record field the yarn lacks raises ConfigError at ``solver.contact_law``.
        """
        if self.core is None:
            import attrs

            return attrs.evolve(self, core=float(yarn.compaction))
        return self

    def rigidity(self, yarn: Yarn) -> float | None:
        """The stiffness k (N/mm³) the rod passes to :meth:`normal`, from the yarn's own compression law.

        None (the default): the rod scales k to the yarn model's line-contact stiffness.
        """
        return None

    def friction_potential(
        self, u: np.ndarray, lam: np.ndarray, dk: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Friction pseudo-potential D (m,), its gradient (m, 3) and Hessian (m, 3, 3) in the slip
        u (m, 3), mm, with lagged normal forces ``lam`` (m,), N."""


@runtime_checkable
class SolidContactLaw(ContactLaw, Protocol):
    """Contact between tetrahedral yarn surfaces (``discretisation = "solid"``).

    Energies are in N·mm; gradients and Hessians are in q = [u (3N), h (6)] (node displacements
    and the macroscopic displacement gradient). ``stiffness`` is the given penalty ε (N/mm³;
    None: from the contact modulus and element size, see :meth:`penalty`).
    """

    stiffness: float | None
    #: the law is a barrier: its energy is infinite once surfaces touch, and :meth:`step_limit` (CCD)
    #: bounds each step so that none cross
    barrier: ClassVar[bool] = False
    #: :meth:`evaluate` takes ``candidates``: a search's pairs held through a Newton iteration's
    #: line search
    holds_candidates: ClassVar[bool] = False
    #: the largest load strain (-) the law has been seen to finish on a knitted cell; None: no limit
    finishes_strain: ClassVar[float | None] = None

    def penalty(self, modulus: float, size: float) -> float:
        """Penalty stiffness ε (N/mm³) for contact modulus E (MPa) and element size h (mm)."""

    def evaluate(
        self,
        surface: Any,
        x: np.ndarray,
        h: np.ndarray | None,
        order: int,
        *,
        stiffness: float,
        reach: float,
        friction_state: Any = None,
        normals: np.ndarray | None = None,
        candidates: Any = None,
    ) -> tuple[float, Any, Any, dict[str, Any]]:
        """Energy, gradient (``order`` >= 1) and Hessian (``order`` == 2) at node positions x (N, 3)
        and macroscopic gradient h (6,), and a dict of diagnostics. ``normals`` and ``candidates``
        are passed only when :meth:`master_normals` gives normals and the law ``holds_candidates``."""

    def friction_state(
        self,
        surface: Any,
        x: np.ndarray,
        h: np.ndarray | None,
        *,
        stiffness: float,
        reach: float,
        normals: np.ndarray | None = None,
    ) -> Any:
        """The contact pairs of the converged state x, frozen for the next increment's friction."""

    def master_normals(self, surface: Any, x: np.ndarray | None = None) -> np.ndarray | None:
        """Nodal normals (N, 3) that shape a smoothed master surface at x, frozen by the solver at
        the start of each increment and passed to :meth:`evaluate`. Default: None (no smoothing)."""
        return None

    def step_limit(
        self,
        surface: Any,
        x: np.ndarray,
        h: np.ndarray | None,
        dx: np.ndarray,
        dh: np.ndarray | None,
        *,
        stiffness: float,
    ) -> float:
        """Largest fraction α ∈ [0, 1] of the step (dx, dh) along which no surfaces cross. Called
        only for a ``barrier`` law. Default: 1.0 (no check)."""
        return 1.0


#: ``factory(**options) -> solve``, a :class:`LinearSolve`.
LinearSolverFactory = Callable[..., "LinearSolve"]


@runtime_checkable
class Factors(Protocol):
    """A factorisation kept for several right-hand sides: ``x = f(b)``; ``f.free()`` releases it."""

    def __call__(self, b: np.ndarray) -> np.ndarray:
        """Solution x (n,) of A x = b for the factorised A."""

    def free(self) -> None:
        """Release the factors (they are also released when ``f`` is garbage-collected)."""


@runtime_checkable
class LinearSolve(Protocol):
    """``solve(A: scipy.sparse matrix, b: ndarray) -> x``, as returned by a linear-solver factory.

    ``factorize`` is the optional capability of a solver that factorises: ``solve.factorize(A) ->
    f`` (:class:`Factors`) keeps the factors for several right-hand sides (Newton's chord steps
    reuse them); None for a solver that does not (an iterative one).
    """

    factorize: Callable[[Any], Factors] | None

    def __call__(self, A: Any, b: np.ndarray) -> np.ndarray:
        """Solution x (n,) of A x = b."""


@runtime_checkable
class Homogenizer(Protocol):
    """A reduced-order membrane model ψ(λ1, λ2; params) with nominal stresses P1 = ∂ψ/∂λ1, P2 = ∂ψ/∂λ2.

    Parameters are a float64 array ordered as ``param_names``; angles in radians. Stretches are
    arrays of one shape (n,); every derivative below is of that shape, ``stress_grad``'s
    parameter derivatives (n, len(param_names)).
    """

    name: ClassVar[str]
    description: ClassVar[str]
    param_names: ClassVar[tuple[str, ...]]
    #: unit of each parameter, for tables and reports
    units: ClassVar[tuple[str, ...]]
    #: parameters a fit searches on a log scale
    log_scale: ClassVar[tuple[bool, ...]]
    #: the model gives the free side's stretch under uniaxial load (False: a fit imposes the measured one)
    predicts_lateral: ClassVar[bool]
    #: bounds that are symmetry planes of the model (a fit reports a parameter there as not determined)
    symmetric_bounds: ClassVar[tuple[bool, ...]]
    #: the formats of :mod:`knitframe.export` :meth:`card` writes (empty: none can express the model)
    card_formats: ClassVar[tuple[str, ...]] = ()
    #: why a format outside ``card_formats`` cannot express the model (one clause)
    card_refusal: ClassVar[str] = ""

    def card(self, fmt: str, params: Any, **options: Any) -> str:
        """The material card in ``fmt`` (one of ``card_formats``) for the parameters as stored in
        params.json. Default: none (``card_formats`` is empty)."""
        raise ValueError(f"{self.name}: no {fmt} card ({self.card_refusal or 'no card formats'})")

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the parameters, each (len(param_names),)."""

    def x0(self) -> np.ndarray:
        """Default parameters, within :meth:`bounds`."""

    def energy(self, params: np.ndarray, lam1: np.ndarray, lam2: np.ndarray) -> np.ndarray:
        """Strain energy per unit reference area, N/mm."""

    def stress(self, params: np.ndarray, lam1: np.ndarray, lam2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nominal stresses (tension per unit reference width) P1, P2 in N/mm."""

    def stress_grad(self, params: np.ndarray, lam1: np.ndarray, lam2: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(P1, P2, ∂P1/∂params, ∂P2/∂params)``, N/mm."""

    def tangent(
        self, params: np.ndarray, lam1: np.ndarray, lam2: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(K11, K12, K22)``, K_ij = ∂P_i/∂λ_j, N/mm (K21 = K12)."""

    def stress_tangent(
        self, params: np.ndarray, lam1: np.ndarray, lam2: np.ndarray
    ) -> tuple[np.ndarray, ...]:
        """``(P1, P2, K11, K12, K22)`` in one evaluation, N/mm."""

    def solve_uniaxial(
        self, params: np.ndarray, lam: np.ndarray, direction: str = "course"
    ) -> tuple[np.ndarray, np.ndarray]:
        """Free-side stretch and loaded tension under uniaxial load along ``direction``:
        ``(lam_free, P_loaded)``, each of the shape of ``lam``."""

    def free_side_slack(self, params: np.ndarray, direction: str = "course") -> float:
        """Loaded stretch up to which a free side keeps the uniaxial tension at zero. Default: 1.0
        (tension from the start)."""
        return 1.0


@runtime_checkable
class Fitter(Protocol):
    """Fits a homogenizer's parameters to one or more Responses jointly."""

    name: ClassVar[str]
    description: ClassVar[str]

    def fit(self, model: Homogenizer, responses: Iterable[Response]) -> Any:
        """Best parameters with NRMSE per direction and overall, wall time and evaluation count."""


@runtime_checkable
class DesignObjective(Protocol):
    """Scores a garment assignment; lower is better.

    The optimiser of :mod:`knitframe.garment` needs the objective as a sum over elements, so that it
    can find the best assignment exactly: :meth:`element_cost` is that sum's term. An objective
    whose target is a free level (uniform tension or pressure, whatever its value) says so with
    ``relative = True``; the optimiser then searches the level τ as well.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    #: the per-element field it scores: ``"tension"`` (N/mm) or ``"pressure"`` (mmHg)
    quantity: ClassVar[str]

    @property
    def relative(self) -> bool:
        """True when the target level is free (uniformity): element_cost then takes a level τ."""

    def score(self, tension: np.ndarray, area: np.ndarray, radius: np.ndarray | None = None) -> float:
        """Score of per-element circumferential tension (N/mm), element area (mm²), limb radius (mm)."""

    def element_cost(
        self, value: np.ndarray, area: np.ndarray, position: np.ndarray, level: float | None = None
    ) -> np.ndarray:
        """Additive cost of each element's value (shape ``(..., E)``), its area (E,) and its position
        along the limb (E,, 0 distal to 1 at the top); ``level`` is τ for relative objectives."""

    def target(self, position: np.ndarray) -> np.ndarray | None:
        """The target pressure (mmHg) at positions along the limb (0 distal, 1 top), or None when the
        objective sets no absolute target (read through :func:`declared`). Default: None."""
        return None

    def evaluate(self, value: np.ndarray, area: np.ndarray, position: np.ndarray) -> float:
        """The objective of a finished design, as reported (lower is better)."""


@runtime_checkable
class Executor(Protocol):
    """Runs many independent jobs; results are cached by the hash of each job's config."""

    name: ClassVar[str]
    description: ClassVar[str]

    def map(
        self,
        fn: Callable[[Mapping[str, Any]], Any],
        jobs: list[Mapping[str, Any]],
        *,
        failures: str = "raise",
        progress: Callable[..., Any] | None = None,
    ) -> list[Any]:
        """``[fn(job) for job in jobs]``, possibly in parallel, in order.

        ``failures = "raise"`` raises the first job's exception; ``"keep"`` puts a
        :class:`~knitframe.cache.JobFailure` in place of each failed job's result. ``progress``
        is called as jobs finish (see :mod:`knitframe_executors`)."""


@runtime_checkable
class Reader(Protocol):
    """Reads one data-file format into Responses."""

    name: ClassVar[str]
    description: ClassVar[str]

    def read(self, path: Path) -> list[Response]:
        """Responses in the file; a malformed file raises DataError naming file, line and column."""


@runtime_checkable
class HeaderReader(Reader, Protocol):
    """A reader that recognises its files by their header row, so the ``auto`` reader can choose it.

    A reader without these members is chosen by name only.
    """

    #: the header it reads, for the message when no reader knows a file's header
    expects: ClassVar[str]

    @classmethod
    def accepts(cls, header: Sequence[str]) -> bool:
        """True if a file with these column names is this reader's format."""


@runtime_checkable
class DispatchingReader(Reader, Protocol):
    """A reader that hands each file to another reader (``auto``); the run records which one."""

    def reader_for(self, path: Path) -> Reader:
        """The reader instance that reads ``path``."""


@runtime_checkable
class Stage(Protocol):
    """A pipeline stage. It owns the top-level config table ``name`` and may read ``uses`` tables.

    Stages run in ascending ``order``. ``from_config`` validates everything (files exist, plugin
    names resolve, effects are supported) before any stage runs; ``run`` does the work.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    order: ClassVar[int]
    uses: ClassVar[tuple[str, ...]]
    #: the table may be given several times (``[[name]]``), one stage instance per table
    repeatable: ClassVar[bool] = False
    #: the top-level table the stage owns when it is not ``name`` (the simulate stage owns ``[solver]``)
    table: ClassVar[str | None] = None

    @property
    def label(self) -> str:
        """The stage's name in timings and results (``fit:measured`` for a named repeat).

        Default: ``name``."""
        return self.name

    @classmethod
    def from_config(cls, config: Mapping[str, Any], ctx: BuildContext) -> Stage:
        """Validated stage from the whole config dict."""

    def run(self, ctx: RunContext) -> None:
        """Do the work, reading and adding to the run context."""


def declared(plugin: Any, protocol: type, member: str) -> Any:
    """``plugin``'s ``member``, or the default that ``protocol`` declares for it.

    For the optional members of a protocol that older plugins may not state (a stage's
    ``repeatable``, ``table`` and ``label``, a pattern's ``stitch_lengths``, a design objective's
    ``target``): the default is the protocol's own definition (a property is evaluated on
    ``plugin``, a method is bound to it). A member the protocol declares without a default is
    required, and asking for it here is an error.
    """
    for klass in protocol.__mro__:
        if member in vars(klass):
            default = vars(klass)[member]
            break
    else:
        raise KeyError(f"{protocol.__name__} declares no default for {member!r}")
    try:
        return getattr(plugin, member)
    except AttributeError:
        if isinstance(default, property):
            return default.fget(plugin)
        return types.MethodType(default, plugin) if isinstance(default, types.FunctionType) else default
