"""Fabric sweeps: the [sweep] stage, the executors it runs on, the result cache and its commands."""

from __future__ import annotations

import csv
import importlib
import json
import os
import re
import sys
import textwrap
import time
from pathlib import Path

import pytest

from knitframe.cache import JobCache, JobFailure, code_hash, job_key, job_keys, module_sources
from knitframe.pipeline import Pipeline, run

ROD = """\
[sweep.solver]
kind = "rod"
segments_per_stitch = 10

[sweep.scene]
effects = ["large_deformation", "bending", "contact", "prestress"]
load = { kind = "equibiaxial", max_strain = 0.2, steps = 3 }
"""

#: 4 fabrics that the rod solver does in about 2 s each
GRID4 = 'grid = { pattern = ["jersey"], stitch_length = [11, 12], yarn = ["cotton", "nylon"] }'

#: 3 listed points; the second starves Newton of iterations, so its pre-stress fails
POINTS3 = """points = [
  { pattern = "jersey", stitch_length = 12, yarn = "cotton" },
  { pattern = "jersey", stitch_length = 11, yarn = "cotton", solver = { max_iterations = 2 }, \
name = "starved" },
  { pattern = "jersey", stitch_length = 11, yarn = "nylon" },
]"""


def write_config(
    folder: Path, points: str, executor: str, *, name: str = "test-sweep", extra: str = ""
) -> Path:
    text = (
        f'[sweep]\nname = "{name}"\n{points}\n\n{ROD}\n[executor]\n{executor}\ncache_dir = "cache"\n{extra}'
    )
    path = folder / "sweep.toml"
    path.write_text(text)
    return path


def read_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def cache_files(folder: Path) -> list[Path]:
    return sorted(folder.glob("*.pkl")) if folder.is_dir() else []


# --------------------------------------------------------------------------- helpers run in workers
def square(job):
    """A trivial job for the executors."""
    return job["x"] ** 2


def square_or_fail(job):
    """A trivial job that raises for x = 2."""
    if job["x"] == 2:
        raise ValueError("x = 2 is\nnot allowed")
    return job["x"] ** 2


# --------------------------------------------------------------------------- Dask against local
def test_dask_sweep_of_4_fabrics_equals_the_local_sweep_bit_for_bit(tmp_path):
    """A 4-fabric rod sweep on a 2-worker LocalCluster gives the same fitted parameters, bit for bit, as in
    this process."""
    runs = {}
    for kind, executor in (
        ("local", 'kind = "local"'),
        ("dask", 'kind = "dask"\nworkers = 2\ndashboard_address = ":0"'),
    ):
        folder = tmp_path / kind
        folder.mkdir()
        cfg = write_config(folder, GRID4, executor)
        res = run(cfg, folder / "out", no_cache=True)
        assert res.results["sweep"]["done"] == 4 and res.results["sweep"]["executor"] == kind
        runs[kind] = (
            read_rows(folder / "out" / "sweep.csv"),
            json.loads((folder / "out" / "library.json").read_text())["entries"],
        )
    (local_rows, local_lib), (dask_rows, dask_lib) = runs["local"], runs["dask"]
    assert [r["name"] for r in local_rows] == [
        "jersey-sl11-cotton",
        "jersey-sl11-nylon",
        "jersey-sl12-cotton",
        "jersey-sl12-nylon",
    ]
    for a, b in zip(local_rows, dask_rows):
        assert a["status"] == b["status"] == "done"
        for key in (
            "a",
            "b",
            "theta_deg",
            "nrmse",
            "course_pitch_mm",
            "wale_pitch_mm",
            "max_tension_N_per_mm",
        ):
            assert float(a[key]) == float(b[key]), (
                a["name"],
                key,
                a[key],
                b[key],
            )  # repr of floats: every bit
    assert [e["params"] for e in local_lib] == [e["params"] for e in dask_lib]
    # the runs really took place in different processes: the Dask run is not a copy of the local one
    assert all(r["cached"] == "no" for r in local_rows + dask_rows)


