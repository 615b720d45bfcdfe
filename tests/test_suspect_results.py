"""Suspect results say so: a fit at a bound, non-finite numbers, and the paper's model with a free side."""

from __future__ import annotations

import json
import math
import warnings

import attrs
import numpy as np
import pytest

from knitframe import run
from knitframe.errors import ConfigError, KnitframeWarning, NumericalError
from knitframe.fitting import FitProblem, FitResult, at_bound, finish, plot_fit, write_fit_outputs
from knitframe.patchwork import ResponseCurve, series
from knitframe.plugins import get_registry
from knitframe.records import LoadPath, Response, Scene
from knitframe.schema import build


def model(name, **kw):
    return get_registry()["homogenizer"][name](**kw)


def linear_test_file(tmp_path):
    """A generic course and wale test whose tension softens: hgo can only follow it with b at its lower
    bound."""
    rows = ["direction,strain,transverse_strain,tension_N_per_mm"]
    for d, k in (("course", 0.2), ("wale", 0.5)):
        rows += [
            f"{d},{0.03 * i:.3f},{-0.009 * i:.4f},{k * 0.03 * i * (1 - 0.03 * i):.5f}" for i in range(11)
        ]
    p = tmp_path / "soft.csv"
    p.write_text("\n".join(rows) + "\n")
    return p


def strict(path):
    """A JSON file parsed with NaN and Infinity refused."""

    def refuse(name):
        raise AssertionError(f"{path.name} holds {name}")

    return json.loads(path.read_text(), parse_constant=refuse)


