"""Sweep points that carry measured tests: simulated as the tests were made and compared with them."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

import knitframe
from knitframe.cli import main
from knitframe.examples import EXAMPLE_DIR
from knitframe.records import Provenance, Response
from knitframe.report import curve, validate_uniaxial

JERSEY = ["cotton-stockinette-x.csv", "cotton-stockinette-y.csv"]


def sweep_config(folder: Path, points: str) -> Path:
    """A rod sweep config in ``folder`` with the given ``points = [...]`` line(s); data paths are absolute."""
    text = f"""[sweep]
name = "val"
{points}

[sweep.fabric]
arc_length = 11.28

[sweep.solver]
kind = "rod"
segments_per_stitch = 10

[sweep.scene]
effects = ["large_deformation", "bending", "contact", "prestress"]
load = {{ kind = "uniaxial", steps = 2 }}

[sweep.fit]
model = "hgo2m"

[executor]
kind = "local"
cache_dir = "cache"
"""
    path = folder / "val.toml"
    path.write_text(text, encoding="utf-8")
    return path


def measured(files, **extra) -> str:
    items = ", ".join(f'"{Path(f).as_posix()}"' for f in files)
    more = "".join(f", {k} = {v!r}" for k, v in extra.items())
    return f'measured = {{ files = [{items}], reader = "singal2024"{more} }}'


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


# ------------------------------------------------------------------------------------ the metrics
def uniaxial(load: str, strain, lateral, tension) -> Response:
    from knitframe.curves import uniaxial_response

    strain, lateral, tension = (np.asarray(x, dtype=float) for x in (strain, lateral, tension))
    return uniaxial_response(
        load, strain, lateral, tension, None, None, 1, load, Provenance(kind="experiment")
    )


def test_validate_uniaxial_on_curves_with_known_answers():
    """Twice the measured tension gives ratio 2 and NRMSE rms(e/2)/max T; the lateral strains are read at 20
    %."""
    e = np.linspace(0.0, 0.4, 41)
    mea = uniaxial("uniaxial-wale", e, -0.3 * e, 0.5 * e)
    s = e[5::5]  # 5 % to 40 %: the simulated path starts from the relaxed cell, zero tension at zero strain
    sim = uniaxial("uniaxial-wale", s, -0.5 * s, s)
    m = validate_uniaxial(sim, mea)
    assert (m["ratio_10"], m["ratio_20"], m["ratio_30"]) == (
        pytest.approx(2.0),
        pytest.approx(2.0),
        pytest.approx(2.0),
    )
    assert m["nrmse"] == pytest.approx(
        0.5 * math.sqrt(np.mean(e**2)) / 0.2
    )  # |T_sim - T_meas| = e/2, max T_meas = 0.2
    assert (m["lateral_at"], m["simulated_to"], m["measured_to"]) == (
        pytest.approx(0.2),
        pytest.approx(0.4),
        pytest.approx(0.4),
    )
    assert m["lateral_simulated"] == pytest.approx(-0.1) and m["lateral_measured"] == pytest.approx(-0.06)
    short = uniaxial("uniaxial-wale", e[:13], -0.3 * e[:13], 0.5 * e[:13])  # the test ends at 12 %
    m = validate_uniaxial(sim, short)
    assert m["ratio_20"] is None and m["lateral_at"] == pytest.approx(0.12)
    with pytest.raises(ValueError):
        validate_uniaxial(uniaxial("uniaxial-course", e, -0.3 * e, e), mea)
    assert m["suspect"] is None


def test_a_pulled_fabric_that_pushes_back_is_suspect():
    """A simulated tension below zero at a positive strain marks the curve suspect, with where; not noise."""
    e = np.linspace(0.0, 0.4, 41)
    mea = uniaxial("uniaxial-course", e, -0.3 * e, 0.5 * e)
    s = e[5::5]
    pushes = uniaxial("uniaxial-course", s, -0.3 * s, s * (s - 0.15))  # negative up to 15 %
    m = validate_uniaxial(pushes, mea)
    assert m["suspect"] == "negative tension -0.005 N/mm at 5 % strain while pulled"
    noise = uniaxial("uniaxial-course", s, -0.3 * s, s - 0.05 - 1e-6)  # -1e-6 at 5 %, largest 0.35
    assert validate_uniaxial(noise, mea)["suspect"] is None


# ------------------------------------------------------------------------------------ a short run
def test_two_measured_curves_and_a_failed_point_give_the_columns_and_the_figure(tmp_path, singal_file):
    """Cotton jersey, course and wale to 12 %: the per-curve columns, validation.csv/.png and the Python
    result agree; a point that fails is recorded in every output and the other finishes."""
    files = [singal_file(f) for f in JERSEY]
    points = (
        f'points = [\n  {{ name = "jersey", pattern = "jersey", yarn = "pearl-cotton", '
        f"{measured(files, max_strain=0.12)} }},\n"
        f'  {{ name = "starved", pattern = "jersey", yarn = "pearl-cotton", '
        f"solver = {{ max_iterations = 2 }}, "
        f"{measured(files[:1], max_strain=0.12)} }},\n]"
    )
    cfg = sweep_config(tmp_path, points)
    with pytest.warns(knitframe.errors.KnitframeWarning, match="starved"):
        res = knitframe.run(cfg, tmp_path / "out", quiet=True)
    out = tmp_path / "out"
    rows = read_rows(out / "sweep.csv")
    assert [r["status"] for r in rows] == ["done", "failed"]
    good, bad = rows
    assert good["load"] == "uniaxial-course+uniaxial-wale" and good["max_strain"] == "0.12/0.12"
    for d in ("course", "wale"):
        assert good[f"measured_status_{d}"] == "done" and good[f"measured_{d}"].endswith(
            f"-{'x' if d == 'course' else 'y'}.csv"
        )
        assert float(good[f"simulated_to_{d}"]) == pytest.approx(0.12)
        assert 0.0 < float(good[f"nrmse_measured_{d}"]) < 10.0
        assert 0.0 < float(good[f"ratio_10_{d}"]) < 100.0
        assert good[f"ratio_20_{d}"] == "" and good[f"ratio_30_{d}"] == ""  # the path stops at 12 %
        assert float(good[f"lateral_at_{d}"]) == pytest.approx(0.12)
        assert float(good[f"lateral_simulated_{d}"]) < 0.0 and float(good[f"lateral_measured_{d}"]) < 0.0
    assert bad["measured_status_course"] == "failed" and bad["measured_status_wale"] == ""
    assert bad["reason"] and bad["ratio_10_course"] == ""
    curves = read_rows(out / "validation.csv")
    assert [(c["name"], c["direction"], c["measured_status"]) for c in curves] == [
        ("jersey", "course", "done"),
        ("jersey", "wale", "done"),
        ("starved", "course", "failed"),
    ]
    assert curves[2]["reason"] == bad["reason"]
    in_python = res.results["sweep"]["validation"]
    assert [c["ratio_10"] for c in in_python[:2]] == [
        float(good["ratio_10_course"]),
        float(good["ratio_10_wale"]),
    ]
    assert "2 of 3 measured tests simulated" in res.results["sweep"]["headline"]
    assert (out / "validation.png").read_bytes()[:4] == b"\x89PNG"
    # the measured tension at 10 % is the test's own, and the goals are judged on these curves
    reader = knitframe.get_registry()["reader"]["singal2024"]()
    ((_, e, t, _),) = curve(reader.read(files[0])[0])
    order = e.argsort()
    assert float(curves[0]["measured_10"]) == pytest.approx(float(np.interp(0.1, e[order], t[order])))
    goals = res.results["sweep"]["goals"]
    assert set(goals) == {"median_ratio", "every_curve", "pattern_order", "lateral"}
    assert goals["pattern_order"] == "undetermined"  # one pattern: nothing to order
    md = (out / "goals.md").read_text()
    assert "- pearl-cotton jersey course: not simulated (" in md  # the starved point, in the notes
    # what was held fixed, and the one thing a point set for itself
    fixed = md.split("## What was held fixed")[1]
    assert fixed.lstrip().startswith("Nothing in this run was fitted to the measured tests")
    assert "- the same yarn record for every point of a yarn: `pearl-cotton`" in fixed
    assert "- set per point:\n  - starved: solver = { max_iterations = 2 }" in fixed
    assert f"goals met: {sum(v == 'met' for v in goals.values())} of 4" in res.results["sweep"]["headline"]


def test_a_failed_load_keeps_the_other_curve_and_is_not_cached(tmp_path, singal_file, monkeypatch):
    """The wale test fails (the solver raises for it): the course curve is still compared and fitted, the
    wale curve is recorded as failed with its reason, and the partial result is not kept in the cache."""
    from knitframe_solvers.rod import RodSolver

    from knitframe.errors import NumericalError

    real = RodSolver.simulate

    def wale_fails(self, fabric, scene, **kwargs):
        if scene.load.direction == "wale":
            raise NumericalError("no convergence (made to fail for this test)")
        return real(self, fabric, scene, **kwargs)

    monkeypatch.setattr(RodSolver, "simulate", wale_fails)  # the local executor runs in this process
    files = [singal_file(f) for f in JERSEY]
    cfg = sweep_config(
        tmp_path,
        f'points = [{{ pattern = "jersey", yarn = "pearl-cotton", {measured(files, max_strain=0.12)} }}]',
    )
    res = knitframe.run(cfg, tmp_path / "out", quiet=True)
    (row,) = read_rows(tmp_path / "out" / "sweep.csv")
    assert (
        row["status"] == "done"
        and row["measured_status_course"] == "done"
        and float(row["ratio_10_course"]) > 0
    )
    assert row["measured_status_wale"] == "failed" and row["ratio_10_wale"] == ""
    assert (
        row["reason"] == "uniaxial-wale failed: NumericalError: no convergence (made to fail for this test)"
    )
    assert row["load"] == "uniaxial-course+uniaxial-wale" and row["nrmse"] != ""  # fitted to the course curve
    wale = [c for c in res.results["sweep"]["validation"] if c["direction"] == "wale"]
    assert wale[0]["reason"] == "NumericalError: no convergence (made to fail for this test)"
    assert not list((tmp_path / "cache").glob("*.pkl"))  # tried again next run, as a failed point is


def test_params_png_leaves_out_a_done_point_without_a_fit(tmp_path):
    """A measured-test point whose fit failed is done but has no parameters: params.png draws the others."""
    from knitframe.sweep import plot_params

    model = knitframe.get_registry()["homogenizer"]["hgo"]()
    base = {
        "status": "done",
        "stitch_length": "",
        "arc_length_mm": 11.28,
        "pattern": "jersey",
        "yarn": "acrylic",
        "load": "uniaxial-course",
        "max_strain": "0.3",
        "steps": "6",
        "effects": "bending",
        "solver": "rod",
        "solver_options": "{}",
        "at_bound": "",
    }
    rows = [
        {**base, "a": 0.5, "b": 1.0, "theta_deg": 40.0},
        {**base, "arc_length_mm": 12.0, "a": 0.4, "b": 2.0, "theta_deg": 45.0},
        {**base, "arc_length_mm": 13.0, "a": "", "b": "", "theta_deg": ""},
    ]
    plot_params(tmp_path / "params.png", rows, model)
    assert (tmp_path / "params.png").read_bytes()[:4] == b"\x89PNG"


# ------------------------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "case, field",
    [
        ("missing", "sweep.points[0].measured.files[1]"),
        ("max_strain", "sweep.points[0].measured.max_strain"),
        ("both", "sweep.points[0].load"),
        ("twice", "sweep.points[0].measured"),
        ("key", "sweep.points[0].measured.file"),
        ("not a table", "sweep.points[0].measured"),
    ],
)
def test_bad_measured_tests_are_one_line_exit_2_and_no_output(tmp_path, singal_file, capsys, case, field):
    """A bad measured table is refused before any work: one line naming the field, exit code 2, nothing
    written."""
    x, y = (singal_file(f) for f in JERSEY)
    value = {
        "missing": measured([x, tmp_path / "nope.csv"]),
        "max_strain": measured([x], max_strain=-0.1),
        "both": 'load = { kind = "uniaxial" }, ' + measured([x]),
        "twice": measured([x, x]),
        "key": f'measured = {{ file = ["{x.as_posix()}"] }}',
        "not a table": f'measured = "{x.as_posix()}"',
    }[case]
    cfg = sweep_config(tmp_path, f'points = [{{ pattern = "jersey", yarn = "pearl-cotton", {value} }}]')
    before = sorted(tmp_path.rglob("*"))
    code = main(["run", str(cfg), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("knitframe: error: ") and f"{field}:" in lines[0], lines[0]
    assert sorted(tmp_path.rglob("*")) == before  # no output folder, no cache


@pytest.mark.parametrize(
    "goals, message",
    [
        ("median_within = 0.5", "sweep.goals.median_within: must be in (1.0, 100.0], got 0.5"),
        ("lateral_within = -0.1", "sweep.goals.lateral_within: must be in (0.0, 1.0], got -0.1"),
        ("order_at = 0.1", "sweep.goals.order_at"),
    ],
)
def test_bad_goal_thresholds_are_one_line_exit_2(tmp_path, singal_file, capsys, goals, message):
    x, _ = (singal_file(f) for f in JERSEY)
    point = f'{{ pattern = "jersey", yarn = "pearl-cotton", {measured([x])} }}'
    cfg = sweep_config(tmp_path, f"points = [{point}]")
    cfg.write_text(cfg.read_text() + f"\n[sweep.goals]\n{goals}\n")
    before = sorted(tmp_path.rglob("*"))
    code = main(["run", str(cfg), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and message in err, err
    assert sorted(tmp_path.rglob("*")) == before


# ------------------------------------------------------------------------------------ the example
@pytest.mark.slow
def test_the_16_singal_curves_with_the_rod_solver(tmp_path):
    """The shipped example: 8 fabrics x course and wale, every curve in validation.csv and the figure."""
    res = knitframe.run(EXAMPLE_DIR / "singal-validation.toml", tmp_path / "out", quiet=True, no_cache=True)
    curves = read_rows(tmp_path / "out" / "validation.csv")
    assert len(curves) == 16
    assert {(c["yarn"], c["pattern"], c["direction"]) for c in curves} == {
        (y, p, d)
        for y in ("pearl-cotton", "acrylic")
        for p in ("jersey", "garter", "rib", "seed")
        for d in ("course", "wale")
    }
    for c in curves:
        assert c["measured_status"] == "failed" or float(c["ratio_10"]) > 0.0, c
    assert res.results["sweep"]["points"] == 8
    assert (tmp_path / "out" / "validation.png").read_bytes()[:4] == b"\x89PNG"
    goals = res.results["sweep"]["goals"]
    assert set(goals) == {"median_ratio", "every_curve", "pattern_order", "lateral"}
    assert "undetermined" not in goals.values()  # 16 curves, 4 patterns per yarn: every goal is judged
    assert (tmp_path / "out" / "goals.md").read_text().startswith("# Validation goals: sweep singal2024-rod")


def test_what_was_held_fixed_names_the_shared_settings_and_every_per_point_choice():
    """The shared tables, the yarn records (a config's own marked) and whatever a point or the grid sets."""
    from knitframe.sweep.goals import held_fixed

    lines = held_fixed(
        common={"sweep.solver": {"kind": "rod", "starts": 5}, "sweep.fabric": {}},
        points=[
            {"name": "a", "pattern": "rib", "yarn": "x", "measured": {}},
            {"pattern": "seed", "arc_length": 12.0},
        ],
        grid={"pattern": ["rib"], "stitch_length": [10, 11]},
        yarns=["x", "acrylic"],
        own_yarns=["x"],
    )
    text = "\n".join(lines)
    assert (
        '- the same for every point, `[sweep.solver]`: kind = "rod", starts = 5; the defaults otherwise'
        in text
    )
    assert "- the same for every point, `[sweep.fabric]`: nothing set; the defaults otherwise" in text
    assert "`x` (this config's `[yarns]` table), `acrylic` (" in text
    assert "  - point 1: arc_length = 12.0" in text and "  - a:" not in text
    assert "  - varied over the grid: `stitch_length`" in text
    quiet = held_fixed(common={}, points=[{"name": "a", "pattern": "rib", "yarn": "x"}])
    assert quiet[-1] == "- set per point: nothing but its pattern, its yarn and its measured tests"
