"""Hostile data files and ``knitframe fit`` arguments: refused in one line, or read with one warning line.

Refusals check, through :func:`assert_refused`, exit code 2, exactly one stderr line that names
the file (or the option) and says what is wrong, no traceback, and nothing created. Inputs that
are unusual but readable (a byte-order mark, CRLF, spaces and non-ASCII in the path, strains in
percent, forces in N with a known width) must fit, with exactly the expected warning lines.

Most cases run the CLI in this process (``knit_here``) to stay fast; a few run it as a real
subprocess (``knit``). The Singal et al. 2024 files (MIT licence, attribution in
``tests/data/singal2024/README.md``) are read from the test data and modified copies written to
the test's own folder.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from .conftest import assert_refused, snapshot

DATA = Path(__file__).resolve().parents[1] / "data" / "singal2024"
RIB_Y = DATA / "cotton-rib-y.csv"

#: a smooth course test in the generic format: 11 points to 40 % strain
GENERIC_HEADER = "strain,transverse_strain,tension_N_per_mm"
GENERIC_ROWS = [f"{e:.2f},{-0.3 * e:.4f},{0.1 * e + 0.5 * e**3:.6f}" for e in (0.04 * i for i in range(11))]
GENERIC = "# direction = course\n" + GENERIC_HEADER + "\n" + "\n".join(GENERIC_ROWS) + "\n"


def singal_lines() -> list[str]:
    """The lines of a real Singal et al. test file: two comments, the header, then the data rows."""
    return RIB_Y.read_text().splitlines()


def singal_with(cell: callable) -> str:
    """The Singal file with every data row's cells rewritten by ``cell(row_index, cells) -> cells``."""
    lines = singal_lines()
    rows = [",".join(cell(i, line.split(","))) for i, line in enumerate(lines[3:])]
    return "\n".join(lines[:3] + rows) + "\n"


def scaled(column: int, factor: float, digits: int = 6):
    """A cell rewriter multiplying one column by ``factor``."""

    def cell(_i, c):
        c = list(c)
        c[column] = f"{float(c[column]) * factor:.{digits}f}"
        return c

    return cell


def bad_row(i: int, text: str) -> str:
    """The generic file with data row ``i`` replaced by ``text``."""
    rows = list(GENERIC_ROWS)
    rows[i] = text
    return "# direction = course\n" + GENERIC_HEADER + "\n" + "\n".join(rows) + "\n"


def unloading() -> str:
    """A generic test that loads to 40 % and unloads back to 8 %."""
    back = [f"{e:.2f},{-0.3 * e:.4f},{0.05 * e:.6f}" for e in (0.32, 0.24, 0.16, 0.08)]
    return "# direction = course\n" + GENERIC_HEADER + "\n" + "\n".join(GENERIC_ROWS + back) + "\n"


def singal_unloading() -> str:
    """The Singal file with video1's loading rows appended again in reverse order (an unloading branch)."""
    lines = singal_lines()
    v1 = [ln for ln in lines[3:] if ln.startswith("video1,")]
    first_other = next(i for i, ln in enumerate(lines) if i > 3 and ln.startswith("video2,"))
    return "\n".join(lines[:first_other] + v1[::-1] + lines[first_other:]) + "\n"


def no_width_comment(text: str) -> str:
    return "\n".join(ln for ln in text.splitlines() if "width" not in ln) + "\n"


