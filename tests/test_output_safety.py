"""The four ways runs used to destroy or lose files, each with a sentinel that must survive, and
the promise that every file summary.json lists exists when a run exits 0."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

import knitframe
from knitframe.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "singal2024"

ROD = """
[solver]
kind = "rod"
segments_per_stitch = 10

[fabric]
pattern = "jersey"
stitch_length = 12
yarn = "cotton"

[scene]
effects = ["large_deformation", "bending", "contact", "prestress"]
load = {{ kind = "equibiaxial", max_strain = 0.1, steps = {steps} }}
"""


def knit(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "knitframe", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )


def data_config(folder: Path) -> Path:
    cfg = folder / "cfg.toml"
    cfg.write_text(f'[data]\nfiles = ["{(DATA / "cotton-rib-x.csv").as_posix()}"]\n')
    return cfg


def listed_files_exist(out: Path) -> dict:
    """summary.json lists exactly the files in the folder (besides itself), and each exists."""
    summary = json.loads((out / "summary.json").read_text())
    on_disk = sorted(str(p.relative_to(out)) for p in out.rglob("*") if p.is_file())
    assert on_disk == sorted(summary["outputs"] + ["summary.json"]), (on_disk, summary["outputs"])
    return summary


def test_out_dotdot_two_levels_down_deletes_nothing(tmp_path):
    """`run CFG --out ..` from two levels down is refused; the parent's config, data and other files
    survive."""
    parent = tmp_path / "project"
    here = parent / "runs" / "today"
    here.mkdir(parents=True)
    cfg = data_config(parent)
    sentinel = parent / "unrelated.txt"
    sentinel.write_text("keep me")
    (parent / "data.csv").write_bytes((DATA / "cotton-rib-x.csv").read_bytes())
    before = sorted(p.name for p in parent.iterdir())
    proc = knit("run", str(cfg), "--out", "../..", cwd=here)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()] and "--out" in proc.stderr
    assert sentinel.read_text() == "keep me" and sorted(p.name for p in parent.iterdir()) == before


def test_out_holding_a_users_file_is_refused_and_the_file_survives(tmp_path):
    """`--out results` where results/ holds a user's file exits 2 and the file is still there."""
    cfg = data_config(tmp_path)
    (tmp_path / "results").mkdir()
    sentinel = tmp_path / "results" / "thesis.docx"
    sentinel.write_text("three years of work")
    proc = knit("run", str(cfg), "--out", "results", cwd=tmp_path)
    assert proc.returncode == 2 and "is not empty" in proc.stderr and "Traceback" not in proc.stderr
    assert sentinel.read_text() == "three years of work"
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == ["thesis.docx"]

    proc = knit("run", str(cfg), "--out", "results", "--overwrite", "--quiet", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert sentinel.read_text() == "three years of work"
    summary = json.loads((tmp_path / "results" / "summary.json").read_text())
    assert "thesis.docx" not in summary["outputs"] and all(
        (tmp_path / "results" / f).exists() for f in summary["outputs"]
    )


def test_two_runs_into_one_folder_never_interleave(tmp_path):
    """A second run into a folder a running run holds stops at once naming it; the first finishes complete."""
    (tmp_path / "rod.toml").write_text(ROD.format(steps=12))
    sentinel = tmp_path / "keep.txt"
    sentinel.write_text("keep")
    first = subprocess.Popen(
        [sys.executable, "-m", "knitframe", "run", "rod.toml", "--out", "out", "--quiet"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    run_record = tmp_path / "out" / ".knitframe" / "run.json"
    deadline = time.monotonic() + 120
    while not run_record.exists() and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert first.poll() is None, "the first run ended before the second could start"
    second = knit("run", "rod.toml", "--out", "out", cwd=tmp_path)
    assert second.returncode == 2 and "Traceback" not in second.stderr
    assert second.stderr.strip() == (
        "knitframe: error: --out: out: another knitframe run is writing to this "
        "folder; wait for it or name another folder"
    )
    _, err = first.communicate(timeout=600)
    assert first.returncode == 0, err
    listed_files_exist(tmp_path / "out")
    assert sentinel.read_text() == "keep"


def test_two_runs_started_together_one_wins_and_its_files_are_all_there(tmp_path):
    """Two runs launched at the same instant into one new folder: one exits 0 with all its files,
    the other 2."""
    cfg = data_config(tmp_path)
    cmd = [sys.executable, "-m", "knitframe", "run", str(cfg), "--out", "out", "--quiet"]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    procs = [
        subprocess.Popen(
            cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        )
        for _ in range(2)
    ]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in procs]
    codes = sorted(code for code, _ in results)
    assert codes == [0, 2], results
    assert all("Traceback" not in err for _, err in results)
    listed_files_exist(tmp_path / "out")


@pytest.mark.parametrize("target", ["a-file", ".", "read-only"])
def test_out_file_dot_or_unwritable_is_refused_and_leaves_nothing(tmp_path, target):
    """--out naming a file, '.', or a place that cannot be made is one line, exit 2, and no .partial or work
    folder."""
    cfg = data_config(tmp_path)
    (tmp_path / "a-file").write_text("a user's file")
    out = {"a-file": "a-file", ".": ".", "read-only": "/proc/knitframe-out/x"}[target]
    before = sorted(str(p) for p in tmp_path.rglob("*"))
    proc = knit("run", str(cfg), "--out", out, cwd=tmp_path)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "Traceback" not in proc.stderr and "--out" in proc.stderr
    assert sorted(str(p) for p in tmp_path.rglob("*")) == before
    assert (tmp_path / "a-file").read_text() == "a user's file"


def test_fit_and_geometry_follow_the_same_rules(tmp_path):
    """`fit --out FILE` and `geometry --out FILE` are refused like `run`, and a non-empty folder too."""
    (tmp_path / "a-file").write_text("x")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "mine.txt").write_text("mine")
    for args in (["fit", str(DATA / "cotton-rib-x.csv")], ["geometry", "jersey", "--stitch-length", "11"]):
        for out, words in (("a-file", "is a file"), ("busy", "is not empty"), ("..", "current folder")):
            proc = knit(*args, "--out", out, cwd=tmp_path)
            assert proc.returncode == 2 and words in proc.stderr and "Traceback" not in proc.stderr, (
                proc.stderr
            )
    assert (tmp_path / "busy" / "mine.txt").read_text() == "mine" and sorted(
        p.name for p in tmp_path.iterdir()
    ) == ["a-file", "busy"]


def test_a_run_that_fails_mid_way_keeps_the_earlier_outputs_and_removes_its_own(tmp_path, monkeypatch):
    """With --overwrite, a run that fails after writing some outputs leaves the earlier run's files as they
    were."""
    from knitframe.report import plot_responses

    cfg = {"data": {"files": [str(DATA / "cotton-rib-x.csv")]}, "fit": {"model": "hgo"}}
    out = tmp_path / "out"
    knitframe.run(cfg, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def boom(*args, **kwargs):
        raise ConfigError("fit", "stands for a failure after the data stage wrote its files")

    monkeypatch.setattr("knitframe.fitting.write_fit_outputs", boom)
    monkeypatch.setattr("knitframe_stages.fit.write_fit_outputs", boom)
    with pytest.raises(ConfigError):
        knitframe.run(cfg, out, overwrite=True)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert plot_responses  # the data stage's writer ran before the failure


def test_a_new_folder_of_a_failed_run_is_removed_with_the_parents_it_made(tmp_path, monkeypatch):
    """A run into new nested folders that fails removes the folders it created and nothing else."""
    cfg = {"data": {"files": [str(DATA / "cotton-rib-x.csv")]}, "fit": {"model": "hgo"}}

    def boom(*args, **kwargs):
        raise ConfigError("fit", "fails")

    monkeypatch.setattr("knitframe_stages.fit.write_fit_outputs", boom)
    with pytest.raises(ConfigError):
        knitframe.run(cfg, tmp_path / "a" / "b" / "out")
    assert list(tmp_path.iterdir()) == []


PATCHWORK = """
[patchwork]
mode = "series"
lateral = "fixed"
max_strain = 0.2
steps = 8

[[patchwork.regions]]
name = "fitted"
source = "fit"
length = 10.0
"""


@pytest.mark.parametrize(
    "stages", ["data", "data+fit", "simulate", "simulate+fit", "data+fit+patchwork", "simulate+vtu"]
)
def test_every_file_summary_lists_exists(tmp_path, stages):
    """For every stage, summary.json lists exactly the files in the output folder, and each exists."""
    parts = []
    if "data" in stages:
        parts.append(f'[data]\nfiles = ["{(DATA / "cotton-rib-x.csv").as_posix()}"]\n')
    if "simulate" in stages:
        parts.append(ROD.format(steps=3) + ('outputs = ["vtu"]\n' if "vtu" in stages else ""))
    if "fit" in stages:
        parts.append('[fit]\nmodel = "hgo"\n')
    if "patchwork" in stages:
        parts.append(PATCHWORK)
    (tmp_path / "cfg.toml").write_text("\n".join(parts))
    res = knitframe.run(tmp_path / "cfg.toml", tmp_path / "out")
    summary = listed_files_exist(tmp_path / "out")
    assert summary["outputs"] == res.summary["outputs"] and summary["outputs"]
    if "vtu" in stages:
        assert any(f.endswith(".pvd") for f in summary["outputs"])
