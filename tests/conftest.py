"""Shared fixtures. External plugins are blocked unless a test opts in, so runs are hermetic."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

os.environ.setdefault("KNITFRAME_DISABLE_EXTERNAL_PLUGINS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

ROOT = Path(__file__).resolve().parents[1]
#: copies of real Singal et al. 2024 test files (attribution in the folder's README)
TEST_DATA = ROOT / "tests" / "data" / "singal2024"
EXAMPLE_DATA = ROOT / "knitframe" / "examples" / "data"
#: the example third-party plugin package shipped with the docs, its distribution name and version
PLUGIN_DIR = ROOT / "docs" / "example-plugin"
DIST = "knitframe-example-plugin"
DIST_VERSION = tomllib.loads((PLUGIN_DIR / "pyproject.toml").read_text())["project"]["version"]
#: environment that lets a subprocess load external (third-party) plugins
EXTERNAL = {"KNITFRAME_DISABLE_EXTERNAL_PLUGINS": "0"}


@pytest.fixture(autouse=True)
def _fresh_registry():
    """Each test sees a registry loaded from the entry points as they are now."""
    from knitframe.plugins import reset_registry

    reset_registry()
    yield
    reset_registry()


@pytest.fixture
def cli(tmp_path):
    """Run the ``knitframe`` CLI in a subprocess; returns CompletedProcess with text output."""

    def run(*args: str, env: dict | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess:
        full_env = {**os.environ, **(env or {})}
        return subprocess.run(
            [sys.executable, "-m", "knitframe", *args],
            capture_output=True,
            text=True,
            cwd=cwd or tmp_path,
            env=full_env,
            timeout=600,
        )

    return run


def _pip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", *args],
        capture_output=True,
        text=True,
        timeout=600,
    )


@pytest.fixture(scope="session")
def installed_plugin():
    """pip-install the example third-party plugin package for the session's tests, then uninstall it."""
    proc = _pip("install", "--no-deps", "--no-build-isolation", str(PLUGIN_DIR))
    assert proc.returncode == 0, proc.stderr
    yield
    _pip("uninstall", "-y", DIST)


@pytest.fixture(scope="session")
def example_run(tmp_path_factory):
    """The built-in example run once through the Python API for the session: (PipelineResult, output
    folder)."""
    import knitframe

    out = tmp_path_factory.mktemp("example") / "ex"
    return knitframe.run(knitframe.example_config(), out), out


@pytest.fixture
def singal_file():
    """Path of a real Singal et al. 2024 test file: the tests' copy, else the package's example copy."""

    def get(name: str) -> Path:
        p = TEST_DATA / name
        return p if p.exists() else EXAMPLE_DATA / name

    return get
