"""Material cards: CalculiX runs them and agrees with knitframe; ABAQUS and FEBio cards match them value by
value.

The fitted parameters come from a real fit (Singal et al. 2024 cotton jersey, course and wale,
model hgo) made once per module by a ``[fit]`` stage with ``export`` set to every format.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import EXAMPLE_DATA, ROOT, TEST_DATA

from knitframe.errors import ConfigError
from knitframe.export import (
    FORMATS,
    calculix_check,
    export_card,
    is_knitframe_card,
    read_check_cases,
)

CCX = shutil.which("ccx")
needs_ccx = pytest.mark.skipif(
    CCX is None,
    reason="CalculiX 'ccx' is not on the PATH (Debian: apt-get install "
    "calculix-ccx; .ci/run installs it when apt-get is available)",
)
#: a second, hand-made parameter set: another angle, a softer exponent and tension-only fibres
OTHER = {"model": "hgo", "options": {"compression_fibre": False}, "a": 0.05, "b": 3.0, "theta_deg": 30.0}


def _data_file(name: str) -> Path:
    p = TEST_DATA / name
    return p if p.exists() else EXAMPLE_DATA / name


@pytest.fixture(scope="module")
def fitted(tmp_path_factory) -> Path:
    """A [fit] stage's output folder: hgo fitted to cotton jersey, with every card exported."""
    import knitframe

    folder = tmp_path_factory.mktemp("fit")
    files = [str(_data_file(n)) for n in ("cotton-stockinette-x.csv", "cotton-stockinette-y.csv")]
    (folder / "fit.toml").write_text(
        f'[data]\nreader = "singal2024"\nfiles = {json.dumps(files)}\n\n'
        f'[fit]\nmodel = "hgo"\nexport = {json.dumps(list(FORMATS))}\n'
    )
    knitframe.run(folder / "fit.toml", out=folder / "out")
    return folder / "out"


def _params(folder: Path) -> dict:
    return json.loads((folder / "params.json").read_text())


def _model_and_params(data: dict):
    """knitframe's own model of a params.json, and its parameters in the code's units (θ in radians)."""
    from knitframe.plugins import get_registry

    model = get_registry()["homogenizer"]["hgo"](**data.get("options", {}))
    return model, np.array([data["a"], data["b"], math.radians(data["theta_deg"])])


def _table(rows, title):
    lines = [
        title,
        f"{'case':<6}{'lam1':>8}{'lam2':>8}{'ccx T1':>12}{'kf T1':>12}{'diff':>9}{'ccx T2':>12}"
        f"{'kf T2':>12}{'diff':>9}",
    ]
    for r in rows:
        (c1, c2), (k1, k2) = r["ccx"], r["knitframe"]
        lines.append(
            f"{r['case']:<6}{r['lam1']:>8.4f}{r['lam2']:>8.4f}{c1:>12.6g}{k1:>12.6g}"
            f"{100 * (c1 / k1 - 1):>8.3f}%{c2:>12.6g}{k2:>12.6g}{100 * (c2 / k2 - 1):>8.3f}%"
        )
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# CalculiX runs the cards
# ---------------------------------------------------------------------------------------------
@needs_ccx
@pytest.mark.parametrize("source", ["fit", "other"])
def test_calculix_matches_knitframe_at_five_stretches_in_two_load_cases(fitted, source):
    """CalculiX's tensions per unit width equal knitframe's hgo to 1 % at 5 stretches, equibiaxial and
    strip-biaxial."""
    data = _params(fitted) if source == "fit" else OTHER
    rows = calculix_check(data)
    model, params = _model_and_params(data)
    for case in ("EQB", "STRIP"):
        sel = [r for r in rows if r["case"] == case]
        assert len(sel) == 5
        lam1 = np.array([r["lam1"] for r in sel])
        lam2 = np.array([r["lam2"] for r in sel])
        assert np.all(np.diff(lam1) > 0) and lam1[0] > 1.0 and lam1[-1] >= 1.15
        np.testing.assert_allclose(lam2, lam1 if case == "EQB" else 1.0)
        P1, P2 = model.stress(params, lam1, lam2)  # knitframe's own homogenizer, computed here
        ccx = np.array([r["ccx"] for r in sel])
        np.testing.assert_allclose(ccx[:, 0], P1, rtol=0.01)
        np.testing.assert_allclose(ccx[:, 1], P2, rtol=0.01)
        # and CalculiX solved the energy the card states: its exact block solution, as printed in the deck
        np.testing.assert_allclose(ccx, np.array([r["card"] for r in sel]), rtol=2e-4)
        assert max(abs(r["J"] - 1.0) for r in sel) < 1e-3  # nearly incompressible, as the header says
    print("\n" + _table([r for r in rows if r["case"] != "COMP"], f"CalculiX vs knitframe ({source})"))


