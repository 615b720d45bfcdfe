"""Fabric library pitches from a knitter's gauge, which pitches are estimates, and the scatter of the tests'
repeats."""

from __future__ import annotations

import json
import math
import statistics

import numpy as np
import pytest

from knitframe.cli import main as cli
from knitframe.config import instantiate
from knitframe.errors import ConfigError
from knitframe.garment.library import (
    BUILTIN_DATA,
    BUILTIN_FILE,
    FabricEntry,
    FabricLibrary,
    builtin_library,
    with_builtin_scatter,
)
from knitframe.plugins import get_registry

NEW_KEYS = ("tension_scatter", "pitch_measured", "gauge")


def _entry(**over) -> dict:
    e = {
        "name": "test-jersey",
        "pattern": "jersey",
        "yarn": "cotton",
        "stitch_length": None,
        "arc_length": None,
        "model": "hgo",
        "params": {"a": 0.1, "b": 1.0, "theta_deg": 45.0},
        "course_pitch": 1.2,
        "wale_pitch": 0.9,
        "max_tension": 0.05,
    }
    e.update(over)
    return e


def _library(**over) -> dict:
    return {"knitframe_library": 1, "name": "test", "entries": [_entry(**over)]}


def _refused(call, start: str) -> str:
    with pytest.raises(ConfigError) as info:
        call()
    text = str(info.value)
    assert "\n" not in text and text.startswith(start), text
    return text


def test_gauge_gives_the_pitches_exactly(tmp_path):
    """22 stitches and 30 courses per 10 cm give course pitch 100/22 and wale pitch 100/30 mm exactly, kept
    through library.json."""
    e = FabricEntry(**_entry()).with_gauge(22, 30)
    assert e.course_pitch == 100 / 22 and e.wale_pitch == 100 / 30
    assert e.gauge == {"stitches_per_10cm": 22.0, "courses_per_10cm": 30.0} and e.pitch_measured is True
    assert "gauge" in e.pitch_source and (e.params, e.max_tension) == (_entry()["params"], 0.05)
    lib = FabricLibrary("mine", (FabricEntry(**_entry()),)).with_gauges({"test-jersey": (22, 30)})
    assert lib["test-jersey"] == e
    lib.save(tmp_path / "library.json")
    again = FabricLibrary.load(tmp_path / "library.json")
    assert again == lib and again[0].course_pitch == 100 / 22
    print(f"course pitch {e.course_pitch!r} mm, wale pitch {e.wale_pitch!r} mm")


@pytest.mark.parametrize(
    "gauge, message",
    [
        ((0, 30), "design.gauge.test-jersey.stitches_per_10cm: must be > 0, got 0"),
        ((22, -3), "design.gauge.test-jersey.courses_per_10cm: must be > 0, got -3"),
        ((math.nan, 30), "design.gauge.test-jersey.stitches_per_10cm: must be finite"),
        ((22, math.inf), "design.gauge.test-jersey.courses_per_10cm: must be finite"),
        (("22", 30), "design.gauge.test-jersey.stitches_per_10cm: expected a number"),
        ((22,), "design.gauge.test-jersey: expected [stitches, courses]"),
    ],
)
def test_bad_gauge_refused_naming_the_field(gauge, message):
    """A gauge number that is not finite and > 0, or not a pair, is refused in one line naming
    field.<name>."""
    lib = FabricLibrary("mine", (FabricEntry(**_entry()),))
    print(_refused(lambda: lib.with_gauges({"test-jersey": gauge}), message))


@pytest.mark.parametrize(
    "over, message",
    [
        (
            {"gauge": {"stitches_per_10cm": 22, "courses_per_10cm": 30}},
            "library.entries[0].course_pitch: 1.2 mm does not match the gauge "
            "(100/stitches_per_10cm = 4.54545 mm)",
        ),
        ({"gauge": {"stitches_per_10cm": 22}}, "library.entries[0].gauge.courses_per_10cm: required key"),
        (
            {"gauge": {"stitches_per_10cm": 22, "courses_per_10cm": 30, "rows": 3}},
            "library.entries[0].gauge.rows: unknown key",
        ),
        ({"gauge": [22, 30]}, "library.entries[0].gauge: expected a table"),
        ({"pitch_measured": "yes"}, "library.entries[0].pitch_measured: expected true, false or null"),
        (
            {
                "course_pitch": 100 / 22,
                "wale_pitch": 100 / 30,
                "gauge": {"stitches_per_10cm": 22, "courses_per_10cm": 30},
                "pitch_measured": False,
            },
            "library.entries[0].pitch_measured: false with a gauge",
        ),
        ({"tension_scatter": -0.1}, "library.entries[0].tension_scatter: must be >= 0"),
        ({"tension_scatter": math.nan}, "library.entries[0].tension_scatter: must be finite"),
    ],
)
def test_bad_new_keys_in_library_json_refused_naming_the_path(over, message):
    """A bad gauge, pitch_measured or tension_scatter in library.json is refused in one line naming its JSON
    path."""
    print(_refused(lambda: FabricLibrary.from_json(_library(**over)), message))


