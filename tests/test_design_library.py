"""Fabric library for garment design: the JSON format, its checks, the built-in Singal et al. 2024 library
and the ``knitframe library`` command."""

from __future__ import annotations

import copy
import fnmatch
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

import knitframe
from knitframe.cli import main as cli
from knitframe.config import instantiate
from knitframe.errors import ConfigError
from knitframe.fitting import FitProblem, params_from_json
from knitframe.garment.library import (
    BUILTIN_DATA,
    BUILTIN_FILE,
    FabricEntry,
    FabricLibrary,
    builtin_library,
    course_limits,
)

ROOT = Path(__file__).resolve().parents[1]
PATTERNS = {"stockinette": "jersey", "garter": "garter", "rib": "rib", "seed": "seed"}
#: bounds on the built-in fits, from the measured 1.20 % (tension, overall), 1.54 % (one direction)
#: and 10.3 % (transverse strain, overall), with margin
NRMSE_OVERALL, NRMSE_DIRECTION, NRMSE_TRANSVERSE = 0.015, 0.02, 0.12


def _entry(**over) -> dict:
    e = {
        "name": "test-jersey",
        "pattern": "jersey",
        "yarn": "cotton",
        "stitch_length": 11,
        "arc_length": 4.7,
        "model": "hgo",
        "params": {"a": 0.1, "b": 1.0, "theta_deg": 45.0},
        "course_pitch": 1.2,
        "wale_pitch": 0.9,
        "max_tension": 0.05,
        "max_stretch": 1.6,
        "source": "hand-written test entry",
        "pitch_source": "measured",
    }
    e.update(over)
    return e


def _library(*entries) -> dict:
    return {"knitframe_library": 1, "name": "test", "source": "tests", "entries": list(entries) or [_entry()]}


def _one_line_error(data, path_start: str) -> str:
    with pytest.raises(ConfigError) as info:
        FabricLibrary.from_json(data)
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(path_start), text
    return text


# ----------------------------------------------------------------------------------------- format
def test_round_trip_json_and_file(tmp_path):
    """A library survives to_json/from_json and save/load unchanged, the built-in one included."""
    lib = FabricLibrary.from_json(
        _library(
            _entry(),
            _entry(
                name="b",
                model="hgo2m",
                max_stretch=None,
                params={"mu1": 0.01, "mu2": 0.02, "K": 0.03, "a1": 0.004, "b1": 0.5, "a2": 0.006, "b2": 2.0},
                model_options={"compression_fibre": False},
            ),
        )
    )
    assert FabricLibrary.from_json(lib.to_json()) == lib
    for original in (lib, builtin_library()):
        original.save(tmp_path / "library.json")
        again = FabricLibrary.load(tmp_path / "library.json")
        assert again == original
        assert again.to_json() == original.to_json()
        assert hash(again) == hash(original)
    assert len(lib) == 2 and lib.names == ["test-jersey", "b"] and lib["b"] is lib[1]
    with pytest.raises(KeyError, match="have test-jersey, b"):
        lib["nope"]


BAD = [
    (
        lambda d: d["entries"][0].update(model="hookean"),
        "library.entries[0].model: unknown homogenizer 'hookean'",
    ),
    (
        lambda d: d["entries"][0]["params"].update(a=-1),
        "library.entries[0].params.a: must be in [1e-06, 100]",
    ),
    (
        lambda d: d["entries"][0]["params"].update(a=math.nan),
        "library.entries[0].params.a: expected a finite number",
    ),
    (
        lambda d: d["entries"][0]["params"].update(theta_deg=120),
        "library.entries[0].params.theta_deg: must be in [0, 90]",
    ),
    (
        lambda d: d["entries"][0]["params"].pop("b"),
        "library.entries[0].params.b: required parameter is missing",
    ),
    (lambda d: d["entries"][0]["params"].update(c=1.0), "library.entries[0].params.c: unknown parameter"),
    (lambda d: d["entries"][0].update(course_pitch=0), "library.entries[0].course_pitch: must be > 0"),
    (lambda d: d["entries"][0].update(wale_pitch=-2.0), "library.entries[0].wale_pitch: must be > 0"),
    (lambda d: d["entries"][0].update(wale_pitch="2"), "library.entries[0].wale_pitch: expected a number"),
    (
        lambda d: d["entries"][0].update(max_tension=math.inf),
        "library.entries[0].max_tension: must be finite",
    ),
    (lambda d: d["entries"][0].update(max_stretch=0.9), "library.entries[0].max_stretch: must be > 1"),
    (lambda d: d["entries"][0].update(arc_length=math.nan), "library.entries[0].arc_length: must be finite"),
    (
        lambda d: d["entries"][0].update(pattern="crochet"),
        "library.entries[0].pattern: unknown pattern 'crochet'",
    ),
    (lambda d: d["entries"][0].update(name=""), "library.entries[0].name: must not be empty"),
    (lambda d: d["entries"][0].pop("max_tension"), "library.entries[0].max_tension: required key is missing"),
    (lambda d: d["entries"][0].update(colour="red"), "library.entries[0].colour: unknown key"),
    (
        lambda d: d["entries"][0].update(model_options={"stiffness": 2}),
        "library.entries[0].model_options.stiffness",
    ),
    (
        lambda d: d["entries"].append(copy.deepcopy(d["entries"][0])),
        "library.entries[1].name: duplicate name 'test-jersey'",
    ),
    (lambda d: d["entries"].clear(), "library.entries: the library has no entries"),
    (lambda d: d.pop("knitframe_library"), "library.knitframe_library: required key is missing"),
    (lambda d: d.update(knitframe_library=2), "library.knitframe_library: unsupported library format 2"),
]


