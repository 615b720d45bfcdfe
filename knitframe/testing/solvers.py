"""Conformance checks for linear-solver and contact-law plugins.

They are merged into :data:`knitframe.testing.CHECKS`.
"""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np

from knitframe import interfaces
from knitframe.testing.members import check_members

__all__ = ["CHECKS", "check_linear_solver", "check_contact_law"]


def _laplacian_3d(n: int):
    """SPD 7-point Laplacian on an n³ grid plus a small shift."""
    import scipy.sparse as sp

    d1 = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    eye = sp.identity(n)
    A = sp.kron(sp.kron(d1, eye), eye) + sp.kron(sp.kron(eye, d1), eye) + sp.kron(sp.kron(eye, eye), d1)
    return (A + 1e-3 * sp.identity(n**3)).tocsr()


def check_linear_solver(factory: Any) -> None:
    """A factory with default options returns ``solve(A, b)`` that solves SPD systems of several sizes
    to 1e-6; its declared ``factorize`` (None, or factors that solve as ``solve`` does and can be freed)."""
    assert callable(factory), "a linear solver is a factory function returning solve(A, b)"
    solve = factory()
    check_members(solve, interfaces.LinearSolve, "the factory's solve(A, b)")
    rng = np.random.default_rng(0)
    for n in (3, 8):
        A = _laplacian_3d(n)
        x_true = rng.standard_normal(A.shape[0])
        x = np.asarray(solve(A, A @ x_true))
        assert x.shape == x_true.shape, f"solve returned shape {x.shape}, expected {x_true.shape}"
        assert np.all(np.isfinite(x)), "solve returned non-finite values"
        err = np.linalg.norm(x - x_true) / np.linalg.norm(x_true)
        assert err < 1e-6, f"relative error {err:.3g} on a {A.shape[0]}-unknown SPD system"
    # a zero right-hand side must give zero, not NaN
    x0 = np.asarray(solve(_laplacian_3d(3), np.zeros(27)))
    assert np.allclose(x0, 0.0), "solve(A, 0) must return 0"
    if solve.factorize is not None:
        assert callable(solve.factorize), "solve.factorize must be None or callable"
        A = _laplacian_3d(4)
        f = solve.factorize(A)
        check_members(f, interfaces.Factors, "solve.factorize(A)")
        for _ in range(2):  # the kept factors serve several right-hand sides
            x_true = rng.standard_normal(A.shape[0])
            err = np.linalg.norm(np.asarray(f(A @ x_true)) - x_true) / np.linalg.norm(x_true)
            assert err < 1e-6, f"factorize(A)(b): relative error {err:.3g}"
        f.free()


def _check_rod_law(inst: Any) -> None:
    """A rod law's energy is zero beyond contact, repulsive, C¹ and stiffening; friction is finite."""
    dk, k = 0.4, 2.0
    d = np.linspace(0.62 * dk, 1.5 * dk, 301)
    e, e1, e2 = (np.asarray(a, dtype=np.float64) for a in inst.normal(d, dk, k))
    for name, a in (("e", e), ("de/dd", e1), ("d2e/dd2", e2)):
        assert a.shape == d.shape, f"{name} has shape {a.shape}, expected {d.shape}"
        assert np.all(np.isfinite(a)), f"{name} is not finite for d in [{d[0]:.3g}, {d[-1]:.3g}] (dk = {dk})"
    out = d >= dk
    assert np.all(e[out] == 0) and np.all(e1[out] == 0), (
        "energy and force must vanish once the yarns separate (d >= dk)"
    )
    assert np.all(e >= 0), "contact energy must be non-negative"
    force = -e1
    assert np.all(force >= -1e-14), "the contact force must push the yarns apart (de/dd <= 0)"
    assert np.all(np.diff(force) <= 1e-12), "the contact force must not decrease as the yarns are squeezed"
    h = 1e-7
    ep, e1p, _ = inst.normal(d + h, dk, k)
    em, e1m, _ = inst.normal(d - h, dk, k)
    fd1 = (np.asarray(ep) - np.asarray(em)) / (2 * h)
    fd2 = (np.asarray(e1p) - np.asarray(e1m)) / (2 * h)
    scale1 = np.abs(e1).max() + 1e-30
    scale2 = np.abs(e2).max() + 1e-30
    assert np.abs(fd1 - e1).max() < 1e-5 * scale1, "de/dd does not match finite differences of e"
    assert np.abs(fd2 - e2).max() < 1e-4 * scale2, "d2e/dd2 does not match finite differences of de/dd"
    u = np.array([[0.0, 0.0, 0.0], [1e-4, 0.0, 0.0], [0.1, 0.05, 0.0]])
    D, gD, HD = (np.asarray(a, dtype=np.float64) for a in inst.friction_potential(u, np.ones(3), dk))
    assert D.shape == (3,) and gD.shape == (3, 3) and HD.shape == (3, 3, 3), (
        "friction_potential must return D (m,), its gradient (m, 3) and Hessian (m, 3, 3)"
    )
    assert np.all(np.isfinite(D)) and np.all(D >= 0), "the friction potential must be finite and >= 0"
    _check_rod_law_reads_the_yarn(inst)


