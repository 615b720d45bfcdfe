"""A run killed at any moment and resumed gives the same curves, every step's VTU file and a .pvd
that lists all steps; the resumed run says where it resumed from; Ctrl-C is one line and exit 130."""

from __future__ import annotations

import csv
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import meshio
import numpy as np
import pytest

import knitframe
from knitframe.numerics.continuation import StepCheckpoints
from knitframe.numerics.stepfiles import StepSeries

CONFIG = """\
[solver]
kind = "rod"
segments_per_stitch = 10

[fabric]
pattern = "jersey"
stitch_length = 12
yarn = "cotton"

[scene]
effects = ["large_deformation", "bending", "contact", "prestress"]
load = {{ kind = "equibiaxial", max_strain = 0.2, steps = {steps} }}
outputs = ["vtu"]
"""


class Killed(BaseException):
    """Stands for the process dying at that moment."""


def pvd_files(out: Path) -> list[str]:
    return re.findall(r'file="([^"]+)"', (out / "vtu" / "rod.pvd").read_text())


def curve(path: Path) -> np.ndarray:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return np.array(
        [[float(r[k]) for k in ("lambda1", "lambda2", "T1_N_per_mm", "T2_N_per_mm")] for r in rows]
    )


def assert_same_run(out: Path, ref: Path) -> None:
    """Same curve, the same VTU files with the same points, and a .pvd that lists every one of them."""
    a, b = curve(out / "simulated.csv"), curve(ref / "simulated.csv")
    assert a.shape == b.shape and np.allclose(a, b, rtol=1e-10, atol=1e-12)
    names = sorted(p.name for p in (out / "vtu").glob("*.vtu"))
    assert names == sorted(p.name for p in (ref / "vtu").glob("*.vtu"))
    assert pvd_files(out) == pvd_files(ref) == names
    for name in (names[0], names[len(names) // 2], names[-1]):
        assert np.allclose(
            meshio.read(out / "vtu" / name).points,
            meshio.read(ref / "vtu" / name).points,
            rtol=1e-9,
            atol=1e-9,
        )


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ref")
    (folder / "rod.toml").write_text(CONFIG.format(steps=6))
    knitframe.run(folder / "rod.toml", folder / "out")
    return folder / "out"


MOMENTS = {
    # killed just after a step's checkpoint was written (before the next step's VTU file)
    "after-checkpoint": (StepCheckpoints, "save", 10),
    # killed after a step's VTU file was written but before its checkpoint
    "between-vtu-and-checkpoint": (StepSeries, "write", 11),
    # killed in the middle of a Newton solve of a load step
    "inside-a-solve": (None, None, 12),
}


@pytest.mark.parametrize("moment", sorted(MOMENTS))
def test_killed_and_resumed_run_has_every_step_file(tmp_path, monkeypatch, reference, moment):
    """Killed at a moment, then resumed: the same curve, a VTU file for every step and a .pvd listing all of
    them."""
    (tmp_path / "rod.toml").write_text(CONFIG.format(steps=6))
    cls, name, at = MOMENTS[moment]
    calls = []
    if cls is not None:
        real = getattr(cls, name)

        def die(self, *args, **kwargs):
            result = real(self, *args, **kwargs)
            calls.append(1)
            if len(calls) == at:
                raise Killed
            return result

        monkeypatch.setattr(cls, name, die)
    else:
        import knitframe_solvers.rod_run as rod

        real_minimise = rod.minimise

        def die_inside(*args, **kwargs):
            calls.append(1)
            if len(calls) == at:
                raise Killed
            return real_minimise(*args, **kwargs)

        monkeypatch.setattr(rod, "minimise", die_inside)
    with pytest.raises(Killed):
        knitframe.run(tmp_path / "rod.toml", tmp_path / "out")
    monkeypatch.undo()
    assert (tmp_path / "out" / ".knitframe" / "checkpoints").is_dir()
    knitframe.run(tmp_path / "rod.toml", tmp_path / "out", resume=True)
    assert_same_run(tmp_path / "out", reference)


def test_sigkilled_cli_run_resumes_with_its_files_and_says_so(tmp_path, reference):
    """`knitframe run` killed by SIGKILL mid-load and resumed prints one resume line and has every step's
    files."""
    (tmp_path / "rod.toml").write_text(CONFIG.format(steps=6))
    env = {**os.environ, "MPLBACKEND": "Agg"}
    cmd = [sys.executable, "-m", "knitframe", "run", "rod.toml", "--out", "out"]
    proc = subprocess.Popen(
        cmd + ["--quiet"], cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env
    )
    ckpt = tmp_path / "out" / ".knitframe" / "checkpoints" / "simulate"
    deadline = time.monotonic() + 300
    while not (ckpt / "step-0011.npz").exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL, "the run ended before it could be killed"
    done = subprocess.run(
        cmd + ["--resume"], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=600
    )
    assert done.returncode == 0, done.stderr
    resumed = [line for line in done.stderr.splitlines() if "resuming" in line]
    assert len(resumed) == 1 and re.fullmatch(
        r"knitframe: resuming from step \d+ of 15 \(checkpoint .*step-\d{4}\.npz\)", resumed[0]
    ), done.stderr
    assert_same_run(tmp_path / "out", reference)


def test_ctrl_c_is_one_line_and_exit_130(tmp_path):
    """SIGINT during a run prints one line, exits 130 and leaves no traceback; checkpoints stay for
    --resume."""
    (tmp_path / "rod.toml").write_text(CONFIG.format(steps=30))
    proc = subprocess.Popen(
        [sys.executable, "-m", "knitframe", "run", "rod.toml", "--out", "out", "--quiet"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    ckpt = tmp_path / "out" / ".knitframe" / "checkpoints" / "simulate"
    deadline = time.monotonic() + 300
    while not (ckpt / "step-0010.npz").exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert err.strip() == "knitframe: interrupted", err
    assert any(ckpt.glob("step-*.npz"))


def test_progress_lines_on_a_non_terminal(tmp_path):
    """Piped to a log, a run prints a progress line at the set interval with the step, elapsed time and time
    left."""
    (tmp_path / "rod.toml").write_text(CONFIG.format(steps=6))
    done = subprocess.run(
        [sys.executable, "-m", "knitframe", "run", "rod.toml", "--out", "out"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "MPLBACKEND": "Agg", "KNITFRAME_PROGRESS_INTERVAL": "0.2"},
    )
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if line.startswith("knitframe: rod jersey: step")]
    assert len(lines) >= 3, done.stderr
    assert re.fullmatch(
        r"knitframe: rod jersey: step 15/15 \(load step 6/6\), \d\d:\d\d elapsed, about 00:00 left", lines[-1]
    ), lines[-1]
    assert all(re.search(r"\d\d:\d\d elapsed, (about \d\d:\d\d|unknown) left$", line) for line in lines)
