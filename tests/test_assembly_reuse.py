"""Solvers that do not rebuild what does not change: the rod's Hessian positions kept per point map and
its contact maps reused while the pairs repeat, and PARDISO handles built once per process; the results
are those of the code before."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp


def small_rod_cell():
    from knitframe import get_registry
    from knitframe.records import Fabric, LoadPath, Scene

    reg = get_registry()
    fab = Fabric(pattern="jersey", yarn=reg["yarn"]["cotton"], stitch_length=11)
    scene = Scene(
        load=LoadPath(kind="equibiaxial", max_strain=0.2, steps=3),
        effects=("large_deformation", "bending", "contact", "prestress"),
    )
    return reg["solver"]["rod"](starts=1).simulate(fab, scene)


def test_rod_curve_is_the_one_before_the_fixed_pattern():
    """Jersey SL11 cotton, pre-stress and equibiaxial 0 → 20 % in 3 steps: the tensions of the code that
    rebuilt every Hessian position and point map at every evaluation (2026-11-28), to the last digits."""
    r = small_rod_cell()
    before_T1 = [0.04222027251207743, 0.5683450583462099, 3.4999510209508142]
    before_T2 = [0.061997360133692885, 0.8742278477818631, 5.538426130034947]
    np.testing.assert_allclose(r.T1, before_T1, rtol=1e-13)
    np.testing.assert_allclose(r.T2, before_T2, rtol=1e-13)


def test_pardiso_handles_are_built_once_and_solve_as_fresh_ones(monkeypatch):
    """Many factorisations build one PARDISO handle per matrix type (each build searches for MKL), and a
    reused handle gives the solution a fresh one gives."""
    pypardiso = pytest.importorskip("pypardiso")
    import knitframe_linsolvers.direct as d

    built = []
    real = pypardiso.PyPardisoSolver

    def counted(*args, **kwargs):
        built.append(kwargs.get("mtype"))
        return real(*args, **kwargs)

    monkeypatch.setattr(d, "_IDLE", {})
    monkeypatch.setattr(pypardiso, "PyPardisoSolver", counted)
    n = 400
    rng = np.random.default_rng(2)
    lap = sp.diags([2.0 * np.ones(n), -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1], format="csr")
    solve = d.direct("pardiso")
    for k in range(4):
        A = (lap + (0.1 * k) * sp.identity(n) + sp.diags([0.2 * np.ones(n - 1)], [1])).tocsr()  # unsymmetric
        b = rng.standard_normal(n)
        f = solve.factorize(A)
        x = f(b)
        f.free()
        fresh = real(mtype=d.UNSYMMETRIC)
        fresh.set_iparm(8, 0)
        y = d._refine(lambda v, s=fresh, M=A: s.solve(M, v), A, b, 4, 1e-10)
        fresh.free_memory(everything=True)
        np.testing.assert_allclose(x, y, rtol=1e-10, atol=1e-12)
        x2 = solve(A, b)  # the one-shot solve takes an idle handle too
        np.testing.assert_allclose(x2, y, rtol=1e-10, atol=1e-12)
    assert built.count(d.UNSYMMETRIC) == 1  # the counted builds (the fresh references are not counted)
