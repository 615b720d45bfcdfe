"""Linear-solver plugins: conformance, rigid-body modes for AMG, missing backends."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from knitframe.errors import ConfigError
from knitframe.testing import check_plugin
from knitframe.testing.solvers import check_contact_law


@pytest.mark.parametrize("name", ["direct", "amg"])
def test_linear_solvers_conform(name):
    """Both built-in linear solvers pass the conformance kit."""
    check_plugin("linear_solver", name)


def _elasticity():
    """P1 linear elasticity on a slender box, one end clamped (scikit-fem)."""
    import skfem
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    m = skfem.MeshTet.init_tensor(np.linspace(0, 10, 21), np.linspace(0, 1, 4), np.linspace(0, 1, 4))
    ib = skfem.Basis(m, skfem.ElementVector(skfem.ElementTetP1()))
    K = linear_elasticity(*lame_parameters(1e3, 0.3)).assemble(ib)
    f = skfem.LinearForm(lambda v, w: -1.0 * v[2]).assemble(ib)
    D = ib.get_dofs(lambda x: x[0] < 1e-9).all()
    I = ib.complement_dofs(D)
    pts = m.p.T
    return K[I][:, I].tocsr(), f[I], I, pts


def test_amg_with_rigid_body_modes_matches_direct():
    """AMG (θ = 0.05, rigid-body near-null space, CG) solves clamped elasticity like the direct solver."""
    from knitframe_linsolvers.amg import rigid_body_modes

    from knitframe import get_registry

    A, b, I, pts = _elasticity()
    B = rigid_body_modes(pts)[I]
    reg = get_registry()["linear_solver"]
    x_ref = reg["direct"]()(A, b)
    x = reg["amg"](tol=1e-10)(A, b, near_null_space=B)
    assert np.linalg.norm(x - x_ref) < 1e-7 * np.linalg.norm(x_ref)


def test_unavailable_backend_is_a_one_line_config_error():
    """Asking for a backend whose library is missing names the package to install."""
    from knitframe_linsolvers.direct import available, direct

    for backend, pkg in (("pardiso", "pypardiso"), ("cholmod", "sksparse")):
        if not available(backend):
            with pytest.raises(ConfigError, match=pkg):
                direct(backend)
    with pytest.raises(ConfigError, match="backend"):
        direct("magic")


def test_contact_law_check_catches_an_attractive_law():
    """The contact-law kit rejects a law whose force pulls the yarns together."""

    class Sticky:
        name, description, discretisation = "sticky", "attractive", "rod"

        def normal(self, d, dk, k):
            x = np.minimum(d - dk, 0.0)
            return -k * x**2, -2 * k * x, np.where(d < dk, -2 * k, 0.0)

    with pytest.raises(AssertionError):
        check_contact_law(Sticky())


def test_symmetry_probe():
    """is_symmetric accepts A = Aᵀ (also with round-off) and rejects a skew part above its tolerance."""
    import scipy.sparse as sp
    from knitframe_linsolvers.direct import is_symmetric

    rng = np.random.default_rng(0)
    B = sp.random(200, 200, density=0.05, random_state=1, format="csr")
    S = (B + B.T).tocsr()
    assert is_symmetric(S)
    assert is_symmetric(S + 1e-15 * sp.random(200, 200, density=0.05, random_state=2))
    assert not is_symmetric((S + 1e-6 * B).tocsr())
    assert not is_symmetric(sp.csr_matrix(rng.normal(size=(3, 4))))


@pytest.mark.skipif(
    not __import__("knitframe_linsolvers.direct", fromlist=["available"]).available("pardiso"),
    reason="pypardiso is not installed",
)
def test_pardiso_symmetric_indefinite_and_unsymmetric():
    """PARDISO solves a symmetric indefinite system (LDLᵀ of the upper triangle) and an unsymmetric one
    (LU)."""
    import scipy.sparse as sp
    from knitframe_linsolvers.direct import direct

    n = 6000
    lap = sp.diags([2.0 * np.ones(n), -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1], format="csr")
    indefinite = (lap - 0.5 * sp.identity(n)).tocsr()  # eigenvalues of lap span (0, 4): some are now negative
    unsym = (lap + sp.diags([0.3 * np.ones(n - 1)], [1])).tocsr()
    b = np.random.default_rng(0).normal(size=n)
    import knitframe_linsolvers.direct as d

    solve = direct("pardiso")
    for A, path in ((indefinite, [d.SYMMETRIC]), (unsym, [d.UNSYMMETRIC])):
        used = []
        refined = d._refined

        def spy(solver, M, A_, b_, refine, rtol, used=used, refined=refined):
            used.append(solver.mtype)
            return refined(solver, M, A_, b_, refine, rtol)

        d._refined = spy
        try:
            x = solve(A, b)
        finally:
            d._refined = refined
        assert np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b)
        assert used == path  # the symmetric matrix got the LDLᵀ and needed no fallback


def test_failed_pardiso_falls_back_to_lu_then_superlu_only_for_small_systems(monkeypatch):
    """When the refined LDLᵀ misses the tolerance the LU is tried; when that fails too, SuperLU takes small
    systems and a large one raises a NumericalError (SuperLU's fill-in on a P2 cell exhausts memory)."""
    import knitframe_linsolvers.direct as d
    import scipy.sparse as sp

    from knitframe.errors import NumericalError

    tried = []
    monkeypatch.setattr(d, "_pardiso_solver", lambda mtype=d.UNSYMMETRIC: mtype)
    monkeypatch.setattr(d, "_refined", lambda solver, M, A, b, refine, rtol: tried.append(solver))
    n = 300
    A = sp.diags([2.0 * np.ones(n), -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1], format="csr")
    b = np.ones(n)
    x = d._pardiso(A, b)
    assert tried == [d.SYMMETRIC, d.UNSYMMETRIC] and np.linalg.norm(A @ x - b) < 1e-10 * np.linalg.norm(b)
    monkeypatch.setattr(d, "SUPERLU_FALLBACK_LIMIT", 100)
    with pytest.raises(NumericalError, match="SuperLU"):
        d._pardiso(A, b)


@pytest.mark.parametrize("backend", ["superlu", "pardiso", "auto"])
def test_kept_factorisation_solves_several_right_hand_sides(backend):
    """``solve.factorize(A)`` keeps the factors: each right-hand side gets the answer of a fresh solve, to
    the refinement tolerance, for a symmetric indefinite matrix (LDLᵀ with PARDISO) and an unsymmetric one."""
    import scipy.sparse as sp
    from knitframe_linsolvers.direct import available, direct

    if backend == "pardiso" and not available("pardiso"):
        pytest.skip("pypardiso is not installed")
    n = 6000
    lap = sp.diags([2.0 * np.ones(n), -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1], format="csr")
    rng = np.random.default_rng(1)
    solve = direct(backend)
    for A in ((lap - 0.5 * sp.identity(n)).tocsr(), (lap + sp.diags([0.3 * np.ones(n - 1)], [1])).tocsr()):
        f = solve.factorize(A)
        try:
            for _ in range(3):
                b = rng.normal(size=n)
                x = f(b)
                assert np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b)
                assert np.allclose(x, solve(A, b), rtol=1e-8, atol=1e-10)
        finally:
            f.free()


