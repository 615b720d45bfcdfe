"""Hooks, tests and docs stay in step: every hook has a docs heading with its signature and a test."""

from __future__ import annotations

import ast
import inspect
import types

import attrs
import pytest
from conftest import ROOT

import knitframe
from knitframe import hookspecs
from knitframe.plugins import KINDS
from knitframe.testing import check_entry

HOOKS = {name: fn for name, fn in vars(hookspecs).items() if name.startswith("register_") and callable(fn)}

#: The built-in plugins every install ships, by kind.
BUILTINS = {
    "pattern": {"jersey", "garter", "rib", "seed"},
    "yarn": {"cotton", "nylon", "pet"},
    "yarn_model": {"transverse_isotropic", "isotropic"},
    "solver": {"reduced", "rod"},
    "contact_law": {"rod_penalty"},
    "linear_solver": {"direct", "amg"},
    "homogenizer": {"hgo"},
    "fitter": {"mads", "lbfgs"},
    "design_objective": {"stress_variance", "pressure_uniformity"},
    "executor": {"local", "dask"},
    "reader": {"singal2024", "generic"},
    "stage": {"data", "fit", "patchwork", "simulate"},
}


def signature(name: str) -> str:
    params = ", ".join(inspect.signature(HOOKS[name]).parameters)
    return f"{name}({params})"


def test_hooks_and_kinds_agree():
    """Each hookspec belongs to exactly one plugin kind."""
    assert sorted(HOOKS) == sorted(KINDS.values())


@pytest.mark.parametrize("hook", sorted(HOOKS))
def test_every_hook_has_a_docs_heading_with_its_signature(hook):
    """docs/plugins.md has a heading with the hook's exact signature."""
    text = (ROOT / "docs" / "plugins.md").read_text()
    assert f"## `{signature(hook)}`" in text.splitlines(), f"docs/plugins.md lacks '## `{signature(hook)}`'"


@pytest.mark.parametrize("hook", sorted(HOOKS))
def test_every_hook_has_a_test(hook):
    """Some test module defines test_hook_<hook>."""
    names = set()
    for path in (ROOT / "tests").glob("test_*.py"):
        names |= {n.name for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.FunctionDef)}
    assert f"test_hook_{hook}" in names


def _check_hook(kind: str) -> None:
    """A plugin implementing only this hook lands in this kind with provenance; built-ins are there and
    conform."""
    hook = KINDS[kind]

    @attrs.frozen
    class Probe:
        name = f"probe-{kind}"
        description = f"probe for {hook}"

    mod = types.ModuleType(f"probe_{kind}")

    def impl(register):
        register(Probe)

    setattr(mod, hook, knitframe.hookimpl(impl))
    reg = knitframe.load_registry({f"probe_{kind}": mod})
    entry = reg[kind].entry(f"probe-{kind}")
    assert (entry.obj, entry.plugin, entry.package) == (Probe, f"probe_{kind}", "extra")
    assert all(f"probe-{kind}" not in reg[k] for k in KINDS if k != kind)
    missing = BUILTINS[kind] - set(reg[kind])
    assert not missing, f"built-in {kind} plugins missing: {sorted(missing)}"
    for name in BUILTINS[kind]:
        check_entry(reg[kind].entry(name))


def test_hook_register_patterns():
    """register_patterns collects patterns; jersey, garter, rib and seed are built in."""
    _check_hook("pattern")


def test_hook_register_yarns():
    """register_yarns collects yarns; cotton, nylon and pet are built in."""
    _check_hook("yarn")


def test_hook_register_yarn_models():
    """register_yarn_models collects yarn laws; transversely isotropic and isotropic are built in."""
    _check_hook("yarn_model")


def test_hook_register_solvers():
    """register_solvers collects solvers; the built-ins declare their effects."""
    _check_hook("solver")


def test_hook_register_contact_laws():
    """register_contact_laws collects contact laws."""
    _check_hook("contact_law")


def test_hook_register_linear_solvers():
    """register_linear_solvers collects linear-solver factories; direct and amg are built in."""
    _check_hook("linear_solver")


def test_hook_register_homogenizers():
    """register_homogenizers collects reduced models; the paper's hgo is built in."""
    _check_hook("homogenizer")


def test_hook_register_fitters():
    """register_fitters collects fitters; mads and lbfgs are built in."""
    _check_hook("fitter")


def test_hook_register_design_objectives():
    """register_design_objectives collects objectives; stress variance and pressure uniformity are built
    in."""
    _check_hook("design_objective")


def test_hook_register_executors():
    """register_executors collects executors; local and dask are built in."""
    _check_hook("executor")


def test_hook_register_readers():
    """register_readers collects readers; singal2024 and generic are built in."""
    _check_hook("reader")


def test_hook_register_stages():
    """register_stages collects pipeline stages; data, fit, patchwork and simulate are built in."""
    _check_hook("stage")
