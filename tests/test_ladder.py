"""The accuracy ladder: ``knitframe ladder``, the ``[ladder]`` stage and ``knitframe.ladder``."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

import knitframe
from knitframe.cli import main
from knitframe.curves import nrmse_between
from knitframe.ladder import RUNGS, CostModel, read_timings, shipped_timings_path, tension_errors
from knitframe.records import Response

DATA = Path(knitframe.__file__).parent / "examples" / "data"

#: a short path, so that the rod rungs take seconds
SHORT = {"kind": "uniaxial", "direction": "course", "max_strain": 0.2, "steps": 2}
FAST_ROD = {"rod": {"prestress_steps": 4}}


def singal_config(tmp_path: Path, **ladder) -> dict:
    """The example's fabric and data (Singal cotton stockinette, pulled along the course, free sides)."""
    return {
        "data": {
            "reader": "singal2024",
            "files": [str(DATA / "cotton-stockinette-x.csv"), str(DATA / "cotton-stockinette-y.csv")],
        },
        "fabric": {"pattern": "jersey", "arc_length": 11.28, "yarn": "pearl-cotton"},
        "scene": {"effects": ["large_deformation", "bending", "contact", "prestress"], "load": SHORT},
        "ladder": {"cache_dir": str(tmp_path / "cache"), "solver_options": FAST_ROD, **ladder},
    }


def read_csv(path: Path) -> dict[str, dict[str, str]]:
    with open(path, encoding="utf-8") as fh:
        return {r["rung"]: r for r in csv.DictReader(fh)}


def write_toml(path: Path, config: dict) -> Path:
    import tomli_w

    path.write_text(tomli_w.dumps(config), encoding="utf-8")
    return path


def test_ladder_writes_every_output_with_the_measured_data(tmp_path):
    """A small ladder writes the CSV, table, Pareto plot and curves, with errors against the best rung and the
    measurement."""
    result = knitframe.ladder(
        singal_config(tmp_path), out=tmp_path / "out", rungs=["reduced", "rod:8", "rod:16"]
    )
    out = tmp_path / "out"
    for name in ("ladder.csv", "ladder.md", "ladder.png", "curves.png", "ladder-curves.csv"):
        assert (out / name).stat().st_size > 500, name
    rows = read_csv(out / "ladder.csv")
    assert list(rows) == ["reduced", "rod:8", "rod:16"]
    assert rows["rod:16"]["reference"] == "true" and result.reference == "rod:16"
    for row in rows.values():
        assert row["status"] == "ok", row
        assert float(row["wall_time_s"]) > 0 and float(row["peak_rss_mb"]) > 20
        assert float(row["nrmse_vs_measured"]) > 0  # every rung is compared with the measured curve
        assert row["nrmse_wale_vs_best"] == ""  # the free side carries no tension: not compared
    assert float(rows["rod:16"]["nrmse_vs_best"]) == 0.0
    assert float(rows["rod:8"]["nrmse_vs_best"]) > 0
    # the reduced rung is hgo2m (a free side) fitted to the best rung, and reproduces it closely
    assert json.loads(rows["reduced"]["options"])["model"] == "hgo2m"
    assert float(rows["reduced"]["nrmse_vs_best"]) < 0.05
    # the measured curve of the other load (wale) is not compared; the table names the one that is
    assert result.measured[0].label == "cotton-stockinette-x" and len(result.measured) == 1
    table = (out / "ladder.md").read_text()
    assert "cotton-stockinette-x" in table and "NRMSE vs measured" in table
    assert table.count("\n| ") == 4  # header and three rungs
    # the measured points beyond the simulated path (20 %) are left out of the comparison
    assert result.measured[0].lambda1.max() <= 1.2 + 1e-9
    summary = json.loads((out / "summary.json").read_text())
    assert "ladder.csv" in summary["outputs"] and summary["results"]["ladder"]["reference"] == "rod:16"


