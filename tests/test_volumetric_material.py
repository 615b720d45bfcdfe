"""Total-Lagrangian solid forms of the volumetric solver: tangent, patch test, Lamé cylinder, pre-stress."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla
import skfem
from knitframe_solvers.volumetric_material import SolidForms, YarnLaw, psd_project, psd_project_elements
from knitframe_yarns.isotropic import Isotropic
from knitframe_yarns.law import linear_stiffness
from knitframe_yarns.transverse_isotropic import TransverseIsotropic
from skfem.helpers import dot

from knitframe.errors import NumericalError


def ti(E_axial: float, E_transverse: float, nu: float = 0.3) -> YarnLaw:
    return YarnLaw(TransverseIsotropic(E_axial=E_axial, radius=0.2, nu=nu, E_transverse=E_transverse))


def iso(E: float, nu: float) -> YarnLaw:
    return YarnLaw(Isotropic(E_axial=E, radius=0.2, nu=nu))


def block(order: int):
    m = skfem.MeshTet1.init_tensor(np.linspace(0, 1, 4), np.linspace(0, 1, 3), np.linspace(0, 2, 4))
    return m if order == 1 else skfem.MeshTet2.from_mesh(m)


def nodes_of(mesh) -> np.ndarray:
    return (mesh.doflocs if isinstance(mesh, skfem.MeshTet2) else mesh.p).T


def newton(
    forms: SolidForms,
    u: np.ndarray,
    free: np.ndarray,
    f_ext: np.ndarray | None = None,
    s: float = 1.0,
    tol: float = 1e-10,
    maxit: int = 25,
) -> np.ndarray:
    """Plain Newton on the free DOFs, started from the linear lift of the prescribed values (test helper)."""
    f_ext = np.zeros_like(u) if f_ext is None else f_ext
    fixed = np.setdiff1d(np.arange(u.size), free)
    if np.any(u[fixed]):
        K0 = forms.tangent(np.zeros_like(u), s)
        u[free] = -spla.spsolve(K0[free][:, free].tocsc(), K0[free][:, fixed] @ u[fixed])
    for _ in range(maxit):
        r = forms.residual(u, s) - f_ext
        if np.linalg.norm(r[free]) < tol * max(1.0, np.linalg.norm(f_ext)):
            return u
        K = forms.tangent(u, s)
        u[free] -= spla.spsolve(K[free][:, free].tocsc(), r[free])
    raise AssertionError("Newton did not converge")


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("s", [1.0, 0.8])
def test_tangent_matches_finite_differences(order, s):
    """K·δu equals the central difference of the residual, and R·δu that of the energy, with and without
    eigenstrain."""
    mesh = block(order)
    rng = np.random.default_rng(0)
    n = nodes_of(mesh).shape[0]
    fibre = rng.normal(size=(n, 3))
    forms = SolidForms(
        mesh,
        ti(500.0, 2.0),
        fibre / np.linalg.norm(fibre, axis=1)[:, None],
        node_offset=0.3 * nodes_of(mesh) + 0.02 * rng.normal(size=(n, 3)),
    )
    u = 0.01 * rng.normal(size=forms.ndof)
    du = rng.normal(size=forms.ndof)
    eps = 1e-6
    fd_K = (forms.residual(u + eps * du, s) - forms.residual(u - eps * du, s)) / (2 * eps)
    fd_R = (forms.energy(u + eps * du, s) - forms.energy(u - eps * du, s)) / (2 * eps)
    K = forms.tangent(u, s)
    assert np.linalg.norm(K @ du - fd_K) < 1e-7 * np.linalg.norm(fd_K)
    assert abs(forms.residual(u, s) @ du - fd_R) < 1e-7 * abs(fd_R)
    assert abs(K - K.T).max() < 1e-12 * abs(K).max()


def test_adapter_keeps_tensor_order():
    """At F = I the adapted tangent is the linear transversely isotropic stiffness with the fibre along x."""
    law = ti(1000.0, 10.0)
    A = law.tangent(np.eye(3)[:, :, None, None], np.array([1.0, 0.0, 0.0])[:, None, None])[..., 0, 0]
    C = linear_stiffness(1000.0, 10.0, 10.0 / 2.6, 0.3)
    assert A[0, 0, 0, 0] == pytest.approx(C[0, 0])
    assert A[1, 1, 1, 1] == pytest.approx(C[1, 1])
    assert A[0, 0, 1, 1] == pytest.approx(C[0, 1])
    assert A[0, 1, 0, 1] == pytest.approx(C[5, 5])


def test_model_without_order_keyword_still_works():
    """A yarn model whose evaluate(F, a) has no ``order`` parameter gives the same energy, stress and
    tangent."""

    class Legacy:
        def __init__(self, inner):
            self.inner = inner

        def evaluate(self, F, a):
            return self.inner.evaluate(F, a)

    inner = TransverseIsotropic(E_axial=200.0, radius=0.2, nu=0.3, E_transverse=5.0)
    new, old = YarnLaw(inner), YarnLaw(Legacy(inner), takes_order=False)
    assert new.takes_order and not old.takes_order
    rng = np.random.default_rng(3)
    F = np.eye(3)[:, :, None, None] + 0.1 * rng.normal(size=(3, 3, 4, 2))
    a = np.broadcast_to(np.array([0.0, 0.6, 0.8])[:, None, None], (3, 4, 2))
    for k in range(3):
        assert np.allclose(new.evaluate(F, a, 2)[k], old.evaluate(F, a, 2)[k], rtol=1e-14, atol=0)
    assert old.evaluate(F, a, 0)[1] is None and old.evaluate(F, a, 1)[2] is None


@pytest.mark.parametrize("order", [1, 2])
def test_patch_test_large_strain(order):
    """An affine displacement on the boundary gives the same affine field inside and the uniform stress's
    tractions."""
    mesh = block(order)
    X = nodes_of(mesh)
    H = np.array([[0.15, 0.05, 0.0], [-0.02, -0.08, 0.03], [0.01, 0.04, 0.1]])
    fibre = np.tile(np.array([1.0, 1.0, 0.0]) / np.sqrt(2), (X.shape[0], 1))
    law = ti(200.0, 5.0)
    forms = SolidForms(mesh, law, fibre)
    exact = (X @ H.T).ravel()
    bnodes = (
        np.unique(mesh.facets[:, mesh.boundary_facets()])
        if order == 1
        else np.unique(skfem.Basis(mesh, skfem.ElementTetP2()).get_dofs().flatten())
    )
    fixed = (3 * bnodes[:, None] + np.arange(3)).ravel()
    free = np.setdiff1d(np.arange(forms.ndof), fixed)
    u = np.zeros(forms.ndof)
    u[fixed] = exact[fixed]
    u = newton(forms, u, free)
    assert np.abs(u - exact).max() < 1e-10
    P = law.stress((np.eye(3) + H)[:, :, None, None], fibre[0][:, None, None])[..., 0, 0]
    R = forms.residual(u).reshape(-1, 3)
    assert np.allclose(R[np.setdiff1d(np.arange(X.shape[0]), bnodes)], 0.0, atol=1e-9)
    # the reactions on the face z = 2, away from its edges, are the consistent nodal forces of P·N
    face = skfem.FacetBasis(
        mesh,
        skfem.ElementVector(forms.basis.elem),
        facets=mesh.facets_satisfying(lambda x: np.isclose(x[2], 2.0)),
    )
    trac = skfem.LinearForm(lambda v, w: dot(np.einsum("ij,j...->i...", P, w.n), v)).assemble(face)
    inner = (
        np.isclose(X[:, 2], 2.0)
        & (X[:, 0] > 1e-9)
        & (X[:, 0] < 1 - 1e-9)
        & (X[:, 1] > 1e-9)
        & (X[:, 1] < 1 - 1e-9)
    )
    assert inner.any()
    assert np.abs(R[inner] - trac.reshape(-1, 3)[inner]).max() < 1e-8 * np.abs(trac).max()


def annulus(order: int, a: float = 1.0, b: float = 2.0, h: float = 0.25):
    """Quarter annulus a ≤ r ≤ b, 0 ≤ θ ≤ π/2, 0 ≤ z ≤ h, isoparametric for P2 (P1 twice as fine)."""
    n = 4 if order == 2 else 8
    ref = skfem.MeshTet1.init_tensor(
        np.linspace(a, b, n + 1), np.linspace(0, np.pi / 2, 2 * n + 1), np.linspace(0, h, 2)
    )

    def polar(p):
        return np.stack([p[0] * np.cos(p[1]), p[0] * np.sin(p[1]), p[2]])

    m1 = skfem.MeshTet1(polar(ref.p), ref.t)
    if order == 1:
        return m1
    return skfem.MeshTet2(polar(skfem.MeshTet2.from_mesh(ref).doflocs), ref.t)


@pytest.mark.parametrize("order", [1, 2])
def test_lame_thick_cylinder(order):
    """A thick cylinder under internal pressure in plane strain matches Lamé's radial displacement."""
    a, b, p, E, nu = 1.0, 2.0, 0.05, 1000.0, 0.3
    mesh = annulus(order, a, b)
    forms = SolidForms(mesh, iso(E, nu), None)
    X = nodes_of(mesh)
    fixed = np.concatenate(
        [
            3 * np.flatnonzero(np.isclose(X[:, 0], 0.0, atol=1e-12)),
            3 * np.flatnonzero(np.isclose(X[:, 1], 0.0, atol=1e-12)) + 1,
            3 * np.arange(X.shape[0]) + 2,
        ]
    )
    free = np.setdiff1d(np.arange(forms.ndof), fixed)
    inner = skfem.FacetBasis(
        mesh,
        skfem.ElementVector(forms.basis.elem),
        intorder=4,
        facets=mesh.facets_satisfying(lambda x: np.isclose(np.hypot(x[0], x[1]), a, atol=0.02)),
    )
    f_ext = skfem.LinearForm(lambda v, w: -p * dot(w.n, v)).assemble(inner)
    u = newton(forms, np.zeros(forms.ndof), free, f_ext)
    r = np.hypot(X[:, 0], X[:, 1])
    ur = (u.reshape(-1, 3)[:, :2] * X[:, :2]).sum(axis=1) / r
    exact = (1 + nu) * p * a**2 / (E * (b**2 - a**2)) * ((1 - 2 * nu) * r + b**2 / r)
    err = np.abs(ur - exact).max() / exact.max()
    assert err < (0.05 if order == 1 else 0.01)


