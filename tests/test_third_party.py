"""A real third-party plugin package, pip-installed, shows up and works from a config."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from conftest import DIST, DIST_VERSION, EXTERNAL

#: these tests share the example plugin that conftest's installed_plugin pip-installs for a worker's session
#: and uninstalls at its end: one worker runs them all (--dist loadgroup), so no other worker removes the
#: package under them
pytestmark = pytest.mark.xdist_group("installed_plugin")


def test_installed_plugin_is_listed_with_its_package(installed_plugin, cli):
    """`knitframe plugins` lists the third-party reader with its own package name."""
    proc = cli("plugins", env=EXTERNAL)
    assert proc.returncode == 0, proc.stderr
    line = next(l for l in proc.stdout.splitlines() if l.strip().startswith("force-extension"))
    assert f"[{DIST} {DIST_VERSION}]" in line


def test_installed_plugin_is_hidden_when_external_plugins_are_blocked(installed_plugin, cli):
    """With external plugins blocked the third-party reader is absent."""
    proc = cli("plugins", env={"KNITFRAME_DISABLE_EXTERNAL_PLUGINS": "1"})
    assert "force-extension" not in proc.stdout


def test_installed_plugin_runs_from_a_config(installed_plugin, cli, tmp_path):
    """A config selects the third-party reader by name with options; the pipeline uses it."""
    ext = np.linspace(0.0, 10.0, 11)
    rows = "\n".join(f"{e:.3f},{0.2 * e + 0.01 * e**2:.5f}" for e in ext)
    (tmp_path / "pull.csv").write_text("extension_mm,force_N\n" + rows + "\n")
    (tmp_path / "c.toml").write_text(
        '[data]\nreader = { kind = "force-extension", gauge_length = 50.0, width = 40.0, '
        'direction = "wale" }\n'
        'files = ["pull.csv"]\n'
    )
    proc = cli("run", "c.toml", "--out", "o", env=EXTERNAL)
    assert proc.returncode == 0, proc.stderr
    lines = (tmp_path / "o" / "responses.csv").read_text().splitlines()
    head = lines[0].split(",")
    last = dict(zip(head, lines[-1].split(",")))
    assert last["load"] == "uniaxial-wale"
    assert float(last["lambda2"]) == pytest.approx(1.2)
    assert float(last["T2_N_per_mm"]) == pytest.approx((0.2 * 10 + 0.01 * 100) / 40.0)
    summary = (tmp_path / "o" / "summary.json").read_text()
    assert '"reader:force-extension"' in summary and DIST in summary


def test_installed_plugin_passes_the_conformance_kit(installed_plugin):
    """The conformance kit accepts the third-party reader."""
    code = (
        "from knitframe.testing import check_plugin; check_plugin('reader', 'force-extension'); print('ok')"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env={**__import__("os").environ, **EXTERNAL},
    )
    assert proc.stdout.strip() == "ok", proc.stderr
