"""Fitting reduced models: objective and gradient, NRMSE, hard cases, both fitters, real data."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from knitframe.errors import NumericalError, PluginError
from knitframe.fitting import FitProblem, FitResult, UnitBox
from knitframe.plugins import get_registry
from knitframe.records import Provenance, Response


def model(name, **kw):
    return get_registry()["homogenizer"][name](**kw)


def fitter(name, **kw):
    return get_registry()["fitter"][name](**kw)


def uniaxial_data(m, p, direction, lam, *, lateral=True):
    """A free-sides test of model m (measured lateral stretch = the model's own)."""
    lf, P = m.solve_uniaxial(p, lam, direction)
    z = np.zeros_like(P)
    if direction == "course":
        return Response(lam, lf, P, z, load="uniaxial-course", label="c")
    return Response(lf, lam, z, P, load="uniaxial-wale", label="w")


def fd_gradient(f, x, h=1e-6):
    g = np.zeros_like(x)
    for k in range(len(x)):
        e = np.zeros_like(x)
        e[k] = h * max(1.0, abs(x[k]))
        g[k] = (f(x + e) - f(x - e)) / (2 * e[k])
    return g


def test_objective_gradient_measured_free_side():
    """For hgo on free-sides data (measured λ2 imposed) the objective's gradient matches finite
    differences."""
    m = model("hgo")
    lam = np.linspace(1.0, 1.5, 30)
    rc = Response(lam, 1 - 0.3 * (lam - 1), 0.4 * (lam - 1) ** 2, 0 * lam, load="uniaxial-course", label="c")
    rw = Response(1 - 0.2 * (lam - 1), lam, 0 * lam, 0.8 * (lam - 1) ** 2, load="uniaxial-wale", label="w")
    prob = FitProblem(m, [rc, rw])
    p = np.array([0.05, 2.0, 0.8])
    f, g = prob.objective(p, grad=True)
    np.testing.assert_allclose(g, fd_gradient(prob.objective, p), rtol=1e-6)


def test_objective_gradient_solved_free_side():
    """For hgo2m the implicit derivative of the solved free side gives the exact objective gradient."""
    m = model("hgo2m")
    truth = np.array([0.03, 0.01, 0.04, 0.02, 2.0, 0.05, 1.0])
    data = [
        uniaxial_data(m, truth, "course", np.linspace(1, 1.6, 25)),
        uniaxial_data(m, truth, "wale", np.linspace(1, 1.3, 25)),
    ]
    prob = FitProblem(m, data)
    p = np.array([0.02, 0.02, 0.03, 0.03, 1.0, 0.04, 2.0])
    f, g = prob.objective(p, grad=True)
    assert f > 0
    np.testing.assert_allclose(g, fd_gradient(prob.objective, p), rtol=1e-5)


def test_nrmse_is_normalised_by_the_maximum_measured_tension():
    """NRMSE per direction is the RMS error over the maximum measured tension of that direction."""
    m = model("hgo")
    p = np.array([0.1, 1.0, math.radians(30)])
    lam = np.linspace(1.0, 1.2, 11)
    P1, P2 = m.stress(p, lam, lam)
    off = np.full_like(lam, 0.01)
    r = Response(lam, lam, P1 + off, P2 - 2 * off, load="equibiaxial")
    ten, tra = FitProblem(m, [r]).nrmse(p)
    assert ten["course"] == pytest.approx(0.01 / np.abs(P1 + off).max())
    assert ten["wale"] == pytest.approx(0.02 / np.abs(P2 - 2 * off).max())
    overall = math.sqrt((0.01**2 + 0.02**2) / 2) / max(np.abs(P1 + off).max(), np.abs(P2 - 2 * off).max())
    assert ten["overall"] == pytest.approx(overall)
    assert tra == {}


def test_lbfgs_is_deterministic_and_recovers_hgo():
    """The same data give the same lbfgs result twice, and it is the generating hgo parameter set."""
    m = model("hgo")
    truth = np.array([0.02, 5.0, math.radians(62)])
    t = np.linspace(0, 1, 40)
    data = [Response(1 + 0.3 * t, 1 + 0.1 * t, *m.stress(truth, 1 + 0.3 * t, 1 + 0.1 * t), load="general")]
    a, b = fitter("lbfgs").fit(m, data), fitter("lbfgs").fit(m, data)
    np.testing.assert_array_equal(a.params, b.params)
    np.testing.assert_allclose(a.params, truth, rtol=1e-4)
    assert a.converged and a.n_evals > 10 and a.wall_time > 0


def test_equal_data_in_both_directions_gives_45_degrees():
    """Equibiaxial data with T1 = T2 can only come from θ = 45° (P1/P2 = cot²θ)."""
    lam = np.linspace(1.0, 1.25, 30)
    T = 0.5 * (lam - 1) + 4 * (lam - 1) ** 3
    res = fitter("lbfgs").fit(model("hgo"), [Response(lam, lam, T, T, load="equibiaxial")])
    assert math.degrees(res.params[2]) == pytest.approx(45.0, abs=1e-4)
    assert res.nrmse["course"] == pytest.approx(res.nrmse["wale"], rel=1e-6)


def test_equal_uniaxial_data_both_ways_gives_symmetric_hgo2m():
    """The same free-sides curve along course and wale gives hgo2m equal course and wale parameters."""
    m = model("hgo2m")
    truth = np.array([0.02, 0.02, 0.03, 0.04, 1.5, 0.04, 1.5])
    lam = np.linspace(1.0, 1.5, 20)
    c = uniaxial_data(m, truth, "course", lam)
    w = uniaxial_data(m, truth, "wale", lam)
    np.testing.assert_allclose(c.T1, w.T2, rtol=1e-12)
    res = fitter("lbfgs").fit(m, [c, w])
    assert res.nrmse["overall"] < 1e-4 and res.nrmse_transverse["overall"] < 1e-4
    mu1, mu2, K, a1, b1, a2, b2 = res.params
    assert (
        mu1 == pytest.approx(mu2, rel=1e-2)
        and a1 == pytest.approx(a2, rel=1e-2)
        and b1 == pytest.approx(b2, rel=1e-2)
    )


@pytest.mark.parametrize("name", ["lbfgs", "mads"])
def test_single_data_point(name):
    """One measured point is enough to run a fit: finite parameters inside the bounds and a tiny NRMSE."""
    m = model("hgo")
    r = Response([1.2], [1.1], [0.05], [0.03], load="general")
    res = fitter(name, **({"max_evals": 300} if name == "mads" else {})).fit(m, [r])
    lo, hi = m.bounds()
    assert np.all(np.isfinite(res.params)) and np.all(res.params >= lo) and np.all(res.params <= hi)
    assert res.nrmse["overall"] < 1e-3


def test_all_zero_tension_is_a_clear_error():
    """Data whose measured tension is zero everywhere cannot be scored and say so."""
    lam = np.linspace(1, 1.1, 5)
    r = Response(lam, lam, 0 * lam, 0 * lam, load="equibiaxial")
    with pytest.raises(NumericalError, match="every measured course tension is zero"):
        FitProblem(model("hgo"), [r])


def test_hgo2m_recovers_its_own_uniaxial_tests_with_mads():
    """MADS fits hgo2m's own course and wale free-sides tests: tension and transverse strain to < 1 %."""
    m = model("hgo2m")
    truth = np.array([0.03, 0.01, 0.04, 0.02, 2.0, 0.05, 1.0])
    data = [
        uniaxial_data(m, truth, "course", np.linspace(1, 1.6, 20)),
        uniaxial_data(m, truth, "wale", np.linspace(1, 1.3, 20)),
    ]
    res = fitter("mads", max_evals=800).fit(m, data)
    assert res.nrmse["overall"] < 0.01 and res.nrmse_transverse["overall"] < 0.01
    assert res.n_evals >= 100 and res.fitter == "mads"


def test_unit_box_round_trip():
    """The fitters' unit box maps parameters to [0, 1] and back, on log scale for a and b."""
    m = model("hgo")
    box = UnitBox(m)
    p = np.array([0.3, 12.0, 0.4])
    np.testing.assert_allclose(box.to_params(box.to_unit(p)), p, rtol=1e-12)
    lo, hi = m.bounds()
    assert box.to_unit(np.sqrt(lo * hi))[0] == pytest.approx(0.5)


def test_fit_result_json_round_trip():
    """FitResult.to_json gives theta in degrees and from_json rebuilds the same model and parameters."""
    m = model("hgo", compression_fibre=False)
    res = FitResult(m, [0.1, 2.0, math.radians(30)], {"course": 0.01, "overall": 0.01}, fitter="lbfgs")
    data = res.to_json()
    assert data["theta_deg"] == pytest.approx(30.0) and "theta" not in data
    back = FitResult.from_json(data)
    assert back.model == m
    np.testing.assert_allclose(back.params, res.params)


def test_mads_without_pynomad_says_what_to_install(monkeypatch):
    """Without PyNomad the mads fitter fails with one line naming the package to install."""
    monkeypatch.setitem(sys.modules, "PyNomad", None)
    lam = np.linspace(1, 1.2, 5)
    r = Response(lam, lam, lam - 1, lam - 1, load="equibiaxial")
    with pytest.raises(PluginError, match="pip install PyNomadBBO") as e:
        fitter("mads").fit(model("hgo"), [r])
    assert "\n" not in str(e.value)


def test_paper_model_on_real_uniaxial_data(singal_file):
    """On Singal's cotton jersey hgo fits the tension (measured λ2) but implies a large free-side tension."""
    reader = get_registry()["reader"]["singal2024"]()
    data = [
        r
        for f in ("cotton-stockinette-x.csv", "cotton-stockinette-y.csv")
        for r in reader.read(singal_file(f))
    ]
    res = fitter("lbfgs").fit(model("hgo"), data)
    assert res.nrmse["overall"] < 0.05
    assert res.diagnostics["free_side_tension"] > 0.2  # the model cannot leave the free side unloaded
    assert all(isinstance(r.provenance, Provenance) for r in data)