def test_a_rungs_peak_memory_is_its_own_not_its_parents(tmp_path):
    """A rung started from a process holding 600 MB reports its own peak memory, far below that."""
    ballast = np.ones(75_000_000)  # 600 MB in this process while the rung runs
    result = knitframe.ladder(singal_config(tmp_path, cache=False), rungs=["rod:8"])
    assert ballast[-1] == 1.0
    assert 20 < result.row("rod:8")["peak_rss_mb"] < 400


def test_tension_errors_are_nrmse_between_with_both_sides_loaded_and_the_loaded_side_otherwise():
    """With both directions loaded the overall error is nrmse_between; under a uniaxial load it is the loaded
    direction's."""
    lam = np.linspace(1.05, 1.3, 6)
    ref = Response(lam, lam, 2 * (lam - 1), 3 * (lam - 1), load="equibiaxial")
    r = Response(lam, lam, 2.2 * (lam - 1), 2.7 * (lam - 1), load="equibiaxial")
    e = tension_errors(ref, r)
    assert e["overall"] == pytest.approx(nrmse_between(ref, r))
    assert e["course"] == pytest.approx(np.sqrt(np.mean((0.2 * (lam - 1)) ** 2)) / (3 * 0.3))
    zero = np.zeros_like(lam)
    uref = Response(lam, 1 - 0.3 * (lam - 1), 2 * (lam - 1), zero, load="uniaxial-course")
    ur = Response(lam, 1 - 0.5 * (lam - 1), 2.2 * (lam - 1), zero, load="uniaxial-course")
    u = tension_errors(uref, ur)
    assert u["wale"] is None and u["overall"] == pytest.approx(u["course"]) and u["course"] > 0


def test_cost_estimate_of_a_second_fabric_comes_from_the_first_fabrics_timings(tmp_path):
    """Rod rungs of jersey SL11 cotton fit the cost model, t = c·DOFs^p per increment; its estimate of
    a rod rung of garter SL12 is that power law at the garter rung's size (how close the estimate
    comes to the measured time is a benchmark, docs/ladder.md, not a timed assertion)."""
    import math

    from knitframe.ladder.cost import EXPONENT_RANGE

    scene = {
        "effects": ["large_deformation", "bending", "contact", "prestress"],
        "load": {"kind": "equibiaxial", "max_strain": 0.2, "steps": 2},
    }
    first = {
        "fabric": {"pattern": "jersey", "stitch_length": 11, "yarn": "cotton"},
        "scene": scene,
        "ladder": {"cache": False, "shipped_timings": False, "solver_options": FAST_ROD},
    }
    knitframe.ladder(first, out=tmp_path / "jersey", rungs=["rod:8", "rod:16"])
    timings = read_timings(tmp_path / "jersey" / "ladder.csv")
    assert sorted(p.rung for p in timings) == ["rod:16", "rod:8"]
    second = {
        "fabric": {"pattern": "garter", "stitch_length": 12, "yarn": "cotton"},
        "scene": scene,
        "ladder": {
            "cache": False,
            "shipped_timings": False,
            "solver_options": FAST_ROD,
            "timings": [str(tmp_path / "jersey" / "ladder.csv")],
        },
    }
    result = knitframe.ladder(second, out=tmp_path / "garter", rungs=["rod:16"])
    row = result.row("rod:16")
    assert row["status"] == "ok" and "from the timings files" in row["estimate_basis"]
    (x8, y8), (x16, y16) = sorted((t.dofs, t.wall_time_s / t.increments) for t in timings)
    p = min(max(math.log(y16 / y8) / math.log(x16 / x8), EXPONENT_RANGE[0]), EXPONENT_RANGE[1])
    c = math.exp((math.log(y8) + math.log(y16) - p * (math.log(x8) + math.log(x16))) / 2)
    expected = c * row["dofs"] ** p * row["increments"]
    assert row["estimated_time_s"] == pytest.approx(expected, rel=1e-6)
    assert row["wall_time_s"] > 0


