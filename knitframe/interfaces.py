"""The contracts each plugin kind honours.

Implementations are usually ``@attrs.frozen`` classes: their fields are the plugin's options,
so a config table ``[solver] kind = "rod"`` plus other keys becomes ``RodSolver(**keys)``
(see :func:`knitframe.config.instantiate`). Every implementation carries ``ClassVar`` fields
``name`` and ``description``. :mod:`knitframe.testing` checks these contracts.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from knitframe.pipeline import BuildContext, RunContext
    from knitframe.records import Fabric, Response, Scene, Yarn

__all__ = [
    "Pattern",
    "YarnModel",
    "Solver",
    "ContactLaw",
    "LinearSolverFactory",
    "Homogenizer",
    "Fitter",
    "DesignObjective",
    "Executor",
    "Reader",
    "Stage",
    "Progress",
]

#: ``progress(done, total, message)``: solvers report progress through this callback.
Progress = Callable[[float, float, str], None]


@runtime_checkable
class Pattern(Protocol):
    """A knit pattern: the 2x2 periodic unit cell of yarn centerlines for a given Fabric."""

    name: ClassVar[str]
    description: ClassVar[str]

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


@runtime_checkable
class Solver(Protocol):
    """Simulates a unit cell: ``simulate(fabric, scene) -> Response``.

    ``effects`` lists the :data:`~knitframe.records.EFFECTS` the solver can model; ``loads``
    the load-path kinds it can follow. A scene asking for anything else is refused before work.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    effects: ClassVar[frozenset[str]]
    loads: ClassVar[frozenset[str]]

    def simulate(self, fabric: Fabric, scene: Scene, *, progress: Progress | None = None) -> Response:
        """Run the scene and return the tension-stretch Response."""


@runtime_checkable
class ContactLaw(Protocol):
    """Yarn-yarn contact terms for one discretisation (``"rod"`` or ``"solid"``)."""

    name: ClassVar[str]
    description: ClassVar[str]
    discretisation: ClassVar[str]


#: ``factory(**options) -> solve`` with ``solve(A: scipy.sparse matrix, b: ndarray) -> ndarray``. A solver
#: that factorises may also offer ``solve.factorize(A) -> f``, ``x = f(b)`` with the factors kept for
#: several right-hand sides and ``f.free()`` to release them (Newton's chord steps reuse them).
LinearSolverFactory = Callable[..., Callable[[Any, np.ndarray], np.ndarray]]


@runtime_checkable
class Homogenizer(Protocol):
    """A reduced-order membrane model ψ(λ1, λ2; params) with nominal stresses P1 = ∂ψ/∂λ1, P2 = ∂ψ/∂λ2.

    Parameters are a float64 array ordered as ``param_names``; angles in radians.
    """

    name: ClassVar[str]
    description: ClassVar[str]
    param_names: ClassVar[tuple[str, ...]]

    def energy(self, params: np.ndarray, lam1: np.ndarray, lam2: np.ndarray) -> np.ndarray:
        """Strain energy per unit reference area, N/mm."""

    def stress(self, params: np.ndarray, lam1: np.ndarray, lam2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nominal stresses (tension per unit reference width) P1, P2 in N/mm."""


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

    def evaluate(self, value: np.ndarray, area: np.ndarray, position: np.ndarray) -> float:
        """The objective of a finished design, as reported (lower is better)."""


@runtime_checkable
class Executor(Protocol):
    """Runs many independent jobs; results are cached by the hash of each job's config."""

    name: ClassVar[str]
    description: ClassVar[str]

    def map(self, fn: Callable[[Mapping[str, Any]], Any], jobs: list[Mapping[str, Any]]) -> list[Any]:
        """``[fn(job) for job in jobs]``, possibly in parallel, in order."""


@runtime_checkable
class Reader(Protocol):
    """Reads one data-file format into Responses."""

    name: ClassVar[str]
    description: ClassVar[str]

    def read(self, path: Path) -> list[Response]:
        """Responses in the file; a malformed file raises DataError naming file, line and column."""


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

    @classmethod
    def from_config(cls, config: Mapping[str, Any], ctx: BuildContext) -> Stage:
        """Validated stage from the whole config dict."""

    def run(self, ctx: RunContext) -> None:
        """Do the work, reading and adding to the run context."""
