"""A full disk, or any other refusal of the file system while writing, is one line on stderr that names
the file and the way on, exit code 1, no traceback, and no temporary or partial file left behind."""

from __future__ import annotations

import builtins
import errno
import io
import json
import os
import shutil
import subprocess
import sys
import types
from pathlib import Path
from typing import ClassVar

import attrs
import pytest

import knitframe
from knitframe.cli import main

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "singal2024" / "cotton-rib-x.csv"
FIT_ONLY = f'[data]\nfiles = ["{DATA.as_posix()}"]\n\n[fit]\nmodel = "hgo"\n'
SPRINGS = """
[solver]
kind = "springcell"

[fabric]
pattern = "jersey"
stitch_length = 11
yarn = "cotton"

[scene]
effects = ["prestress"]
load = { kind = "equibiaxial", max_strain = 0.2, steps = 4 }
outputs = ["vtu"]
"""
FULL = "no space left on device; free space, then run again"

pytestmark = pytest.mark.skipif(
    not (os.path.exists("/dev/full") and os.path.isdir("/proc/self/fd")),
    reason="the full disk is /dev/full under a file's descriptor (Linux)",
)


def full_disk(monkeypatch, fails) -> list[str]:
    """Files opened for writing whose path ``fails(path)`` accepts get /dev/full as their descriptor, so
    that writing them raises the kernel's own ENOSPC; returns the paths that failed."""
    real = io.open
    failed = []

    def open_(file, mode="r", *args, **kwargs):
        f = real(file, mode, *args, **kwargs)
        path = os.readlink(f"/proc/self/fd/{file}") if isinstance(file, int) else os.fsdecode(file)
        if set(mode) & set("wax+") and fails(path):
            full = os.open("/dev/full", os.O_WRONLY)
            os.dup2(full, f.fileno())
            os.close(full)
            failed.append(path)
        return f

    monkeypatch.setattr(io, "open", open_)
    monkeypatch.setattr(builtins, "open", open_)
    return failed


def knit(capsys, *args: str) -> tuple[int, str]:
    """``knitframe ARGS`` in this process: its exit code and its one stderr line."""
    code = main(list(args))
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return code, lines[0]


def tree(folder: Path) -> dict[str, bytes | None]:
    """Every file under ``folder`` with its bytes, and every folder (None)."""
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else None for p in folder.rglob("*")}


def temporary(folder: Path) -> list[str]:
    return [str(p) for p in folder.rglob("*") if p.name.endswith(".tmp")]


def fails_on_a_full_disk(tmp_path, monkeypatch, capsys, at: str, *args: str) -> str:
    """``knitframe ARGS`` in ``tmp_path`` with the disk full at the file whose name holds ``at`` (or at its
    temporary file): exit code 1, one line (returned), and every file and folder as it was before."""
    before = tree(tmp_path)
    failed = full_disk(monkeypatch, lambda p: at in os.path.basename(p))
    code, line = knit(capsys, *args)
    print(line)
    assert failed and code == 1
    assert tree(tmp_path) == before
    return line


@pytest.fixture
def springs():
    """The spring-chain test solver as solver ``springcell``, with checkpoints and VTU files."""
    from knitframe import hookimpl
    from knitframe.interfaces import Solver
    from knitframe.plugins import load_registry, reset_registry
    from knitframe.testing.springcell import SpringCell

    @attrs.frozen
    class Springs(SpringCell, Solver):
        checkpoints: ClassVar[bool] = True
        writes_vtu: ClassVar[bool] = True

    @hookimpl
    def register_solvers(register):
        register(Springs)

    reset_registry(load_registry(extra={"springs": types.SimpleNamespace(register_solvers=register_solvers)}))


def test_run_on_a_full_disk_is_one_line_and_leaves_the_earlier_run_and_the_users_file(
    tmp_path, monkeypatch, capsys
):
    """`run --overwrite` filling the disk at fit.png names res/fit.png, exits 1, and leaves the folder as it
    was: the earlier run's outputs and the user's own file."""
    monkeypatch.chdir(tmp_path)
    Path("fit.toml").write_text(FIT_ONLY)
    knitframe.run("fit.toml", "res")
    Path("res/notes.txt").write_text("the user's notes")
    args = ("run", "fit.toml", "--out", "res", "--overwrite", "--quiet")
    line = fails_on_a_full_disk(tmp_path, monkeypatch, capsys, "fit.png", *args)
    assert line == f"knitframe: error: writing res/fit.png: {FULL}"