def test_unknown_fabric_name_refused_naming_it():
    """A gauge for a fabric the library does not have is refused in one line naming field.<name> and listing
    the names."""
    text = _refused(
        lambda: builtin_library().with_gauges(
            {"cotton-rib": (18, 24), "wool-rib": (18, 24)}, field="sleeve.gauge"
        ),
        "sleeve.gauge.wool-rib: no fabric 'wool-rib' in library 'singal2024'; "
        "have cotton-jersey, cotton-garter",
    )
    print(text)


def test_old_json_without_new_keys_loads_and_builtin_pitches_are_estimates(tmp_path):
    """The shipped library without the new keys (an older file) loads with the same numbers, its Munden
    pitches read as estimates from pitch_source; other old pitch sources are read as said."""
    data = json.loads(BUILTIN_FILE.read_text())
    assert all(e["pitch_measured"] is False and e["gauge"] is None for e in data["entries"])
    for e in data["entries"]:
        for key in NEW_KEYS:
            del e[key]
    (tmp_path / "old.json").write_text(json.dumps(data))
    old = FabricLibrary.load(tmp_path / "old.json")
    for a, b in zip(old, builtin_library(), strict=True):
        assert (a.params, a.course_pitch, a.wale_pitch, a.max_tension) == (
            b.params,
            b.course_pitch,
            b.wale_pitch,
            b.max_tension,
        )
        assert a.pitch_measured is None and a.tension_scatter is None and a.gauge is None
        assert a.pitch_is_estimate and b.pitch_is_estimate, a.name
    readings = {
        "measured with a ruler on the relaxed swatch": False,
        "given": False,
        "": True,
        "relaxed rod cell: course pitch |L1|·λ1/2": True,
        "course pitch from Munden's plain-knit relations, loop length 4.7 mm (estimate)": True,
        "the knitted cell's pitches: not relaxed, measure them": True,
    }
    for text, estimate in readings.items():
        assert FabricEntry(**_entry(pitch_source=text)).pitch_is_estimate is estimate, text
    print(f"{len(old)} old entries load; all pitches estimates")


def test_gauge_given_entry_reports_measured():
    """An entry given a gauge reports measured pitches; the library's other entries stay estimates."""
    lib = builtin_library().with_gauges({"cotton-rib": (18, 24)})
    rib = lib["cotton-rib"]
    assert not rib.pitch_is_estimate and rib.pitch_measured is True
    assert (rib.course_pitch, rib.wale_pitch) == (100 / 18, 100 / 24)
    assert rib.params == builtin_library()["cotton-rib"].params
    assert rib.tension_scatter == builtin_library()["cotton-rib"].tension_scatter
    assert [e.name for e in lib if e.pitch_is_estimate] == [n for n in lib.names if n != "cotton-rib"]
    assert not FabricEntry(**_entry(pitch_measured=True, pitch_source="")).pitch_is_estimate
    print(rib.pitch_source)


def _hand_scatter(x_file) -> float:
    """The scatter written out: repeats to 100 common stretches, (max - min) / (2 mean), median where the
    mean is at least 10 % of its peak."""
    reader = instantiate(get_registry(), "reader", {"kind": "singal2024", "average": False}, "reader")
    curves = []
    for r in reader.read(x_file):
        order = np.argsort(r.lambda1, kind="stable")
        curves.append((r.lambda1[order], r.T1[order]))
    lo = max(lam[0] for lam, _ in curves)
    hi = min(lam[-1] for lam, _ in curves)
    rows = []
    for j in range(100):
        lam = lo + (hi - lo) * j / 99
        values = [float(np.interp(lam, s, t)) for s, t in curves]
        rows.append((sum(values) / len(values), max(values) - min(values)))
    peak = max(mean for mean, _ in rows)
    return statistics.median(spread / (2 * mean) for mean, spread in rows if mean >= 0.1 * peak)


def test_builtin_scatter_matches_a_hand_computation():
    """Cotton jersey's tension_scatter is the hand computation from its five course repeats, and every shipped
    scatter is the one computed from the shipped data."""
    shipped = builtin_library()
    hand = _hand_scatter(BUILTIN_DATA / "cotton-stockinette-x.csv")
    assert shipped["cotton-jersey"].tension_scatter == pytest.approx(hand, rel=1e-12)
    assert with_builtin_scatter(shipped) == shipped
    for e in shipped:
        assert 0.03 < e.tension_scatter < 0.5, e.name
    print(", ".join(f"{e.name} {e.tension_scatter:.4f}" for e in shipped))


