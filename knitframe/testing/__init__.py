"""Conformance kit: the contract checks every plugin of a kind must pass.

Third-party authors run it on their own plugins::

    from knitframe.testing import check_plugin
    check_plugin("pattern", "tuck")          # raises AssertionError explaining what is wrong

The project's own test suite runs :func:`check_plugin` over every registered implementation.
Every plugin is first checked for the members its protocol in :mod:`knitframe.interfaces`
declares (:func:`~knitframe.testing.members.check_members`); kind-specific checks live in
submodules (``patterns``, ``models``, ``solvers``), each exposing a ``CHECKS`` dict that is merged
into :data:`CHECKS` here.
"""

from __future__ import annotations

import importlib
import inspect
import tempfile
from collections.abc import Callable
from typing import Any

import attrs
import numpy as np

from knitframe import interfaces
from knitframe.cache import JobCache, JobFailure, job_key
from knitframe.plugins import KINDS, Entry, Registry, get_registry
from knitframe.records import Yarn
from knitframe.testing.members import check_members

__all__ = ["CHECKS", "PROTOCOLS", "check_plugin", "check_entry", "check_registry", "default_instance"]

#: kind → Protocol the registered object (or an instance of it) must satisfy
PROTOCOLS: dict[str, type] = {
    "pattern": interfaces.Pattern,
    "yarn_model": interfaces.YarnModel,
    "solver": interfaces.Solver,
    "contact_law": interfaces.ContactLaw,
    "homogenizer": interfaces.Homogenizer,
    "fitter": interfaces.Fitter,
    "design_objective": interfaces.DesignObjective,
    "executor": interfaces.Executor,
    "reader": interfaces.Reader,
    "stage": interfaces.Stage,
}


def default_instance(obj: Any) -> Any:
    """An instance built with default options (attrs classes), or the object itself."""
    if isinstance(obj, type) and attrs.has(obj):
        return obj()
    return obj


def _square(job: dict) -> float:
    return float(job["x"]) ** 2


def _square_or_fail(job: dict) -> float:
    if job["x"] < 0:
        raise ValueError("negative")
    return float(job["x"]) ** 2


def check_executor(obj: Any) -> None:
    """Runs jobs in order, reuses cached results instead of recomputing them, keeps failures as
    JobFailures with ``failures = "keep"`` and reports through ``progress``."""
    calls: list[tuple[float, float]] = []
    with tempfile.TemporaryDirectory() as tmp:
        ex = obj(cache_dir=tmp) if attrs.has(obj) else obj
        try:
            out = ex.map(
                _square_or_fail,
                [{"x": 3}, {"x": -1}],
                failures="keep",
                progress=lambda done, total, message: calls.append((done, total)),
            )
        except TypeError as e:
            raise AssertionError(
                f"map(fn, jobs) must take the keywords failures= and progress=: {e}"
            ) from None
    assert out[0] == 9.0 and isinstance(out[1], JobFailure), (
        f'map(..., failures="keep") must put a JobFailure in place of a failed job, got {out!r}'
    )
    assert calls and calls[-1] == (2, 2), f"progress must be told when all jobs are done, got {calls}"
    jobs = [{"x": i} for i in range(4)]
    with tempfile.TemporaryDirectory() as tmp:
        ex = obj(cache_dir=tmp) if attrs.has(obj) else obj
        assert ex.map(_square, jobs) == [0.0, 1.0, 4.0, 9.0], "map must return results in job order"
        # plant a sentinel in the cache: a cached job must come back from the cache, not be recomputed
        JobCache(tmp).put(job_key(_square, jobs[2]), "cached")
        assert ex.map(_square, jobs)[2] == "cached", (
            "a finished job was recomputed instead of read from the cache"
        )


