"""Reduced fabric models: the paper's hgo (Eq. 1-3) and the uniaxial-capable hgo2m."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from knitframe.fitting import FREE_MIN
from knitframe.plugins import get_registry
from knitframe.testing.models import check_homogenizer


def hgo(**kw):
    return get_registry()["homogenizer"]["hgo"](**kw)


def hgo2m(**kw):
    return get_registry()["homogenizer"]["hgo2m"](**kw)


def closed_form(a, b, theta, l1, l2):
    """Paper Eq. 3 written out directly (no cap, small arguments only)."""
    i4 = l1**2 * math.cos(theta) ** 2 + l2**2 * math.sin(theta) ** 2
    g = 2 * a * (i4 - 1) * np.exp(b * (i4 - 1) ** 2)
    return g * 2 * l1 * math.cos(theta) ** 2, g * 2 * l2 * math.sin(theta) ** 2


@pytest.mark.parametrize("name", ["hgo", "hgo2m"])
@pytest.mark.parametrize("compression", [True, False])
def test_conformance_both_fibre_options(name, compression):
    """Both models pass the homogenizer contract with and without fibre compression."""
    cls = get_registry()["homogenizer"][name]
    check_homogenizer(cls(compression_fibre=compression))


def test_hgo_matches_paper_equation():
    """hgo's tensions equal the paper's Eq. 3 evaluated directly."""
    p = np.array([0.07, 2.5, math.radians(30)])
    l1, l2 = np.linspace(0.9, 1.4, 11), np.linspace(1.2, 0.95, 11)
    P1, P2 = hgo().stress(p, l1, l2)
    E1, E2 = closed_form(*p, l1, l2)
    np.testing.assert_allclose(P1, E1, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(P2, E2, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("theta_deg", [20.0, 45.0, 70.0])
def test_hgo_equibiaxial_ratio_is_cot_squared(theta_deg):
    """Under equibiaxial stretch I4 = λ² for every θ and P1/P2 = cot²θ (45° gives equal tensions)."""
    th = math.radians(theta_deg)
    lam = np.linspace(1.01, 1.3, 8)
    P1, P2 = hgo().stress(np.array([0.1, 1.0, th]), lam, lam)
    np.testing.assert_allclose(P1 / P2, 1 / math.tan(th) ** 2, rtol=1e-12)


def test_hgo_theta_zero_and_ninety():
    """θ = 0 loads only the course (P2 ≡ 0, P1 independent of λ2); θ = 90° only the wale."""
    lam = np.linspace(0.8, 1.5, 9)
    P1, P2 = hgo().stress(np.array([0.1, 2.0, 0.0]), lam, 1.3 * np.ones(9))
    Q1, _ = hgo().stress(np.array([0.1, 2.0, 0.0]), lam, 0.7 * np.ones(9))
    assert np.all(P2 == 0) and np.array_equal(P1, Q1)
    R1, R2 = hgo().stress(np.array([0.1, 2.0, math.pi / 2]), 1.3 * np.ones(9), lam)
    np.testing.assert_allclose(R1, 0.0, atol=1e-15)
    E1, E2 = closed_form(0.1, 2.0, math.pi / 2, 1.3, lam)
    np.testing.assert_allclose(R2, E2, rtol=1e-13)


@pytest.mark.parametrize("b", [0.0, 1e-12, 1e-7])
def test_hgo_small_b_limit(b):
    """b → 0 gives ψ = a(I4 − 1)² and P = 2a(I4 − 1)∂I4/∂λ, with no 0/0 at b = 0."""
    a, th = 0.2, math.radians(40)
    l1, l2 = np.linspace(0.8, 1.6, 9), np.linspace(1.5, 0.9, 9)
    m = hgo()
    p = np.array([a, b, th])
    i4 = l1**2 * math.cos(th) ** 2 + l2**2 * math.sin(th) ** 2
    np.testing.assert_allclose(m.energy(p, l1, l2), a * (i4 - 1) ** 2, rtol=1e-6)
    P1, _ = m.stress(p, l1, l2)
    np.testing.assert_allclose(P1, 2 * a * (i4 - 1) * 2 * l1 * math.cos(th) ** 2, rtol=1e-6)
    dP1 = m.stress_grad(p, l1, l2)[2]
    assert np.all(np.isfinite(dP1))
    # ∂P/∂b at b = 0 is 2a(I4 − 1)³ ∂I4/∂λ1
    np.testing.assert_allclose(
        dP1[:, 1], 2 * a * (i4 - 1) ** 3 * 2 * l1 * math.cos(th) ** 2, rtol=1e-5, atol=1e-12
    )


def test_hgo_b_1e3_at_100_percent_stretch_is_finite_and_monotone():
    """b = 1e3 at 100 % stretch (b(I4 − 1)² = 9000 ≫ 709) gives huge but finite, increasing values and no
    warning."""
    m = hgo()
    p = np.array([1.0, 1e3, 0.0])
    lam = np.linspace(1.0, 2.0, 201)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with np.errstate(all="raise"):
            P1, P2 = m.stress(p, lam, np.ones_like(lam))
            psi = m.energy(p, lam, np.ones_like(lam))
            dP1 = m.stress_grad(p, lam, np.ones_like(lam))[2]
            K = m.tangent(p, lam, np.ones_like(lam))
    for arr in (P1, P2, psi, dP1, *K):
        assert np.all(np.isfinite(arr))
    assert np.all(np.diff(P1) > 0) and np.all(np.diff(psi[1:]) > 0)
    assert P1[-1] > 1e80  # the cap keeps the penalty steep


def test_compression_fibre_option():
    """compression_fibre = false drops the fibre for I4 < 1 and changes nothing for I4 > 1."""
    p = np.array([0.1, 2.0, math.radians(30)])
    l1 = np.array([0.8, 0.9, 1.1, 1.3])
    l2 = np.array([0.9, 0.95, 1.05, 1.2])
    P_on = hgo(compression_fibre=True).stress(p, l1, l2)
    P_off = hgo(compression_fibre=False).stress(p, l1, l2)
    assert np.all(P_on[0][:2] < 0) and np.all(P_off[0][:2] == 0)
    np.testing.assert_array_equal(P_on[0][2:], P_off[0][2:])


def test_non_finite_stretch_is_refused():
    """A NaN or non-positive stretch raises instead of returning NaN."""
    with pytest.raises(ValueError, match="finite and > 0"):
        hgo().stress(hgo().x0(), np.array([1.0, np.nan]), np.ones(2))
    with pytest.raises(ValueError, match="finite and > 0"):
        hgo2m().stress(hgo2m().x0(), np.array([1.0, -0.1]), np.ones(2))


def test_hgo_uniaxial_limitation():
    """With free sides hgo keeps I4 = 1 and carries no tension until λ1 = 1/cos θ, then the free side
    collapses."""
    th = math.radians(45)
    p = np.array([0.1, 2.0, th])
    lam = np.array([1.1, 1.2, 1.4, 1.5, 1.8])
    lf, P = hgo().solve_uniaxial(p, lam, "course")
    below = lam < 1 / math.cos(th)
    np.testing.assert_allclose(
        lf[below], np.sqrt((1 - lam[below] ** 2 * math.cos(th) ** 2) / math.sin(th) ** 2), rtol=1e-10
    )
    np.testing.assert_allclose(P[below], 0.0, atol=1e-12)
    assert np.all(lf[~below] == FREE_MIN) and np.all(P[~below] > 0)


def test_hgo2m_small_strain_poisson_ratio():
    """hgo2m's uniaxial contraction at small strain is ν12 = K/(2μ2 + K) (course) and ν21 = K/(2μ1 + K)
    (wale)."""
    p = np.array([0.03, 0.01, 0.04, 0.05, 1.0, 0.08, 2.0])
    eps = 1e-6
    lf, _ = hgo2m().solve_uniaxial(p, np.array([1 + eps]), "course")
    assert (1 - lf[0]) / eps == pytest.approx(0.04 / (2 * 0.01 + 0.04), rel=1e-4)
    lf, _ = hgo2m().solve_uniaxial(p, np.array([1 + eps]), "wale")
    assert (1 - lf[0]) / eps == pytest.approx(0.04 / (2 * 0.03 + 0.04), rel=1e-4)


@pytest.mark.parametrize("direction", ["course", "wale"])
def test_hgo2m_free_side_root_is_unique_and_solved(direction):
    """The free side of hgo2m has one root of P_free = 0, found to round-off for large and compressive
    strains."""
    m = hgo2m()
    p = np.array([0.02, 0.05, 0.03, 0.01, 3.0, 0.2, 0.5])
    lam = np.linspace(0.7, 3.0, 50)
    lf, P = m.solve_uniaxial(p, lam, direction)
    d = 0 if direction == "course" else 1
    pair = (lam, lf) if d == 0 else (lf, lam)
    Pf = m.stress(p, *pair)[1 - d]
    assert np.abs(Pf).max() < 1e-12 * np.abs(P).max()
    assert np.all(np.diff(lf) < 0)  # the more it is pulled, the more it contracts
    # uniqueness: P_free is strictly increasing in the free stretch along the whole bracket
    grid = np.linspace(FREE_MIN, 3.0, 400)
    for ll in lam[::7]:
        g = m.stress(p, *((np.full_like(grid, ll), grid) if d == 0 else (grid, np.full_like(grid, ll))))[
            1 - d
        ]
        assert np.all(np.diff(g) > 0)
