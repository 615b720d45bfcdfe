"""Bad input gives one line naming the TOML path and the problem, exit code 2, no partial output."""

from __future__ import annotations

import pytest

GOOD_FILE = "cotton-stockinette-x.csv"


def _config(tmp_path, singal_file, body: str):
    (tmp_path / GOOD_FILE).write_bytes(singal_file(GOOD_FILE).read_bytes())
    cfg = tmp_path / "bad.toml"
    cfg.write_text(body)
    return cfg


CASES = [
    (
        "unknown key",
        f'[data]\nfilez = ["{GOOD_FILE}"]\n',
        "data.filez: unknown key; expected one of files, reader",
    ),
    ("wrong type", '[data]\nfiles = "x.csv"\n', "data.files: expected array of string, got 'x.csv'"),
    ("wrong item type", "[data]\nfiles = [3]\n", "data.files[0]: expected a string, got 3"),
    (
        "out of range",
        f'[data]\nfiles = ["{GOOD_FILE}"]\nreader = {{ kind = "singal2024", points = 1 }}\n',
        "data.reader.points: must be in [2, 100000], got 1",
    ),
    (
        "unknown option",
        f'[data]\nfiles = ["{GOOD_FILE}"]\nreader = {{ kind = "singal2024", smooth = 3 }}\n',
        "data.reader.smooth: unknown key; expected one of average, points",
    ),
    (
        "unknown plugin",
        f'[data]\nfiles = ["{GOOD_FILE}"]\nreader = "nope"\n',
        "data.reader: unknown reader 'nope'; available: auto, generic, singal2024",
    ),
    ("missing file", '[data]\nfiles = ["missing.csv"]\n', "data.files[0]: file not found: missing.csv"),
    ("malformed toml", "[data\nfiles = 1\n", "malformed TOML"),
    ("unknown table", f'[dataa]\nfiles = ["{GOOD_FILE}"]\n', "dataa: unknown table; expected one of"),
    ("empty list", "[data]\nfiles = []\n", "data.files: must list at least one file"),
    ("nothing to do", '[pipeline]\nname = "x"\n', "nothing to do"),
]


@pytest.mark.parametrize("case, body, message", CASES, ids=[c[0] for c in CASES])
def test_bad_config_is_one_line_exit_2_no_output(tmp_path, singal_file, cli, case, body, message):
    """The CLI prints one error line containing the path and problem, exits 2, and writes nothing."""
    cfg = _config(tmp_path, singal_file, body)
    out = tmp_path / "out"
    proc = cli("run", str(cfg), "--out", str(out))
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert message in lines[0]
    assert lines[0].startswith("knitframe: error: ")
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == sorted(["bad.toml", GOOD_FILE])


def test_missing_config_file(tmp_path, cli):
    """A config path that does not exist is one line and exit 2."""
    proc = cli("run", str(tmp_path / "nope.toml"))
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"knitframe: error: config file not found: {tmp_path / 'nope.toml'}"
    ]


def test_malformed_csv_names_file_line_and_column(tmp_path, singal_file, cli):
    """A bad cell in a data file is reported with the file, its line and its column."""
    src = singal_file(GOOD_FILE).read_text().splitlines()
    src[5] = src[5].replace(src[5].split(",")[2], "abc", 1)
    bad = tmp_path / "broken-x.csv"
    bad.write_text("\n".join(src) + "\n")
    cfg = tmp_path / "c.toml"
    cfg.write_text('[data]\nfiles = ["broken-x.csv"]\n')
    proc = cli("run", str(cfg), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2
    assert (
        proc.stderr.strip()
        == f"knitframe: error: {bad}, line 6, column 'strain_axial': expected a number, got 'abc'"
    )
    assert not (tmp_path / "out").exists()


def test_api_raises_config_error_with_path(tmp_path):
    """The Python API raises ConfigError whose str() is the same one line."""
    import knitframe

    with pytest.raises(knitframe.ConfigError) as e:
        knitframe.run({"data": {"files": ["a.csv"], "reader": 5}})
    assert str(e.value) == "data.reader: expected string or table, got 5"
