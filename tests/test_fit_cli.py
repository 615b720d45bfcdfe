"""``knitframe fit`` and the [fit] stage: params.json and fit.png from real test data."""

from __future__ import annotations

import json

import pytest

from knitframe import run


def test_fit_cli_writes_params_and_plot(cli, tmp_path, singal_file):
    """`knitframe fit X Y --model hgo --fitter lbfgs --out DIR` writes every parameter, theta_deg and
    nrmse."""
    out = tmp_path / "fit"
    r = cli(
        "fit",
        str(singal_file("cotton-stockinette-x.csv")),
        str(singal_file("cotton-stockinette-y.csv")),
        "--model",
        "hgo",
        "--fitter",
        "lbfgs",
        "--out",
        str(out),
    )
    assert r.returncode == 0, r.stderr
    data = json.loads((out / "params.json").read_text())
    assert {"a", "b", "theta_deg", "nrmse"} <= set(data) and 0 < data["theta_deg"] < 90
    assert set(data["nrmse"]) == {"course", "wale", "overall"} and data["nrmse"]["overall"] < 0.05
    assert data["fitter"] == "lbfgs" and data["n_evals"] > 0 and data["wall_time_s"] > 0
    assert (out / "fit.png").stat().st_size > 10_000
    assert "NRMSE" in r.stdout


def test_fit_cli_mads_and_generic_reader(cli, tmp_path):
    """The mads fitter and the generic reader work through the CLI; hgo2m also reports transverse NRMSE."""
    rows = ["sample,direction,strain,transverse_strain,tension_N_per_mm"]
    for d, k, nu in (("course", 0.2, 0.4), ("wale", 0.8, 0.3)):
        for i in range(11):
            e = 0.04 * i
            rows.append(f"1,{d},{e},{-nu * e / (1 + e):.6f},{k * e + 2 * k * e**3:.6f}")
    data = tmp_path / "test.csv"
    data.write_text("\n".join(rows) + "\n")
    r = cli(
        "fit",
        str(data),
        "--model",
        "hgo",
        "--fitter",
        "mads",
        "--reader",
        "generic",
        "--out",
        str(tmp_path / "m"),
    )
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "m" / "params.json").read_text())["fitter"] == "mads"
    r = cli("fit", str(data), "--model", "hgo2m", "--reader", "generic", "--out", str(tmp_path / "l"))
    assert r.returncode == 0, r.stderr
    params = json.loads((tmp_path / "l" / "params.json").read_text())
    assert {"mu1", "mu2", "K", "a1", "b1", "a2", "b2"} <= set(params)
    assert set(params["nrmse_transverse"]) == {"course", "wale", "overall"}


def test_fit_cli_bad_data_is_one_line(cli, tmp_path):
    """A malformed data file stops the command with one line naming the file, line and column."""
    bad = tmp_path / "bad-x.csv"
    bad.write_text(
        "# source\n# uniaxial\n"
        "video,frame,strain_axial,strain_transverse,tension_N_per_mm\nv1,1,0.1,nan,0.2\n"
    )
    r = cli("fit", str(bad), "--out", str(tmp_path / "o"))
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "bad-x.csv, line 4, column 'strain_transverse'" in r.stderr
    assert not (tmp_path / "o").exists()


def test_fit_cli_unknown_model(cli, tmp_path, singal_file):
    """An unknown model name lists the available ones."""
    r = cli(
        "fit", str(singal_file("cotton-stockinette-x.csv")), "--model", "nope", "--out", str(tmp_path / "o")
    )
    assert r.returncode == 2 and "available: hgo, hgo2m" in r.stderr


def test_example_pipeline_ends_with_a_fit(example_run):
    """The built-in example imports the cotton jersey tests and ends with a fitted model and its plot."""
    res, out = example_run
    assert (out / "params.json").exists() and (out / "fit.png").exists()
    assert len(res.models) == 1 and res.results["fit"]["nrmse"]["overall"] < 0.05
    assert res.summary["plugins"]["homogenizer:hgo"]["package"] == "knitframe"


def test_fit_stage_config_errors(tmp_path, singal_file):
    """Bad [fit] tables fail before any work, naming the TOML path."""
    from knitframe.errors import ConfigError

    data = {"files": [str(singal_file("cotton-stockinette-x.csv"))]}
    with pytest.raises(ConfigError, match="fit.model.*unknown homogenizer 'hog'"):
        run({"data": data, "fit": {"model": "hog"}}, None)
    with pytest.raises(ConfigError, match="fit.fitter.max_evals"):
        run({"data": data, "fit": {"fitter": {"kind": "mads", "max_evals": -1}}}, None)
    with pytest.raises(ConfigError, match="nothing to fit"):
        run({"fit": {}}, None)
    with pytest.raises(ConfigError, match="fit.labels"):
        run({"data": data, "fit": {"labels": ["missing"]}}, tmp_path / "o")