@needs_ccx
def test_calculix_compression_branch_is_matrix_only_as_the_header_says(fitted):
    """Under equibiaxial compression CalculiX's fibre carries nothing: only the small matrix term remains."""
    data = _params(fitted)
    rows = [r for r in calculix_check(data) if r["case"] == "COMP"]
    assert len(rows) == 5 and all(r["lam1"] < 1 and r["lam2"] < 1 for r in rows)
    card = export_card(data, "calculix")
    assert "no stress while it is shorter than at rest" in " ".join(card.split())
    c10 = float(card.strip().splitlines()[-1].split(",")[0])
    lam = np.array([r["lam1"] for r in rows])
    matrix = 2.0 * c10 * 1.0 * (lam - lam**-5)  # incompressible neo-Hookean membrane, t0 = 1 mm
    ccx = np.array([r["ccx"] for r in rows])
    np.testing.assert_allclose(ccx[:, 0], matrix, rtol=0.01)
    np.testing.assert_allclose(ccx[:, 1], matrix, rtol=0.01)
    model, params = _model_and_params(data)
    assert data["options"]["compression_fibre"] is True  # this fit kept the fibre's compression
    P1, P2 = model.stress(params, lam, lam)
    assert np.all(P1 < 0) and np.all(np.abs(ccx[:, 0]) < 1e-2 * np.abs(P1))
    assert np.all(np.abs(ccx[:, 1]) < 1e-2 * np.abs(P2))
    slack = _model_and_params({**data, "options": {"compression_fibre": False}})[0]
    assert np.all(slack.stress(params, lam, lam)[0] == 0)  # the paper's model without compression: zero too
    print(
        "\n"
        + "\n".join(
            f"COMP lam {r['lam1']:.3f}: ccx T1 {r['ccx'][0]:.4g}, matrix {m:.4g}, knitframe "
            f"(compression kept) {p:.4g} N/mm"
            for r, m, p in zip(rows, matrix, P1)
        )
    )