#: (id, file name, content (str or bytes, None: nothing written), words the error line must hold)
FILES = [
    ("semicolon", "semi.csv", "strain;tension_N_per_mm\n0.0;0.0\n0.1;0.05\n", ["';'", "not commas"]),
    (
        "semicolon-decimal-comma",
        "semi-dc.csv",
        "# direction = course\nstrain;tension_N_per_mm\n0,0;0,0\n0,1;0,05\n",
        ["';'", "decimal commas"],
    ),
    ("tab", "tab.csv", "strain\ttension_N_per_mm\n0.0\t0.0\n0.1\t0.05\n", ["tabs"]),
    ("pipe", "pipe.csv", "strain|tension_N_per_mm\n0.0|0.0\n0.1|0.05\n", ["'|'"]),
    (
        "decimal-comma",
        "dc.csv",
        "# direction = course\nstrain,tension_N_per_mm\n0,0,0,0\n0,1,0,05\n",
        ["line 3", "decimal commas"],
    ),
    (
        "decimal-comma-quoted",
        "dcq.csv",
        '# direction = course\nstrain,tension_N_per_mm\n"0,0","0,0"\n',
        ["column 'strain'", "decimal comma"],
    ),
    (
        "unknown-header",
        "mine.csv",
        "time_s,force,extension_mm\n0,0,0\n1,2,3\n",
        [
            "no reader knows the header (time_s, force, extension_mm)",
            "singal2024: video, frame",
            "generic: strain or stretch",
        ],
    ),
    ("one-column", "one.csv", "strain\n0.1\n0.2\n", ["no reader knows the header (strain)"]),
    ("toml-as-data", "cfg.csv", '[data]\nfiles = ["x.csv"]\n', ["no reader knows the header"]),
    ("empty", "empty.csv", "", ["empty file"]),
    ("blank-lines", "blank.csv", "\n   \n\n", ["empty file"]),
    ("comments-only", "comments.csv", "# direction = course\n# nothing else\n", ["empty file"]),
    ("header-only-generic", "hdr.csv", "# direction = course\n" + GENERIC_HEADER + "\n", ["no data rows"]),
    ("header-only-singal", "hdr-y.csv", "\n".join(singal_lines()[:3]) + "\n", ["no data rows"]),
    (
        "text-cell",
        "text.csv",
        bad_row(3, "abc,-0.036,0.01"),
        ["line 6", "column 'strain'", "expected a number"],
    ),
    (
        "text-cell-singal",
        "txt-y.csv",
        singal_with(lambda i, c: c[:4] + ["n/a"] if i == 5 else c),
        ["line 9", "column 'tension_N_per_mm'", "'n/a'"],
    ),
    (
        "empty-cell",
        "ecell.csv",
        bad_row(2, "0.08,,0.01"),
        ["column 'transverse_strain'", "the cell is empty"],
    ),
    ("nan-cell", "nan.csv", bad_row(4, "0.16,-0.048,nan"), ["column 'tension_n_per_mm'", "finite number"]),
    ("inf-cell", "inf.csv", bad_row(4, "inf,-0.048,0.02"), ["column 'strain'", "finite number"]),
    (
        "minus-inf-cell",
        "minf.csv",
        bad_row(4, "0.16,-inf,0.02"),
        ["column 'transverse_strain'", "finite number"],
    ),
    (
        "overflow-cell",
        "ovf.csv",
        bad_row(4, "0.16,-0.048,1e999"),
        ["column 'tension_n_per_mm'", "finite number"],
    ),
    ("ragged-short", "short.csv", bad_row(6, "0.24,-0.072"), ["line 9", "expected 3 cells, got 2"]),
    ("ragged-long", "long.csv", bad_row(6, "0.24,-0.072,0.03,9"), ["line 9", "expected 3 cells, got 4"]),
    ("duplicate-column", "dup.csv", "strain,strain,tension_N_per_mm\n0,0,0\n", ["column 'strain'", "twice"]),
    (
        "duplicate-column-case",
        "dupc.csv",
        "Strain,tension_N_per_mm,strain\n0,0,0\n",
        ["column 'strain'", "twice"],
    ),
    ("binary-garbage", "garbage.csv", bytes(range(256)) * 8, ["binary file"]),
    ("png-renamed", "plot.csv", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(64), ["binary file"]),
    ("xlsx-renamed", "sheet.csv", b"PK\x03\x04\x14\x00\x06\x00\x08\x00" + bytes(40), ["binary file"]),
    ("utf16", "u16.csv", GENERIC.encode("utf-16"), ["UTF-16"]),
    (
        "latin1",
        "latin.csv",
        ("# direction = course\n# température 23 °C\n" + GENERIC_HEADER + "\n0,0,0\n").encode("latin-1"),
        ["not UTF-8", "line 2"],
    ),
    ("directory", "folder.csv", None, ["is a directory"]),
    ("missing", "nope.csv", None, ["file not found"]),
    (
        "negative-stretch",
        "neg.csv",
        "# direction = wale\nstretch,tension_N_per_mm\n1.0,0\n1.1,0.1\n-0.2,0.2\n",
        ["line 5", "column 'stretch'", "non-positive stretch"],
    ),
    (
        "zero-stretch",
        "zero.csv",
        "# direction = wale\nstretch,tension_N_per_mm\n1.0,0\n0,0.1\n",
        ["line 4", "non-positive stretch"],
    ),
    ("strain-below-minus-one", "m1.csv", bad_row(1, "-1.5,0.0,0.01"), ["line 4", "non-positive stretch"]),
    (
        "singal-strain-below-minus-one",
        "m1-y.csv",
        singal_with(lambda i, c: [c[0], c[1], "-2.0"] + c[3:] if i == 7 else c),
        ["line 11", "column 'strain_axial'", "non-positive stretch"],
    ),
    ("unloading-branch", "unload.csv", unloading(), ["line 14", "unloading branch"]),
    (
        "singal-unloading-branch",
        "unload-y.csv",
        singal_unloading(),
        ["column 'strain_axial'", "unloading branch"],
    ),
    (
        "newtons-generic",
        "newtons.csv",
        "# direction = course\nstrain,tension_N_per_mm\n0,0\n0.2,12.5\n0.4,31.0\n",
        ["column 'tension_n_per_mm'", "force in N", "width_mm"],
    ),
    (
        "newtons-singal-no-width",
        "newtons-y.csv",
        no_width_comment(singal_with(scaled(4, 90.52, 4))),
        ["column 'tension_N_per_mm'", "force in N", "width at clamp"],
    ),
    (
        "force-without-width",
        "force.csv",
        "# direction = course\nstrain,force_N\n0,0\n0.2,3\n",
        ["column 'force_n'", "needs the specimen width"],
    ),
    (
        "negative-width",
        "wneg.csv",
        "# direction = course\n# width_mm = -25\nstrain,force_N\n0,0\n0.2,3\n",
        ["'# width_mm' must be a number > 0"],
    ),
    (
        "zero-width-column",
        "wcol.csv",
        "# direction = course\nstrain,force_N,width_mm\n0,0,25\n0.2,3,0\n",
        ["line 4", "column 'width_mm'", "width must be > 0"],
    ),
    (
        "stress-without-thickness",
        "mpa.csv",
        "# direction = course\nstrain,stress_MPa\n0,0\n0.2,0.3\n",
        ["needs a thickness"],
    ),
    (
        "thickness-not-a-number",
        "thick.csv",
        "# direction = course\n# thickness_mm = thin\nstrain,stress_MPa\n0,0\n0.2,0.3\n",
        ["'# thickness_mm' must be a number > 0"],
    ),
    (
        "strain-and-stretch",
        "both.csv",
        "# direction = course\nstrain,stretch,tension_N_per_mm\n0,1,0\n0.1,1.1,0.1\n",
        ["only one of the columns strain, stretch"],
    ),
    (
        "unknown-direction",
        "bias.csv",
        "direction,strain,tension_N_per_mm\ncourse,0,0\nbias,0.1,0.1\n",
        ["line 3", "column 'direction'", "course or wale"],
    ),
    (
        "no-direction",
        "nodir.csv",
        GENERIC_HEADER + "\n" + "\n".join(GENERIC_ROWS) + "\n",
        ["cannot tell the direction"],
    ),
    (
        "zero-tension",
        "zeroT.csv",
        "# direction = course\nstrain,tension_N_per_mm\n0,0\n0.1,0\n0.2,0\n",
        ["column 'tension_n_per_mm'", "zero on every row"],
    ),
    (
        "negative-tension",
        "negT.csv",
        "# direction = course\nstrain,tension_N_per_mm\n0,0\n0.1,-0.1\n0.2,-0.3\n",
        ["negative on every row"],
    ),
    (
        "zero-tension-one-direction",
        "zeroW.csv",
        "direction,strain,tension_N_per_mm\ncourse,0,0\ncourse,0.2,0.1\nwale,0,0\nwale,0.2,0\n",
        ["zero on every row of the wale rows"],
    ),
    (
        "transverse-in-percent-only",
        "mixed.csv",
        "# direction = course\n" + GENERIC_HEADER + "\n0,0,0\n0.2,-12,0.05\n0.4,-25,0.2\n",
        ["line 5", "column 'transverse_strain'", "same unit"],
    ),
    (
        "singal-no-direction",
        "cotton-rib.csv",
        "\n".join(singal_lines()[2:]) + "\n",
        ["-x (course) or -y (wale)"],
    ),
    (
        "repeats-without-overlap",
        "apart.csv",
        "# direction = course\nsample,strain,tension_N_per_mm\n1,0,0\n1,0.1,0.1\n2,0.2,0.2\n2,0.3,0.3\n",
        ["share no strain range"],
    ),
]


