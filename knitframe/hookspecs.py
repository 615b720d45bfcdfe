"""Every knitframe hook. A plugin implements one or more of them with ``@knitframe.hookimpl``.

Each hook receives a ``register`` callback: ``register(impl, name=None, description=None)``.
``impl`` is usually a class whose ``ClassVar`` fields ``name`` and ``description`` say what it is;
for yarns it is a :class:`~knitframe.records.Yarn`, for linear solvers a factory function.
Passing a callback (rather than returning values) lets the core add keyword arguments later
without breaking plugins.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import pluggy

if TYPE_CHECKING:  # pragma: no cover
    from knitframe.plugins import Register

hookspec = pluggy.HookspecMarker("knitframe")
hookimpl = pluggy.HookimplMarker("knitframe")

__all__ = ["hookspec", "hookimpl"]


@hookspec
def register_patterns(register: Register) -> None:
    """Register stitch patterns: unit-cell yarn centerlines and lattice vectors
    (:class:`~knitframe.interfaces.Pattern`).

    :param register: call ``register(PatternClass)`` once per pattern. A class attribute
        ``aliases`` (a tuple of names, e.g. jersey's ``("stockinette",)``) lets a config name the
        pattern by those too; it is recorded under its own name.
    """


@hookspec
def register_yarns(register: Register) -> None:
    """Register named yarns for the yarn library (:class:`~knitframe.records.Yarn` records).

    :param register: call ``register(Yarn(...))`` once per yarn; the yarn's ``name`` is its key.
    """


@hookspec
def register_yarn_models(register: Register) -> None:
    """Register yarn constitutive laws and their rod stiffnesses (:class:`~knitframe.interfaces.YarnModel`).

    :param register: call ``register(YarnModelClass)`` once per law.
    """


@hookspec
def register_solvers(register: Register) -> None:
    """Register unit-cell solvers that turn a Fabric and a Scene into a Response
    (:class:`~knitframe.interfaces.Solver`).

    :param register: call ``register(SolverClass)``; the class declares its supported ``effects``.
    """


@hookspec
def register_contact_laws(register: Register) -> None:
    """Register yarn-yarn contact laws for a solver's discretisation
    (:class:`~knitframe.interfaces.ContactLaw`).

    :param register: call ``register(ContactLawClass)`` once per law.
    """


@hookspec
def register_linear_solvers(register: Register) -> None:
    """Register sparse linear solvers as factories returning ``solve(A, b) -> x`` closures.

    :param register: call ``register(factory, name="direct")``.
    """


@hookspec
def register_homogenizers(register: Register) -> None:
    """Register reduced-order fabric models: energy, stresses and export cards
    (:class:`~knitframe.interfaces.Homogenizer`).

    :param register: call ``register(HomogenizerClass)`` once per model.
    """


@hookspec
def register_fitters(register: Register) -> None:
    """Register optimisers that fit a homogenizer to Responses (:class:`~knitframe.interfaces.Fitter`).

    :param register: call ``register(FitterClass)`` once per fitter.
    """


@hookspec
def register_design_objectives(register: Register) -> None:
    """Register scores of a garment assignment (:class:`~knitframe.interfaces.DesignObjective`).

    :param register: call ``register(ObjectiveClass)`` once per objective.
    """


@hookspec
def register_executors(register: Register) -> None:
    """Register executors that run many independent jobs (:class:`~knitframe.interfaces.Executor`).

    :param register: call ``register(ExecutorClass)`` once per executor.
    """


@hookspec
def register_readers(register: Register) -> None:
    """Register data-file readers that turn test files into Responses (:class:`~knitframe.interfaces.Reader`).

    :param register: call ``register(ReaderClass)`` once per file format.
    """


@hookspec
def register_stages(register: Register) -> None:
    """Register pipeline stages, each owning a top-level config table (:class:`~knitframe.interfaces.Stage`).

    :param register: call ``register(StageClass)`` once per stage.
    """