@pytest.mark.parametrize("change, message", BAD, ids=[m[:60] for _, m in BAD])
def test_validation_errors_name_the_json_path(change, message):
    """Every bad field is refused in one line that starts with its JSON path and says what is wrong."""
    data = _library()
    change(data)
    _one_line_error(data, message)


def test_load_names_the_file(tmp_path):
    """A bad library file is refused in one line naming the file and the JSON path; broken JSON names the
    line."""
    data = _library(_entry(params={"a": math.nan, "b": 1.0, "theta_deg": 45.0}))
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))  # NaN is what a careless writer puts there
    with pytest.raises(ConfigError) as info:
        FabricLibrary.load(bad)
    assert str(info.value).startswith(f"{bad}: library.entries[0].params.a: expected a finite number")
    bad.write_text('{"knitframe_library": 1,')
    with pytest.raises(ConfigError, match=r"not valid JSON: .*\(line 1, column 25\)"):
        FabricLibrary.load(bad)
    with pytest.raises(ConfigError, match="library file not found"):
        FabricLibrary.load(tmp_path / "missing.json")


def test_direct_construction_is_checked():
    """Building a FabricEntry in Python runs the same checks as loading."""
    good = _entry()
    FabricEntry(**good)
    with pytest.raises(ConfigError, match=r"entry 'test-jersey'\.max_tension: must be > 0"):
        FabricEntry(**{**good, "max_tension": 0.0})
    with pytest.raises(ConfigError, match="library.entries\\[1\\].name: duplicate name"):
        FabricLibrary("x", (FabricEntry(**good), FabricEntry(**good)))


# ----------------------------------------------------------------------------------------- model
def test_tensions_equal_the_homogenizer_stress():
    """tensions() is the registered homogenizer's stress at the entry's parameters, vectorised with
    broadcasting."""
    reg = knitframe.get_registry()
    lam1 = np.linspace(0.9, 1.6, 7)[:, None]
    lam2 = np.linspace(0.8, 1.3, 5)[None, :]
    entries = [FabricEntry(**_entry()), *builtin_library()]
    for e in entries:
        model = reg["homogenizer"][e.model](**e.model_options)
        p = params_from_json(model.param_names, e.params)
        T1, T2 = e.tensions(lam1, lam2)
        P1, P2 = model.stress(p, *np.broadcast_arrays(lam1, lam2))
        assert T1.shape == T2.shape == (7, 5)
        np.testing.assert_array_equal(T1, P1)
        np.testing.assert_array_equal(T2, P2)
        t1, t2 = e.tensions(1.3, 1.0)  # scalars too
        assert float(t1) == pytest.approx(
            float(model.stress(p, np.array([1.3]), np.array([1.0]))[0][0]), rel=1e-15
        )
    assert entries[0].homogenizer is entries[0].homogenizer  # built once


