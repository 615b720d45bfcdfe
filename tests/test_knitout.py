"""Machine output of a designed sleeve: every program is run through knitout-interpreter (a simulated Shima
SWG091N2) and its knit graph is checked against the knit map; what a machine cannot knit is refused in
one line."""

from __future__ import annotations

import csv
import json
import struct
import tempfile
import types
import warnings
from pathlib import Path
from typing import ClassVar

import attrs
import pytest
from hostile.conftest import assert_refused, knit_here, snapshot  # noqa: F401 (knit_here is a fixture)

import knitframe
from knitframe.garment.knitout import (
    DEFAULT_STITCH_NUMBERS,
    Band,
    KnitMap,
    MachineSpec,
    interpreter_text,
    knitout_lines,
    missing,
    plan,
)

COLUMNS = [
    "row",
    "column",
    "course_start",
    "course_end",
    "wale_start",
    "wale_end",
    "position_mm",
    "fabric",
    "pattern",
    "yarn",
    "stitch_length",
]


def write_design(folder: Path, needles: int | None, bands: list[tuple], mode: str = "knitting") -> Path:
    """A design folder by hand: the tube of design.json and a knit-map.csv with two element columns per row.

    ``bands`` holds (courses, fabric, pattern, yarn, stitch length or None[, fabric of column 1]).
    """
    folder.mkdir(parents=True, exist_ok=True)
    total = sum(b[0] for b in bands)
    (folder / "design.json").write_text(
        json.dumps({"tube": {"mode": mode, "needles": needles, "courses": total}})
    )
    with open(folder / "knit-map.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        start = 0
        for i, (n, fabric, pattern, yarn, sl, *other) in enumerate(bands):
            for j in range(2):
                name = other[0] if (other and j == 1) else fabric
                w.writerow([i, j, start, start + n, "", "", 0, name, pattern, yarn, "" if sl is None else sl])
            start += n
    return folder


def bands_of(folder: Path) -> list[tuple[int, int, str, str]]:
    """(first course, end course, pattern, yarn) of each element row of a knit-map.csv, read independently."""
    rows = {}
    with open(folder / "knit-map.csv", newline="") as fh:
        for r in csv.DictReader(fh):
            rows[int(r["row"])] = (int(r["course_start"]), int(r["course_end"]), r["pattern"], r["yarn"])
    return [rows[i] for i in sorted(rows)]


def run_program(lines: list[str]):
    """The program through knitout-interpreter's run_knitout, with full validation and no warning allowed.

    The interpreter's grammar has neither ``;;Width:`` nor ``x-`` extensions: exactly those lines become
    comments, every other line is run as written.
    """
    from knitout_interpreter.run_knitout import run_knitout

    text = interpreter_text(lines).splitlines()
    assert len(text) == len(lines)
    changed = [(a, b) for a, b in zip(lines, text) if a != b]
    assert all(a.startswith(("x-stitch-number ", ";;Width: ")) and b == "; " + a for a, b in changed)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sleeve.k"
        path.write_text("\n".join(text) + "\n")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _, machine, graph = run_knitout(str(path))
    assert not caught, [str(w.message) for w in caught]
    return machine, graph


def check_knitted(
    lines: list[str],
    needles: int | list[int],
    bands: list[tuple[int, int, str, str]],
    carriers: dict[str, int],
):
    """Cast-on, then each course of the map with one loop per needle (``needles``: of every course, or the
    stitches of each course of a shaped tube), each band in its yarn's carrier; no loop left."""
    machine, graph = run_program(lines)
    courses = graph.get_courses()
    total = bands[-1][1]
    per_course = [needles] * total if isinstance(needles, int) else list(needles)
    assert [len(c) for c in courses[: total + 1]] == per_course[:1] + per_course
    assert len(courses) > total + 1  # the bind-off follows
    for start, end, _, yarn in bands:
        made = {loop.yarn.carrier.carrier_id for c in courses[1 + start : 1 + end] for loop in c}
        assert made == {carriers[yarn]}, (start, end, yarn, made)
    assert not [n for bed in (machine.front_bed, machine.back_bed) for n in bed if n.has_loops]
    return courses[1 : total + 1]


def reverse_stitches(course, needles: int) -> list[bool]:
    """Seen from outside the tube, which stitches of a course (in knitting order, once around) are purls.

    A course knits the front layer (the first half, rounded up) from the front bed's side and then the back
    layer from the back: a plain stitch is pulled back-to-front on the front layer and front-to-back on the
    back.
    """
    from knit_graphs.Pull_Direction import Pull_Direction

    front = (needles + 1) // 2
    return [(loop.pull_direction is Pull_Direction.BtF) != (i < front) for i, loop in enumerate(course)]


def test_example_design_runs_clean_in_the_interpreter_and_matches_its_knit_map(tmp_path, knit_here):  # noqa: F811
    """The built-in example's knitout runs with no error, warning or violation: N loops in each of its courses
    after the cast-on, each band in its yarn's carrier, and the stitch number of the table before it."""
    assert knit_here("design", "--example", "--out", "sleeve", cwd=tmp_path).returncode == 0
    proc = knit_here(
        "knitout", "sleeve", "--out", "machine", "--stitch-numbers", "default=7", "--no-check", cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "machine"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outputs"] == ["sleeve-chart.png", "sleeve.k"] and summary["check"] is None
    tube = json.loads((tmp_path / "sleeve" / "design.json").read_text())["tube"]
    needles = tube.get("needles_per_course") or tube["needles"]
    bands = bands_of(tmp_path / "sleeve")
    lines = (out / "sleeve.k").read_text().splitlines()
    assert lines[:6] == [
        ";!knitout-2",
        ";;Machine: SWG091N2",
        ";;Gauge: 15",
        ";;Width: 540",
        ";;Carriers: 1 2 3 4 5 6 7 8 9 10",
        ";;Position: Center",
    ]
    assert [s for s in lines if s.startswith("x-")] == ["x-stitch-number 7"]
    knitted = check_knitted(lines, needles, bands, summary["carriers"])
    assert len(knitted) == bands[-1][1] == 199
    assert {p for *_, p, _ in bands} == {"jersey", "garter", "seed"}
    assert (out / "sleeve-chart.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_patterns_knit_their_stitches_and_each_band_its_stitch_number():
    """In a tube, jersey has no purl, rib alternates around and not up, garter up and not around, seed both;
    stitch lengths 10, 11 and 12 get x-stitch-number 4, 5 and 6 from the default table before their band."""
    N = 10
    km = KnitMap(
        N,
        [
            Band(0, 3, "j", "jersey", "a", 11),
            Band(3, 7, "r", "rib", "a", 12),
            Band(7, 11, "g", "garter", "a", 10),
            Band(11, 15, "s", "seed", "a", 11),
        ],
    )
    p = plan(km, MachineSpec())
    lines = knitout_lines(p)
    courses = check_knitted(lines, N, [(b.start, b.end, b.pattern, b.yarn) for b in km.bands], p.carriers)
    rev = [reverse_stitches(c, N) for c in courses]
    around = lambda r: all(a != b for a, b in zip(r, r[1:] + r[:1]))  # noqa: E731 - alternates once around
    assert not any(any(r) for r in rev[0:3])
    assert all(around(r) for r in rev[3:7]) and rev[3] == rev[4] == rev[5] == rev[6]
    assert [sum(r) for r in rev[7:11]] == [0, N, 0, N]
    assert all(around(r) for r in rev[11:15]) and all(
        a == [not x for x in b] for a, b in zip(rev[12:15], rev[11:14])
    )
    numbers = [int(s.split()[1]) for s in lines if s.startswith("x-stitch-number")]
    assert numbers == [DEFAULT_STITCH_NUMBERS[k] for k in ("11", "12", "10", "11")] == [5, 6, 4, 5]


def test_jersey_only_tube_from_a_config_is_checked_and_written(tmp_path):
    """A [design.machine] table makes the design stage also write sleeve.k (checked by the interpreter before
    it is written) and the chart; a one-yarn jersey tube runs clean on the carrier the table gives it."""
    from knitframe.garment.library import FabricLibrary, builtin_library

    lib = builtin_library()
    FabricLibrary("jersey-only", [lib["cotton-jersey"]], "test").save(tmp_path / "lib.json")
    config = {
        "pipeline": {"name": "design"},
        "design": {
            "limb": {"positions_mm": [0, 30], "circumferences_mm": [40, 44]},
            "ceiling_mmHg": 100,  # a finger-sized tube on 12 stitches: about 80 mmHg
            "library": str(tmp_path / "lib.json"),
            "objective": "stress_variance",
            "stations": 4,
            "around": 8,
            "min_courses": 1,
            "tube": {"mode": "knitting", "needles": 12},
            "machine": {"gauge": 14, "carriers": {"pearl-cotton": 4}},
        },
    }
    result = knitframe.run(config, out=tmp_path / "out", quiet=True)
    out = tmp_path / "out"
    assert {"sleeve.k", "sleeve-chart.png", "design.json"} <= set(result.summary["outputs"])
    check = result.results["design"]["machine"]["check"]
    bands = bands_of(out)
    assert check["stitches_per_course"] == 12 and check["courses"] == bands[-1][1] and check["warnings"] == 0
    lines = (out / "sleeve.k").read_text().splitlines()
    assert ";;Gauge: 14" in lines and "inhook 4" in lines
    courses = check_knitted(lines, 12, bands, {"pearl-cotton": 4})
    assert {p for *_, p, _ in bands} == {"jersey"} and not any(any(reverse_stitches(c, 12)) for c in courses)


def test_two_yarn_stripes_change_carrier_between_courses(tmp_path, knit_here):  # noqa: F811
    """Stripes of two yarns: each stripe is knitted by its yarn's carrier (one given, one assigned); a yarn is
    carried up inside the tube over a short stripe and cut and brought in again over a long one; a
    stitch-number table file is read."""
    design = write_design(
        tmp_path / "d",
        10,
        [
            (2, "a-j", "jersey", "a", None),
            (2, "b-j", "jersey", "b", None),
            (2, "a-j", "jersey", "a", None),
            (9, "b-j", "jersey", "b", None),
            (2, "a-j", "jersey", "a", None),
        ],
    )
    (tmp_path / "sn.toml").write_text("[stitch_numbers]\ndefault = 9\n")
    proc = knit_here(
        "knitout", design, "--out", "out", "--carriers", "b=5", "--stitch-numbers", "sn.toml", cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["carriers"] == {"a": 1, "b": 5} and summary["check"]["loops"] > 17 * 10
    lines = (tmp_path / "out" / "sleeve.k").read_text().splitlines()
    check_knitted(lines, 10, bands_of(design), summary["carriers"])
    assert [s for s in lines if s.startswith("x-")] == ["x-stitch-number 9"]
    hooks = [s for s in lines if s.split()[0] in ("inhook", "outhook")]
    assert hooks == ["inhook 1", "inhook 5", "outhook 1", "outhook 5", "inhook 1", "outhook 1"]


def test_the_check_refuses_a_program_that_does_not_knit_the_design():
    """verify() fails a program whose stripe is knitted by the wrong carrier, or that knits on an empty
    needle."""
    from knitframe.garment.knitout import MachineOutputError, verify

    km = KnitMap(
        8,
        [
            Band(0, 2, "a-j", "jersey", "a"),
            Band(2, 4, "b-j", "jersey", "b"),
            Band(4, 6, "a-j", "jersey", "a"),
        ],
    )
    p = plan(km, MachineSpec())
    lines = knitout_lines(p)
    assert verify(p, lines)["loops"] > 6 * 8
    first_b = lines.index("; band 1: b-j, carrier 2")
    swapped = (
        lines[:first_b]
        + [s.replace(" 2", " 1") if s.startswith("knit") else s for s in lines[first_b : first_b + 20]]
        + lines[first_b + 20 :]
    )
    with pytest.raises(MachineOutputError, match="band 1 .* knitted by carriers"):
        verify(p, swapped)
    knit = next(i for i, s in enumerate(lines) if s.startswith("knit - f"))
    with pytest.raises(MachineOutputError, match="knitout-interpreter"):
        verify(p, lines[:knit] + [lines[knit].replace("knit - f", "knit - b")] + lines[knit + 1 :])


def test_dat_file_carries_the_stitch_numbers_or_is_refused_in_one_line(tmp_path, knit_here):  # noqa: F811
    """With a knitout-to-dat-python that works, sleeve.dat holds each band's stitch number in its passes'
    stitch option line; where it does not work with the installed interpreter, --dat is refused in one
    line."""
    design = write_design(tmp_path / "d", 6, [(2, "a-j", "jersey", "a", 11), (4, "b-g", "garter", "b", 12)])
    before = snapshot(tmp_path)
    proc = knit_here("knitout", design, "--out", "out", "--dat", cwd=tmp_path)
    if missing(check=False, dat=True) is not None:
        assert_refused(proc, "--dat", before=before, folder=tmp_path)
        return
    assert proc.returncode == 0, proc.stderr
    data = (tmp_path / "out" / "sleeve.dat").read_bytes()
    x0, y0, x1, y1 = struct.unpack("<HHHH", data[:8])
    width = x1 - x0 + 1
    pixels = [c for i in range(0x600, len(data) - 1, 2) for c in [data[i]] * data[i + 1]]
    rows = [pixels[r * width : (r + 1) * width] for r in range(y1 - y0 + 1)]
    stitch = [
        row[width - 10 - 40 + 11] for row in rows
    ]  # right option line 6 (after 10 blank pixels, 20 lines)
    assert {5, 6} <= set(stitch) <= {0, 5, 6}


def test_unknit_patterns_are_left_out_of_the_library_when_machine_output_is_asked(tmp_path):
    """A library fabric whose pattern the machine output cannot knit is kept out of the design, with a
    warning."""
    from knitframe_patterns.jersey import Jersey

    from knitframe.errors import KnitframeWarning
    from knitframe.garment.library import FabricLibrary, builtin_library
    from knitframe.plugins import load_registry, reset_registry

    @attrs.frozen
    class Ladder(Jersey):
        name: ClassVar[str] = "ladder"
        description: ClassVar[str] = "a pattern the machine output does not knit"

    plugin = types.ModuleType("third")

    @knitframe.hookimpl
    def register_patterns(register):
        register(Ladder)

    plugin.register_patterns = register_patterns
    reset_registry(load_registry({"third": plugin}))
    lib = builtin_library()
    ladder = attrs.evolve(lib["cotton-jersey"], name="cotton-ladder", pattern="ladder", max_tension=10.0)
    FabricLibrary("with-ladder", [ladder, lib["cotton-jersey"]], "test").save(tmp_path / "lib.json")
    config = {
        "pipeline": {"name": "design"},
        "design": {
            "limb": {"positions_mm": [0, 30], "circumferences_mm": [40, 44]},
            "ceiling_mmHg": 100,  # a finger-sized tube on 12 stitches: about 80 mmHg
            "library": str(tmp_path / "lib.json"),
            "objective": "stress_variance",
            "stations": 4,
            "around": 8,
            "min_courses": 1,
            "base": "cotton-jersey",
            "tube": {"needles": 12},
            "machine": {"check": False},
        },
    }
    with pytest.warns(KnitframeWarning, match="cotton-ladder are left out of the library"):
        knitframe.run(config, out=tmp_path / "out", quiet=True)
    design = json.loads((tmp_path / "out" / "design.json").read_text())
    assert design["library"]["fabrics"] == ["cotton-jersey"]
    assert {r["pattern"] for r in design["regions"]} == {"jersey"}


TEN = [(3, "a-j", "jersey", "a", None)]
#: (case, design folder bands or None for no folder, needles, mode, extra arguments, field in the error line)
REFUSED = [
    ("paper-mode-design", TEN, None, "paper", [], "design.json"),
    ("too-narrow-machine", TEN, 10, "knitting", ["--width", "8"], "--width"),
    (
        "too-many-yarns",
        [(1, f"y{i}-j", "jersey", f"y{i}", None) for i in range(11)],
        10,
        "knitting",
        [],
        "--carriers",
    ),
    ("unknown-pattern", [(3, "a-t", "tuck", "a", None)], 10, "knitting", [], "DESIGN_DIR"),
    ("intarsia-row", [(3, "a-j", "jersey", "a", None, "b-j")], 10, "knitting", [], "DESIGN_DIR"),
    ("stitch-length-not-in-table", [(3, "a-j", "jersey", "a", 13)], 10, "knitting", [], "--stitch-numbers"),
    ("stitch-number-out-of-range", TEN, 10, "knitting", ["--stitch-numbers", "11=0"], "--stitch-numbers"),
    ("stitch-number-bad-key", TEN, 10, "knitting", ["--stitch-numbers", "tight=3"], "--stitch-numbers"),
    ("stitch-number-not-integer", TEN, 10, "knitting", ["--stitch-numbers", "11=4.5"], "--stitch-numbers"),
    (
        "stitch-number-file-missing",
        TEN,
        10,
        "knitting",
        ["--stitch-numbers", "nope.toml"],
        "--stitch-numbers",
    ),
    (
        "carrier-twice",
        TEN + [(2, "b-j", "jersey", "b", None)],
        10,
        "knitting",
        ["--carriers", "a=2,b=2"],
        "--carriers",
    ),
    ("carrier-unknown-yarn", TEN, 10, "knitting", ["--carriers", "wool=2"], "--carriers"),
    ("carrier-out-of-range", TEN, 10, "knitting", ["--carriers", "a=11"], "--carriers"),
    ("unknown-machine", TEN, 10, "knitting", ["--machine", "SWG061N2"], "--machine"),
    ("missing-design-files", None, 10, "knitting", [], "DESIGN_DIR"),
]


@pytest.mark.parametrize("case, bands, needles, mode, args, field", REFUSED, ids=[c[0] for c in REFUSED])
def test_what_the_machine_cannot_knit_is_refused_in_one_line(
    tmp_path,
    knit_here,  # noqa: F811
    case,
    bands,
    needles,
    mode,
    args,
    field,
):
    """A paper-mode design, a tube wider than the machine, more yarns than carriers, a pattern or intarsia it
    cannot knit, a bad stitch-number or carrier table, or no design files: one line, exit 2, nothing
    written."""
    if bands is None:
        (tmp_path / "d").mkdir()
        (tmp_path / "d" / "design.json").write_text("{}")
    else:
        write_design(tmp_path / "d", needles, bands, mode)
    before = snapshot(tmp_path)
    proc = knit_here("knitout", "d", "--out", "out", *args, cwd=tmp_path)
    assert_refused(proc, field, before=before, folder=tmp_path)


STAGE = {"limb": "example", "tube": {"mode": "knitting", "needles": 60}}
#: (case, [design] changes, field in the error line): refused while the config is read, before any work
STAGE_REFUSED = [
    ("paper-mode-tube", {"tube": {"mode": "paper"}, "machine": {}}, "design.tube.mode"),
    ("needles-wider-than-machine", {"machine": {"width": 50}}, "design.machine.width"),
    (
        "stitch-number-out-of-range",
        {"machine": {"stitch_numbers": {"11": 200}}},
        "design.machine.stitch_numbers.11",
    ),
    ("stitch-number-key", {"machine": {"stitch_numbers": {"loose": 7}}}, "design.machine.stitch_numbers"),
    ("carrier-for-no-yarn", {"machine": {"carriers": {"wool": 3}}}, "design.machine.carriers.wool"),
    ("unknown-machine", {"machine": {"machine": "SWG061N2"}}, "design.machine.machine"),
    ("unknown-key", {"machine": {"colour": "red"}}, "design.machine.colour"),
]


@pytest.mark.parametrize("case, changes, field", STAGE_REFUSED, ids=[c[0] for c in STAGE_REFUSED])
def test_bad_machine_table_is_refused_before_any_work(tmp_path, knit_here, case, changes, field):  # noqa: F811
    """Every [design.machine] problem the config shows is refused in one line naming its key, before any
    work."""
    import tomli_w

    table = {**STAGE, **changes, "tube": {**STAGE["tube"], **changes.get("tube", {})}}
    (tmp_path / "cfg.toml").write_text(tomli_w.dumps({"pipeline": {"name": "design"}, "design": table}))
    before = snapshot(tmp_path)
    proc = knit_here("run", "cfg.toml", "--out", "out", cwd=tmp_path)
    assert_refused(proc, field, before=before, folder=tmp_path)