def test_eigenstrain_shrinks_a_free_tube_transversely():
    """A free body with transverse eigenstrain s contracts by s across the fibre and not along it."""
    mesh = block(2)
    X = nodes_of(mesh)
    fibre = np.tile([0.0, 0.0, 1.0], (X.shape[0], 1))
    forms = SolidForms(mesh, ti(1000.0, 1.0), fibre, node_offset=X * np.array([1.0, 1.0, 0.0]))
    s = 0.7
    corner = np.flatnonzero(np.all(np.isclose(X, 0.0), axis=1))[0]
    fixed = np.array([3 * corner, 3 * corner + 1, 3 * corner + 2])
    # remove the rotations with two more point constraints
    px = np.flatnonzero(np.isclose(X[:, 0], 1) & np.isclose(X[:, 1], 0) & np.isclose(X[:, 2], 0))[0]
    pz = np.flatnonzero(np.isclose(X[:, 0], 0) & np.isclose(X[:, 1], 0) & np.isclose(X[:, 2], 2))[0]
    fixed = np.concatenate([fixed, [3 * px + 1, 3 * px + 2, 3 * pz, 3 * pz + 1]])
    free = np.setdiff1d(np.arange(forms.ndof), fixed)
    u = newton(forms, np.zeros(forms.ndof), free, s=s)
    expected = X * np.array([s - 1, s - 1, 0.0])
    assert np.abs(u.reshape(-1, 3) - expected).max() < 1e-9
    assert forms.energy(u, s) < 1e-12


