"""Lagged regularised Coulomb friction of the solid contact laws ``penalty`` and ``mortar``."""

from __future__ import annotations

import attrs
import numpy as np
import pytest
from contact_solid_helpers import (
    assert_derivatives,
    image_blocks,
    iso,
    nodes,
    quarter_cylinder_on_flat,
    solve,
    stacked_blocks,
    surface,
)
from knitframe_contact.mortar import SolidMortar
from knitframe_contact.penalty import SolidPenalty
from knitframe_solvers.volumetric_material import SolidForms

from knitframe.numerics.contact import friction_potential

LAWS = [SolidPenalty(friction=0.4, slip=0.05), SolidMortar(friction=0.4, slip=0.05)]
IDS = ["penalty", "mortar"]


def test_friction_potential_force_reaches_coulomb():
    """|∇D| = μλ(2y − y²) below the regularisation slip and μλ beyond, with the exact Hessian; zero slip is
    finite."""
    rng = np.random.default_rng(0)
    u = rng.normal(size=(200, 3))
    u[0] = 0.0
    eps = np.full(200, 0.7)
    mu_lam = rng.uniform(0.0, 2.0, 200)
    mu_lam[1] = 0.0
    D, g, H = friction_potential(u, mu_lam, eps)
    assert np.all(np.isfinite(D)) and np.all(np.isfinite(g)) and np.all(np.isfinite(H))
    y = np.linalg.norm(u, axis=1) / eps
    phi = np.where(y < 1, 2 * y - y**2, 1.0)
    assert np.allclose(np.linalg.norm(g, axis=1), mu_lam * phi)
    h = 1e-7
    for i in range(3):
        du = np.zeros_like(u)
        du[:, i] = h
        Dp, gp, _ = friction_potential(u + du, mu_lam, eps)
        Dm, gm, _ = friction_potential(u - du, mu_lam, eps)
        assert np.allclose((Dp - Dm) / (2 * h), g[:, i], atol=1e-6)
        assert np.allclose((gp - gm)[2:] / (2 * h), H[2:, :, i], atol=1e-5)


@pytest.fixture(scope="module", params=[1, 2], ids=["P1", "P2"])
def cylinder(request):
    order = request.param
    mesh, body, arc, top = quarter_cylinder_on_flat(1.0, 0.01 if order == 1 else 0.02, 0.25, 0.05, order)
    return mesh, body, surface(mesh, body, arc, top)


@pytest.mark.parametrize("law", LAWS, ids=IDS)
def test_friction_derivatives_match_finite_differences(cylinder, law):
    """With a friction state, gradient = FD of the energy and Hessian = FD of the gradient, sticking and
    slipping pairs."""
    mesh, body, surf = cylinder
    X = nodes(mesh)
    n = 3 * len(X)
    rng = np.random.default_rng(1)
    u0 = np.zeros((len(X), 3))
    u0[body == 0, 1] = -0.01
    state = law.friction_state(surf, X + u0, None, stiffness=1e3, reach=0.1)
    assert len(state) > 0 and np.all(state.force > 0)
    eps_s = law.slip * float(np.median(state.size))
    u = u0.copy()
    u[body == 0, 0] += eps_s  # slide the cylinder by about the regularisation slip, with scatter
    u += 0.5 * eps_s * rng.normal(size=u.shape)
    u = u.ravel()
    du = rng.normal(size=n)

    def f(v, order):
        return law.evaluate(
            surf, X + v.reshape(-1, 3), None, order, stiffness=1e3, reach=0.1, friction_state=state
        )

    info = assert_derivatives(f, u, du, n)
    assert 0 < info["slipping"] < len(state)  # both regimes of the regularised law are exercised
    assert info["friction_energy"] > 0


@pytest.mark.parametrize("law", LAWS, ids=IDS)
def test_friction_with_periodic_image_macro_derivatives(law):
    """Friction against a periodic image: the slip includes the image shift F̄·S_k, with exact
    h-derivatives."""
    X, surf, n = image_blocks()
    state = law.friction_state(surf, X, np.zeros(6), stiffness=100.0, reach=0.1)
    assert len(state) > 0 and np.any(state.image != 0)
    # shear the lattice: the image slides past the slave face
    h0 = np.array([0.0, 0.0, 0.004, 0.0, 0.0, 0.0])

    def f(hv, order):
        return law.evaluate(surf, X, hv, order, stiffness=100.0, reach=0.1, friction_state=state)

    E, g, H, info = f(h0, 2)
    assert info["friction_energy"] > 0
    dh = np.array([0.2, 0.3, -1.0, 0.5, 0.1, 0.0])
    eps = 1e-7
    Ep, Em = f(h0 + eps * dh, 1), f(h0 - eps * dh, 1)
    assert g[3 * n :] @ dh == pytest.approx((Ep[0] - Em[0]) / (2 * eps), rel=1e-6)
    assert np.allclose(H[:, 3 * n :] @ dh, (Ep[1] - Em[1]) / (2 * eps), atol=1e-6 * np.abs(H).max())