@needs_ccx
def test_calculix_deck_written_by_the_fit_runs_as_is(fitted, tmp_path):
    """The params.calculix-check.inp a [fit] stage wrote runs with `ccx -i` and prints the totals its header
    announces."""
    from knitframe.export import read_dat_totals

    deck = (fitted / "params.calculix-check.inp").read_text()
    shutil.copy(fitted / "params.calculix-check.inp", tmp_path / "deck.inp")
    proc = subprocess.run(
        [CCX, "-i", "deck"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stdout[-500:]
    totals = read_dat_totals((tmp_path / "deck.dat").read_text())
    for case in read_check_cases(deck):
        fx = [f for _, f in totals[f"{case['set']}_X1"]]
        assert len(fx) == case["increments"] == len(case["expected"])
        np.testing.assert_allclose([f[0] for f in fx], [e[4] for e in case["expected"]], rtol=2e-4, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# ABAQUS and FEBio, checked against the CalculiX card of the same params.json
# ---------------------------------------------------------------------------------------------
def _keywords(text: str) -> dict:
    """ABAQUS-style keyword lines with their data lines (comments dropped), by keyword."""
    out, cur = {}, None
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("**"):
            continue
        if line.startswith("*"):
            head, *opts = [p.strip() for p in line[1:].split(",")]
            cur = out.setdefault(head.upper(), [])
            cur.append({"opts": [o.upper() for o in opts], "data": []})
        else:
            cur[-1]["data"].append([_number(x) for x in line.split(",")])
    return out


def _number(text: str) -> float | str:
    try:
        return float(text)
    except ValueError:
        return text.strip()


def _calculix_constants(text: str) -> dict:
    kw = _keywords(text)
    mat, user = kw["MATERIAL"][0], kw["USER MATERIAL"][0]
    values = [v for row in user["data"] for v in row]
    assert user["opts"] == [f"CONSTANTS={len(values)}"] and len(values) == 6
    assert mat["opts"][0].startswith("NAME=ELASTIC_FIBER")
    c10, d1, cx, cy, k1, k2 = values
    return {"c10": c10, "d": d1, "direction": (cx, cy), "k1": k1, "k2": k2}


def test_abaqus_and_febio_cards_match_the_calculix_deck_value_by_value(fitted):
    """Parsed back, the ABAQUS and FEBio cards hold the CalculiX deck's k1, k2, direction, C10 and D (in their
    forms)."""
    data = _params(fitted)
    deck = _calculix_constants((fitted / "params.calculix-check.inp").read_text())
    assert deck == _calculix_constants((fitted / "params.calculix.inp").read_text())
    theta = math.radians(data["theta_deg"])
    assert deck["k1"] == pytest.approx(2 * data["a"] / 1.0, rel=1e-9) and deck["k2"] == pytest.approx(
        data["b"], rel=1e-9
    )
    np.testing.assert_allclose(deck["direction"], (math.cos(theta), math.sin(theta)), atol=1e-9)
    assert 0 < deck["c10"] < 1e-3 * deck["k1"] and 0 < deck["d"] * deck["k1"] < 1e-3

    abq = _keywords((fitted / "params.abaqus.inp").read_text())
    holz = abq["ANISOTROPIC HYPERELASTIC"][0]
    assert holz["opts"] == ["HOLZAPFEL", "LOCAL DIRECTIONS=1"]
    c10, d, k1, k2, kappa = holz["data"][0]
    assert (c10, d, k1, k2, kappa) == pytest.approx(
        (deck["c10"], deck["d"], deck["k1"], deck["k2"], 0.0), rel=1e-9
    )
    ori = abq["ORIENTATION"][0]
    assert "LOCAL DIRECTIONS=1" in ori["opts"] and ori["data"][0] == [1, 0, 0, 0, 1, 0]
    np.testing.assert_allclose(ori["data"][-1], (*deck["direction"], 0.0), atol=1e-12)
    assert (
        f"ORIENTATION=ORI-{abq['MATERIAL'][0]['opts'][0][5:]}" in (fitted / "params.abaqus.inp").read_text()
    )

    root = ET.fromstring((fitted / "params.febio.xml").read_text())
    assert root.tag == "material" and root.get("type") == "Holzapfel-Gasser-Ogden"
    val = {t: float(root.findtext(t)) for t in ("c", "k1", "k2", "gamma", "kappa", "k")}
    assert val["c"] == pytest.approx(2 * deck["c10"], rel=1e-9)  # FEBio's matrix is c/2 (I1 - 3)
    assert val["k1"] == pytest.approx(deck["k1"] / 2, rel=1e-9)  # two coincident families (gamma = 0)
    assert val["k2"] == pytest.approx(deck["k2"], rel=1e-9)
    assert val["gamma"] == 0 and val["kappa"] == 0
    assert val["k"] == pytest.approx(2 / deck["d"], rel=1e-9)  # the same initial bulk modulus 2/D
    axis = root.find("mat_axis")
    assert axis.get("type") == "vector"
    a = [float(x) for x in axis.findtext("a").split(",")]
    dvec = [float(x) for x in axis.findtext("d").split(",")]
    np.testing.assert_allclose(a, (*deck["direction"], 0.0), atol=1e-12)
    assert abs(np.dot(a, dvec)) < 1e-9 and dvec[2] == 0


def _isochoric_energies(F, ccx, febio):
    """Deviatoric energies of the CalculiX and FEBio materials at F (det F = 1), from their published
    forms."""
    C = F.T @ F
    J = np.linalg.det(F)
    Cb = J ** (-2 / 3) * C
    i1 = np.trace(Cb)
    a = np.array([*ccx["direction"], math.sqrt(max(0.0, 1 - sum(v * v for v in ccx["direction"])))])
    x = max(a @ Cb @ a - 1.0, 0.0)
    u_ccx = ccx["c10"] * (i1 - 3) + ccx["k1"] / (2 * ccx["k2"]) * math.expm1(ccx["k2"] * x * x)
    # FEBio Holzapfel-Gasser-Ogden: families n0 cos g +- n1 sin g about mat_axis (a, d)
    n0 = np.array(febio["a"]) / np.linalg.norm(febio["a"])
    n1 = np.array(febio["d"]) - (np.array(febio["d"]) @ n0) * n0
    n1 /= np.linalg.norm(n1)
    g = math.radians(febio["gamma"])
    u_feb = 0.5 * febio["c"] * (i1 - 3)
    for s in (1, -1):
        ar = n0 * math.cos(g) + s * n1 * math.sin(g)
        E = febio["kappa"] * (i1 - 3) + (1 - 3 * febio["kappa"]) * (ar @ Cb @ ar - 1)
        if E >= 0:
            u_feb += 0.5 * febio["k1"] / febio["k2"] * math.expm1(febio["k2"] * E * E)
    return u_ccx, u_feb


def test_febio_card_has_the_calculix_energy_under_shear_too(fitted):
    """FEBio's two coincident families (gamma = 0) give the CalculiX card's energy at random isochoric
    deformations."""
    ccx = _calculix_constants((fitted / "params.calculix.inp").read_text())
    root = ET.fromstring((fitted / "params.febio.xml").read_text())
    febio = {t: float(root.findtext(t)) for t in ("c", "k1", "k2", "gamma", "kappa")}
    febio["a"] = [float(x) for x in root.find("mat_axis").findtext("a").split(",")]
    febio["d"] = [float(x) for x in root.find("mat_axis").findtext("d").split(",")]
    rng = np.random.default_rng(7)
    active = 0
    for _ in range(50):
        F = np.eye(3) + 0.25 * rng.standard_normal((3, 3))
        if np.linalg.det(F) <= 0.2:
            continue
        F /= np.linalg.det(F) ** (1 / 3)
        u_ccx, u_feb = _isochoric_energies(F, ccx, febio)
        assert u_feb == pytest.approx(u_ccx, rel=1e-9, abs=1e-14)
        active += u_ccx > ccx["c10"] * 10
    assert active > 5  # the fibre term was on in many of them


# ---------------------------------------------------------------------------------------------
# headers, angles, refusals
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("fmt", list(FORMATS))
def test_every_card_header_states_units_angles_and_the_four_differences(fitted, fmt):
    """Each card's header names units, θ in degrees as stored, the Macaulay bracket, isochoric invariants,
    matrix and bulk."""
    path = fitted / f"params.{FORMATS[fmt]}"
    text = path.read_text()
    assert is_knitframe_card(path)
    head = " ".join(line.strip("*<!-> ") for line in text.split("<material")[0].splitlines())
    data = _params(fitted)
    for words in (
        "Units: mm, N, MPa",
        "angles in degrees",
        f"theta = {data['theta_deg']:.10g} deg",
        "Macaulay bracket",
        "Isochoric invariants",
        "(3) Matrix: C10",
        "(4) Bulk:",
        "Tension per unit width (N/mm) = t0 x nominal stress",
    ):
        assert words in head, words
    cite = {
        "abaqus": "*ANISOTROPIC HYPERELASTIC with HOLZAPFEL",
        "calculix": "ELASTIC_FIBER",
        "calculix-deck": "Fiber reinforced materials",
        "febio": "'Holzapfel-Gasser-Ogden'",
    }[fmt]
    assert cite in head


def test_theta_is_taken_in_degrees_as_stored(tmp_path):
    """theta_deg = 30 gives the direction (cos 30°, sin 30°); a small value is never taken for radians."""
    for theta in (30.0, 0.5, 90.0, -20.0):
        card = export_card({"model": "hgo", "a": 0.1, "b": 2.0, "theta_deg": theta}, "calculix")
        c = _calculix_constants(card)
        t = math.radians(theta)
        np.testing.assert_allclose(c["direction"], (math.cos(t), math.sin(t)), atol=1e-9)
        assert c["direction"][0] ** 2 + c["direction"][1] ** 2 <= 1.0  # CalculiX needs a unit direction


def test_old_abaqus_and_febio_methods_still_take_radians():
    """HGO.abaqus/.febio keep their radian parameters and card layout for existing callers."""
    from knitframe.plugins import get_registry

    m = get_registry()["homogenizer"]["hgo"]()
    old = _keywords(m.abaqus(np.array([0.1, 2.0, math.radians(30)])))
    assert old["ANISOTROPIC HYPERELASTIC"][0]["data"][0][1] == 0.0  # D = 0 as before
    np.testing.assert_allclose(
        old["ORIENTATION"][0]["data"][-1], (math.cos(math.radians(30)), 0.5, 0), atol=1e-9
    )


def _main(argv, capsys):
    """Run the CLI in this process: (exit code, stdout, stderr); argparse's own exits count too."""
    from knitframe.cli import main

    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("fmt", list(FORMATS))
def test_hgo2m_is_refused_in_every_format_in_one_line(tmp_path, capsys, fmt):
    """hgo2m has no card: one line naming every format and the reason, exit 2, nothing written."""
    params = tmp_path / "params.json"
    params.write_text(
        json.dumps(
            {
                "model": "hgo2m",
                "options": {"compression_fibre": False},
                "mu1": 0.05,
                "mu2": 0.08,
                "K": 0.13,
                "a1": 0.002,
                "b1": 1.5,
                "a2": 0.06,
                "b2": 5.5,
            }
        )
    )
    code, out, err = _main(["export", str(params), "--format", fmt, "--out", str(tmp_path / "card")], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert f"'hgo2m' has no {fmt} card: none of abaqus, calculix, calculix-deck, febio can express it" in err
    assert "orthotropic" in err and "fit 'hgo'" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["params.json"]
    with pytest.raises(ConfigError):
        export_card(json.loads(params.read_text()), fmt)


def _snapshot(folder: Path) -> dict:
    return {
        p.name: (p.read_bytes() if p.is_file() and not p.is_symlink() else None) for p in folder.iterdir()
    }


@pytest.mark.parametrize(
    "case",
    [
        "exists",
        "exists-not-card",
        "folder",
        "missing-parent",
        "dot",
        "dotdot",
        "empty",
        "trailing-slash",
        "under-a-file",
        "link",
        "unwritable",
    ],
)
def test_out_refusals_are_one_line_exit_2_and_write_nothing(tmp_path, capsys, monkeypatch, fitted, case):
    """Every --out refusal is one line with exit 2, and leaves the folder exactly as it was."""
    work = tmp_path / "w"
    work.mkdir()
    shutil.copy(fitted / "params.json", work / "params.json")
    (work / "notes.inp").write_text("my own deck\n")
    (work / "old.inp").write_text(export_card(_params(fitted), "abaqus"))
    (work / "sub").mkdir()
    (work / "afile").write_text("x")
    (work / "link.inp").symlink_to(work / "old.inp")
    monkeypatch.chdir(work)
    out, extra = {
        "exists": ("old.inp", []),
        "exists-not-card": ("notes.inp", ["--overwrite"]),
        "folder": ("sub", []),
        "missing-parent": ("nope/card.inp", []),
        "dot": (".", []),
        "dotdot": ("..", []),
        "empty": ("", []),
        "trailing-slash": ("new/", []),
        "under-a-file": ("afile/card.inp", []),
        "link": ("link.inp", ["--overwrite"]),
        "unwritable": ("/proc/knit-card.inp", []),
    }[case]
    before = _snapshot(work)
    code, stdout, err = _main(["export", "params.json", "--format", "abaqus", "--out", out, *extra], capsys)
    assert code == 2 and stdout == "" and err.count("\n") == 1 and err.startswith("knitframe: error: --out")
    assert _snapshot(work) == before
    assert _snapshot(work / "sub") == {}


def test_other_refusals_are_one_line_exit_2_and_write_nothing(tmp_path, capsys, fitted):
    """Bad params files and options are refused in one line, exit 2, with no file written."""
    good = tmp_path / "params.json"
    shutil.copy(fitted / "params.json", good)
    bad = {
        "null-theta": {**_params(fitted), "theta_deg": None},
        "negative-a": {**_params(fitted), "a": -1.0},
        "no-model": {"a": 0.1, "b": 1.0, "theta_deg": 30.0},
        "unknown-model": {"model": "nope"},
        "list": [1, 2],
    }
    cases = [
        [str(good), "--format", "pdf"],
        [str(good), "--format", "abaqus", "--thickness", "0"],
        [str(good), "--format", "abaqus", "--thickness", "nan"],
        [str(good), "--format", "abaqus", "--name", "a b"],
        [str(good), "--format", "abaqus", "--max-stretch", "1.3"],
        [str(good), "--format", "calculix-deck", "--max-stretch", "0.9"],
        [str(tmp_path / "missing.json"), "--format", "abaqus"],
        [str(tmp_path), "--format", "abaqus"],
    ]
    for name, content in bad.items():
        (tmp_path / f"{name}.json").write_text(json.dumps(content))
        cases.append([str(tmp_path / f"{name}.json"), "--format", "calculix"])
    (tmp_path / "text.json").write_text("not json")
    cases.append([str(tmp_path / "text.json"), "--format", "febio"])
    before = _snapshot(tmp_path)
    for args in cases:
        code, out, err = _main(["export", *args, "--out", str(tmp_path / "card.inp")], capsys)
        assert code == 2 and out == "" and err.count("\n") == 1 and err.startswith("knitframe: error: "), args
        assert _snapshot(tmp_path) == before, args


def test_overwrite_replaces_only_a_knitframe_card_atomically(tmp_path, capsys, fitted):
    """--overwrite replaces an earlier card (no temporary file left); without it the card is kept."""
    shutil.copy(fitted / "params.json", tmp_path / "params.json")
    card = tmp_path / "knit.inp"
    code, out, _ = _main(
        ["export", str(tmp_path / "params.json"), "--format", "calculix", "--out", str(card)], capsys
    )
    assert code == 0 and "wrote" in out and is_knitframe_card(card)
    first = card.read_text()
    code, _, err = _main(
        ["export", str(tmp_path / "params.json"), "--format", "abaqus", "--out", str(card)], capsys
    )
    assert code == 2 and "exists" in err and card.read_text() == first
    code, _, _ = _main(
        [
            "export",
            str(tmp_path / "params.json"),
            "--format",
            "abaqus",
            "--out",
            str(card),
            "--overwrite",
            "--thickness",
            "2",
            "--quiet",
        ],
        capsys,
    )
    assert code == 0 and card.read_text() == export_card(_params(fitted), "abaqus", thickness=2.0)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["knit.inp", "params.json"]


def test_export_command_runs_as_a_subprocess(cli, tmp_path, fitted):
    """`knitframe export PARAMS.json --format febio --out FILE` writes the same card as the API."""
    r = cli("export", str(fitted / "params.json"), "--format", "febio", "--out", str(tmp_path / "knit.xml"))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "knit.xml").read_text() == export_card(_params(fitted), "febio")


# ---------------------------------------------------------------------------------------------
# the [fit] stage option
# ---------------------------------------------------------------------------------------------
def test_fit_stage_export_writes_the_cards_and_lists_them_in_summary(fitted):
    """[fit] export = [...] writes params.<format suffix> next to params.json, as `knitframe export` would,
    listed in summary.json."""
    summary = json.loads((fitted / "summary.json").read_text())
    cards = [f"params.{s}" for s in FORMATS.values()]
    assert set(cards) <= set(summary["outputs"])
    assert summary["results"]["fit"]["cards"] == cards
    data = _params(fitted)
    for fmt, name in zip(FORMATS, cards):
        assert (fitted / name).read_text() == export_card(data, fmt, path="params.json"), fmt
    import typing

    from knitframe_stages.fit import FitTable

    hint = typing.get_type_hints(FitTable)["export"]
    assert typing.get_args(typing.get_args(hint)[0]) == tuple(FORMATS)


def test_fit_stage_refuses_an_impossible_export_before_any_work(tmp_path):
    """[fit] with hgo2m and export = ["calculix"], or a format listed twice, is refused and creates no
    folder."""
    import knitframe

    files = [str(_data_file("cotton-stockinette-x.csv"))]
    for model, export, where in (
        ("hgo2m", ["calculix"], "fit.export[0]"),
        ("hgo", ["abaqus", "abaqus"], "fit.export[1]"),
    ):
        cfg = tmp_path / f"{model}.toml"
        cfg.write_text(
            f'[data]\nreader = "singal2024"\nfiles = {json.dumps(files)}\n\n'
            f'[fit]\nmodel = "{model}"\nexport = {json.dumps(export)}\n'
        )
        with pytest.raises(ConfigError) as e:
            knitframe.run(cfg, out=tmp_path / f"out-{model}")
        assert where in str(e.value) and "\n" not in str(e.value)
        assert not (tmp_path / f"out-{model}").exists()


def test_ci_installs_calculix_before_the_test_command(tmp_path):
    """.ci/run installs calculix-ccx when apt-get exists and ccx is missing, and a failed install does not
    stop CI."""
    text = (ROOT / ".ci" / "run").read_text()
    assert text.index("apt-get install") < text.index(".venv/bin/python -m pytest")
    block = text[text.index("if ! command -v ccx") : text.index("\nfi\n") + 4]
    fake = tmp_path / "bin"
    fake.mkdir()
    (fake / "apt-get").write_text('#!/bin/sh\necho "apt-get $*" >> "$LOG"\nexit 100\n')
    (fake / "apt-get").chmod(0o755)
    env = {"PATH": str(fake), "LOG": str(tmp_path / "log")}
    proc = subprocess.run(
        ["/bin/bash", "-c", "set -euo pipefail\n" + block + "echo reached"],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
    )
    assert proc.returncode == 0 and proc.stdout.strip() == "reached", proc.stderr
    assert "will be skipped" in proc.stderr and "apt-get update" in (tmp_path / "log").read_text()
