"""Config-selected pipelines: the built-in example, outputs, summary, atomic output directory."""

from __future__ import annotations

import csv
import json

import attrs
import numpy as np
import pytest

import knitframe
from knitframe.errors import ConfigError
from knitframe.pipeline import Pipeline


def test_example_imports_real_data_and_writes_csv_plot_summary(example_run):
    """The built-in example reads the Singal files as Responses and writes CSV, PNG and summary.json."""
    res, out = example_run
    loads = sorted(r.load for r in res.responses if r.provenance.kind == "experiment")
    assert loads == ["uniaxial-course", "uniaxial-wale"]
    course = next(r for r in res.responses if r.load == "uniaxial-course")
    assert course.n_samples >= 2 and course.T1_sd is not None
    assert np.all(course.T2 == 0) and course.T1.max() > 0.1  # N/mm, free sides
    assert (out / "responses.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = list(csv.DictReader(open(out / "responses.csv")))
    assert len(rows) == sum(len(r) for r in res.responses if r.provenance.kind == "experiment")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["knitframe"] == knitframe.__version__
    assert [s["stage"] for s in summary["stages"]][0] == "data"
    assert summary["plugins"]["reader:singal2024"]["package"] == "knitframe"
    assert "responses.csv" in summary["outputs"]
    assert not (out / ".knitframe").exists() and sorted(p.name for p in out.iterdir()) == sorted(
        summary["outputs"] + ["summary.json"]
    )


def test_reader_averages_repeats_with_spread(singal_file):
    """Averaging gives mean tension within the repeat envelope and a non-negative sd."""
    reader = knitframe.get_registry()["reader"]["singal2024"]
    per_repeat = reader(average=False).read(singal_file("cotton-garter-y.csv"))
    (mean,) = reader().read(singal_file("cotton-garter-y.csv"))
    assert len(per_repeat) == mean.n_samples >= 2
    assert mean.load == "uniaxial-wale" and np.all(mean.T1 == 0)
    assert np.all(mean.T2_sd >= 0)
    lam = mean.lambda2[len(mean) // 2]
    vals = [np.interp(lam, np.sort(r.lambda2), r.T2[np.argsort(r.lambda2)]) for r in per_repeat]
    assert min(vals) - 1e-12 <= mean.T2[len(mean) // 2] <= max(vals) + 1e-12


def test_api_accepts_a_dict_and_runs_without_output(tmp_path, singal_file):
    """knitframe.run(dict) runs the same pipeline; out=None keeps no files."""
    res = knitframe.run({"data": {"files": [str(singal_file("cotton-rib-x.csv"))]}})
    assert res.out is None and len(res.responses) == 1


def test_existing_output_is_replaced_only_on_success(tmp_path, singal_file):
    """A failing run leaves a previous good output untouched and no work folder."""
    out = tmp_path / "out"
    knitframe.run({"data": {"files": [str(singal_file("cotton-rib-x.csv"))]}}, out)
    before = (out / "summary.json").read_text()
    with pytest.raises(ConfigError):
        knitframe.run({"data": {"files": ["missing.csv"]}}, out)
    assert (out / "summary.json").read_text() == before
    assert not (out / ".knitframe").exists()


def test_stages_run_in_order_and_new_stages_plug_in_without_core_changes(tmp_path, singal_file):
    """A stage registered by a plugin runs after the data stage and sees its Responses."""
    import types

    seen = []

    @attrs.frozen
    class CountStage:
        name = "count"
        description = "counts responses"
        order = 99
        uses = ()
        factor: int = 1

        @classmethod
        def from_config(cls, config, ctx):
            from knitframe.schema import build

            return build(cls, config["count"], "count")

        def run(self, ctx):
            seen.append(len(ctx.responses) * self.factor)
            ctx.output("count.txt").write_text(str(seen[-1]))

    mod = types.ModuleType("count_plugin")

    @knitframe.hookimpl
    def register_stages(register):
        register(CountStage)

    mod.register_stages = register_stages
    reg = knitframe.load_registry({"count_plugin": mod})
    cfg = {"data": {"files": [str(singal_file("cotton-rib-x.csv"))]}, "count": {"factor": 10}}
    res = knitframe.run(cfg, tmp_path / "o", registry=reg)
    assert seen == [10]
    assert [s["stage"] for s in res.summary["stages"]] == ["data", "count"]
    assert (tmp_path / "o" / "count.txt").read_text() == "10"
    with pytest.raises(ConfigError, match="count.factor: expected an integer"):
        Pipeline({"count": {"factor": "x"}}, base_dir=tmp_path, registry=reg)


def test_repeated_fit_tables_run_one_fit_each(tmp_path, singal_file):
    """[[fit]] arrays give one fit per table, filtered by kind or label, with prefixed outputs."""
    cfg = {
        "data": {"files": [str(singal_file("cotton-rib-x.csv")), str(singal_file("cotton-rib-y.csv"))]},
        "fit": [
            {"name": "course", "labels": ["cotton-rib-x"]},
            {"name": "both", "kinds": ["experiment"]},
        ],
    }
    res = knitframe.run(cfg, tmp_path / "o")
    assert [s["stage"] for s in res.summary["stages"]] == ["data", "fit:course", "fit:both"]
    assert json.loads((tmp_path / "o" / "course-params.json").read_text())["responses"] == ["cotton-rib-x"]
    assert len(json.loads((tmp_path / "o" / "both-params.json").read_text())["responses"]) == 2
    assert (tmp_path / "o" / "both-fit.png").exists()


def test_repeated_tables_name_the_failing_entry(tmp_path, singal_file):
    """An error inside the second [[fit]] table names fit[1]; duplicate names are refused."""
    data = {"files": [str(singal_file("cotton-rib-x.csv"))]}
    with pytest.raises(ConfigError, match=r"^fit\[1\]\.fitter: unknown fitter 'nope'"):
        knitframe.run({"data": data, "fit": [{"name": "a"}, {"name": "b", "fitter": "nope"}]})
    with pytest.raises(
        ConfigError, match=r"^fit\[1\]\.name: repeated \[\[fit\]\] tables need distinct names"
    ):
        knitframe.run({"data": data, "fit": [{"name": "a"}, {"name": "a"}]})
    with pytest.raises(ConfigError, match=r"^data: expected a table"):
        knitframe.run({"data": [data]})
