"""Hostile output paths and command lines: refused in one line before any work, and nothing is touched.

Each case runs from a folder two levels below a scratch root, with a user's file at every level,
and checks the exit code, one line naming the option, no traceback, and that no file anywhere
under the root changed.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from .conftest import assert_refused, snapshot

DATA = Path(__file__).resolve().parents[1] / "data" / "singal2024" / "cotton-rib-x.csv"

CONFIG = f'[data]\nfiles = ["{DATA.as_posix()}"]\n'


@pytest.fixture
def home(tmp_path):
    """root/work/here, each holding a user's file; here holds a config; returns (root, here)."""
    here = tmp_path / "work" / "here"
    here.mkdir(parents=True)
    for folder in (tmp_path, tmp_path / "work", here):
        (folder / "keep.txt").write_text("the user's own file\n")
    (here / "cfg.toml").write_text(CONFIG)
    (here / "results").mkdir()
    (here / "results" / "notes.txt").write_text("user notes\n")
    (here / "afile").write_text("not a folder\n")
    os.symlink(here / "nowhere", here / "broken")
    os.symlink(here, here / "loop")
    return tmp_path, here


COMMANDS = {
    "run": ["run", "cfg.toml"],
    "fit": ["fit", str(DATA)],
    "geometry": ["geometry", "jersey", "--stitch-length", "11"],
}

#: (case, --out value with {here} and {root} filled in, words the error line must contain)
OUTS = [
    ("dot", ".", "current folder or one of its parents"),
    ("dot-slash", "./", "current folder or one of its parents"),
    ("dotdot", "..", "current folder or one of its parents"),
    ("dotdot-dotdot", "../..", "current folder or one of its parents"),
    ("cwd-absolute", "{here}", "current folder or one of its parents"),
    ("parent-absolute", "{root}", "current folder or one of its parents"),
    ("filesystem-root", "/", "current folder or one of its parents"),
    ("down-and-up", "results/..", "current folder or one of its parents"),
    ("link-to-cwd", "loop", "current folder or one of its parents"),
    ("a-file", "afile", "is a file"),
    ("below-a-file", "afile/out", "is a file"),
    ("non-empty", "results", "is not empty"),
    ("parent-with-user-file", "../", "current folder or one of its parents"),
    ("broken-link", "broken", "broken link"),
    ("empty-string", "", "is empty"),
    ("blank", "   ", "is empty"),
    ("not-creatable", "/proc/knitframe-out", "cannot create"),
    ("read-only-fs", "/sys/knitframe-out", "cannot create"),
]


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("case, out, words", OUTS, ids=[c[0] for c in OUTS])
def test_bad_out_is_refused_before_any_work(knit_here, home, command, case, out, words):
    """A dangerous or impossible --out is refused in one line, and no file under the root changes."""
    root, here = home
    before = snapshot(root)
    proc = knit_here(*COMMANDS[command], "--out", out.format(here=here, root=root), cwd=here)
    assert_refused(proc, "--out", before=before, folder=root)
    assert words in proc.stderr


ARGS = [
    ("unknown-option", ["run", "cfg.toml", "--out", "o", "--bogus"], "--bogus"),
    ("unknown-command", ["simulate"], "simulate"),
    ("resume-and-overwrite", ["run", "cfg.toml", "--out", "o", "--resume", "--overwrite"], "--overwrite"),
    ("config-and-example", ["run", "cfg.toml", "--example", "--out", "o"], "CONFIG"),
    ("no-config", ["run", "--out", "o"], "CONFIG"),
    ("missing-config", ["run", "nope.toml", "--out", "o"], "not found"),
    ("config-is-a-folder", ["run", "results", "--out", "o"], "not a file"),
    ("fit-without-data", ["fit", "--out", "o"], "data"),
    ("fit-without-out", ["fit", str(DATA)], "--out"),
    ("fit-data-missing", ["fit", "missing.csv", "--out", "o"], "missing.csv"),
    ("fit-data-is-a-folder", ["fit", "results", "--out", "o"], "results"),
    ("geometry-segments-not-int", ["geometry", "jersey", "--segments", "many"], "--segments"),
    (
        "geometry-stitch-length-not-number",
        ["geometry", "jersey", "--stitch-length", "eleven"],
        "--stitch-length",
    ),
    ("out-without-value", ["run", "cfg.toml", "--out"], "--out"),
]


@pytest.mark.parametrize("case, args, field", ARGS, ids=[c[0] for c in ARGS])
def test_bad_command_line_is_one_line(knit_here, home, case, args, field):
    """A malformed command line gets one line naming the argument, exit 2, and writes nothing."""
    root, here = home
    before = snapshot(root)
    proc = knit_here(*args, cwd=here)
    assert_refused(proc, field, before=before, folder=root)


def _fake_run(out: Path, *, fingerprint: str, command: str = "run") -> None:
    """The state a killed run leaves: the work folder with its run record and a checkpoint."""
    (out / ".knitframe" / "checkpoints" / "simulate").mkdir(parents=True)
    (out / ".knitframe" / "checkpoints" / "simulate" / "step-0000.npz").write_bytes(b"x")
    (out / ".knitframe" / "run.json").write_text(json.dumps({"command": command, "fingerprint": fingerprint}))


