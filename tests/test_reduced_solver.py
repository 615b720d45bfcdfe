"""The ``reduced`` solver: a parameterised homogenizer along a Scene's load path."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from knitframe import run
from knitframe.errors import ConfigError, UnsupportedEffectError
from knitframe.fitting import FREE_MIN, FitResult
from knitframe.plugins import get_registry
from knitframe.records import LoadPath, Scene
from knitframe.schema import build

EFFECTS = frozenset({"large_deformation", "anisotropy"})


def solver(**options):
    return build(get_registry()["solver"]["reduced"], options, "solver")


def test_equibiaxial_matches_closed_form():
    """Equibiaxial hgo gives the paper's closed form, P1/P2 = cot²θ, as a "model" Response."""
    s = solver(model="hgo", params={"a": 0.1, "b": 2.0, "theta_deg": 30.0})
    r = s.simulate(None, Scene(load=LoadPath("equibiaxial", 0.2, 4), effects=EFFECTS))
    lam = 1 + 0.2 * np.arange(1, 5) / 4
    x = lam**2 - 1
    P = 2 * 0.1 * x * np.exp(2.0 * x**2) * 2 * lam
    np.testing.assert_allclose(r.T1, P * math.cos(math.radians(30)) ** 2, rtol=1e-12)
    np.testing.assert_allclose(r.T1 / r.T2, 3.0, rtol=1e-12)
    assert r.provenance.kind == "model" and r.provenance.solver == "reduced" and len(r) == 4


def test_uniaxial_free_side_with_hgo2m():
    """A uniaxial wale load solves the free course side to P1 = 0 and reports T1 = 0."""
    p = {"mu1": 0.02, "mu2": 0.01, "K": 0.03, "a1": 0.05, "b1": 2.0, "a2": 0.08, "b2": 1.0}
    r = solver(model="hgo2m", params=p).simulate(
        None, Scene(load=LoadPath("uniaxial", 0.5, 5, direction="wale"), effects=EFFECTS)
    )
    m = get_registry()["homogenizer"]["hgo2m"]()
    params = np.array(list(p.values()))
    assert r.load == "uniaxial-wale" and np.all(r.T1 == 0) and np.all(np.diff(r.lambda1) < 0)
    np.testing.assert_allclose(m.stress(params, r.lambda1, r.lambda2)[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(m.stress(params, r.lambda1, r.lambda2)[1], r.T2, rtol=1e-12)


def test_uniaxial_hgo_reports_the_collapse():
    """The paper's model under free sides is slack up to 1/cos θ and then collapses laterally; the Response
    says so."""
    s = solver(model="hgo", params={"a": 0.1, "b": 2.0, "theta_deg": 45.0})
    r = s.simulate(None, Scene(load=LoadPath("uniaxial", 0.8, 8), effects=EFFECTS))
    slack = r.lambda1 < math.sqrt(2)
    np.testing.assert_allclose(r.T1[slack], 0.0, atol=1e-12)
    assert np.all(r.T1[~slack] > 0) and np.all(r.lambda2[~slack] == FREE_MIN)
    assert "collapsed" in r.provenance.notes


def test_general_path():
    """A general path imposes both stretches point by point."""
    path = LoadPath("general", lambda1=(1.1, 1.2, 1.0), lambda2=(1.0, 1.1, 1.3))
    r = solver(model="hgo").simulate(None, Scene(load=path, effects=EFFECTS))
    m = get_registry()["homogenizer"]["hgo"]()
    np.testing.assert_allclose(r.T1, m.stress(m.x0(), np.array(path.lambda1), np.array(path.lambda2))[0])


def test_unsupported_effect_is_refused():
    """A scene asking for contact names the effect and the solvers that model it."""
    with pytest.raises(
        UnsupportedEffectError, match="does not support effect 'contact'; solvers that do: .*rod"
    ):
        solver().simulate(None, Scene(load=LoadPath("equibiaxial", 0.1, 2), effects=EFFECTS | {"contact"}))


def test_bad_parameters_name_the_config_key():
    """A missing or unknown parameter fails when the solver is configured, naming the key."""
    with pytest.raises(ConfigError, match="solver.params.theta_deg"):
        solver(model="hgo", params={"a": 0.1, "b": 2.0})
    with pytest.raises(ConfigError, match="solver.params.c"):
        solver(model="hgo", params={"a": 0.1, "b": 2.0, "theta_deg": 10.0, "c": 1.0})


def test_params_file_round_trip(tmp_path):
    """A params.json written by a fit drives the solver to the fitted model's tensions."""
    m = get_registry()["homogenizer"]["hgo"](compression_fibre=False)
    fit = FitResult(m, [0.2, 5.0, math.radians(60)], {"overall": 0.01}, fitter="lbfgs")
    (tmp_path / "params.json").write_text(json.dumps(fit.to_json()))
    s = solver(params_file=str(tmp_path / "params.json"))
    r = s.simulate(None, Scene(load=LoadPath("equibiaxial", 0.3, 3), effects=EFFECTS))
    lam = 1 + 0.3 * np.arange(1, 4) / 3
    np.testing.assert_allclose(r.T1, fit.stress(lam, lam)[0], rtol=1e-14)
    assert r.provenance.extra["params"]["theta_deg"] == pytest.approx(60.0)
    np.testing.assert_allclose(get_registry()["solver"]["reduced"].from_fit(fit).resolved()[1], fit.params)


def test_simulate_then_fit_recovers_the_parameters(tmp_path):
    """The simulate stage with the reduced solver feeds the fit stage, which recovers the parameters it was
    given."""
    cfg = {
        "solver": {"kind": "reduced", "model": "hgo", "params": {"a": 0.03, "b": 4.0, "theta_deg": 65.0}},
        "fabric": {"pattern": "jersey", "stitch_length": 10, "yarn": "cotton"},
        "scene": {
            "effects": ["large_deformation", "anisotropy"],
            "load": {
                "kind": "general",
                "lambda1": [1.05, 1.1, 1.15, 1.2, 1.25],
                "lambda2": [1.02, 1.04, 1.05, 1.08, 1.1],
            },
        },
        "fit": {"model": "hgo", "fitter": "lbfgs"},
    }
    res = run(cfg, tmp_path / "out")
    fit = res.models[0]
    np.testing.assert_allclose(fit.params, [0.03, 4.0, math.radians(65)], rtol=1e-5)
    assert json.loads((tmp_path / "out" / "params.json").read_text())["theta_deg"] == pytest.approx(
        65.0, abs=1e-3
    )