def test_fit_on_a_full_disk_is_one_line_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    """`fit` filling the disk at params.json names res/params.json, does not mention --resume, and removes
    the folder it made."""
    monkeypatch.chdir(tmp_path)
    Path("mine.txt").write_text("mine")
    line = fails_on_a_full_disk(
        tmp_path, monkeypatch, capsys, "params.json", "fit", str(DATA), "--out", "res"
    )
    assert line == f"knitframe: error: writing res/params.json: {FULL}"


def test_design_on_a_full_disk_is_one_line_and_leaves_the_users_file(tmp_path, monkeypatch, capsys):
    """`design --overwrite` filling the disk at pressure.png names it and keeps the earlier design and the
    user's file."""
    monkeypatch.chdir(tmp_path)
    assert main(["design", "--example", "--out", "res", "--quiet"]) == 0
    Path("res/notes.txt").write_text("the user's notes")
    args = ("design", "--example", "--out", "res", "--overwrite", "--quiet")
    line = fails_on_a_full_disk(tmp_path, monkeypatch, capsys, "pressure.png", *args)
    assert line == f"knitframe: error: writing res/pressure.png: {FULL}"


def test_geometry_on_a_full_disk_is_one_line_and_leaves_nothing(tmp_path, monkeypatch, capsys):
    """`geometry` filling the disk at tubes.vtu names res/tubes.vtu and removes the folder it made."""
    monkeypatch.chdir(tmp_path)
    args = ("geometry", "jersey", "--stitch-length", "11", "--out", "res")
    line = fails_on_a_full_disk(tmp_path, monkeypatch, capsys, "tubes.vtu", *args)
    assert line == f"knitframe: error: writing res/tubes.vtu: {FULL}"


def test_a_run_that_fills_the_disk_at_a_checkpoint_says_resume_and_resumes(
    tmp_path, monkeypatch, capsys, springs
):
    """A run whose third checkpoint fills the disk names that checkpoint, says --resume, keeps the two
    before it and no temporary file; once there is room, --resume finishes it with the clean run's curve."""
    monkeypatch.chdir(tmp_path)
    Path("springs.toml").write_text(SPRINGS)
    knitframe.run("springs.toml", "clean")
    checkpoints = []

    def third_checkpoint(path: str) -> bool:
        if "/checkpoints/" not in path:
            return False
        checkpoints.append(path)
        return len(checkpoints) == 3

    failed = full_disk(monkeypatch, third_checkpoint)
    code, line = knit(capsys, "run", "springs.toml", "--out", "res", "--quiet")
    print(line)
    assert failed and code == 1
    assert line == (
        "knitframe: error: writing res/.knitframe/checkpoints/simulate/step-0002.npz: no space left on "
        "device; free space, then run again with --resume (its checkpoints are kept)"
    )
    kept = sorted(p.name for p in (tmp_path / "res/.knitframe/checkpoints/simulate").iterdir())
    assert kept == ["step-0000.npz", "step-0001.npz"] and not temporary(tmp_path)
    monkeypatch.undo()
    monkeypatch.chdir(tmp_path)
    assert main(["run", "springs.toml", "--out", "res", "--resume"]) == 0
    assert "resuming from step 2 of" in capsys.readouterr().err
    assert (tmp_path / "res/simulated.csv").read_bytes() == (tmp_path / "clean/simulated.csv").read_bytes()
    assert not (tmp_path / "res/.knitframe").exists()


def test_a_folder_removed_mid_run_is_one_line(tmp_path, monkeypatch, capsys):
    """The output folder removed while `fit` writes into it is one line naming the file, exit 1, and
    nothing is made again."""
    import knitframe.fitting

    monkeypatch.chdir(tmp_path)
    real = knitframe.fitting.write_fit_outputs

    def remove_then_write(*args, **kwargs):
        shutil.rmtree(tmp_path / "res")
        return real(*args, **kwargs)

    monkeypatch.setattr(knitframe.fitting, "write_fit_outputs", remove_then_write)
    code, line = knit(capsys, "fit", str(DATA), "--out", "res", "--quiet")
    print(line)
    assert code == 1 and line.startswith("knitframe: error: writing res/")  # the first file fit writes
    assert line.endswith(": no such file or directory (was the folder removed during the run?); run again")
    assert tree(tmp_path) == {}