def test_refinement_takes_a_backward_stable_solution_whose_residual_is_at_the_conditioning_floor():
    """A soft chain tied by stiff springs (like yarns pressed together by a barrier deep inside d̂): no float64
    solve gets |b − A x| ≤ 1e-10 |b|, but the factorised solve is backward stable (componentwise backward
    error of a few ε), so the refinement takes it; a solution that is not (here x = 0) is still refused."""
    import knitframe_linsolvers.direct as d
    import scipy.sparse as sp
    import scipy.sparse.linalg as sla

    n = 2000
    lap = sp.diags([2.0 * np.ones(n), -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1])
    pairs = np.arange(0, n - 1, 2)
    C = sp.csr_matrix(
        (
            np.r_[np.ones(len(pairs)), -np.ones(len(pairs))],
            (np.r_[np.arange(len(pairs)), np.arange(len(pairs))], np.r_[pairs, pairs + 1]),
        ),
        shape=(len(pairs), n),
    )
    A = (1e-3 * lap + 1e-3 * sp.identity(n) + 1e10 * (C.T @ C)).tocsc()
    b = np.random.default_rng(0).normal(size=n)
    lu = sla.splu(A)
    x = lu.solve(b)
    assert np.linalg.norm(b - A @ x) > 1e-10 * np.linalg.norm(b)  # the residual test alone would refuse it
    y = d._refine(lu.solve, A, b, 4, 1e-10)
    assert y is not None and d.backward_error(A, y, b) <= d.BACKWARD_ERROR_TOL
    assert d._refine(lambda v: np.zeros_like(v), A, b, 4, 1e-10) is None


def test_upper_triangle_is_scipys_triu():
    """upper(A) = scipy's triu(A) (diagonal included), with sorted indices, also from unsorted or empty-row
    input."""
    from knitframe_linsolvers.direct import upper

    rng = np.random.default_rng(4)
    A = sp.random(300, 300, density=0.05, random_state=5, format="csr")
    A = A + A.T + sp.diags(rng.uniform(1, 2, 300))
    A = sp.csr_matrix(A)
    A.data[A.indptr[7] : A.indptr[8]] = 0.0  # an empty row
    A.eliminate_zeros()
    assert A.indptr[8] == A.indptr[7]
    shuffled = A.copy()
    for i in range(0, 300, 3):  # unsorted column indices in some rows
        lo, hi = shuffled.indptr[i], shuffled.indptr[i + 1]
        shuffled.indices[lo:hi] = shuffled.indices[lo:hi][::-1]
        shuffled.data[lo:hi] = shuffled.data[lo:hi][::-1]
    shuffled.has_sorted_indices = False
    for M in (A, shuffled):
        U = upper(M)
        ref = sp.triu(A, format="csr")
        ref.sort_indices()
        assert U.has_sorted_indices and np.array_equal(U.indptr, ref.indptr)
        assert np.array_equal(U.indices, ref.indices) and np.array_equal(U.data, ref.data)
