"""The ``[solver]`` stage with the rod solver: resume after a killed run, progress bar, fitted model at the
end."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from knitframe.numerics.continuation import StepCheckpoints
from knitframe.pipeline import run

CONFIG = """\
[pipeline]
name = "rod-resume"

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
{extra}"""

FIT = """
[fit]
model = "hgo"
fitter = "lbfgs"
"""


def write_config(tmp_path: Path, steps: int = 6, extra: str = "") -> Path:
    path = tmp_path / "rod.toml"
    path.write_text(CONFIG.format(steps=steps, extra=extra))
    return path


def read_curve(path: Path) -> np.ndarray:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return np.array(
        [[float(r[k]) for k in ("lambda1", "lambda2", "T1_N_per_mm", "T2_N_per_mm")] for r in rows]
    )


def knitframe_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "knitframe", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )


class Killed(BaseException):
    """Stands for the process dying right after a checkpoint was written."""


@pytest.mark.parametrize("kill_after", [3, 11], ids=["during-prestress", "during-load"])
def test_interrupted_run_resumes_to_the_same_curve(tmp_path, monkeypatch, kill_after):
    """A run stopped after its k-th checkpoint and continued by `knitframe run --resume` ends with the
    uninterrupted curve."""
    config = write_config(tmp_path)
    full = run(config, tmp_path / "full")
    reference = read_curve(full.out / "simulated.csv")

    real_save = StepCheckpoints.save
    saved = []

    def save_then_die(self, index, arrays, meta):
        path = real_save(self, index, arrays, meta)
        saved.append(index)
        if len(saved) == kill_after:
            raise Killed
        return path

    monkeypatch.setattr(StepCheckpoints, "save", save_then_die)
    with pytest.raises(Killed):
        run(config, tmp_path / "out")
    monkeypatch.undo()
    partial = tmp_path / "out" / ".knitframe"
    assert (
        sorted(p.name for p in (partial / "checkpoints" / "simulate").glob("step-*.npz"))[-1]
        == f"step-{kill_after - 1:04d}.npz"
    )
    assert [p.name for p in (tmp_path / "out").iterdir()] == [".knitframe"]

    done = knitframe_cli("run", str(config), "--out", "out", "--resume", "--quiet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    resumed = read_curve(tmp_path / "out" / "simulated.csv")
    assert resumed.shape == reference.shape
    assert np.allclose(resumed, reference, rtol=1e-10, atol=1e-12)
    assert not partial.exists() and not (tmp_path / "out" / "checkpoints").exists()


def test_sigkilled_cli_run_resumes_from_its_checkpoints(tmp_path):
    """`knitframe run` killed with SIGKILL once its first load step is checkpointed resumes to the
    uninterrupted curve."""
    config = write_config(tmp_path, steps=30)
    proc = subprocess.Popen(
        [sys.executable, "-m", "knitframe", "run", str(config), "--out", "out", "--quiet"],
        cwd=tmp_path,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    # after 8 pre-stress steps and the relaxed lattice
    first_load_step = tmp_path / "out" / ".knitframe" / "checkpoints" / "simulate" / "step-0009.npz"
    deadline = time.monotonic() + 300
    while not first_load_step.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL, (
        f"the run ended before it could be killed: {proc.stderr.read()!r}"
    )
    left = sorted((tmp_path / "out" / ".knitframe" / "checkpoints" / "simulate").glob("step-*.npz"))
    assert left and left[-1].name >= first_load_step.name

    done = knitframe_cli("run", str(config), "--out", "out", "--resume", "--quiet", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    full = run(config, tmp_path / "full")
    assert np.allclose(
        read_curve(tmp_path / "out" / "simulated.csv"),
        read_curve(full.out / "simulated.csv"),
        rtol=1e-10,
        atol=1e-12,
    )


def test_rod_run_shows_a_progress_bar_and_ends_with_a_fitted_model(tmp_path):
    """On a terminal `knitframe run` redraws a progress bar per converged step; a [fit] table fits hgo to the
    simulated curve."""
    import pty

    config = write_config(tmp_path, extra=FIT)
    pid, fd = pty.fork()
    if pid == 0:  # child: the CLI with the pseudo-terminal as its stdout and stderr
        os.chdir(tmp_path)
        os.environ["MPLBACKEND"] = "Agg"
        os.execv(sys.executable, [sys.executable, "-m", "knitframe", "run", str(config), "--out", "out"])
    chunks = []
    while True:
        try:
            data = os.read(fd, 4096)
        except OSError:  # the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    _, status = os.waitpid(pid, 0)
    text = b"".join(chunks).decode(errors="replace")
    assert os.waitstatus_to_exitcode(status) == 0, text
    frames = [f for f in text.split("\r") if "rod jersey [" in f]
    assert len(frames) >= 8 + 6, text  # one redraw per pre-stress and load step
    assert "pre-stress" in text and "1/8" in text and "load step 6/6" in text and "100.0%" in text
    params = json.loads((tmp_path / "out" / "params.json").read_text())
    assert params["model"] == "hgo" and params["responses"] == ["rod jersey SL12 cotton"]
    assert params["a"] > 0 and 0 < params["theta_deg"] < 90 and params["nrmse"]["overall"] < 0.1
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert [s["stage"] for s in summary["stages"]] == ["simulate", "fit"]
    assert "fit: hgo by lbfgs" in text