@pytest.mark.parametrize("law", LAWS, ids=IDS)
def test_friction_only_with_a_state(law):
    """No state: the frictionless law. A state at the current position: no slip, no friction force.

    Pairs with zero normal force contribute nothing, and nothing is NaN at zero slip.
    """
    mesh, body, surf, _ = stacked_blocks(1)
    X = nodes(mesh)
    u = np.zeros((len(X), 3))
    u[body == 1, 2] = -0.01
    x = X + u
    ref = law.evaluate(surf, x, None, 2, stiffness=100.0, reach=0.1)
    none = law.evaluate(surf, x, None, 2, stiffness=100.0, reach=0.1, friction_state=None)
    assert ref[0] == none[0] and np.array_equal(ref[1], none[1]) and abs(ref[2] - none[2]).max() == 0.0
    state = law.friction_state(surf, x, None, stiffness=100.0, reach=0.1)
    assert len(state) > 0
    at = law.evaluate(surf, x, None, 2, stiffness=100.0, reach=0.1, friction_state=state)
    assert at[0] == pytest.approx(ref[0], rel=1e-14) and np.allclose(at[1], ref[1], rtol=0, atol=1e-14)
    assert np.all(np.isfinite(at[2].data))
    # a slid state with all normal forces zero: finite, and the frictionless result
    xs = x.copy()
    xs[body == 1, 0] += 0.003
    zero = attrs.evolve(state, force=np.zeros(len(state)))
    E0, g0, H0, info = law.evaluate(surf, xs, None, 2, stiffness=100.0, reach=0.1, friction_state=zero)
    free = law.evaluate(surf, xs, None, 2, stiffness=100.0, reach=0.1)
    assert np.isfinite(E0) and np.all(np.isfinite(g0)) and np.all(np.isfinite(H0.data))
    assert E0 == pytest.approx(free[0], rel=1e-14) and np.allclose(g0, free[1], rtol=0, atol=1e-14)
    assert info["friction_energy"] == 0.0
    # and with friction μ = 0 the state is ignored
    off = attrs.evolve(law, friction=0.0).evaluate(
        surf, xs, None, 1, stiffness=100.0, reach=0.1, friction_state=state
    )
    assert off[0] == free[0]


def _shear_block(law, order: int, slides: list[float]):
    """Press the upper block on the lower one by 0.01, freeze friction there, slide its top by each of
    ``slides``.

    Returns (normal force Σλ of the state, [(tangential reaction, normal reaction) per slide]) in N.
    """
    E, nu = 100.0, 0.3
    mesh, body, surf, _ = stacked_blocks(order)
    forms = SolidForms(mesh, iso(E, nu), None)
    X = nodes(mesh)
    top, bottom = np.isclose(X[:, 2], 1.0), np.isclose(X[:, 2], 0.0)
    fixed = np.zeros((len(X), 3), bool)
    fixed[top | bottom] = True
    free = ~fixed.ravel()
    stiffness, reach = law.penalty(E, 0.2), 0.1
    u = np.zeros((len(X), 3))
    u[body == 1, 2] = -0.01
    u, _ = solve(forms, law, surf, u.ravel(), free, stiffness, reach)
    state = law.friction_state(surf, X + u.reshape(-1, 3), None, stiffness=stiffness, reach=reach)
    out = []
    for s in slides:
        v = u.reshape(-1, 3).copy()
        v[top, 0] = s
        v, _ = solve(forms, law, surf, v.ravel(), free, stiffness, reach, friction_state=state)
        reaction = forms.residual(v).reshape(-1, 3)[top]
        out.append((reaction[:, 0].sum(), -reaction[:, 2].sum()))
    return float(state.force.sum()), out, law.slip * float(np.median(state.size))


@pytest.mark.parametrize("law", LAWS, ids=IDS)
def test_sheared_block_sticks_then_slides_at_coulomb(law):
    """A block pressed on a flat and sheared: linear (stick) for a small slide, μ·N once it slips past ε_s.

    The reaction at the slid face also carries the tilt of the normal contact forces (the mesh's
    diagonals make it slightly non-zero before any slide), so it is compared within a few %.
    """
    small = 0.02 * 0.0128  # ~2 % of the regularisation slip
    N, res, eps_s = _shear_block(law, 1, [0.0, small, 2 * small, 0.08])
    (f0, _), (f1, _), (f2, _), (f3, n3) = res
    mu = law.friction
    assert 0.08 > 4 * eps_s  # the large slide is well past the regularisation
    assert N > 0 and n3 == pytest.approx(N, rel=0.05)
    assert f3 == pytest.approx(mu * N, rel=0.03)  # saturated: Coulomb's μ N
    assert f3 == pytest.approx(mu * n3, rel=0.05)
    assert 0 < f1 - f0 < 0.05 * mu * N
    assert (f2 - f0) / (f1 - f0) == pytest.approx(2.0, rel=0.01)  # stick: linear in the slide


def test_sheared_block_slides_at_coulomb_on_quadratic_facets():
    """Both laws on P2 facets saturate at μ·N too."""
    for law in LAWS:
        N, ((f, n),), _ = _shear_block(law, 2, [0.08])
        assert f == pytest.approx(law.friction * N, rel=0.04)