def test_cost_model_takes_the_scale_from_this_run_and_the_slope_from_the_shipped_timings():
    """One rung of this run sets the scale; the shipped timings' two sizes set the exponent."""
    from knitframe.ladder import TimingPoint

    shipped = [
        TimingPoint("f", 100, 1, 1.0, 100.0, "shipped"),
        TimingPoint("f", 400, 1, 4.0, 200.0, "shipped"),
    ]
    model = CostModel(shipped)
    assert model.estimate("f", 800, 2).seconds == pytest.approx(16.0)
    assert model.estimate("other", 800, 2) is None
    model.add(TimingPoint("f", 100, 1, 3.0, 300.0, "run"))  # this machine is 3x slower
    e = model.estimate("f", 800, 2)
    assert e.seconds == pytest.approx(48.0) and "this run" in e.basis
    assert e.rss_mb == pytest.approx(300.0 * 8**0.5)  # memory: 100 → 200 MB from 100 to 400 DOFs is DOFs^0.5


def test_cost_model_scales_a_family_without_rungs_in_this_run_by_its_sibling():
    """A P2 estimate from shipped timings (one size: P1's exponent) is scaled as this run's P1 rung compares
    with its own."""
    from knitframe.ladder import TimingPoint

    model = CostModel(
        [
            TimingPoint("volumetric:p1", 1000, 10, 10.0, None, "shipped"),
            TimingPoint("volumetric:p1", 4000, 10, 40.0, None, "shipped"),
            TimingPoint("volumetric:p2", 2000, 10, 50.0, None, "shipped"),
        ]
    )
    assert model.estimate("volumetric:p2", 8000, 10).seconds == pytest.approx(200.0)  # P1's exponent, 1
    model.add(TimingPoint("volumetric:p1", 1000, 5, 15.0, None, "run"))  # 3 s per increment here, 1 s shipped
    e = model.estimate("volumetric:p2", 8000, 10)
    assert e.seconds == pytest.approx(600.0) and "volumetric:p1" in e.basis and e.rss_mb is None


def test_max_time_skips_an_expensive_rung_and_says_so(tmp_path, capsys):
    """--max-time skips the rung whose estimate (from the shipped timings) is over it, with a one-line
    notice."""
    assert any(p.family == "volumetric:p1" for p in read_timings(shipped_timings_path(), "shipped"))
    cfg = write_toml(tmp_path / "small.toml", singal_config(tmp_path))
    code = main(
        [
            "ladder",
            str(cfg),
            "--out",
            str(tmp_path / "out"),
            "--rungs",
            "rod:8,volumetric:p1:r/3",
            "--max-time",
            "120",
        ]
    )
    assert code == 0
    err = capsys.readouterr().err
    notice = [ln for ln in err.splitlines() if "skipping volumetric:p1:r/3" in ln]
    assert len(notice) == 1 and "over max_time 2 min" in notice[0] and "estimated" in notice[0]
    rows = read_csv(tmp_path / "out" / "ladder.csv")
    assert rows["volumetric:p1:r/3"]["status"].startswith("skipped: estimated")
    assert (
        rows["volumetric:p1:r/3"]["wall_time_s"] == ""
        and float(rows["volumetric:p1:r/3"]["estimated_time_s"]) > 120
    )
    assert rows["rod:8"]["status"] == "ok" and rows["rod:8"]["reference"] == "true"