@pytest.fixture
def params_files(tmp_path):
    """Two params.json of hgo2m fits (the built-in cotton and acrylic jersey parameters)."""
    files = []
    for name in ("cotton-jersey", "acrylic-jersey"):
        e = builtin_library()[name]
        p = tmp_path / "fits" / name / "params.json"
        p.parent.mkdir(parents=True)
        p.write_text(json.dumps({"model": e.model, "options": e.model_options, **e.params}))
        files.append(str(p))
    return files


def test_library_build_gauge_writes_the_pitches(params_files, tmp_path, capsys):
    """`knitframe library build --gauge 22,30` writes pitches 100/22 and 100/30 mm for every fit, as measured,
    with --scatter recorded; `library show` marks no estimate."""
    out = tmp_path / "lib"
    common = ["--pattern", "jersey", "--yarn", "cotton", "acrylic", "--max-tension", "0.4", "--out"]
    args = ["library", "build", *params_files, *common, str(out), "--gauge", "22,30", "--scatter", "0.09"]
    assert cli(args) == 0
    lib = FabricLibrary.load(out / "library.json")
    for e in lib:
        assert (e.course_pitch, e.wale_pitch) == (100 / 22, 100 / 30)
        assert e.gauge == {"stitches_per_10cm": 22.0, "courses_per_10cm": 30.0}
        assert not e.pitch_is_estimate and e.tension_scatter == 0.09
    capsys.readouterr()
    assert cli(["library", "show", str(out / "library.json")]) == 0
    shown = capsys.readouterr().out
    assert " est" not in shown and "4.55/3.33" in shown and "gauge: 22 stitches and 30 courses" in shown
    munden = tmp_path / "munden"
    assert (
        cli(["library", "build", *params_files, *common, str(munden), "--arc-length", "11.28", "--quiet"])
        == 0
    )
    assert all(
        e.pitch_is_estimate and e.tension_scatter is None for e in FabricLibrary.load(munden / "library.json")
    )
    assert cli(["library", "show", str(munden / "library.json")]) == 0
    assert capsys.readouterr().out.count("2.82/2.13 est") == 2
    print(f"pitches {lib[0].course_pitch:.6g}/{lib[0].wale_pitch:.6g} mm")


@pytest.mark.parametrize(
    "extra, expected",
    [
        (
            ["--gauge", "22,30", "--course-pitch", "4.5"],
            "--gauge: give either --gauge or --course-pitch, not both",
        ),
        (
            ["--gauge", "22,30", "--wale-pitch", "3.3"],
            "--gauge: give either --gauge or --wale-pitch, not both",
        ),
        (["--gauge", "22x30"], "--gauge: expected STITCHES,COURSES per 10 cm (e.g. 22,30), got '22x30'"),
        (["--gauge", "22,0"], "--gauge: courses per 10 cm must be a finite number > 0, got 0.0"),
        (["--gauge", "nan,30"], "--gauge: stitches per 10 cm must be a finite number > 0"),
        (["--gauge", "22,30", "--scatter", "-1"], "--scatter: must be >= 0"),
    ],
)
def test_library_build_gauge_refused_in_one_line(params_files, tmp_path, capsys, extra, expected):
    """A gauge with pitches, or a malformed gauge or scatter, is refused in one line, exit code 2, nothing
    written."""
    out = tmp_path / "refused"
    args = ["library", "build", *params_files, "--pattern", "jersey", "--yarn", "c", "--max-tension", "0.4"]
    assert cli([*args, *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("knitframe: error: ") and expected in err, err
    assert not out.exists()
    print(err)


def test_from_fits_records_how_the_pitches_were_found(params_files):
    """from_fits: a gauge or both pitches given are measured, Munden's are estimates, and a gauge with a
    pitch is refused."""
    kw = {"pattern": "jersey", "yarn": "cotton", "max_tension": 0.4}
    gauged = FabricLibrary.from_fits(params_files, gauge=(22, 30), **kw)
    per_file = FabricLibrary.from_fits(params_files, gauge=[(22, 30), None], arc_length=11.28, **kw)
    given = FabricLibrary.from_fits(params_files, course_pitch=3.0, wale_pitch=2.0, **kw)
    munden = FabricLibrary.from_fits(params_files, arc_length=11.28, tension_scatter=[0.1, 0.2], **kw)
    estimates = [e.pitch_is_estimate for e in (*gauged, *per_file, *given, *munden)]
    assert estimates == [False, False, False, True, False, False, True, True]
    assert per_file[0].course_pitch == 100 / 22 and per_file[1].course_pitch == pytest.approx(11.28 / 4)
    assert [e.tension_scatter for e in munden] == [0.1, 0.2]
    _refused(
        lambda: FabricLibrary.from_fits(params_files, gauge=(22, 30), wale_pitch=2.0, **kw),
        f"{params_files[0]}: gauge: give a gauge or the pitches, not both (wale_pitch is given too)",
    )