def test_inverted_element_raises():
    """An inverted element stops the assembly with a NumericalError naming the element, never NaN."""
    mesh = block(1)
    forms = SolidForms(mesh, iso(1.0, 0.3), None)
    u = -2.5 * nodes_of(mesh).ravel()
    assert forms.energy(u) == np.inf
    with pytest.raises(NumericalError, match="inverted"):
        forms.residual(u)


@pytest.mark.parametrize("order", [1, 2])
def test_undersized_curved_tube_is_stress_free(order):
    """A curved tube shrunk across its fibre to s·r is stress-free under the pre-stress eigenstrain at s."""
    from test_mesh import helix_cell

    from knitframe.numerics.mesh import cell_mesh

    cm = cell_mesh(helix_cell(R=0.8, c=0.5, r=0.3), seed=0.5, order=order)
    forms = SolidForms(cm.mesh, ti(1000.0, 0.1), cm.node_tangent, node_offset=cm.node_offset)
    s = 0.6
    shrunk = ((s - 1.0) * cm.node_offset).ravel()
    assert forms.energy(shrunk, s) < 1e-10 * forms.energy(shrunk, 1.0)


def test_force_flux_does_not_cancel_at_equilibrium():
    """The flux Σ_e |R_e| bounds |R|, stays positive where the assembled R cancels, and scales with the
    stress."""
    mesh = block(1)
    X = nodes_of(mesh)
    fibre = np.tile(np.array([0.0, 0.0, 1.0]), (X.shape[0], 1))
    forms = SolidForms(mesh, ti(200.0, 5.0), fibre)
    H = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 1e-4]])
    fluxes = []
    for k in (1.0, 2.0):
        _, R, _ = forms.evaluate((k * X @ H.T).ravel(), 1.0, 1)
        assert np.all(forms.flux >= np.abs(R) - 1e-15)
        fluxes.append(forms.flux.copy())
    inner = (X[:, 2] > 1e-9) & (X[:, 2] < 2 - 1e-9)
    z = 3 * np.flatnonzero(inner) + 2
    assert (
        np.abs(R[z]).max() < 1e-10 * fluxes[1][z].min()
    )  # interior axial forces cancel, their flux does not
    assert np.allclose(fluxes[1], 2.0 * fluxes[0], rtol=1e-3)
    # the flux into the loaded face equals the axial force P_zz·A it carries
    top = 3 * np.flatnonzero(np.isclose(X[:, 2], 2.0)) + 2
    P_zz = forms.stress((X @ H.T).ravel())[2, 2].mean()
    assert fluxes[0][top].sum() == pytest.approx(P_zz * 1.0, rel=1e-3)