@pytest.mark.parametrize(
    "rungs, problem",
    [
        ("rod:8,rod:7x", "--rungs: unknown rung 'rod:7x'; the rungs are reduced, rod:8"),
        ("rod:8,rod:2", "--rungs: rung 'rod:2': segments per stitch must be 4..256"),
        (
            "rod:8,volumetric:p2:r/12",
            "--rungs: rung 'volumetric:p2:r/12': the mesh divisor X of r/X must be 0.5..8",
        ),
        ("rod:8,rod:8", "--rungs: rung 'rod:8' is named twice"),
        ("reduced", "--rungs: 'reduced' is fitted to the best simulated rung"),
        ("rod:8,,rod:16", "--rungs: expected comma-separated rung names"),
    ],
)
def test_rung_names_are_checked_before_any_work(tmp_path, capsys, rungs, problem):
    """A bad rung name is one line and exit code 2, before anything runs or any folder is made."""
    cfg = write_toml(tmp_path / "small.toml", singal_config(tmp_path))
    code = main(["ladder", str(cfg), "--out", str(tmp_path / "out"), "--rungs", rungs])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("knitframe: error: ") and problem in err
    assert not (tmp_path / "out").exists() and not (tmp_path / "cache").exists()


def test_a_bad_rung_in_the_config_names_its_key(tmp_path):
    """In a config the error names ladder.rungs[i]."""
    config = singal_config(tmp_path, rungs=["rod:8", "volumetric:p3:r/3"])
    with pytest.raises(knitframe.ConfigError, match=r"ladder\.rungs\[1\]: unknown rung 'volumetric:p3:r/3'"):
        knitframe.ladder(config)


def test_cached_rungs_are_not_recomputed(tmp_path, capsys):
    """A second ladder with the same cache reads the finished rungs back instead of running them again."""
    config = singal_config(tmp_path)
    first = knitframe.ladder(config, out=tmp_path / "a", rungs=["reduced", "rod:8"])
    second = knitframe.ladder(config, out=tmp_path / "b", rungs=["reduced", "rod:8"])
    for rung in ("reduced", "rod:8"):
        a, b = first.row(rung), second.row(rung)
        assert not a["cached"] and b["cached"], rung
        assert b["wall_time_s"] == a["wall_time_s"] and b["peak_rss_mb"] == a["peak_rss_mb"]
    assert list(Path(tmp_path / "cache").glob("*.pkl"))
    # another scene is another job: not taken from the cache
    other = {**config, "scene": {**config["scene"], "load": {**SHORT, "steps": 3}}}
    assert not knitframe.ladder(other, rungs=["rod:8"]).row("rod:8")["cached"]
    # and a run without the cache (knitframe run --no-cache) computes the rung again
    fresh = knitframe.run({**config, "ladder": {**config["ladder"], "rungs": ["rod:8"]}}, no_cache=True)
    assert not fresh.objects["ladder"].row("rod:8")["cached"]


def test_a_configs_executor_table_runs_the_rungs_of_a_wave_side_by_side(tmp_path):
    """With [executor] kind = "local", workers = 2, the two rod rungs of one wave run at the same time, in
    their own processes."""
    config = singal_config(tmp_path)
    config["executor"] = {"kind": "local", "workers": 2, "cache_dir": str(tmp_path / "jobs")}
    result = knitframe.ladder(config, rungs=["rod:8", "rod:16"])
    a, b = result.row("rod:8"), result.row("rod:16")
    assert a["status"] == b["status"] == "ok"
    assert a["started_unix"] < b["finished_unix"] and b["started_unix"] < a["finished_unix"]  # overlapping
    assert list((tmp_path / "jobs").glob("*.pkl")) and not (tmp_path / "cache").exists()
    config["ladder"]["executor"] = "local"
    with pytest.raises(
        knitframe.ConfigError, match=r"ladder\.executor: the config has an \[executor\] table"
    ):
        knitframe.ladder(config)


def test_every_rung_has_solver_options_a_family_and_a_known_solver():
    """The rung table: names unique, solvers registered, options accepted by the solver class."""
    import attrs

    reg = knitframe.get_registry()
    for name, rung in RUNGS.items():
        cls = reg["solver"][rung.solver]
        assert set(rung.options) <= set(attrs.fields_dict(cls)), name
        assert rung.family.split(":")[0] == rung.solver
    assert sorted(RUNGS, key=lambda n: RUNGS[n].fidelity) == list(RUNGS)  # the table is in order of fidelity