# --------------------------------------------------------------------------- cache keys
def _write_module(folder: Path, name: str, body: str) -> None:
    path = folder / f"{name}.py"
    path.write_text(textwrap.dedent(body))
    stamp = time.time() + 10 * len(
        body
    )  # a new mtime: the import system must not reuse a stale bytecode file
    os.utime(path, (stamp, stamp))


def test_cache_key_changes_when_the_job_function_or_a_module_it_imports_changes(tmp_path, monkeypatch):
    """Editing the job function's code, or a module its package imports, gives a new key, so a rerun computes
    afresh."""
    from knitframe_executors.local import LocalExecutor

    pkg = tmp_path / "sweepjobs_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    _write_module(pkg, "helper", "FACTOR = 2\n")
    _write_module(
        pkg,
        "jobs",
        """\
        from . import helper

        def job(d):
            return d["x"] * helper.FACTOR
        """,
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    jobs_mod = importlib.import_module("sweepjobs_pkg.jobs")
    ex = LocalExecutor(cache_dir=str(tmp_path / "cache"))
    key0 = job_key(jobs_mod.job, {"x": 5})
    assert "sweepjobs_pkg.helper" in module_sources(["sweepjobs_pkg.jobs"])  # the import is followed
    assert ex.map(jobs_mod.job, [{"x": 5}]) == [10]
    assert job_key(jobs_mod.job, {"x": 5}) == key0  # nothing changed: the same key, and the result is reused
    JobCache(ex.cache_dir).put(key0, "from the cache")
    assert ex.map(jobs_mod.job, [{"x": 5}]) == ["from the cache"]

    # the function's code changes: the key changes, and the stale result is not returned
    _write_module(
        pkg,
        "jobs",
        """\
        from . import helper

        def job(d):
            return d["x"] * helper.FACTOR + 1000
        """,
    )
    importlib.invalidate_caches()
    jobs_mod = importlib.reload(jobs_mod)
    key1 = job_key(jobs_mod.job, {"x": 5})
    assert key1 != key0
    assert ex.map(jobs_mod.job, [{"x": 5}]) == [1010]

    # a module it imports changes (the function itself does not): a new key again
    _write_module(pkg, "helper", "FACTOR = 3\n")
    importlib.invalidate_caches()
    importlib.reload(sys.modules["sweepjobs_pkg.helper"])
    key2 = job_key(jobs_mod.job, {"x": 5})
    assert key2 not in (key0, key1)
    assert ex.map(jobs_mod.job, [{"x": 5}]) == [1015]
    assert job_key(jobs_mod.job, {"x": 6}) != key2  # and every input counts


def test_cache_key_changes_with_a_solver_option_and_covers_the_solver_code(tmp_path):
    """A changed solver option gives new keys; the key hashes the rod solver's modules (and what they import)
    and knitframe's version."""
    from knitframe.sweep import point_modules, run_point

    def keys(segments: int) -> list[str]:
        cfg = (
            write_config(tmp_path, GRID4, 'kind = "local"')
            .read_text()
            .replace("segments_per_stitch = 10", f"segments_per_stitch = {segments}")
        )
        (tmp_path / "s.toml").write_text(cfg)
        from knitframe.config import load_toml

        stage = Pipeline(load_toml(tmp_path / "s.toml"), base_dir=tmp_path).stages[0]
        return job_keys(run_point, list(stage.jobs)), stage.jobs

    k10, jobs = keys(10)
    assert k10 == keys(10)[0]  # deterministic
    k12, _ = keys(12)
    assert len(set(k10)) == 4 and not set(k10) & set(k12)
    sources = module_sources(["knitframe_stages.sweep", *point_modules(jobs[0])])
    for mod in (
        "knitframe_solvers.rod",
        "knitframe_solvers.rod_model",
        "knitframe_solvers.rod_contact",
        "knitframe_contact.rod_penalty",
        "knitframe_contact.rod_shell",  # contact_law = "auto" may pick either
        "knitframe_linsolvers.direct",
        "knitframe_patterns.jersey",
        "knitframe_homogenizers.hgo",
        "knitframe_fitters.lbfgs",
        "knitframe.numerics.newton",
        "knitframe.geometry",
    ):
        assert mod in sources, mod
    # the code hash is of exactly these sources: a different set gives a different hash
    assert code_hash(run_point, point_modules(jobs[0])) != code_hash(run_point, [])


# --------------------------------------------------------------------------- failures, cache, outputs
def test_a_failed_point_is_recorded_the_rest_finish_and_the_cache_serves_a_rerun(
    tmp_path, monkeypatch, capsys
):
    """A point that raises is 'failed' with a one-line reason, the others finish and are cached; a rerun
    reuses them, --no-cache does not."""
    monkeypatch.setenv("KNITFRAME_PROGRESS_INTERVAL", "0.05")
    cfg = write_config(tmp_path, POINTS3, 'kind = "local"')
    res = run(cfg, tmp_path / "out1", quiet=False)
    rows = read_rows(tmp_path / "out1" / "sweep.csv")
    assert [r["status"] for r in rows] == ["done", "failed", "done"]
    assert rows[1]["name"] == "starved" and rows[1]["reason"].startswith(
        "NumericalError: rod solver (jersey, cotton)"
    )
    assert "\n" not in rows[1]["reason"] and rows[1]["a"] == ""
    assert res.results["sweep"] == {**res.results["sweep"], "points": 3, "done": 2, "failed": 1, "cached": 0}
    assert any("sweep point 1 (starved) failed: NumericalError" in w for w in res.summary["warnings"])
    err = capsys.readouterr().err
    assert re.search(
        r"knitframe: sweep test-sweep \(3 fabrics, local, 1 worker\): \d/3 finished "
        r"\(\d done, \d failed, \d running\), \d\d:\d\d elapsed, (about \d\d:\d\d|unknown) left",
        err,
    )
    assert len(cache_files(tmp_path / "cache")) == 2  # the two results; a failure is never cached

    res2 = run(cfg, tmp_path / "out2")
    rows2 = read_rows(tmp_path / "out2" / "sweep.csv")
    assert [r["cached"] for r in rows2] == ["yes", "no", "yes"] and res2.results["sweep"]["cached"] == 2
    assert [r["a"] for r in rows2] == [r["a"] for r in rows]
    assert [r["status"] for r in rows2] == ["done", "failed", "done"]

    run(cfg, tmp_path / "out3", no_cache=True)
    assert [r["cached"] for r in read_rows(tmp_path / "out3" / "sweep.csv")] == ["no", "no", "no"]


def test_outputs_are_written_and_library_json_drives_design(tmp_path):
    """sweep.csv, library.json and params.png are written; the library loads and knitframe.design uses it."""
    import knitframe
    from knitframe.garment.library import FabricLibrary

    cfg = write_config(tmp_path, POINTS3, 'kind = "local"', name="my-fabrics")
    res = run(cfg, tmp_path / "out")
    out = tmp_path / "out"
    assert sorted(res.summary["outputs"]) == ["library.json", "params.png", "sweep.csv"]
    rows = read_rows(out / "sweep.csv")
    for key in (
        "pattern",
        "yarn",
        "stitch_length",
        "load",
        "max_strain",
        "solver_options",
        "a",
        "b",
        "theta_deg",
        "nrmse",
        "wall_time_s",
        "status",
        "reason",
        "cached",
        "course_pitch_mm",
        "max_tension_N_per_mm",
    ):
        assert key in rows[0], key
    assert json.loads(rows[1]["solver_options"]) == {"segments_per_stitch": 10, "max_iterations": 2}
    lib = FabricLibrary.load(out / "library.json")
    assert lib.name == "my-fabrics" and lib.names == ["jersey-sl12-cotton", "jersey-sl11-nylon"]
    done = [r for r in rows if r["status"] == "done"]
    for entry, row in zip(lib, done):
        assert entry.params["a"] == float(row["a"]) and entry.model == "hgo"
        assert entry.course_pitch == float(row["course_pitch_mm"]) and entry.max_tension == float(
            row["max_tension_N_per_mm"]
        )
        assert entry.max_stretch == pytest.approx(1.2) and "largest simulated course tension" in entry.source
        assert entry.pitch_source.startswith("relaxed rod cell")
    assert (out / "params.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # a limb whose circumference stays within the simulated stretch range of these fabrics
    limb = {"positions_mm": [0, 100, 200], "circumferences_mm": [200, 205, 210]}
    design = knitframe.design(limb, out / "library.json", "stress_variance")
    assert design.library.names == lib.names
    assert design.limits_respected and design.T1.max() > 0


def test_a_point_with_an_array_of_loads_is_fitted_to_all_its_curves(tmp_path):
    """A point whose load is an array (course and wale pulls) simulates each and fits the model to both
    jointly."""
    points = """points = [{ pattern = "jersey", stitch_length = 12, yarn = "cotton", load = [
  { kind = "uniaxial", direction = "course", max_strain = 0.2, steps = 3 },
  { kind = "uniaxial", direction = "wale", max_strain = 0.2, steps = 3 }] }]"""
    cfg = write_config(tmp_path, points, 'kind = "local"', extra="")
    cfg.write_text(
        cfg.read_text().replace("[sweep.solver]", '[sweep.fit]\nmodel = "hgo2m"\n\n[sweep.solver]')
    )
    run(cfg, tmp_path / "out")
    (row,) = read_rows(tmp_path / "out" / "sweep.csv")
    assert (
        row["status"] == "done" and row["load"] == "uniaxial-course+uniaxial-wale" and row["steps"] == "3/3"
    )
    assert row["model"] == "hgo2m" and float(row["nrmse_course"]) >= 0 and float(row["nrmse_wale"]) >= 0
    lib = json.loads((tmp_path / "out" / "library.json").read_text())
    assert "uniaxial course (free side) 0-20 % in 3 steps and uniaxial wale" in lib["entries"][0]["source"]


# --------------------------------------------------------------------------- executors directly
@pytest.mark.parametrize("kind", ["local", "local-pool", "dask"])
def test_executors_keep_failures_and_report_progress(kind, tmp_path):
    """Each executor puts a one-line JobFailure where a job raised (never cached), keeps the rest, and reports
    done/failed/running."""
    from knitframe_executors.dask import DaskExecutor
    from knitframe_executors.local import LocalExecutor

    ex = {
        "local": LocalExecutor(cache_dir=str(tmp_path)),
        "local-pool": LocalExecutor(workers=2, cache_dir=str(tmp_path)),
        "dask": DaskExecutor(workers=1, dashboard_address=":0", cache_dir=str(tmp_path)),
    }[kind]
    seen = []
    jobs = [{"x": i} for i in range(4)]
    out = ex.map(square_or_fail, jobs, failures="keep", progress=lambda d, t, m: seen.append((d, t, m)))
    assert out[:2] == [0, 1] and out[3] == 9
    assert isinstance(out[2], JobFailure) and out[2].reason == "ValueError: x = 2 is not allowed"
    assert seen[-1][:2] == (4, 4) and seen[-1][2].startswith("3 done, 1 failed, 0 running")
    assert len(cache_files(tmp_path)) == 3
    with pytest.raises(ValueError, match="not allowed"):
        ex.map(square_or_fail, [{"x": 2}])  # the default: the first failure stops the map
    again = ex.map(square_or_fail, jobs, failures="keep", progress=lambda d, t, m: seen.append((d, t, m)))
    assert isinstance(again[2], JobFailure) and seen[-1][2] == "0 done, 1 failed, 0 running, 3 cached"


def test_dask_workers_run_without_the_nanny_malloc_trim_setting(tmp_path):
    """The LocalCluster's workers do not get Dask's MALLOC_TRIM_THRESHOLD_ (it slows assembly 7-8x)."""
    from knitframe_executors.dask import DaskExecutor

    assert DaskExecutor(workers=1, dashboard_address=":0").map(_malloc_trim_job, [{"i": 0}]) == [None]


def _malloc_trim_job(job):
    return os.environ.get("MALLOC_TRIM_THRESHOLD_")


# --------------------------------------------------------------------------- config errors
BAD = [
    (
        "points-stitch-length",
        POINTS3.replace('stitch_length = 11, yarn = "nylon"', 'stitch_length = -1, yarn = "nylon"'),
        'kind = "local"',
        "sweep.points[2].stitch_length: ",
    ),
    (
        "grid-yarn",
        GRID4.replace('"nylon"', '"wool"'),
        'kind = "local"',
        "sweep.grid.yarn[1]: unknown yarn 'wool'",
    ),
    (
        "grid-solver-option",
        GRID4.replace("}", ", segments_per_stitch = [10, 2] }"),
        'kind = "local"',
        "sweep.grid.segments_per_stitch[1]: ",
    ),
    (
        "grid-unknown-key",
        GRID4.replace("}", ", colour = [1] }"),
        'kind = "local"',
        "sweep.grid.colour: unknown key",
    ),
    ("grid-and-points", GRID4 + "\n" + POINTS3, 'kind = "local"', "sweep: give the points as a grid"),
    (
        "point-load",
        POINTS3.replace('yarn = "nylon" }', 'yarn = "nylon", load = { max_strain = -0.1 } }'),
        'kind = "local"',
        "sweep.points[2].load.max_strain: ",
    ),
    ("executor-workers", GRID4, 'kind = "dask"\nworkers = 0', "executor.workers: "),
    ("executor-kind", GRID4, 'kind = "slurm"', "executor.kind: unknown executor 'slurm'"),
    (
        "executor-memory",
        GRID4,
        'kind = "dask"\nmemory_limit = "lots"',
        "executor.memory_limit: expected a size",
    ),
    (
        "fit-model",
        GRID4 + '\nfit = { model = "nope" }',
        'kind = "local"',
        "sweep.fit.model: unknown homogenizer 'nope'",
    ),
]


@pytest.mark.parametrize("case,points,executor,message", BAD, ids=[b[0] for b in BAD])
def test_config_errors_are_one_line_before_any_work(case, points, executor, message, tmp_path, cli):
    """A bad point, grid, fit or executor key is one line naming it, exit code 2, and nothing is computed or
    written."""
    cfg = write_config(tmp_path, points, executor)
    proc = cli("run", str(cfg), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"knitframe: error: {cfg}: {message}"), proc.stderr
    assert not (tmp_path / "out").exists() and not (tmp_path / "cache").exists()


# --------------------------------------------------------------------------- the cache command
def test_cache_clear_removes_only_cached_results(tmp_path, cli):
    """knitframe cache info/clear count and delete the cached results and leave every other file alone."""
    cache = JobCache(tmp_path / "c")
    for i in range(3):
        cache.put(job_key(square, {"x": i}), i * i)
    (tmp_path / "c" / "notes.txt").write_text("mine")
    (tmp_path / "c" / "x.pkl").write_bytes(b"not a cache entry name")
    proc = cli("cache", "info", "--dir", str(tmp_path / "c"))
    assert proc.returncode == 0 and "3 cached results" in proc.stdout
    proc = cli("cache", "clear", "--dir", str(tmp_path / "c"))
    assert proc.returncode == 0 and "removed 3 cached results" in proc.stdout
    assert sorted(p.name for p in (tmp_path / "c").iterdir()) == ["notes.txt", "x.pkl"]
    proc = cli("cache", "clear", "--dir", str(tmp_path / "nothing-here"))
    assert proc.returncode == 0 and "no cache" in proc.stdout and not (tmp_path / "nothing-here").exists()
    proc = cli("cache", "clear", "--dir", str(tmp_path / "c" / "notes.txt"))
    assert proc.returncode == 2 and proc.stderr.strip().count("\n") == 0 and "not a folder" in proc.stderr


def test_default_cache_folder_follows_the_environment(tmp_path, monkeypatch):
    """KNITFRAME_CACHE_DIR, else XDG_CACHE_HOME/knitframe/jobs, is where sweeps keep results by default."""
    from knitframe.cache import default_cache_dir

    monkeypatch.delenv("KNITFRAME_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert default_cache_dir() == tmp_path / "xdg" / "knitframe" / "jobs"
    monkeypatch.setenv("KNITFRAME_CACHE_DIR", str(tmp_path / "mine"))
    assert default_cache_dir() == tmp_path / "mine"
    stage = Pipeline(
        {"sweep": {"points": [{"pattern": "jersey", "stitch_length": 11, "yarn": "cotton"}]}},
        base_dir=tmp_path,
    ).stages[0]
    assert stage.executor_name == "local" and stage.executor.cache_dir == str(tmp_path / "mine")