def test_unfinished_run_is_refused_without_resume_or_overwrite(knit_here, home):
    """A folder holding a killed run's checkpoints is refused unless the user says --resume or --overwrite."""
    root, here = home
    _fake_run(here / "o", fingerprint="another")
    before = snapshot(root)
    proc = knit_here("run", "cfg.toml", "--out", "o", cwd=here)
    assert_refused(proc, "--out", before=before, folder=root)
    assert "unfinished run" in proc.stderr


def test_resume_of_another_configs_run_is_refused(knit_here, home):
    """--resume into a killed run of a different config is refused and its checkpoints stay."""
    root, here = home
    _fake_run(here / "o", fingerprint="another")
    before = snapshot(root)
    proc = knit_here("run", "cfg.toml", "--out", "o", "--resume", cwd=here)
    assert_refused(proc, "--out", before=before, folder=root)
    assert "another config" in proc.stderr


def test_resume_of_a_folder_without_a_run_is_refused(knit_here, home):
    """--resume into a user's folder that holds no knitframe run is refused."""
    root, here = home
    before = snapshot(root)
    proc = knit_here("run", "cfg.toml", "--out", "results", "--resume", cwd=here)
    assert_refused(proc, "--out", before=before, folder=root)
    assert "no knitframe run to resume" in proc.stderr


def test_resume_of_a_finished_run_of_another_config_is_refused(knit_here, home):
    """--resume into a finished run made from another config is refused and its outputs stay."""
    root, here = home
    assert knit_here("run", "cfg.toml", "--out", "o", "--quiet", cwd=here).returncode == 0
    (here / "other.toml").write_text(CONFIG.replace("[data]", "[pipeline]\nname = 'other'\n\n[data]"))
    before = snapshot(root)
    proc = knit_here("run", "other.toml", "--out", "o", "--resume", cwd=here)
    assert_refused(proc, "--out", before=before, folder=root)


def test_overwrite_never_replaces_a_file_no_run_wrote(knit_here, home):
    """--overwrite into a user's folder that already has a file named like an output refuses and moves
    nothing."""
    root, here = home
    (here / "results" / "responses.csv").write_text("the user's own table\n")
    before = snapshot(root)
    proc = knit_here("run", "cfg.toml", "--out", "results", "--overwrite", cwd=here)
    assert_refused(proc, "--out", before=before, folder=root)
    assert (
        "responses.csv" in proc.stderr
        and (here / "results" / "responses.csv").read_text() == "the user's own table\n"
    )


def test_locked_folder_is_refused_at_once(knit_here, home):
    """A folder whose lock another process holds is refused in one line naming the folder."""
    root, here = home
    (here / "o" / ".knitframe").mkdir(parents=True)
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, filelock; lock = filelock.FileLock(sys.argv[1], timeout=0); "
            "lock.acquire(); print('held', flush=True); sys.stdin.read()",
            str(here / "o" / ".knitframe" / "lock"),
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "held"
        before = snapshot(root)
        proc = knit_here("run", "cfg.toml", "--out", "o", cwd=here)
        assert_refused(proc, "--out", before=before, folder=root)
        assert "another knitframe run is writing" in proc.stderr and "o:" in proc.stderr
    finally:
        holder.communicate("", timeout=30)


GOOD = [
    ("spaces", "my results/run one"),
    ("non-ascii", "résultats/ñandú-σ"),
    ("nested-new", "a/b/c/d"),
    ("existing-empty", "empty"),
    ("absolute", "{root}/elsewhere/out"),
]


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("case, out", GOOD, ids=[c[0] for c in GOOD])
def test_unusual_but_valid_out_works(knit_here, home, command, case, out):
    """Folders with spaces, non-ASCII names, new nested parents or an empty existing folder are fine."""
    root, here = home
    (here / "empty").mkdir()
    target = Path(out.format(root=root))
    proc = knit_here(*COMMANDS[command], "--out", str(target), cwd=here)
    assert proc.returncode == 0, proc.stderr
    folder = target if target.is_absolute() else here / target
    summary = json.loads((folder / "summary.json").read_text())
    assert sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file()) == sorted(
        summary["outputs"] + ["summary.json"]
    )
    assert (root / "keep.txt").exists() and (here / "keep.txt").exists()


def test_config_with_bom_crlf_spaces_and_non_ascii_path_runs(knit_here, home):
    """A config saved with a byte-order mark and CRLF line ends, at a path with spaces and accents, runs."""
    root, here = home
    folder = here / "my configs é"
    folder.mkdir()
    shutil.copy(DATA, folder / "données brutes-x.csv")
    (folder / "ma config.toml").write_bytes(
        b"\xef\xbb\xbf" + '[data]\r\nfiles = ["données brutes-x.csv"]\r\n'.encode()
    )
    proc = knit_here("run", str(folder / "ma config.toml"), "--out", "sortie é", "--quiet", cwd=here)
    assert proc.returncode == 0, proc.stderr
    assert (here / "sortie é" / "responses.csv").exists()
