"""The hostile-input suite: bad input of every kind gets one line, exit code 2, and leaves nothing.

Every case checks the same four things through :func:`assert_refused`: the exit code, exactly one
line on stderr that names the field, no traceback, and no output left behind.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest


def snapshot(folder: Path) -> set[str]:
    """Every path below ``folder`` (relative, with a trailing / for folders), to compare before and after."""
    return {str(p.relative_to(folder)) + ("/" if p.is_dir() else "") for p in folder.rglob("*")}


def assert_refused(
    proc: subprocess.CompletedProcess,
    field: str,
    *,
    code: int = 2,
    before: set[str] | None = None,
    folder: Path | None = None,
) -> None:
    """One line on stderr naming ``field``, exit ``code``, no traceback, and (when given) ``folder``
    unchanged."""
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == code, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout, proc.stderr
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("knitframe: error: "), lines[0]
    assert field in lines[0], (field, lines[0])
    if before is not None:
        assert snapshot(folder) == before, sorted(snapshot(folder) ^ before)


@pytest.fixture
def knit(tmp_path):
    """Run the ``knitframe`` CLI in a subprocess in ``tmp_path`` (or ``cwd``); returns CompletedProcess."""

    def run(
        *args: str,
        cwd: Path | None = None,
        env: dict | None = None,
        timeout: float = 300,
        stdin: str | None = None,
    ) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "knitframe", *map(str, args)],
            capture_output=True,
            text=True,
            cwd=cwd or tmp_path,
            env={**os.environ, **(env or {})},
            timeout=timeout,
            input=stdin,
        )

    return run


@pytest.fixture
def knit_here(capsys, monkeypatch):
    """Run the CLI in this process (fast), in folder ``cwd``; returns a CompletedProcess-like result.

    An uncaught exception (a traceback for the user) fails the test by propagating.
    """

    def run(*args: str, cwd: Path) -> subprocess.CompletedProcess:
        from knitframe.cli import main
        from knitframe.plugins import reset_registry

        monkeypatch.chdir(cwd)
        reset_registry()
        capsys.readouterr()
        try:
            code = main([str(a) for a in args])
        except SystemExit as e:  # argparse
            code = e.code
        out, err = capsys.readouterr()
        return subprocess.CompletedProcess(list(args), code, out, err)

    return run
