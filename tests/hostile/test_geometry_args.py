"""Hostile ``knitframe geometry`` arguments: geometry requests that cannot be met are refused before any
output.

Each case runs ``knitframe geometry PATTERN ... --out geo`` in a fresh folder (in this process, a few
as real subprocesses) and checks exit code 2, one stderr line naming the option, no traceback, and
that the folder is unchanged: no ``geo``, no half-written VTU.
"""

from __future__ import annotations

import pytest

from .conftest import assert_refused, snapshot

SL = ("--stitch-length", "11")

#: (case, arguments after ``geometry``, the option the error line must name)
CASES: list[tuple[str, tuple[str, ...], str]] = [
    ("arc-length-1e9", ("jersey", "--arc-length", "1e9"), "--arc-length"),
    ("arc-length-1e300", ("jersey", "--arc-length", "1e300"), "--arc-length"),
    ("arc-length-0.01", ("jersey", "--arc-length", "0.01"), "--arc-length"),
    ("arc-length-1e-300", ("jersey", "--arc-length", "1e-300"), "--arc-length"),
    ("arc-length-too-short-to-interlock", ("jersey", "--arc-length", "1.5"), "--arc-length"),
    ("arc-length-zero", ("jersey", "--arc-length", "0"), "--arc-length"),
    ("arc-length-negative", ("jersey", "--arc-length", "-1"), "--arc-length"),
    ("arc-length-nan", ("jersey", "--arc-length", "nan"), "--arc-length"),
    ("arc-length-inf", ("jersey", "--arc-length", "inf"), "--arc-length"),
    ("arc-length-a-word", ("jersey", "--arc-length", "long"), "--arc-length"),
    ("arc-length-rib-1e9", ("rib", "--arc-length", "1e9"), "--arc-length"),
    ("arc-length-seed-tiny", ("seed", "--arc-length", "0.5"), "--arc-length"),
    ("arc-length-garter-huge-for-pet", ("garter", "--arc-length", "50", "--yarn", "pet"), "--arc-length"),
    ("stitch-length-1e9", ("jersey", "--stitch-length", "1e9"), "--stitch-length"),
    ("stitch-length-13", ("jersey", "--stitch-length", "13"), "--stitch-length"),
    ("stitch-length-negative", ("jersey", "--stitch-length", "-11"), "--stitch-length"),
    ("stitch-length-nan", ("jersey", "--stitch-length", "nan"), "--stitch-length"),
    ("no-length-given", ("jersey",), "--stitch-length"),
    ("course-pitch-1e-9", ("jersey", *SL, "--course-pitch", "1e-9"), "--course-pitch"),
    ("course-pitch-zero", ("jersey", *SL, "--course-pitch", "0"), "--course-pitch"),
    ("course-pitch-100", ("jersey", *SL, "--course-pitch", "100"), "--course-pitch"),
    ("course-pitch-inf", ("jersey", *SL, "--course-pitch", "inf"), "--course-pitch"),
    ("wale-pitch-zero", ("jersey", *SL, "--wale-pitch", "0"), "--wale-pitch"),
    ("wale-pitch-negative", ("jersey", *SL, "--wale-pitch", "-1"), "--wale-pitch"),
    ("wale-pitch-nan", ("jersey", *SL, "--wale-pitch", "nan"), "--wale-pitch"),
    ("wale-pitch-inf", ("jersey", *SL, "--wale-pitch", "inf"), "--wale-pitch"),
    ("wale-pitch-1e-9", ("jersey", *SL, "--wale-pitch", "1e-9"), "--wale-pitch"),
    ("wale-pitch-100", ("jersey", *SL, "--wale-pitch", "100"), "--wale-pitch"),
    ("wale-pitch-loops-do-not-reach", ("jersey", "--arc-length", "4", "--wale-pitch", "1.9"), "--wale-pitch"),
    ("both-pitches-tiny", ("rib", *SL, "--course-pitch", "1e-6", "--wale-pitch", "1e-6"), "--course-pitch"),
    ("yarn-unknown", ("jersey", *SL, "--yarn", "wool"), "--yarn"),
    ("pattern-unknown", ("jersy", *SL), "PATTERN"),
    ("segments-too-few", ("jersey", *SL, "--segments", "2"), "--segments"),
    ("segments-1e8", ("jersey", *SL, "--segments", "100000000"), "--segments"),
    ("segments-negative", ("jersey", *SL, "--segments", "-256"), "--segments"),
]


@pytest.mark.parametrize("case, args, option", CASES, ids=[c[0] for c in CASES])
def test_impossible_geometry_request_is_refused_before_any_output(tmp_path, knit_here, case, args, option):
    """An impossible geometry request exits 2 with one line naming its option, and writes nothing."""
    before = snapshot(tmp_path)
    proc = knit_here("geometry", *args, "--out", tmp_path / "geo", cwd=tmp_path)
    assert_refused(proc, option, before=before, folder=tmp_path)
    assert "fabric." not in proc.stderr, proc.stderr  # config paths are named as the command's options


def test_the_cases_are_distinct():
    """Every case has its own name and its own arguments."""
    assert len({c[0] for c in CASES}) == len({c[1] for c in CASES}) == len(CASES)


@pytest.mark.parametrize("case", ["arc-length-1e9", "arc-length-0.01", "course-pitch-1e-9"])
def test_impossible_geometry_request_in_a_real_process(tmp_path, knit, case):
    """In a real process the request that once tried to allocate 336 GiB, and its kin, end in one line and
    exit 2."""
    _, args, option = next(c for c in CASES if c[0] == case)
    before = snapshot(tmp_path)
    proc = knit("geometry", *args, "--out", "geo", cwd=tmp_path, timeout=60)
    assert_refused(proc, option, before=before, folder=tmp_path)


def test_a_feasible_request_still_writes_its_files(tmp_path, knit_here):
    """The limits leave real fabrics alone: a loose pet garter at 20 mm per stitch (112 dk) is built and
    written."""
    proc = knit_here(
        "geometry", "garter", "--arc-length", "20", "--yarn", "pet", "--out", tmp_path / "geo", cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "geo" / "geometry.json").is_file()
