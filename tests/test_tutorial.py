"""The pattern-plugin tutorial end to end: its package installs, passes the kit, builds a tuck cell and
matches the docs."""

from __future__ import annotations

import importlib
import json
import os
import re
import subprocess
import sys

import pytest
from conftest import DIST, DIST_VERSION, EXTERNAL, PLUGIN_DIR, ROOT

from knitframe import Fabric, GeometryError, get_registry

#: these tests share the example plugin that conftest's installed_plugin pip-installs for a worker's session
#: and uninstalls at its end: one worker runs them all (--dist loadgroup), so no other worker removes the
#: package under them
pytestmark = pytest.mark.xdist_group("installed_plugin")

TUTORIAL = ROOT / "docs" / "tutorial-pattern-plugin.md"
#: a fenced block that names its file: ```python title="knitframe_example/tuck.py"
BLOCK = re.compile(r'^```(\w+) title="([^"]+)"\n(.*?)^```$', re.S | re.M)


@pytest.fixture(scope="module")
def tuck(installed_plugin):
    """The installed ``knitframe_example.tuck`` module."""
    importlib.invalidate_caches()
    return importlib.import_module("knitframe_example.tuck")


def test_tuck_is_listed_with_its_package(installed_plugin, cli):
    """`knitframe plugins` lists the tutorial's pattern with the example package's name and version."""
    proc = cli("plugins", env=EXTERNAL)
    assert proc.returncode == 0, proc.stderr
    line = next(l for l in proc.stdout.splitlines() if l.strip().startswith("tuck "))
    assert f"[{DIST} {DIST_VERSION}]" in line


def test_tuck_passes_the_conformance_kit(installed_plugin):
    """check_plugin("pattern", "tuck") accepts the installed pattern, as the tutorial runs it."""
    code = "from knitframe.testing import check_plugin; check_plugin('pattern', 'tuck'); print('ok')"
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env={**os.environ, **EXTERNAL}
    )
    assert proc.stdout.strip() == "ok", proc.stderr


def test_geometry_command_builds_the_tuck_cell(installed_plugin, cli, tmp_path):
    """`knitframe geometry tuck --stitch-length 11 --yarn cotton` writes the files and a geometry.json at 4.7
    mm/stitch."""
    proc = cli("geometry", "tuck", "--stitch-length", "11", "--yarn", "cotton", "--out", "geo", env=EXTERNAL)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "geo"
    for name in ("centerlines.vtu", "tubes.vtu", "preview.png"):
        assert (out / name).stat().st_size > 0, name
    info = json.loads((out / "geometry.json").read_text())
    assert info["pattern"] == "tuck"
    assert info["arc_length_per_stitch"] == pytest.approx(4.7, rel=1e-9)
    assert sum(info["yarn_lengths"]) / 4 == pytest.approx(4.7, rel=1e-9)
    assert info["shape"]["stitches"] == [["knit", "tuck"], ["tuck", "knit"]]
    assert info["course_pitch"] == pytest.approx(4.7 / 3.6) and info["wale_pitch"] == pytest.approx(4.7 / 8.5)
    # the overlap is left to the pre-stress step, but the defaults keep it near half a diameter
    assert 0.3 < info["clearance"]["minimum_over_dk"] < 1.0


def test_impossible_tuck_request_is_one_line_error(installed_plugin, cli):
    """An arc length too short for the pitches ends the geometry command with one line naming the problem."""
    proc = cli("geometry", "tuck", "--arc-length", "1.5", "--yarn", "cotton", "--out", "geo", env=EXTERNAL)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "too short" in proc.stderr, proc.stderr


@pytest.mark.parametrize("sl, arc", [(10, 3.9), (11, 4.7), (12, 5.9)])
def test_tuck_cell_is_a_periodic_cross_tuck(tuck, sl, arc):
    """At SL10-12 the cell hits the arc length, is periodic to 1e-9 and every loop links as a cross tuck
    should."""
    from knitframe.testing.patterns import check_periodicity

    cell = tuck.Tuck().cell(Fabric(pattern="tuck", yarn=get_registry()["yarn"]["cotton"], stitch_length=sl))
    assert sum(y.arc_length() for y in cell.yarns) / 4 == pytest.approx(arc, rel=1e-9)
    check_periodicity(cell, tol=1e-9)
    links = tuck.links(cell)
    for row, knit_col in ((0, 0), (1, 1)):
        assert cell.info["stitches"][row][knit_col] == "knit"
        # a knit loop enters the tuck loop below and the loop held on its needle from behind, leaves in front
        assert links[(row, "knit", "course below")] == "-++-"
        assert links[(row, "knit", "two courses below")] == "-++-"
        # a tuck loop is drawn through nothing: it lies behind the held loop and meets nothing two
        # courses down
        assert links[(row, "tuck", "course below")] == "--"
        assert links[(row, "tuck", "two courses below")] == ""


def test_tuck_rejects_a_structure_that_does_not_interlock(tuck):
    """A wale pitch so large that a knit loop no longer reaches through the tuck loop below raises
    GeometryError."""
    fabric = Fabric(pattern="tuck", yarn=get_registry()["yarn"]["cotton"], arc_length=4.7, wale_pitch=1.0)
    with pytest.raises(GeometryError, match="knit stitch of course 0 crosses the course below as ''"):
        tuck.Tuck().cell(fabric)


def test_rod_config_simulates_the_tuck_cell(installed_plugin, cli, tmp_path):
    """The tutorial's config (`[fabric] pattern = "tuck"`, rod solver) runs to 30 % equibiaxial stretch and
    credits the package."""
    proc = cli("run", str(PLUGIN_DIR / "examples" / "rod-tuck.toml"), "--out", "o", env=EXTERNAL)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["plugins"]["pattern:tuck"] == {"package": DIST, "version": DIST_VERSION}
    assert summary["results"]["simulate"]["converged"] is True
    lines = (tmp_path / "o" / "simulated.csv").read_text().splitlines()
    rows = [dict(zip(lines[0].split(","), line.split(","))) for line in lines[1:]]
    assert len(rows) == 10 and float(rows[-1]["lambda1"]) == pytest.approx(1.3)
    assert all(float(r["T1_N_per_mm"]) > 0 and float(r["T2_N_per_mm"]) > 0 for r in rows)


def _code_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip()]


def test_tutorial_code_is_the_shipped_code():
    """The tutorial's code blocks that name a file, joined in order, are that file line for line (blank lines
    aside)."""
    blocks: dict[str, str] = {}
    for _, path, body in BLOCK.findall(TUTORIAL.read_text(encoding="utf-8")):
        blocks[path] = blocks.get(path, "") + body
    assert sorted(blocks) == ["examples/rod-tuck.toml", "knitframe_example/tuck.py", "pyproject.toml"]
    for path, text in blocks.items():
        assert _code_lines(text) == _code_lines((PLUGIN_DIR / path).read_text(encoding="utf-8")), (
            f"tutorial differs from {path}"
        )