def make(tmp_path: Path, name: str, content) -> Path:
    """Write one data file (or make a directory for ``folder.csv``) in ``tmp_path/in``."""
    folder = tmp_path / "in"
    folder.mkdir(exist_ok=True)
    p = folder / name
    if name == "folder.csv":
        p.mkdir()
    elif isinstance(content, bytes):
        p.write_bytes(content)
    elif content is not None:
        p.write_text(content, encoding="utf-8")
    return p


@pytest.mark.parametrize("case, name, content, words", FILES, ids=[f[0] for f in FILES])
def test_bad_data_file_is_refused(knit_here, tmp_path, case, name, content, words):
    """A malformed or mis-unit data file stops `knitframe fit` with one line naming the file and the
    problem."""
    path = make(tmp_path, name, content)
    before = snapshot(tmp_path)
    proc = knit_here("fit", path, "--out", tmp_path / "out", cwd=tmp_path)
    assert_refused(proc, name, before=before, folder=tmp_path)
    for w in words:
        assert w in proc.stderr, (w, proc.stderr)


#: (id, extra arguments, data: "singal" | "generic" | "both", words the error line must hold)
ARGS = [
    (
        "unknown-reader",
        ["--reader", "excel"],
        "singal",
        ["--reader", "unknown reader 'excel'", "auto, generic, singal2024"],
    ),
    ("unknown-model", ["--model", "neo-hooke"], "singal", ["--model", "unknown homogenizer 'neo-hooke'"]),
    ("unknown-fitter", ["--fitter", "adam"], "singal", ["--fitter", "unknown fitter 'adam'"]),
    (
        "generic-reader-on-singal-file",
        ["--reader", "generic"],
        "singal",
        ["cotton-rib-y.csv", "missing column for the loaded strain", "strain_axial"],
    ),
    (
        "singal-reader-on-generic-file",
        ["--reader", "singal2024"],
        "generic",
        ["g.csv", "missing column 'video'"],
    ),
    ("good-then-bad-file", [], "both", ["bad.csv", "line 3", "finite number"]),
]


