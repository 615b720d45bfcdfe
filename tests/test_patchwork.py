"""Patchworks: parallel strips, series chains and grids of Responses and fitted models."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from knitframe import run
from knitframe.fitting import FitResult
from knitframe.patchwork import ModelCurve, ResponseCurve, grid, parallel, series
from knitframe.plugins import get_registry
from knitframe.records import Response


def linear(k, label="", lam_max=2.0):
    """A linear spring T = k (λ − 1) as a measured course curve."""
    lam = np.linspace(1.0, lam_max, 21)
    return Response(lam, np.ones_like(lam), k * (lam - 1), 0 * lam, load="uniaxial-course", label=label)


def test_series_of_linear_springs_matches_closed_form():
    """Springs in series carry T = u / Σ(L_j/k_j); each interface moves by the strain of the regions before
    it."""
    eps = np.linspace(0, 0.5, 6)
    res = series([linear(2.0), linear(1.0), linear(4.0)], [10.0, 20.0, 5.0], eps)
    T = eps * 35.0 / (10 / 2 + 20 / 1 + 5 / 4)
    np.testing.assert_allclose(res.tension, T, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(res.stretch[:, 0, :], 1 + T[:, None] / np.array([2.0, 1.0, 4.0]), rtol=1e-10)
    u1 = 10 * T / 2
    np.testing.assert_allclose(res.interface_displacement[:, 0, 0], u1, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(res.interface_displacement[:, 0, 1], u1 + 20 * T, rtol=1e-10, atol=1e-14)


def test_parallel_is_width_weighted():
    """Strips in parallel share the stretch; the mean tension is the width-weighted average."""
    eps = np.linspace(0, 0.4, 5)
    res = parallel([linear(2.0), linear(1.0)], [10.0, 30.0], eps)
    np.testing.assert_allclose(res.tension, eps * (20 + 30) / 40, rtol=1e-12)
    np.testing.assert_allclose(res.force, eps * (20 + 30), rtol=1e-12)


def test_grid_equals_parallel_rows_of_series():
    """A 2 × 2 grid carries the width-weighted sum of its rows' series tensions."""
    eps = np.linspace(0, 0.3, 4)
    A, B = linear(2.0), linear(1.0)
    g = grid([[A, B], [B, B]], [5.0, 15.0], [[10.0, 10.0], [4.0, 16.0]], eps)
    r0 = series([A, B], [10.0, 10.0], eps).tension
    r1 = series([B, B], [4.0, 16.0], eps).tension
    np.testing.assert_allclose(g.row_tension, np.stack([r0, r1], axis=1), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(g.tension, (5 * r0 + 15 * r1) / 20, rtol=1e-12, atol=1e-15)


def test_identical_model_regions_in_series_behave_as_one():
    """A chain of identical hgo2m regions has the single region's uniaxial curve at every strain."""
    m = get_registry()["homogenizer"]["hgo2m"]()
    p = np.array([0.02, 0.01, 0.03, 0.05, 2.0, 0.08, 1.0])
    eps = np.linspace(0, 0.6, 7)
    res = series([(m, p), (m, p), (m, p)], [3.0, 5.0, 7.0], eps)
    _, T = m.solve_uniaxial(p, 1 + eps, "course")
    np.testing.assert_allclose(res.tension, T, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(res.stretch[:, 0, :], (1 + eps)[:, None] * np.ones(3), rtol=1e-8)


def test_mixed_model_and_response_regions():
    """A fitted model and a measured Response chain with equal tension in both."""
    m = get_registry()["homogenizer"]["hgo2m"]()
    fit = FitResult(m, [0.02, 0.01, 0.03, 0.05, 2.0, 0.08, 1.0])
    res = series([fit, linear(0.3)], [10.0, 10.0], np.linspace(0, 0.5, 6))
    lam_model = res.stretch[:, 0, 0]
    np.testing.assert_allclose(fit.solve_uniaxial(lam_model)[1], res.tension, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(0.3 * (res.stretch[:, 0, 1] - 1), res.tension, rtol=1e-8, atol=1e-12)


def test_slack_region_takes_up_strain_before_tension():
    """hgo with free sides is slack up to 1/cos θ: a chain carries no tension until that slack is used."""
    m = get_registry()["homogenizer"]["hgo"]()
    p = np.array([0.1, 2.0, math.radians(45)])
    slack = 10.0 * (math.sqrt(2) - 1)  # mm of the 10 mm hgo region
    eps = np.array([0.0, 0.5 * slack / 20, 0.9 * slack / 20, 1.5 * slack / 20, 0.5])
    res = series([(m, p), linear(1.0)], [10.0, 10.0], eps)
    assert np.all(res.tension[:3] == 0) and np.all(res.tension[3:] > 0)
    np.testing.assert_allclose(
        res.stretch[1:3, 0, 0], 1 + eps[1:3] * 20 / 10, rtol=1e-8
    )  # all strain in the slack region
    u = (res.stretch[:, 0, :] - 1) @ np.array([10.0, 10.0])
    np.testing.assert_allclose(u, eps * 20, rtol=1e-9, atol=1e-12)


def test_response_curve_is_made_monotone():
    """Noisy measured points become a non-decreasing curve starting at (1, 0) that inverts exactly."""
    lam = np.array([1.02, 1.05, 1.1, 1.15, 1.2])
    T = np.array([0.01, 0.03, 0.025, 0.06, 0.1])
    c = ResponseCurve.from_response(Response(lam, np.ones(5), T, np.zeros(5), load="uniaxial-course"))
    assert c.lam[0] == 1.0 and c.T[0] == 0.0 and np.all(np.diff(c.T) >= 0)
    x = np.array([1.01, 1.12, 1.18])
    np.testing.assert_allclose(c.stretch(c.tension(x)), x, rtol=1e-12)
    assert c.tension(np.array([1.3]))[0] == pytest.approx(0.18)  # last segment (slope 0.8) extended


def test_model_curve_inverts_its_tension():
    """ModelCurve.stretch inverts ModelCurve.tension for free and fixed lateral sides."""
    m = get_registry()["homogenizer"]["hgo2m"]()
    for lateral in ("free", "fixed"):
        c = ModelCurve(m, m.x0(), 1, lateral)
        lam = np.linspace(1.01, 1.8, 9)
        np.testing.assert_allclose(c.stretch(c.tension(lam)), lam, rtol=1e-9)


@pytest.mark.parametrize(
    "bad, match",
    [
        (dict(lengths=[[10.0, 10.0], [5.0, 5.0]]), "same length"),
        (dict(strain=np.array([-0.1, 0.2])), ">= 0"),
        (dict(widths=[1.0, -1.0]), "widths"),
    ],
)
def test_grid_input_errors(bad, match):
    """Rows of unequal length, compressive strain and non-positive widths are refused with a clear message."""
    args = dict(
        regions=[[linear(1.0), linear(2.0)], [linear(1.0), linear(1.0)]],
        widths=[1.0, 1.0],
        lengths=[[10.0, 10.0], [8.0, 12.0]],
        strain=np.array([0.0, 0.1]),
    )
    args.update(bad)
    with pytest.raises(ValueError, match=match):
        grid(**args)


def test_patchwork_stage_after_fit(tmp_path, singal_file):
    """A config with [data], [fit] and a series [patchwork] writes the chain's tension and interface
    displacement."""
    cfg = {
        "data": {
            "files": [
                str(singal_file("cotton-stockinette-x.csv")),
                str(singal_file("cotton-stockinette-y.csv")),
            ]
        },
        "fit": {"model": "hgo2m", "fitter": {"kind": "lbfgs", "starts": 2, "screen": 16}},
        "patchwork": {
            "mode": "series",
            "max_strain": 0.3,
            "steps": 6,
            "regions": [
                {"name": "fitted", "source": "fit", "length": 20.0},
                {"name": "measured", "source": "response:cotton-stockinette-x", "length": 10.0},
            ],
        },
    }
    res = run(cfg, tmp_path / "out")
    rows = list(csv.DictReader(open(tmp_path / "out" / "patchwork.csv")))
    assert len(rows) == 7 and "row0_interface0_displacement_mm" in rows[0]
    assert float(rows[-1]["tension_N_per_mm"]) > 0
    assert (tmp_path / "out" / "patchwork.png").exists()
    assert res.responses[-1].label == "patchwork (series)"


def test_patchwork_stage_config_errors(tmp_path):
    """Unknown region sources and grid layouts naming missing regions fail before any work, at their TOML
    path."""
    from knitframe.errors import ConfigError

    with pytest.raises(ConfigError, match=r"patchwork.regions\[0\].source"):
        run({"patchwork": {"regions": [{"name": "a", "source": "bogus"}]}}, None)
    with pytest.raises(ConfigError, match=r"patchwork.layout\[0\]"):
        run(
            {
                "patchwork": {
                    "mode": "grid",
                    "layout": [["a", "b"]],
                    "row_widths": [1.0],
                    "regions": [{"name": "a", "source": "file:p.json"}],
                }
            },
            None,
        )