def test_any_resolution_can_be_named_and_is_ordered_by_fidelity():
    """rod:N and volumetric:pK:r/X at any resolution: a mesh-convergence study names three seeds of one
    order."""
    from knitframe.ladder import rung

    r = rung("volumetric:p2:r/2.25")
    assert r.options == {"order": 2, "seed": pytest.approx(1 / 2.25)} and r.family == "volumetric:p2"
    assert rung("rod:24").options == {"segments_per_stitch": 24} and rung("rod:24").family == "rod"
    assert rung("volumetric:p1:r/3") is RUNGS["volumetric:p1:r/3"]
    names = [
        "volumetric:p2:r/3",
        "reduced",
        "volumetric:p1:r/3",
        "volumetric:p2:r/1.5",
        "rod:24",
        "rod:8",
        "volumetric:p2:r/2.25",
    ]
    assert sorted(names, key=lambda n: rung(n).fidelity) == [
        "reduced",
        "rod:8",
        "rod:24",
        "volumetric:p1:r/3",
        "volumetric:p2:r/1.5",
        "volumetric:p2:r/2.25",
        "volumetric:p2:r/3",
    ]


@pytest.mark.slow
def test_rungs_of_a_wave_run_in_parallel_on_dask_and_a_volumetric_rung_is_the_best(tmp_path):
    """On a Dask LocalCluster the two rod rungs of one wave run at the same time; the coarse P1 rung is the
    reference."""
    config = singal_config(tmp_path, executor={"kind": "dask", "workers": 2})
    config["scene"]["load"] = {"kind": "uniaxial", "direction": "course", "max_strain": 0.1, "steps": 1}
    result = knitframe.ladder(
        config, out=tmp_path / "out", rungs=["rod:8", "rod:16", "volumetric:p1:coarse", "reduced"]
    )
    a, b = result.row("rod:8"), result.row("rod:16")
    assert a["started_unix"] < b["finished_unix"] and b["started_unix"] < a["finished_unix"]  # overlapping
    vol = result.row("volumetric:p1:coarse")
    assert vol["status"] == "ok" and result.reference == "volumetric:p1:coarse"
    assert vol["dofs"] == 3 * int(vol["notes"].split(" nodes")[0].split()[-1])
    assert vol["peak_rss_mb"] > a["peak_rss_mb"]
    assert a["nrmse_vs_best"] > 0 and result.row("reduced")["nrmse_vs_measured"] > 0


@pytest.mark.slow
def test_three_seeds_of_one_order_give_a_mesh_convergence_table(tmp_path):
    """Three P1 seeds on a one-step path: convergence.csv and the ladder.md section, with an order or a named
    behaviour."""
    config = singal_config(tmp_path)
    config["scene"]["load"] = {"kind": "uniaxial", "direction": "course", "max_strain": 0.05, "steps": 1}
    rungs = ["volumetric:p1:r/1", "volumetric:p1:r/1.2", "volumetric:p1:r/1.4"]
    knitframe.ladder(config, out=tmp_path / "out", rungs=rungs)
    with open(tmp_path / "out" / "convergence.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert (
        len(rows) == 1
        and rows[0]["direction"] == "course"
        and float(rows[0]["strain"]) == pytest.approx(0.05)
    )
    assert rows[0]["rungs"].split() == rungs[::-1]
    assert rows[0]["behaviour"] in {"converging", "oscillating", "diverging"}
    if rows[0]["behaviour"] == "converging":
        assert float(rows[0]["order"]) > 0 and float(rows[0]["error_finest"]) >= 0
    assert "### Mesh convergence of volumetric:p1" in (tmp_path / "out" / "ladder.md").read_text()