def test_within_limits():
    """within_limits is true exactly where T1 <= max_tension and λ1 <= max_stretch (when known)."""
    e = FabricEntry(**_entry(max_tension=0.05, max_stretch=1.6))
    ok = e.within_limits(np.array([1.2, 1.7, 1.2, 1.6]), np.array([0.04, 0.04, 0.06, 0.05]))
    assert ok.tolist() == [True, False, False, True]
    free = FabricEntry(**_entry(max_stretch=None))
    assert free.within_limits(5.0, 0.01).item() is True
    assert e.within_limits(np.ones((3, 1)), np.zeros((1, 4))).shape == (3, 4)


# ----------------------------------------------------------------------------------------- built-in
def test_builtin_library_entries_and_limits():
    """The built-in library has the 8 yarn x pattern fits, limits that are the course tests' measured maxima,
    and no parameter at a bound."""
    lib = builtin_library()
    assert len(lib) == 8
    assert sorted(lib.names) == sorted(f"{y}-{p}" for y in ("cotton", "acrylic") for p in PATTERNS.values())
    for yarn, pattern in ((y, p) for y in ("cotton", "acrylic") for p in PATTERNS):
        e = lib[f"{yarn}-{PATTERNS[pattern]}"]
        assert (
            e.pattern == PATTERNS[pattern]
            and e.yarn == {"cotton": "pearl-cotton", "acrylic": "acrylic"}[yarn]
        )
        assert e.model == "hgo2m" and e.fit["fitter"] == "lbfgs" and e.fit["at_bound"] == []
        t_max, lam_max, _ = course_limits(BUILTIN_DATA / f"{yarn}-{pattern}-x.csv")
        assert e.max_tension == t_max and e.max_stretch == lam_max
        for v in (e.max_tension, e.max_stretch - 1, e.course_pitch, e.wale_pitch):
            assert math.isfinite(v) and v > 0
        assert "Singal et al. 2024" in e.source and "max_tension = peak course tension" in e.source
        assert "Munden" in e.pitch_source and "11.28 mm" in e.pitch_source and "estimate" in e.pitch_source
        assert e.course_pitch == pytest.approx(11.28 / 4.0) and e.wale_pitch == pytest.approx(11.28 / 5.3)


def test_builtin_fits_nrmse_recomputed_from_the_shipped_data():
    """Each built-in entry's NRMSE, recomputed from its parameters and the shipped CSVs, is the recorded one
    and below 1.5 % overall, 2 % per direction and 12 % for the lateral strain."""
    reg = knitframe.get_registry()
    reader = instantiate(reg, "reader", "singal2024", "reader")
    for e in builtin_library():
        responses = [r for f in e.fit["responses"] for r in reader.read(BUILTIN_DATA / f"{f}.csv")]
        tension, transverse = FitProblem(e.homogenizer, responses).nrmse(e.params_array)
        for key, value in e.fit["nrmse"].items():
            assert tension[key] == pytest.approx(value, rel=1e-9, abs=1e-12), (e.name, key)
        for key, value in e.fit["nrmse_transverse"].items():
            assert transverse[key] == pytest.approx(value, rel=1e-9, abs=1e-12), (e.name, key)
        assert tension["overall"] < NRMSE_OVERALL, e.name
        assert max(tension["course"], tension["wale"]) < NRMSE_DIRECTION, e.name
        assert transverse["overall"] < NRMSE_TRANSVERSE, e.name


def test_acrylic_stiffer_than_cotton_at_20_percent_course_strain():
    """At 20 % course strain the acrylic carries more tension than the pearl cotton in every pattern, as
    measured (mean of the repeats) and as the built-in models predict for the same free-sides test."""
    reg = knitframe.get_registry()
    raw = instantiate(reg, "reader", {"kind": "singal2024", "average": False}, "reader")
    lib = builtin_library()
    for pattern, name in PATTERNS.items():
        measured, model = {}, {}
        for yarn in ("cotton", "acrylic"):
            repeats = raw.read(BUILTIN_DATA / f"{yarn}-{pattern}-x.csv")
            measured[yarn] = np.mean([np.interp(1.2, r.lambda1, r.T1) for r in repeats])
            model[yarn] = float(lib[f"{yarn}-{name}"].uniaxial([1.2])[1][0])
            assert model[yarn] == pytest.approx(measured[yarn], rel=0.3), (yarn, pattern)
        assert measured["acrylic"] > 1.5 * measured["cotton"], pattern
        assert model["acrylic"] > 1.5 * model["cotton"], pattern