def test_fit_at_a_bound_is_printed_recorded_and_plotted(cli, tmp_path):
    """`knitframe fit` on data that push b to its lower bound prints one warning and records it in params.json
    and fit.png."""
    from PIL import Image

    out = tmp_path / "out"
    proc = cli("fit", str(linear_test_file(tmp_path)), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("knitframe: warning: hgo fit: b = 0.0001"), lines
    assert "lower bound" in lines[0]
    params = strict(out / "params.json")
    assert params["at_bound"] == ["b"] and params["b"] == pytest.approx(1e-4)
    assert len(params["warnings"]) == 1 and params["warnings"][0] in lines[0]
    assert "b = 0.0001" in Image.open(out / "fit.png").info["Description"]


def test_fit_inside_the_box_has_no_bound_warning(singal_file, recwarn):
    """A fit of real jersey tests ends inside the box: at_bound and warnings stay empty and nothing is
    warned."""
    reader = get_registry()["reader"]["singal2024"]()
    data = [
        r
        for f in ("cotton-stockinette-x.csv", "cotton-stockinette-y.csv")
        for r in reader.read(singal_file(f))
    ]
    res = get_registry()["fitter"]["lbfgs"](starts=2, screen=16).fit(model("hgo"), data)
    assert res.at_bound == () and res.warnings == ()
    assert not [w for w in recwarn if issubclass(w.category, KnitframeWarning)]
    assert res.to_json()["at_bound"] == [] and res.to_json()["warnings"] == []


def test_at_bound_names_both_ends_but_not_symmetry_planes():
    """at_bound lists parameters at either end of the box in params.json names, but not hgo's θ
    at 0 or 90°."""
    m = model("hgo")
    names, msg = at_bound(m, np.array([100.0, 1e-4, math.radians(90)]))
    assert (
        names == ("a", "b") and "a = 100 (its upper bound is 100)" in msg and "b = 0.0001 (its lower" in msg
    )
    assert "\n" not in msg
    assert at_bound(m, np.array([0.1, 2.0, 0.0])) == ((), "")
    m2 = model("hgo2m")
    names, _ = at_bound(m2, np.array([0.02, 0.02, 1e-6, 0.05, 1.0, 0.05, 1e3]))
    assert names == ("K", "b2")


def test_fit_png_shows_the_warnings(tmp_path):
    """fit.png of a result with warnings carries them in red and in its metadata; without them it has no red
    text."""
    from PIL import Image

    m = model("hgo")
    lam = np.linspace(1, 1.3, 12)
    r = Response(lam, 1 - 0.2 * (lam - 1), 0.2 * (lam - 1), 0 * lam, load="uniaxial-course")
    flagged = FitResult(
        m,
        [0.05, 1e-4, 0.3],
        {"course": 0.1, "overall": 0.1},
        fitter="lbfgs",
        at_bound=("b",),
        warnings=("hgo fit: b = 0.0001 (its lower bound is 0.0001)",),
    )
    plot_fit(tmp_path / "flagged.png", flagged, [r])
    plot_fit(tmp_path / "clean.png", attrs.evolve(flagged, at_bound=(), warnings=()), [r])

    def red(path):
        px = np.asarray(Image.open(path).convert("RGB")).astype(int)
        return int(np.sum((px[..., 0] > 200) & (px[..., 1] < 60) & (px[..., 2] < 60)))

    assert red(tmp_path / "flagged.png") > 200 and red(tmp_path / "clean.png") == 0
    assert "b = 0.0001" in Image.open(tmp_path / "flagged.png").info["Description"]
    assert Image.open(tmp_path / "clean.png").info["Description"] == "no warnings"


def test_non_finite_metrics_are_written_as_null_with_a_flag(tmp_path):
    """A result holding NaN and Infinity is written as strict JSON: null values, their keys in non_finite, and
    a warning."""
    m = model("hgo")
    lam = np.linspace(1, 1.3, 5)
    r = Response(lam, lam, 0.2 * (lam - 1), 0.1 * (lam - 1), load="equibiaxial")
    res = FitResult(
        m,
        [0.05, 2.0, 0.3],
        {"course": float("nan"), "overall": float("inf")},
        fitter="lbfgs",
        objective=float("nan"),
        diagnostics={"worst": [1.0, float("-inf")]},
    )
    with pytest.warns(KnitframeWarning, match="non-finite values written as null") as rec:
        write_fit_outputs(res, [r], tmp_path / "params.json", tmp_path / "fit.png")
    assert len(rec) == 1 and "\n" not in str(rec[0].message)
    data = strict(tmp_path / "params.json")
    assert data["non_finite"] == ["nrmse.course", "nrmse.overall", "objective", "diagnostics.worst[1]"]
    assert data["nrmse"] == {"course": None, "overall": None} and data["objective"] is None
    assert data["warnings"][-1].startswith("non-finite values written as null")
    assert FitResult.from_json(data).warnings == tuple(data["warnings"])


def test_non_finite_parameters_are_refused():
    """A fitter that ends at non-finite parameters gets a NumericalError, not a params.json with NaN."""
    lam = np.linspace(1, 1.2, 6)
    r = Response(lam, lam, 0.3 * (lam - 1), 0.1 * (lam - 1), load="equibiaxial")
    problem = FitProblem(model("hgo"), [r])
    with pytest.raises(NumericalError, match="non-finite parameters"):
        finish(
            problem, np.array([0.1, float("nan"), 0.3]), fitter="probe", t0=0.0, converged=True, message=""
        )


def test_reader_conversions_are_recorded_with_the_fit(tmp_path, singal_file):
    """Strains converted from percent while reading are listed in the fit's warnings (and so in
    params.json)."""
    src = singal_file("cotton-stockinette-y.csv").read_text().splitlines()
    rows = [
        ",".join(c[:2] + [f"{float(c[2]) * 100:.3f}", f"{float(c[3]) * 100:.3f}", c[4]])
        for c in (ln.split(",") for ln in src[3:])
    ]
    p = tmp_path / "pct-y.csv"
    p.write_text("\n".join(src[:3] + rows) + "\n")
    with pytest.warns(KnitframeWarning, match="reads as percent"):
        data = get_registry()["reader"]["auto"]().read(p)
    res = get_registry()["fitter"]["lbfgs"](starts=1, screen=8).fit(model("hgo2m"), data)
    assert any("pct-y.csv: column 'strain_axial'" in w for w in res.warnings)


def test_hgo_free_side_zero_curve_warns_once():
    """hgo's uniaxial curve that never passes 1/cos θ warns in one line; one that passes it does not."""
    m = model("hgo")
    p = np.array([0.1, 2.0, math.radians(45)])
    with pytest.warns(KnitframeWarning) as rec:
        _, P = m.solve_uniaxial(p, np.linspace(1, 1.3, 7), "course")
    assert np.all(np.abs(P) < 1e-12)
    msgs = [str(w.message) for w in rec if issubclass(w.category, KnitframeWarning)]
    assert len(msgs) == 1 and "\n" not in msgs[0]
    assert "zero tension at every loaded stretch up to 1.3" in msgs[0] and "1/cos(theta) = 1.414" in msgs[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", KnitframeWarning)
        _, P = m.solve_uniaxial(p, np.linspace(1, 1.6, 7), "course")
        model("hgo2m").solve_uniaxial(model("hgo2m").x0(), np.linspace(1, 1.3, 7), "wale")
    assert P[-1] > 0


def test_replayed_uniaxial_test_with_hgo_warns():
    """The reduced solver replaying a 30 % uniaxial test with hgo (θ = 45°) warns that its curve is zero."""
    s = build(
        get_registry()["solver"]["reduced"],
        {"model": "hgo", "params": {"a": 0.1, "b": 2.0, "theta_deg": 45.0}},
        "solver",
    )
    with pytest.warns(KnitframeWarning, match="'hgo' with a free side gives zero tension"):
        r = s.simulate(
            None,
            Scene(load=LoadPath("uniaxial", 0.3, 6), effects=frozenset({"large_deformation", "anisotropy"})),
        )
    assert np.all(np.abs(r.T1) < 1e-12)


def test_patchwork_region_that_stays_slack_warns():
    """A series patchwork whose hgo region never leaves its free-side slack warns, naming the region."""
    m = model("hgo")
    p = np.array([0.1, 2.0, math.radians(60)])  # slack up to stretch 2
    lam = np.linspace(1, 1.5, 6)
    stiff = ResponseCurve(lam, 0.5 * (lam - 1), "stiff")
    with pytest.warns(KnitframeWarning, match="patchwork region 'hgo': 'hgo' with a free side"):
        res = series([(m, p), stiff], [10.0, 10.0], np.linspace(0, 0.3, 4))
    assert np.all(res.tension == 0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", KnitframeWarning)
        series([(m, p), stiff], [10.0, 10.0], np.linspace(0, 0.3, 4), lateral="fixed")


def test_default_patchwork_refuses_hgo_with_a_free_side(tmp_path, singal_file):
    """[fit] with its default model and a default (free-side) [patchwork] are refused in one line before any
    work."""
    cfg = {
        "data": {"files": [str(singal_file("cotton-stockinette-x.csv"))]},
        "fit": {},
        "patchwork": {"regions": [{"name": "jersey", "source": "fit", "length": 30.0}]},
    }
    with pytest.raises(ConfigError) as e:
        run(cfg, tmp_path / "out")
    msg = str(e.value)
    assert (
        msg.startswith("patchwork.lateral: 'free' needs models that predict their free side")
        and "\n" not in msg
    )
    assert (
        "'jersey' uses 'hgo' (the [fit] default)" in msg and "fit 'hgo2m' or set lateral = \"fixed\"" in msg
    )
    assert not (tmp_path / "out").exists()


def test_patchwork_with_hgo2m_or_a_fixed_side_runs(tmp_path, singal_file):
    """hgo with a fixed lateral side, and hgo2m with a free one, give a patchwork that carries tension."""
    data = {"files": [str(singal_file("cotton-stockinette-x.csv"))]}
    fitter = {"kind": "lbfgs", "starts": 1, "screen": 8}
    for name, fit, lateral in (
        ("fixed", {"model": "hgo", "fitter": fitter}, "fixed"),
        ("free", {"model": "hgo2m", "fitter": fitter}, "free"),
    ):
        res = run(
            {
                "data": data,
                "fit": fit,
                "patchwork": {
                    "lateral": lateral,
                    "max_strain": 0.3,
                    "steps": 3,
                    "regions": [{"name": "j", "source": "fit"}],
                },
            },
            tmp_path / name,
        )
        assert res.results["patchwork"]["max_tension_N_per_mm"] > 0
