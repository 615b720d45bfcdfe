"""The conformance kit passes on every registered implementation."""

from __future__ import annotations

import pytest

from knitframe.plugins import load_registry
from knitframe.testing import check_entry

ENTRIES = load_registry().entries()


@pytest.mark.parametrize("entry", ENTRIES, ids=[f"{e.kind}:{e.name}" for e in ENTRIES])
def test_plugin_conforms(entry):
    """Each registered plugin honours the contract of its kind."""
    check_entry(entry)


def test_kit_catches_a_broken_objective():
    """The objective check fails for an objective that ignores non-uniformity."""
    from knitframe.testing import check_design_objective

    class Flat:
        name = "flat"
        description = "always zero"

        def score(self, tension, area, radius=None):
            return 0.0

    with pytest.raises(AssertionError, match="non-uniform"):
        check_design_objective(Flat)


def _registered(kind: str, obj, hook: str):
    """The entry of ``obj`` registered as a ``kind`` plugin from a throwaway module."""
    import types

    import knitframe

    mod = types.ModuleType(f"incomplete_{kind}")

    def impl(register):
        register(obj)

    setattr(mod, hook, knitframe.hookimpl(impl))
    return knitframe.load_registry({mod.__name__: mod})[kind].entry(obj.name)


class _Solver:
    name = "incomplete"
    description = "declares simulate only"
    effects = frozenset({"large_deformation"})
    loads = frozenset({"equibiaxial"})

    def simulate(self, fabric, scene, *, progress=None):
        raise AssertionError("the kit must not simulate it")


def test_kit_catches_a_solver_without_its_declared_flags_and_validate():
    """A solver without checkpoints, writes_vtu, conformance_simulate and validate fails the kit, naming
    them."""
    with pytest.raises(AssertionError, match="lacks checkpoints, conformance_simulate, validate, writes_vtu"):
        check_entry(_registered("solver", _Solver, "register_solvers"))


def test_kit_accepts_a_solver_that_inherits_the_declared_defaults():
    """Subclassing the Solver protocol gives the declared defaults: the kit accepts it."""
    from knitframe.interfaces import Solver

    class Complete(_Solver, Solver):
        pass

    assert Complete().checkpoints is False and Complete().validate(None, None) is None
    check_entry(_registered("solver", Complete, "register_solvers"))


def test_kit_catches_a_solid_contact_law_without_its_barrier_members():
    """A solid law that declares only evaluate and penalty fails: its flags, friction and CCD members are
    missing."""
    from knitframe.testing.solvers import check_contact_law

    class Bare:
        name = "bare"
        description = "no flags"
        discretisation = "solid"
        stiffness = None

        def penalty(self, modulus, size):
            return 10.0 * modulus / size

        def evaluate(self, surface, x, h, order, *, stiffness, reach, **_):
            return 0.0, None, None, {}

    with pytest.raises(
        AssertionError, match="lacks barrier, finishes_strain, friction_state, holds_candidates"
    ):
        check_contact_law(Bare)


def test_kit_catches_a_rod_law_that_ignores_the_yarn():
    """A rod law whose ``for_yarn`` leaves the core unset fails, and so does a negative ``rigidity``;
    the shipped law it derives from passes."""
    from knitframe_contact.rod_penalty import RodPenalty

    from knitframe.testing.solvers import check_contact_law

    check_contact_law(RodPenalty)

    class Careless(RodPenalty):
        def for_yarn(self, yarn):
            return self

    class Negative(RodPenalty):
        def rigidity(self, yarn):
            return -1.0

    with pytest.raises(AssertionError, match="for_yarn must set the core"):
        check_contact_law(Careless)
    with pytest.raises(AssertionError, match="rigidity"):
        check_contact_law(Negative)


def test_kit_catches_a_non_boolean_flag():
    """A declared ClassVar[bool] flag must be True or False."""
    from knitframe.testing.solvers import check_contact_law

    law = load_registry()["contact_law"]["ipc"]

    class Vague(law):
        barrier = "yes"

    with pytest.raises(AssertionError, match="barrier must be True or False"):
        check_contact_law(Vague)


def test_kit_catches_a_linear_solve_without_factorize():
    """The factory's solve must declare factorize (None when it keeps no factors)."""
    import scipy.sparse.linalg as spla

    from knitframe.testing.solvers import check_linear_solver

    def plain():
        return lambda A, b: spla.spsolve(A.tocsc(), b)

    with pytest.raises(AssertionError, match="lacks factorize"):
        check_linear_solver(plain)


def test_kit_catches_a_homogenizer_without_stress_tangent():
    """A homogenizer missing a declared derivative fails the kit, naming it."""

    class NoTangent:
        name = "no-tangent"
        description = "every member but stress_tangent"
        param_names, units, log_scale, symmetric_bounds = ("a",), ("N/mm",), (True,), (False,)
        predicts_lateral = False
        card_formats, card_refusal = (), "no card"

    for method in (
        "card",
        "bounds",
        "x0",
        "energy",
        "stress",
        "stress_grad",
        "tangent",
        "solve_uniaxial",
        "free_side_slack",
    ):
        setattr(NoTangent, method, lambda self, *args: None)
    with pytest.raises(AssertionError, match="no-tangent' lacks stress_tangent "):
        check_entry(_registered("homogenizer", NoTangent, "register_homogenizers"))


def test_kit_catches_an_executor_whose_map_lacks_the_keywords():
    """map(fn, jobs) without failures= and progress= fails the executor check."""
    from knitframe.testing import check_executor

    class Plain:
        name = "plain"
        description = "map without keywords"

        def map(self, fn, jobs):
            return [fn(j) for j in jobs]

    with pytest.raises(AssertionError, match="failures= and progress="):
        check_executor(Plain())


def test_kit_catches_a_reader_with_half_of_the_header_protocol():
    """A reader with accepts but no expects fails: the auto reader needs both to choose it."""

    class Half:
        name = "half"
        description = "accepts without expects"

        @classmethod
        def accepts(cls, header):
            return False

        def read(self, path):
            return []

    with pytest.raises(AssertionError, match="lacks expects"):
        check_entry(_registered("reader", Half, "register_readers"))


def test_declared_gives_a_stage_the_protocol_defaults_and_refuses_a_required_member():
    """An optional member a plugin does not state reads as the protocol's default (a property is
    evaluated); a member declared without a default cannot be read that way."""
    from knitframe.interfaces import Stage, declared

    class Old:
        name = "old"

    class Own:
        name = "own"
        table = "solver"
        repeatable = True

    assert declared(Old(), Stage, "table") is None and declared(Old, Stage, "repeatable") is False
    assert declared(Old(), Stage, "label") == "old"
    assert declared(Own(), Stage, "table") == "solver" and declared(Own, Stage, "repeatable") is True
    with pytest.raises(KeyError, match="no default for 'order'"):
        declared(Old(), Stage, "order")