@pytest.mark.parametrize("case, extra, data, words", ARGS, ids=[a[0] for a in ARGS])
def test_bad_fit_arguments_are_refused(knit_here, tmp_path, case, extra, data, words):
    """Unknown plugins, the wrong reader and a bad file after a good one are one line, with nothing
    created."""
    files = {
        "singal": [RIB_Y],
        "generic": [make(tmp_path, "g.csv", GENERIC)],
        "both": [RIB_Y, make(tmp_path, "bad.csv", bad_row(0, "nan,0,0"))],
    }[data]
    before = snapshot(tmp_path)
    proc = knit_here("fit", *files, *extra, "--out", tmp_path / "out", cwd=tmp_path)
    assert_refused(proc, words[0], before=before, folder=tmp_path)
    for w in words[1:]:
        assert w in proc.stderr, (w, proc.stderr)


#: cases run as a real subprocess as well: the same single line from the installed command
SUBPROCESS = ["semicolon-decimal-comma", "unknown-header", "binary-garbage", "missing", "newtons-generic"]


@pytest.mark.parametrize("case", SUBPROCESS)
def test_refusal_in_a_subprocess(knit, tmp_path, case):
    """The real `knitframe` process refuses the same files with one line, exit 2 and nothing created."""
    _, name, content, words = next(f for f in FILES if f[0] == case)
    path = make(tmp_path, name, content)
    before = snapshot(tmp_path)
    proc = knit("fit", path, "--out", tmp_path / "out")
    assert_refused(proc, name, before=before, folder=tmp_path)
    assert all(w in proc.stderr for w in words), proc.stderr


def strict_json(path: Path) -> dict:
    """params.json parsed with NaN and Infinity refused."""

    def refuse(name):
        raise AssertionError(f"{path.name} holds {name}")

    return json.loads(path.read_text(encoding="utf-8"), parse_constant=refuse)


def percent_singal() -> str:
    """The Singal file with both strain columns in percent."""
    return singal_with(
        lambda i, c: [c[0], c[1], f"{float(c[2]) * 100:.3f}", f"{float(c[3]) * 100:.3f}", c[4]]
    )