def test_a_move_that_fails_puts_the_folder_back(tmp_path, monkeypatch, capsys):
    """A move into the folder refused by the file system at the second output puts the first back and
    restores the earlier run's file it replaced: the folder is as it was, the user's file untouched."""
    monkeypatch.chdir(tmp_path)
    assert main(["fit", str(DATA), "--out", "res", "--quiet"]) == 0
    Path("res/notes.txt").write_text("the user's notes")
    before = tree(tmp_path / "res")
    real = os.replace
    refused = []

    def replace(src, dst, **kwargs):
        if os.fspath(dst).endswith("res/params.json") and not refused:
            refused.append(dst)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), os.fspath(src), None, os.fspath(dst))
        return real(src, dst, **kwargs)

    monkeypatch.setattr(os, "replace", replace)
    code, line = knit(capsys, "fit", str(DATA), "--out", "res", "--overwrite", "--quiet")
    print(line)
    assert code == 1 and line == f"knitframe: error: writing res/params.json: {FULL}"
    assert tree(tmp_path / "res") == before and not temporary(tmp_path)


def test_export_on_a_full_disk_is_one_line_and_leaves_no_temporary_file(tmp_path, monkeypatch, capsys):
    """`export` filling the disk names the card, exits 1 and leaves neither the card nor its temporary
    file."""
    monkeypatch.chdir(tmp_path)
    assert main(["fit", str(DATA), "--out", "res", "--quiet"]) == 0
    args = ("export", "res/params.json", "--format", "abaqus", "--out", "knit.inp")
    line = fails_on_a_full_disk(tmp_path, monkeypatch, capsys, "knit.inp", *args)
    assert line == f"knitframe: error: writing knit.inp: {FULL}"


def test_cache_clear_on_a_read_only_cache_is_one_line(tmp_path, monkeypatch, capsys):
    """`cache clear` whose files the file system will not remove is one line naming the file, exit 1."""
    key = "0" * 64
    (tmp_path / f"{key}.pkl").write_bytes(b"result")

    def read_only(self, missing_ok=False):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(self))

    monkeypatch.setattr(Path, "unlink", read_only)
    code, line = knit(capsys, "cache", "clear", "--dir", str(tmp_path))
    print(line)
    assert code == 1
    assert line == (
        f"knitframe: error: writing {tmp_path / key}.pkl: read-only file system; make the file system "
        "writable, then run again"
    )


def _small_file_system() -> bool:
    """Whether this user can mount a tmpfs in a new user and mount namespace (no root needed)."""
    if shutil.which("unshare") is None:
        return False
    probe = subprocess.run(
        ["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"],
        capture_output=True,
        timeout=60,
    )
    return probe.returncode == 0


@pytest.mark.skipif(not _small_file_system(), reason="needs unshare and a tmpfs mount in a user namespace")
def test_fit_on_a_genuinely_full_file_system(tmp_path):
    """`fit` into a 48 kB tmpfs that holds a user's file: one line naming the file that did not fit, exit
    1, and the file system holds the user's file alone afterwards."""
    (tmp_path / "small").mkdir()
    script = (
        "import json, subprocess, sys; from pathlib import Path\n"
        "Path('keep.txt').write_text('mine')\n"
        f"p = subprocess.run([sys.executable, '-m', 'knitframe', 'fit', {str(DATA)!r}, '--out', 'res',"
        " '--quiet'], capture_output=True, text=True)\n"
        "print(json.dumps([p.returncode, p.stderr, sorted(str(f) for f in Path('.').rglob('*'))]))\n"
    )
    proc = subprocess.run(
        [
            "unshare",
            "-rm",
            "sh",
            "-c",
            'mount -t tmpfs -o size=48k tmpfs "$1" && cd "$1" && "$2" -c "$3"',
            "sh",
            str(tmp_path / "small"),
            sys.executable,
            script,
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    assert proc.returncode == 0, proc.stderr
    code, err, files = json.loads(proc.stdout)
    print(err)
    assert code == 1 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert err.startswith("knitframe: error: writing res/") and FULL in err
    assert files == ["keep.txt"]