def test_builtin_data_attribution_and_package_data():
    """The 16 CSVs and their attribution README ship with the package, and pyproject's package data covers
    them."""
    readme = (BUILTIN_DATA / "README.md").read_text()
    for text in ("Singal", "doi:10.1038/s41467-024-46498-z", "MIT licence", "Copyright (c) 2023 sabetta"):
        assert text in readme
    csvs = sorted(BUILTIN_DATA.glob("*.csv"))
    assert len(csvs) == 16
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"][
        "knitframe"
    ]
    pkg = ROOT / "knitframe"
    for f in [*csvs, BUILTIN_DATA / "README.md", BUILTIN_FILE]:
        rel = f.relative_to(pkg).as_posix()
        assert any(fnmatch.fnmatch(rel, g) for g in globs), rel


@pytest.mark.slow
def test_builtin_rebuild_reproduces_shipped(tmp_path):
    """`knitframe library build-builtin` refits the shipped library: same entries, parameters within 1e-6
    relative."""
    assert cli(["library", "build-builtin", "--out", str(tmp_path / "b"), "--quiet"]) == 0
    rebuilt = FabricLibrary.load(tmp_path / "b" / "library.json")
    shipped = builtin_library()
    assert rebuilt.names == shipped.names
    for a, b in zip(rebuilt, shipped):
        for k in b.params:
            assert a.params[k] == pytest.approx(b.params[k], rel=1e-6), (b.name, k)
        assert (a.max_tension, a.max_stretch, a.course_pitch, a.wale_pitch) == (
            b.max_tension,
            b.max_stretch,
            b.course_pitch,
            b.wale_pitch,
        )
        assert a.source == b.source and a.pitch_source == b.pitch_source
        assert (a.tension_scatter, a.pitch_measured, a.gauge) == (b.tension_scatter, False, None)


# ----------------------------------------------------------------------------------------- command
@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """params.json of two `knitframe fit` runs (cotton garter, acrylic seed; model hgo2m)."""
    root = tmp_path_factory.mktemp("fits")
    out = []
    for name in ("cotton-garter", "acrylic-seed"):
        folder = root / f"fit-{name}"
        data = [str(BUILTIN_DATA / f"{name}-{d}.csv") for d in "xy"]
        assert (
            cli(["fit", *data, "--model", "hgo2m", "--reader", "singal2024", "--out", str(folder), "--quiet"])
            == 0
        )
        out.append(folder / "params.json")
    return out


def test_library_build_writes_a_loadable_library(fitted, tmp_path, capsys):
    """`knitframe library build` on two fits writes library.json through the output folder, with given
    pitches for one and Munden's from the arc length for the other."""
    out = tmp_path / "lib"
    code = cli(
        [
            "library",
            "build",
            *map(str, fitted),
            "--out",
            str(out),
            "--name",
            "mine",
            "--pattern",
            "garter",
            "seed",
            "--yarn",
            "pearl-cotton",
            "acrylic",
            "--max-tension",
            "0.5",
            "--max-stretch",
            "1.6",
            "1.55",
            "--course-pitch",
            "3.1",
            "--arc-length",
            "11.28",
        ]
    )
    assert code == 0
    assert "library 'mine': 2 fabrics (fit-cotton-garter, fit-acrylic-seed)" in capsys.readouterr().out
    lib = FabricLibrary.load(out / "library.json")
    assert lib.name == "mine" and lib.names == ["fit-cotton-garter", "fit-acrylic-seed"]
    garter, seed = lib
    assert (garter.pattern, garter.yarn, garter.max_tension, garter.max_stretch) == (
        "garter",
        "pearl-cotton",
        0.5,
        1.6,
    )
    assert seed.max_stretch == 1.55 and seed.arc_length == 11.28
    assert garter.course_pitch == 3.1 and garter.wale_pitch == pytest.approx(11.28 / 5.3)
    params = json.loads(fitted[0].read_text())
    assert garter.params == {k: params[k] for k in garter.params} and garter.fit["nrmse"] == params["nrmse"]
    assert "hgo2m by lbfgs" in garter.source
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outputs"] == ["library.json"]
    assert sorted(p.name for p in out.iterdir()) == ["library.json", "summary.json"]