def test_psd_projection_of_the_tangent():
    """psd_project clamps the eigenvalues of each 9x9 tangent at zero: the result is PSD, idempotent, and a
    PSD tangent is unchanged."""
    rng = np.random.default_rng(3)
    M = rng.normal(size=(5, 7, 9, 9))
    M = M + np.swapaxes(M, -1, -2)
    A = np.moveaxis(M, (2, 3), (0, 1)).reshape(3, 3, 3, 3, 5, 7)
    P = psd_project(A)
    w = np.linalg.eigvalsh(np.moveaxis(P.reshape(9, 9, 5, 7), (0, 1), (-2, -1)))
    assert w.min() > -1e-12 * np.abs(w).max()
    assert np.allclose(psd_project(P), P, atol=1e-12)
    assert np.min(np.linalg.eigvalsh(M)) < 0 and not np.allclose(P, A)
    S = np.einsum("...ij,...kj->...ik", M, M)  # PSD
    B = np.moveaxis(S, (2, 3), (0, 1)).reshape(3, 3, 3, 3, 5, 7)
    assert np.allclose(psd_project(B), B, atol=1e-10 * np.abs(B).max())


def test_absolute_value_and_element_eigenvalue_filters():
    """ "abs" maps each 9x9 tangent's eigenvalues to their absolute values (same eigenvectors); the element
    filter clamps each element matrix's eigenvalues at zero. Both leave a PSD matrix unchanged; an unknown
    method is a ValueError."""
    rng = np.random.default_rng(4)
    M = rng.normal(size=(5, 7, 9, 9))
    M = M + np.swapaxes(M, -1, -2)
    A = np.moveaxis(M, (2, 3), (0, 1)).reshape(3, 3, 3, 3, 5, 7)
    P = np.moveaxis(psd_project(A, "abs").reshape(9, 9, 5, 7), (0, 1), (-2, -1))
    assert np.allclose(np.linalg.eigvalsh(P), np.sort(np.abs(np.linalg.eigvalsh(M)), axis=-1), atol=1e-10)
    S = np.einsum("...ij,...kj->...ik", M, M)
    B = np.moveaxis(S, (2, 3), (0, 1)).reshape(3, 3, 3, 3, 5, 7)
    assert np.allclose(psd_project(B, "abs"), B, atol=1e-10 * np.abs(B).max())
    with pytest.raises(ValueError, match="method"):
        psd_project(A, "flip")
    K = rng.normal(size=(6, 4, 3, 4, 3))
    K = K + np.moveaxis(K, (1, 2), (3, 4))  # symmetric 12x12 element matrices
    Kp = psd_project_elements(K).reshape(6, 12, 12)
    w = np.linalg.eigvalsh(K.reshape(6, 12, 12))
    assert np.allclose(np.linalg.eigvalsh(Kp), np.sort(np.maximum(w, 0.0), axis=-1), atol=1e-10)
    assert w.min() < 0
    Kpsd = np.einsum("eij,ekj->eik", K.reshape(6, 12, 12), K.reshape(6, 12, 12)).reshape(K.shape)
    assert np.allclose(psd_project_elements(Kpsd), Kpsd, atol=1e-10 * np.abs(Kpsd).max())