def _check_rod_law_reads_the_yarn(inst: Any) -> None:
    """``for_yarn`` returns a rod law of the same kind with a core set (a yarn with every record
    field, so that no law lacks what it reads); its ``rigidity`` is None or positive, its ``outer``
    None or a positive distance."""
    from knitframe.plugins import get_registry

    yarn = get_registry()["yarn"]["acrylic"]  # carries a compression law too
    law = inst.for_yarn(yarn)
    assert type(law) is type(inst), f"for_yarn must return a {type(inst).__name__}, got {type(law).__name__}"
    assert law.core is not None, "for_yarn must set the core (None means the yarn's compaction limit)"
    k = law.rigidity(yarn)
    assert k is None or (np.isfinite(k) and k > 0), f"rigidity(yarn) must be None or positive, got {k!r}"
    assert law.outer is None or law.outer > 0, f"outer must be None or a positive distance, got {law.outer!r}"


def _check_solid_law(inst: Any) -> None:
    """A solid law's penalty is positive and grows with the modulus (unless the stiffness is given);
    ``finishes_strain`` is None or a positive strain."""
    eps = inst.penalty(5.0, 0.1)
    assert np.isfinite(eps) and eps > 0, f"penalty(E, h) must be a positive stiffness, got {eps!r}"
    if inst.stiffness is None:
        assert inst.penalty(10.0, 0.1) > eps, "without a given stiffness the penalty must grow with E"
    fs = inst.finishes_strain
    assert fs is None or 0 < fs, f"finishes_strain must be None or a positive strain, got {fs!r}"


def check_contact_law(obj: Any) -> None:
    """Declares its discretisation and every member of its protocol, then the checks of its kind.

    For ``discretisation == "rod"`` (:class:`~knitframe.interfaces.RodContactLaw`):
    ``normal(d, dk, k) -> (e, e', e'')`` vectorised over centre distances d; e = 0 for d ≥ dk,
    e ≥ 0, the force −e′ ≥ 0 grows as d shrinks, e′ and e″ match finite differences, and nothing
    is NaN; ``friction_potential`` is finite; ``for_yarn`` returns the law with its core set. For ``"solid"``
    (:class:`~knitframe.interfaces.SolidContactLaw`): a positive penalty stiffness.
    """
    inst = obj() if isinstance(obj, type) and attrs.has(obj) else obj
    disc = inst.discretisation
    assert disc in ("rod", "solid"), f"contact law discretisation must be 'rod' or 'solid', got {disc!r}"
    proto = interfaces.RodContactLaw if disc == "rod" else interfaces.SolidContactLaw
    check_members(inst, proto, f"{disc} contact law '{inst.name}'")
    (_check_rod_law if disc == "rod" else _check_solid_law)(inst)


CHECKS = {"linear_solver": check_linear_solver, "contact_law": check_contact_law}