def test_from_fits_takes_fabric_metadata_from_the_params_file(fitted, tmp_path):
    """Pattern, yarn, stitch length and name come from a params file's ``fabric`` table; the pitches then
    follow from the pattern's stitch-length table by Munden's relations, and a contradicting option is
    refused."""
    data = json.loads(fitted[0].read_text())
    data["fabric"] = {"pattern": "rib", "yarn": "acrylic", "stitch_length": 11, "name": "acrylic-rib-sl11"}
    p = tmp_path / "sweep" / "rib-params.json"
    p.parent.mkdir()
    p.write_text(json.dumps(data))
    lib = FabricLibrary.from_fits([p], max_tension=0.3)
    e = lib["acrylic-rib-sl11"]
    assert (e.pattern, e.yarn, e.stitch_length, e.arc_length) == ("rib", "acrylic", 11.0, None)
    assert e.course_pitch == pytest.approx(4.7 / 4.0) and e.wale_pitch == pytest.approx(4.7 / 5.3)
    assert "stitch length 11" in e.pitch_source and "Munden" in e.pitch_source
    with pytest.raises(
        ConfigError, match=r"rib-params.json: pattern: the params file says 'rib', the option says 'seed'"
    ):
        FabricLibrary.from_fits([p], max_tension=0.3, pattern="seed")


def _refused(args, capsys, tmp_path, expected: str):
    out = tmp_path / "refused"
    code = cli(["library", "build", *args, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.count("\n") == 0 and err.startswith("knitframe: error: "), err
    assert expected in err, err
    assert not out.exists()


def test_library_build_bad_input_refused_in_one_line(fitted, tmp_path, capsys):
    """Bad arguments or files are refused in one line naming the option or file, exit code 2, nothing
    written."""
    good = [*map(str, fitted), "--pattern", "garter", "seed", "--yarn", "cotton", "--arc-length", "11"]
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    other = tmp_path / "x" / "params.json"
    other.parent.mkdir()
    other.write_text(json.dumps({**json.loads(fitted[0].read_text()), "a1": -3.0}))
    cases = [
        ([*good], "--max-tension: required"),
        ([*good, "--max-tension", "0.1", "0.2", "0.3"], "--max-tension: got 3 values for 2 params files"),
        ([*good, "--max-tension", "0"], "--max-tension: must be > 0"),
        ([*good, "--max-tension", "nan"], "--max-tension: must be finite"),
        ([*good, "--max-tension", "0.2", "--course-pitch", "-1"], "--course-pitch: must be > 0"),
        (
            [*map(str, fitted), "--yarn", "cotton", "--arc-length", "11", "--max-tension", "0.2"],
            "--pattern: not in the params",
        ),
        (
            [*good[:2], "--pattern", "crochet", "--yarn", "c", "--max-tension", "0.2", "--arc-length", "11"],
            "unknown pattern 'crochet'",
        ),
        (
            [*map(str, fitted), "--pattern", "garter", "--yarn", "c", "--max-tension", "0.2"],
            "--course-pitch: not given, and no arc length",
        ),
        (
            [str(tmp_path / "nope.json"), "--pattern", "jersey", "--yarn", "c", "--max-tension", "0.2"],
            "params file not found",
        ),
        (
            [str(broken), "--pattern", "jersey", "--yarn", "c", "--max-tension", "0.2"],
            f"{broken}: not valid JSON",
        ),
        (
            [str(other), "--pattern", "jersey", "--yarn", "c", "--max-tension", "0.2", "--arc-length", "11"],
            f"{other}: params.a1: must be in",
        ),
        (
            [
                fitted[0].as_posix(),
                fitted[0].as_posix(),
                "--pattern",
                "jersey",
                "--yarn",
                "c",
                "--max-tension",
                "0.2",
                "--arc-length",
                "11",
            ],
            "--entry-name: 'fit-cotton-garter' is the name of two params files",
        ),
    ]
    for args, expected in cases:
        _refused(args, capsys, tmp_path, expected)


def test_library_show_builtin_prints_eight_rows(capsys):
    """`knitframe library show builtin` prints one table row per built-in fabric, with its parameters and
    limits."""
    assert cli(["library", "show", "builtin"]) == 0
    out = capsys.readouterr().out
    names = builtin_library().names
    rows = [line for line in out.splitlines() if line.split(" ")[0] in names]
    assert len(rows) == 8
    row = next(r for r in rows if r.startswith("cotton-rib "))
    assert "rib" in row and "hgo2m" in row and "0/90" in row and "0.2996" in row
    assert out.count("pitches: Munden") == 8