def check_design_objective(obj: Any) -> None:
    """Scores uniform tension better than non-uniform, always finite; its per-element cost is
    additive, non-negative and zero where the target (or, for a relative objective, the level) is met."""
    inst = default_instance(obj)
    area = np.array([1.0, 2.0, 1.5, 0.5])
    radius = np.array([30.0, 30.0, 30.0, 30.0])
    uniform = inst.score(np.full(4, 0.07), area, radius)
    varied = inst.score(np.array([0.05, 0.07, 0.09, 0.11]), area, radius)
    assert np.isfinite(uniform) and np.isfinite(varied), "scores must be finite"
    assert varied > uniform, f"non-uniform tension must score worse ({varied} <= {uniform})"
    assert inst.quantity in ("tension", "pressure"), (
        f"quantity must be 'tension' or 'pressure', got {inst.quantity!r}"
    )
    position = np.linspace(0.0, 1.0, 4)
    values = np.array([[5.0, 10.0, 15.0, 20.0], [12.0, 12.0, 12.0, 12.0]])
    level = 12.0 if inst.relative else None
    cost = np.asarray(inst.element_cost(values, area, position, level))
    assert cost.shape == values.shape, f"element_cost must keep the shape of the values, got {cost.shape}"
    assert np.all(np.isfinite(cost)) and np.all(cost >= 0), "element costs must be finite and >= 0"
    if inst.relative:
        assert np.allclose(cost[1], 0.0), (
            "a relative objective's cost is zero where every value equals the level"
        )
    assert np.isfinite(inst.evaluate(values[0], area, position)), "evaluate must be finite"


def check_stage(obj: Any) -> None:
    """Declares its table, order and used tables, and has from_config/run."""
    assert isinstance(obj.order, int), "stage.order must be an int"
    assert isinstance(obj.uses, tuple), "stage.uses must be a tuple of table names"
    assert inspect.ismethod(obj.from_config), "stage.from_config must be a classmethod"
    assert callable(obj.run), "stage.run must be callable"


def check_yarn(obj: Any) -> None:
    """Is a valid Yarn record that round-trips through a dict."""
    assert isinstance(obj, Yarn), f"a registered yarn must be a knitframe.Yarn, got {type(obj).__name__}"
    assert Yarn.from_dict(obj.to_dict()) == obj, "yarn must round-trip through to_dict/from_dict"


def check_linear_solver_basic(obj: Any) -> None:
    """The factory returns a closure solving a small SPD system."""
    import scipy.sparse as sp

    n = 50
    A = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n), format="csr") + sp.eye(n) * 0.01
    x_true = np.linspace(0.0, 1.0, n)
    x = obj()(A, A @ x_true)
    assert np.allclose(x, x_true, rtol=1e-6, atol=1e-8), "solve(A, A @ x) must return x"


CHECKS: dict[str, Callable[[Any], None]] = {
    "executor": check_executor,
    "design_objective": check_design_objective,
    "stage": check_stage,
    "yarn": check_yarn,
    "linear_solver": check_linear_solver_basic,
}

for _mod in ("patterns", "models", "solvers"):
    try:
        CHECKS.update(importlib.import_module(f"knitframe.testing.{_mod}").CHECKS)
    except ModuleNotFoundError as _e:  # a kit part whose plugins are not part of this install
        if _e.name != f"knitframe.testing.{_mod}":
            raise


def check_entry(entry: Entry) -> None:
    """Common contract (name, description, every member its protocol declares) plus the kind's own check."""
    assert entry.kind in KINDS, f"unknown kind {entry.kind}"
    assert isinstance(entry.name, str) and entry.name, "a plugin needs a non-empty name"
    assert entry.description, f"{entry.kind} '{entry.name}' needs a description (ClassVar or docstring)"
    obj = entry.obj
    declared = getattr(obj, "name", entry.name)
    if entry.kind not in ("yarn", "linear_solver"):
        assert declared == entry.name, f"registered as '{entry.name}' but its name attribute is '{declared}'"
    proto = PROTOCOLS.get(entry.kind)
    if proto is not None:
        # stages and yarn models are built from a config / a Yarn, not from defaults
        target = default_instance(obj) if entry.kind not in ("stage", "yarn_model") else obj
        check_members(target, proto, f"{entry.kind} '{entry.name}'")
    if entry.kind == "linear_solver":
        assert callable(obj), "a linear solver is a factory function returning solve(A, b)"
    check = CHECKS.get(entry.kind)
    if check is not None:
        check(obj)


def check_plugin(kind: str, name: str, registry: Registry | None = None) -> None:
    """Run the conformance checks on the plugin ``name`` of ``kind``."""
    check_entry((registry or get_registry())[kind].entry(name))


def check_registry(registry: Registry | None = None) -> list[tuple[Entry, str]]:
    """Run every check over every registered plugin; returns ``(entry, failure)`` pairs."""
    failures = []
    for entry in (registry or get_registry()).entries():
        try:
            check_entry(entry)
        except AssertionError as e:
            failures.append((entry, str(e)))
    return failures
