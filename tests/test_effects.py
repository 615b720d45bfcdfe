"""Effects are opt-in: unsupported effects and loads are refused by name before any work."""

from __future__ import annotations

import types

import pytest

import knitframe
from knitframe import LoadPath, Scene
from knitframe.effects import require_effects, solvers_supporting
from knitframe.errors import ConfigError, UnsupportedEffectError


class _Solver:
    calls = 0

    def simulate(self, fabric, scene, *, progress=None):
        type(self).calls += 1
        raise AssertionError("simulate must not run in these tests")


class MembraneOnly(_Solver):
    name = "membrane-only"
    description = "large deformation only"
    effects = frozenset({"large_deformation"})
    loads = frozenset({"equibiaxial"})


class WithContact(_Solver):
    name = "with-contact"
    description = "contact and friction"
    effects = frozenset({"large_deformation", "contact", "friction"})
    loads = frozenset({"equibiaxial", "uniaxial-course"})


@pytest.fixture
def registry():
    mod = types.ModuleType("effect_solvers")

    @knitframe.hookimpl
    def register_solvers(register):
        register(MembraneOnly)
        register(WithContact)

    mod.register_solvers = register_solvers
    return knitframe.load_registry({"effect_solvers": mod})


def test_unsupported_effect_names_effect_and_lists_supporting_solvers(registry):
    """Asking a solver for friction it lacks names 'friction' and lists every solver that has it."""
    scene = Scene(effects={"large_deformation", "contact", "friction"})
    with pytest.raises(UnsupportedEffectError) as e:
        require_effects(scene, MembraneOnly, registry)
    assert e.value.effect == "contact"  # checked in sorted order
    assert "with-contact" in e.value.supporting and "membrane-only" not in e.value.supporting
    assert str(e.value).startswith("scene.effects: solver 'membrane-only' does not support effect 'contact'")
    assert MembraneOnly.calls == 0


def test_supported_effects_pass(registry):
    """A scene within the solver's effects and loads passes silently."""
    require_effects(Scene(effects={"contact", "friction"}), WithContact, registry)


def test_unsupported_load_is_refused(registry):
    """A load path the solver cannot follow is refused with the solvers that can."""
    scene = Scene(LoadPath("uniaxial", direction="course"), effects={"large_deformation"})
    with pytest.raises(ConfigError, match="cannot follow load 'uniaxial-course'; solvers that can: ") as e:
        require_effects(scene, MembraneOnly, registry)
    assert "with-contact" in str(e.value).split("solvers that can: ")[1]
    assert "membrane-only" not in str(e.value).split("solvers that can: ")[1]


def test_solvers_supporting(registry):
    """solvers_supporting lists exactly the solvers declaring the effect."""
    assert "with-contact" in solvers_supporting(registry, "friction")
    assert "membrane-only" not in solvers_supporting(registry, "friction")