#: (id, relative path, content, extra arguments, words of each expected warning line (empty: no warning))
READABLE = [
    ("utf8-bom", "bom-y.csv", "\ufeff" + RIB_Y.read_text(), [], []),
    ("crlf", "crlf-y.csv", RIB_Y.read_text().replace("\n", "\r\n"), [], []),
    ("spaces-in-path", "my tests/cotton rib-y.csv", RIB_Y.read_text(), [], []),
    ("non-ascii-path", "données/tricot côte-y.csv", RIB_Y.read_text(), [], []),
    (
        "percent-strain",
        "pct-y.csv",
        percent_singal(),
        [],
        [
            [
                "pct-y.csv",
                "column 'strain_axial'",
                "percent",
                "divided 'strain_axial', 'strain_transverse' by 100",
            ]
        ],
    ),
    (
        "newtons-with-clamp-width",
        "n-y.csv",
        singal_with(scaled(4, 90.52, 4)),
        [],
        [["n-y.csv", "column 'tension_N_per_mm'", "force in N", "90.52 mm"]],
    ),
    (
        "newtons-with-width-line",
        "nw.csv",
        "# direction = course\n# width_mm = 150\n"
        + GENERIC_HEADER
        + "\n"
        + "\n".join(
            f"{e:.2f},{-0.3 * e:.4f},{150 * (0.2 * e + 2 * e**3):.5f}" for e in (0.04 * i for i in range(11))
        )
        + "\n",
        [],
        [["nw.csv", "force in N", "150 mm"]],
    ),
    (
        "force-column-with-width",
        "f.csv",
        "# direction = course\n# width_mm = 50\nstrain,force_N\n"
        + "\n".join(f"{e:.2f},{50 * (0.1 * e + 0.5 * e**3):.5f}" for e in (0.04 * i for i in range(11)))
        + "\n",
        [],
        [],
    ),
    (
        "percent-stretch",
        "ps.csv",
        "# direction = wale\nstretch,tension_N_per_mm\n"
        + "\n".join(f"{100 + 4 * i},{0.1 * 0.04 * i + 0.5 * (0.04 * i) ** 3:.6f}" for i in range(11))
        + "\n",
        [],
        [["ps.csv", "column 'stretch'", "percent, not stretch"]],
    ),
    (
        "whitespace-and-trailing-blank-lines",
        "ws.csv",
        "# direction = course\n strain , tension_N_per_mm \n"
        + "\n".join(f" {e:.2f} , {0.1 * e + 0.5 * e**3:.6f} " for e in (0.04 * i for i in range(11)))
        + "\n\n\n",
        [],
        [],
    ),
]


@pytest.mark.parametrize("case, rel, content, extra, expected", READABLE, ids=[r[0] for r in READABLE])
def test_unusual_but_readable_file_fits(knit_here, tmp_path, case, rel, content, extra, expected):
    """Unusual but readable files fit, writing strict JSON, with exactly one warning line per unit
    conversion."""
    path = tmp_path / rel
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(content, encoding="utf-8", newline="")
    proc = knit_here("fit", path, *extra, "--out", tmp_path / "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == len(expected), lines
    for line, words in zip(lines, expected):
        assert line.startswith("knitframe: warning: ") and all(w in line for w in words), (line, words)
    params = strict_json(tmp_path / "out" / "params.json")
    assert params["nrmse"]["overall"] < 0.15 and params["at_bound"] == []
    assert len(params["warnings"]) == len(expected)  # the conversions are recorded with the fit


def test_percent_strain_fits_like_the_original(knit_here, tmp_path):
    """Strains in percent, once divided by 100, give the parameters of the original file to 1e-6."""
    pct = tmp_path / "pct-y.csv"
    pct.write_text(percent_singal())
    assert knit_here("fit", RIB_Y, "--out", tmp_path / "a", cwd=tmp_path).returncode == 0
    assert knit_here("fit", pct, "--out", tmp_path / "b", cwd=tmp_path).returncode == 0
    a, b = strict_json(tmp_path / "a" / "params.json"), strict_json(tmp_path / "b" / "params.json")
    for key in ("a", "b", "theta_deg"):
        assert math.isclose(a[key], b[key], rel_tol=1e-6), (key, a[key], b[key])


def test_percent_file_in_a_subprocess(knit, tmp_path):
    """The real process converts a percent file with exactly one warning line and exits 0."""
    pct = tmp_path / "pct-y.csv"
    pct.write_text(percent_singal())
    proc = knit("fit", pct, "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("knitframe: warning: ") and "pct-y.csv" in lines[0], lines
    assert "reads as percent" in lines[0] and "divided 'strain_axial', 'strain_transverse' by 100" in lines[0]