@pytest.mark.parametrize("order, filt", [(1, "clamp"), (2, "clamp"), (2, "abs"), (2, "element")])
def test_projected_tangent_is_psd_where_the_exact_one_is_not(order, filt):
    """Fibres compressed by 2 % make the exact tangent of a 10³-anisotropic yarn indefinite (dozens of
    negative eigenvalues, the fibres' buckling modes); the projected one is PSD, with the same energy and
    residual, for each eigenvalue filter (the forms' ``projection``: per point clamped or absolute, per
    element clamped)."""
    mesh = block(order)
    X = nodes_of(mesh)
    n = X.shape[0]
    forms = SolidForms(
        mesh, ti(500.0, 0.5), np.tile([0.0, 0.0, 1.0], (n, 1)), node_offset=X - [0.5, 0.5, 0.0]
    )
    u = np.zeros((n, 3))
    u[:, 2] = -0.02 * X[:, 2]
    u = u.ravel()
    W, R, K = forms.evaluate(u, 1.0, 2)
    forms.projection = filt
    Wp, Rp, Kp = forms.evaluate(u, 1.0, 2, project=True)
    assert Wp == W and np.array_equal(Rp, R)
    w = np.linalg.eigvalsh(K.toarray())
    wp = np.linalg.eigvalsh(Kp.toarray())
    assert w.min() < -1e-3 * w.max() and np.sum(w < -1e-9 * w.max()) > 10
    assert wp.min() > -1e-10 * wp.max()


@pytest.mark.parametrize("order", [1, 2])
def test_threaded_chunks_give_the_serial_result(order):
    """The element chunks on several threads give bit for bit the serial energy, residual, flux and tangent
    (chunks are summed in their order), under the pre-stress eigenstrain and with the projected tangent; an
    inverted element raises the same error."""
    from test_mesh import helix_cell

    from knitframe.numerics.mesh import cell_mesh

    cm = cell_mesh(helix_cell(R=0.8, c=0.5, r=0.3), seed=0.5, order=order)
    law = ti(1000.0, 0.1)
    serial = SolidForms(cm.mesh, law, cm.node_tangent, node_offset=cm.node_offset, chunk=37, threads=1)
    threaded = SolidForms(cm.mesh, law, cm.node_tangent, node_offset=cm.node_offset, chunk=37, threads=3)
    assert threaded.threads == 3 and len(threaded._chunks()) > 3
    rng = np.random.default_rng(5)
    u = 0.002 * rng.normal(size=serial.ndof)
    for s in (1.0, 0.8):
        for project in (False, True):
            W1, R1, K1 = serial.evaluate(u, s, 2, project=project)
            W3, R3, K3 = threaded.evaluate(u, s, 2, project=project)
            assert W3 == W1 and np.array_equal(R3, R1) and np.array_equal(threaded.flux, serial.flux)
            assert np.array_equal(K3.indptr, K1.indptr) and np.array_equal(K3.data, K1.data)
        assert threaded.energy(u, s) == serial.energy(u, s)
        assert np.array_equal(threaded.residual(u, s), serial.residual(u, s))
        assert np.array_equal(threaded.stress(u, s), serial.stress(u, s))
    bad = (-2.0 * cm.nodes).ravel()  # F = −I: every element inverted
    with pytest.raises(NumericalError) as e1:
        serial.residual(bad)
    with pytest.raises(NumericalError) as e3:
        threaded.residual(bad)
    assert str(e1.value) == str(e3.value)
