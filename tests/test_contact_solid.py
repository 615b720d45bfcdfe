"""Solid contact laws ``penalty`` (node-to-surface) and ``mortar`` (segment-to-segment): derivatives, Hertz, patch test, images."""

from __future__ import annotations

import numpy as np
import pytest
import skfem

from contact_solid_helpers import iso, join, nodes, quarter_cylinder_on_flat, solve, surface
from knitframe.contact_search import SegmentTopology
from knitframe.geometry import Centerline, UnitCell
from knitframe.mesh import cell_mesh, surface_facets
from knitframe.periodic import Lattice
from knitframe.plugins import get_registry
from knitframe_contact.mortar import SolidMortar
from knitframe_contact.penalty import SolidPenalty
from knitframe_contact.solid_geometry import SolidSurface, facet_gap, plane_gap
from knitframe_solvers.volumetric_material import SolidForms
from knitframe_yarns.law import line_contact_approach


def test_laws_are_registered_for_solids():
    """Both laws are registered contact-law plugins for the solid discretisation."""
    kind = get_registry()["contact_law"]
    assert kind["penalty"] is SolidPenalty and kind["mortar"] is SolidMortar
    assert SolidPenalty.discretisation == SolidMortar.discretisation == "solid"


def test_plane_gap_derivatives():
    """The plane gap's gradient and Hessian equal central differences."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(6, 4, 3))
    g, dg, H = plane_gap(*X.transpose(1, 0, 2))
    eps = 1e-6
    for k in range(4):
        for i in range(3):
            Xp, Xm = X.copy(), X.copy()
            Xp[:, k, i] += eps
            Xm[:, k, i] -= eps
            gp, dgp, _ = plane_gap(*Xp.transpose(1, 0, 2))
            gm, dgm, _ = plane_gap(*Xm.transpose(1, 0, 2))
            assert np.allclose((gp - gm) / (2 * eps), dg[:, k, i], atol=1e-7)
            assert np.allclose((dgp - dgm) / (2 * eps), H[:, :, :, k, i], atol=1e-6)


def test_quadratic_facet_gap_gradient():
    """The gap to a curved quadratic facet has the gradient n, −N_i n of its closest point."""
    rng = np.random.default_rng(1)
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    mids = 0.5 * (corners[[0, 1, 2]] + corners[[1, 2, 0]]) + np.array([0, 0, 0.05])
    Xf = np.tile(np.vstack([corners, mids]), (5, 1, 1)) + 0.01 * rng.normal(size=(5, 6, 3))
    p = np.array([0.25, 0.25, 0.02]) + 0.02 * rng.normal(size=(5, 3))
    g, dg, _ = facet_gap(p, Xf)
    eps = 1e-7
    for k in range(7):
        for i in range(3):
            pp, Xp = p.copy(), Xf.copy()
            pm, Xm = p.copy(), Xf.copy()
            if k == 0:
                pp[:, i] += eps
                pm[:, i] -= eps
            else:
                Xp[:, k - 1, i] += eps
                Xm[:, k - 1, i] -= eps
            fd = (facet_gap(pp, Xp, 0)[0] - facet_gap(pm, Xm, 0)[0]) / (2 * eps)
            assert np.allclose(fd, dg[:, k, i], atol=1e-6)


@pytest.fixture(scope="module", params=[1, 2])
def cylinder(request):
    order = request.param
    mesh, body, arc, top = quarter_cylinder_on_flat(1.0, 0.01 if order == 1 else 0.02, 0.25, 0.05, order)
    return mesh, body, surface(mesh, body, arc, top)


@pytest.mark.parametrize("law", [SolidPenalty(), SolidMortar()], ids=["penalty", "mortar"])
def test_contact_derivatives_match_finite_differences(cylinder, law):
    """Contact gradient = FD of the energy; Hessian = FD of the gradient (exact for linear facets).

    On quadratic facets the mortar Hessian is Gauss-Newton (the terms proportional to the gap are
    dropped), so it is checked at a shallow penetration, where those terms are small.
    """
    mesh, body, surf = cylinder
    X = nodes(mesh)
    n = 3 * len(X)
    rng = np.random.default_rng(0)
    exact_hessian = not (isinstance(law, SolidMortar) and isinstance(mesh, skfem.MeshTet2))
    u = np.zeros(n)
    u[1::3] = -(0.01 if exact_hessian else 0.001) * (body == 0)
    u += 1e-4 * rng.normal(size=n)
    du = rng.normal(size=n) * np.repeat(body == 0, 3)

    def f(v, order):
        return law.evaluate(surf, X + v.reshape(-1, 3), None, order, stiffness=1e3, reach=0.1)

    E, g, H, info = f(u, 2)
    assert info["active"] > 0
    h = 1e-7
    fd_g = (f(u + h * du, 0)[0] - f(u - h * du, 0)[0]) / (2 * h)
    fd_H = (f(u + h * du, 1)[1] - f(u - h * du, 1)[1])[:n] / (2 * h)
    assert abs(g[:n] @ du - fd_g) < 1e-6 * abs(fd_g)
    tol = 1e-6 if exact_hessian else 0.1
    assert np.linalg.norm(H[:n, :n] @ du - fd_H) < tol * np.linalg.norm(fd_H)


@pytest.mark.parametrize("law", [SolidPenalty(), SolidMortar()], ids=["penalty", "mortar"])
def test_hertz_cylinder_on_flat(cylinder, law):
    """The axis approach of an elastic cylinder pressed on a rigid flat matches Hertz line contact within 5 %."""
    mesh, body, surf = cylinder
    E, nu, R, t, d = 100.0, 0.3, 1.0, 0.05, 0.02
    forms = SolidForms(mesh, iso(E, nu), None)
    X = nodes(mesh)
    fixed = np.zeros((len(X), 3), bool)
    fixed[:, 2] = True
    fixed[body == 1] = True
    fixed[(body == 0) & np.isclose(X[:, 0], 0), 0] = True
    sym = (body == 0) & np.isclose(X[:, 1], 0)
    fixed[sym, 1] = True
    u = np.zeros((len(X), 3))
    u[body == 0, 1] = -d
    h_c = 0.01 if isinstance(mesh, skfem.MeshTet1) and not isinstance(mesh, skfem.MeshTet2) else 0.02
    u, info = solve(forms, law, surf, u.ravel(), ~fixed.ravel(), law.penalty(E / (1 - nu**2), h_c), reach=0.2)
    reaction = forms.residual(u).reshape(-1, 3)
    f = -2 * reaction[sym, 1].sum() / t  # line load on the whole cylinder, N/mm
    assert 2 * info["force"] / t == pytest.approx(f, rel=1e-6)
    assert d / line_contact_approach(np.array([f]), R, E, nu, rigid_partner=True)[0] == pytest.approx(1.0, abs=0.05)


def stacked_blocks(order: int):
    lo = skfem.MeshTet1.init_tensor(np.linspace(0, 1, 4), np.linspace(0, 1, 4), np.linspace(0, 0.5, 3))
    hi = skfem.MeshTet1.init_tensor(np.linspace(0, 1, 6), np.linspace(0, 1, 5), np.linspace(0.5, 1, 3))
    mesh, body = join([lo, hi], order)
    X = nodes(mesh)
    bf = mesh.boundary_facets()
    fz, vb = X[mesh.facets[:, bf], 2], body[mesh.facets[0, bf]]
    at = np.all(np.isclose(fz, 0.5), axis=0)
    return mesh, body, surface(mesh, body, bf[(vb == 1) & at], bf[(vb == 0) & at]), lo.t.shape[1]


@pytest.mark.parametrize("order,law,tol", [
    (1, SolidMortar(quadrature=10), 0.005),
    (2, SolidMortar(quadrature=6), 0.03),
    (1, SolidPenalty(), None),
    (2, SolidPenalty(), None),
], ids=["mortar-P1", "mortar-P2", "penalty-P1", "penalty-P2"])
def test_contact_patch_test(order, law, tol):
    """Two blocks with non-matching meshes in confined compression: mortar transmits a uniform stress.

    Node-to-surface penalty balances the load globally but, as is known for single-pass
    node-to-surface contact, not pointwise; for it only the transmitted force is checked.
    """
    E, nu, strain = 100.0, 0.3, 0.02
    mesh, body, surf, n_lo = stacked_blocks(order)
    forms = SolidForms(mesh, iso(E, nu), None)
    X = nodes(mesh)
    fixed = np.zeros((len(X), 3), bool)
    fixed[np.isclose(X[:, 0], 0) | np.isclose(X[:, 0], 1), 0] = True
    fixed[np.isclose(X[:, 1], 0) | np.isclose(X[:, 1], 1), 1] = True
    fixed[np.isclose(X[:, 2], 0) | np.isclose(X[:, 2], 1), 2] = True
    u = np.zeros((len(X), 3))
    u[body == 1, 2] = -strain
    u, info = solve(forms, law, surf, u.ravel(), ~fixed.ravel(), law.penalty(E, 0.2), reach=0.1)
    szz = forms.stress(u)[2, 2]
    reaction = forms.residual(u).reshape(-1, 3)
    bottom = -reaction[np.isclose(X[:, 2], 0), 2].sum()
    assert info["force"] == pytest.approx(-bottom, rel=1e-4)  # contact force = support reaction
    assert -bottom == pytest.approx(-szz.mean(), rel=0.02)
    if tol is not None:
        assert np.ptp(szz) < tol * abs(szz.mean())
        p = info["pressure"][surf.slave_nodes]
        assert np.ptp(p) < 2 * tol * p.mean()


def test_contact_with_periodic_image_moves_with_macro_dofs():
    """A block overlapping its own image across the lattice feels contact whose h-derivatives match FD.

    The image is offset sideways so that no slave node projects onto a master edge (where the
    nearest-facet choice, and with it the Hessian, would be ambiguous).
    """
    m = skfem.MeshTet1.init_tensor(np.linspace(0, 1, 4), np.linspace(0, 1, 3), np.linspace(0, 0.5, 2))
    X = m.p.T
    bf = m.boundary_facets()
    fx = X[m.facets[:, bf], 0]
    right, left = bf[np.all(np.isclose(fx, 1), axis=0)], bf[np.all(np.isclose(fx, 0), axis=0)]
    facets = np.vstack([surface_facets(m, right), surface_facets(m, left)])
    n = len(X)
    topo = SegmentTopology(np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n), np.zeros(1, np.int64), np.zeros(1))
    lattice = Lattice([0.98, 0.0731, 0], [0, 3.0, 0])
    surf = SolidSurface.build(X, facets, np.arange(len(right)), np.arange(len(right), len(facets)), topo, 1.0, lattice)
    hdofs = np.zeros(6)
    for law in (SolidPenalty(), SolidMortar()):
        E, g, H, info = law.evaluate(surf, X, hdofs, 2, stiffness=100.0, reach=0.1)
        assert info["active"] > 0 and E > 0
        # stretching the lattice along x by more than the overlap separates the images
        assert law.evaluate(surf, X, np.array([0.05, 0, 0, 0, 0, 0]), 0, stiffness=100.0, reach=0.1)[0] == 0.0
        dh = np.array([1.0, 0.3, -0.2, 0.5, 0.1, 0.0])
        eps = 1e-7
        Ep = law.evaluate(surf, X, eps * dh, 1, stiffness=100.0, reach=0.1)
        Em = law.evaluate(surf, X, -eps * dh, 1, stiffness=100.0, reach=0.1)
        assert g[3 * n:] @ dh == pytest.approx((Ep[0] - Em[0]) / (2 * eps), rel=1e-6)
        assert np.allclose(H[:, 3 * n:] @ dh, (Ep[1] - Em[1]) / (2 * eps), atol=1e-6 * np.abs(H).max())


def helix_cell(c: float, r: float = 0.3) -> UnitCell:
    """Two helical turns (pitch 2πc) periodic along the axis z."""
    R = 1.0
    heli = Centerline("helix", lambda t: np.stack([R * np.cos(t), R * np.sin(t), c * t], 1),
                      lambda t: np.stack([-R * np.sin(t), R * np.cos(t), c + 0 * t], 1), 0.0, 4 * np.pi,
                      [0.0, 0.0, 4 * np.pi * c])
    return UnitCell("helix", (heli,), heli.period, [10.0, 0, 0], r, ((0, 0),), (("k",),), 1.0, 1.0, 1.0)


@pytest.mark.parametrize("law", [SolidPenalty(), SolidMortar()], ids=["penalty", "mortar"])
def test_self_contact_between_helix_turns_only(law):
    """A tube is never in contact with its own cross-section, but overlapping turns of a helix are."""
    from knitframe_solvers.volumetric import contact_surface

    for c, expect in ((0.2, False), (0.085, True)):  # pitch 1.26 mm (> 2r) and 0.53 mm (< 2r = 0.6)
        cm = cell_mesh(helix_cell(c), seed=0.6, check=False)
        surf = contact_surface(cm, None)
        E, _, _, info = law.evaluate(surf, cm.nodes, None, 0, stiffness=10.0, reach=0.2)
        assert (info["active"] > 0) == expect
