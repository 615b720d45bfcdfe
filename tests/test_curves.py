"""Curve comparison shared by the benchmarks (accuracy ladder, volumetric against rod)."""

from __future__ import annotations

import numpy as np
import pytest

from knitframe.curves import by_strain, nrmse_between, value_at
from knitframe.records import Response


def test_nrmse_between_matches_the_hand_computed_value():
    """Errors (0.1, 0.2 course; 0, −0.2 wale) at the reference's stretches over max |T_ref| = 2."""
    lam = np.array([1.1, 1.2])
    ref = Response(lam, lam, [1.0, 2.0], [0.5, 1.5])
    # r is sampled elsewhere and linear in λ: 1.1, 2.2 (course) and 0.5, 1.3 (wale) at 1.1, 1.2
    lr = np.array([1.0, 1.3])
    r = Response(lr, lr, [0.0, 3.3], [-0.3, 2.1])
    expected = np.sqrt(np.mean(np.array([0.1, 0.2, 0.0, -0.2]) ** 2)) / 2.0
    assert nrmse_between(ref, r) == pytest.approx(expected, rel=1e-12)
    assert nrmse_between(ref, ref) == 0.0


def test_value_at_sorts_the_curve_and_refuses_strains_outside_it():
    """value_at interpolates the curve sorted by strain, and is None outside the strains it covers."""
    e = np.array([0.3, 0.0, 0.2, 0.1])
    t = 2.0 * e**2
    assert value_at(e, t, 0.15) == pytest.approx(0.5 * (0.02 + 0.08))
    assert value_at(e, t, 0.3) == pytest.approx(0.18) and value_at(e, t, 0.0) == 0.0
    assert value_at(e, t, 0.31) is None and value_at(e + 0.05, t, 0.0) is None
    s, v = by_strain(e, t)
    assert list(s) == [0.0, 0.1, 0.2, 0.3] and np.allclose(v, 2.0 * s**2)
