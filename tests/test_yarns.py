"""Yarn library, config resolution, yarn models (stress, tangent, rod, contact) and fits to test files."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from knitframe_yarns.law import linear_stiffness
from knitframe_yarns.library import resolve_yarn

from knitframe import ConfigError, DataError, NumericalError, Yarn, get_registry
from knitframe.testing.patterns import derivative_errors
from knitframe.yarn import yarn_properties
from knitframe.yarn.fit import (
    fit_compression,
    fit_tension,
    fit_yarn,
    line_contact_approach,
    line_contact_load,
    pretension,
)

DATA = Path(__file__).parent / "data" / "yarn"
_spec = importlib.util.spec_from_file_location("yarn_make", DATA / "make.py")
make = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make)


def test_library_has_the_papers_yarns_with_sources():
    """cotton, nylon and pet carry the paper's diameters, a 1e-4 transverse ratio (cotton, nylon) and a
    source."""
    yarns = get_registry()["yarn"]
    assert (yarns["cotton"].d0, yarns["cotton"].dk) == (0.445, 0.444)
    assert (yarns["nylon"].d0, yarns["nylon"].dk) == (0.951, 0.334)
    assert yarns["pet"].dk == 0.178 and yarns["pet"].isotropic and yarns["pet"].model == "isotropic"
    for name in ("cotton", "nylon"):
        assert yarns[name].E_transverse == pytest.approx(1e-4 * yarns[name].E_axial)
        assert yarns[name].model == "transverse_isotropic"
    assert all(yarns[n].source for n in yarns)


def test_resolve_yarn_from_name_table_and_like():
    """A yarn comes from a library name, a full table, or a library yarn with overrides."""
    reg = get_registry()
    assert resolve_yarn(reg, "cotton", "fabric.yarn") is reg["yarn"]["cotton"]
    table = {"d0": 0.5, "dk": 0.4, "E_axial": 900.0, "E_transverse": 0.09}
    mine = resolve_yarn(reg, table, "yarns.myyarn")
    assert mine.name == "myyarn" and mine.E_axial == 900.0 and "yarns.myyarn" in mine.source
    thin = resolve_yarn(reg, {"like": "cotton", "dk": 0.4}, "yarns.thin")
    assert (thin.name, thin.d0, thin.dk, thin.E_axial) == ("thin", 0.445, 0.4, reg["yarn"]["cotton"].E_axial)


@pytest.mark.parametrize(
    "value, message",
    [
        ("wool", "yarns.x: unknown yarn 'wool'; available: acrylic, cotton, nylon, pearl-cotton, pet"),
        ({"like": "cotton", "dk": -1}, "yarns.x.dk: must be > 0"),
        ({"like": "cotton", "colour": "red"}, "yarns.x.colour: unknown key"),
        ({"d0": 0.5}, "yarns.x.dk: required key is missing"),
        (3, "yarns.x: expected a yarn name or a table"),
    ],
)
def test_resolve_yarn_errors_name_the_path(value, message):
    """Bad yarn config values give one-line ConfigErrors naming the TOML path."""
    with pytest.raises(ConfigError) as e:
        resolve_yarn(get_registry(), value, "yarns.x")
    assert str(e.value).startswith(message) and "\n" not in str(e.value)


@pytest.mark.parametrize("yarn", ["cotton", "nylon", "pet"])
def test_stress_and_tangent_match_finite_differences(yarn):
    """P = ∂W/∂F and A = ∂P/∂F hold to finite-difference accuracy for each library yarn's model."""
    reg = get_registry()
    y = reg["yarn"][yarn]
    model = reg["yarn_model"][y.model].from_yarn(y)
    rng = np.random.default_rng(3)
    F = np.eye(3) + 0.1 * rng.standard_normal((2, 3, 3, 3))  # (..., 3, 3) with two batch axes
    a = rng.standard_normal((2, 3, 3))
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    eP, eA = derivative_errors(model, F, a)
    assert eP < 1e-6 and eA < 1e-6, (eP, eA)


def test_transverse_isotropic_linearises_to_the_engineering_constants():
    """At F = I the tangent equals the linear transversely isotropic stiffness from E_A, E_T, G_A, ν."""
    model = get_registry()["yarn_model"]["transverse_isotropic"](
        E_axial=50.0, E_transverse=3.0, G_axial=1.2, nu=0.3, radius=0.2
    )
    _, _, A = model.evaluate(np.eye(3), np.array([1.0, 0.0, 0.0]))
    C = linear_stiffness(50.0, 3.0, 1.2, 0.3)
    voigt = [(0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1)]
    for I, (i, j) in enumerate(voigt):
        for J, (k, l) in enumerate(voigt):
            assert A[i, j, k, l] == pytest.approx(C[I, J], abs=1e-9)
    # uniaxial stress along the fibre: the compliance gives back E_A
    strain = np.linalg.solve(C[:3, :3], [1.0, 0.0, 0.0])
    assert 1.0 / strain[0] == pytest.approx(50.0)


def test_fibre_direction_follows_the_yarn_tangent():
    """Stretching along the fibre costs E_A, across it E_T-level energy (transverse isotropy)."""
    model = get_registry()["yarn_model"]["transverse_isotropic"](
        E_axial=100.0, E_transverse=1.0, nu=0.3, radius=0.2
    )
    F = np.diag([1.001, 1.0, 1.0])
    along = model.energy(F, np.array([1.0, 0, 0]))
    across = model.energy(F, np.array([0, 1.0, 0]))
    assert along / across > 50


def test_rod_stiffnesses():
    """EA = E π r², EI = E π r⁴/4 (or the fitted bending modulus), GJ = G π r⁴/2."""
    reg = get_registry()
    y = reg["yarn"]["pet"]
    m = reg["yarn_model"]["isotropic"].from_yarn(y)
    r = y.dk / 2
    assert m.EA == pytest.approx(y.E_axial * np.pi * r**2)
    assert m.EI == pytest.approx(y.E_axial * np.pi * r**4 / 4)
    assert m.GJ == pytest.approx(y.E_axial / (2 * (1 + y.nu)) * np.pi * r**4 / 2)
    fitted = reg["yarn_model"]["isotropic"](E_axial=y.E_axial, radius=r, bending_modulus=0.07)
    assert fitted.EI == 0.07


def test_line_contact_inverse_and_tangent_stiffness():
    """contact_load inverts contact_approach and contact_stiffness is its derivative."""
    reg = get_registry()
    m = reg["yarn_model"]["transverse_isotropic"].from_yarn(reg["yarn"]["cotton"])
    f = np.geomspace(1e-6, 1e-2, 7)
    d = m.contact_approach(f)
    assert np.all(np.diff(d) > 0)
    assert np.allclose(m.contact_load(d), f, rtol=1e-9)
    h = 1e-6 * f
    fd = 2 * h / (m.contact_approach(f + h) - m.contact_approach(f - h))
    assert np.allclose(m.contact_stiffness(f), fd, rtol=1e-5)


def test_line_contact_matches_hertz_half_width_and_scaling():
    """δ(f) follows the Hertz form: for two cylinders twice a cylinder on a flat of the doubled modulus
    term."""
    R, E, nu, f = 0.2, 1.0, 0.3, np.array([1e-4, 1e-3])
    k = (1 - nu**2) / E
    b = np.sqrt(4 * f * R * k / np.pi)  # two identical cylinders: R* = R/2, E* = 1/(2k)
    expected = 2 * (2 * f / np.pi) * k * (np.log(4 * R / b) - 0.5)
    assert np.allclose(line_contact_approach(f, R, E, nu), expected, rtol=1e-14)
    with pytest.raises(NumericalError, match="beyond the Hertz law"):
        line_contact_load(np.array([10.0]), R, E, nu)
    assert pretension(0.01, 2.0) == pytest.approx(0.02)


@pytest.mark.parametrize("name", list(make.CASES))
def test_fits_recover_known_parameters_from_noisy_synthetic_tests(name, tmp_path):
    """Fits to the noisy synthetic tension and compression tests recover E_axial, failure strain,
    E_T and f_k."""
    p = make.CASES[name]
    make.main(tmp_path)
    t = fit_tension(tmp_path / f"{name}_tension.csv", diameter=p["dk"])
    assert t.E_axial == pytest.approx(p["E_axial"], rel=0.03)
    assert t.failure_strain == pytest.approx(p["failure_strain"], rel=0.03)
    c = fit_compression(tmp_path / f"{name}_compression.csv", d0=p["d0"], dk=p["dk"], nu=p["nu"])
    assert c.E_transverse == pytest.approx(p["E_transverse"], rel=0.05)
    assert c.precompression == pytest.approx(p["precompression"], rel=0.05)
    assert c.pressure == pytest.approx(c.precompression / p["dk"])
    y = fit_yarn(
        name,
        d0=p["d0"],
        dk=p["dk"],
        tension=tmp_path / f"{name}_tension.csv",
        compression=tmp_path / f"{name}_compression.csv",
    )
    assert isinstance(y, Yarn) and y.model == "transverse_isotropic" and "fitted" in y.source


def test_committed_yarn_csvs_are_the_generators_output(tmp_path):
    """The CSVs in tests/data/yarn are exactly what make.py writes (nobody typed them by hand)."""
    for path in make.main(tmp_path):
        assert path.read_text() == (DATA / path.name).read_text(), f"regenerate {path.name} with make.py"


def _write(tmp_path, text: str) -> Path:
    p = tmp_path / "t.csv"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "text, message",
    [
        ("# test: tension\n# gauge_length_mm: 50\ndisplacement_mm,load\n0,0\n", "missing column 'force_N'"),
        (
            "# gauge_length_mm: 50\ndisplacement_mm,force_N\n0,0\n1,1\n2,x\n3,3\n4,4\n",
            "line 5, column 'force_N': expected a number",
        ),
        ("displacement_mm,force_N\n0,0\n1,1\n2,2\n3,3\n4,4\n", "missing header line '# gauge_length_mm"),
        (
            "# gauge_length_mm: -5\ndisplacement_mm,force_N\n0,0\n1,1\n2,2\n3,3\n4,4\n",
            "'gauge_length_mm' must be > 0",
        ),
        (
            "# test: compression\n# gauge_length_mm: 5\ndisplacement_mm,force_N\n0,0\n1,1\n2,2\n3,3\n4,4\n",
            "expected a tension test",
        ),
        (
            "# gauge_length_mm: 5\ndisplacement_mm,force_N\n0,0\n1,-1\n2,-2\n3,-3\n4,-4\n",
            "force never becomes positive",
        ),
        ("# gauge_length_mm: 5\ndisplacement_mm,force_N\n0,0\n1,1\n", "at least 5 data rows"),
    ],
)
def test_bad_tension_files_give_one_line_data_errors(tmp_path, text, message):
    """Malformed tension files raise a one-line DataError naming the file and the problem."""
    with pytest.raises(DataError) as e:
        fit_tension(_write(tmp_path, text), diameter=0.4)
    assert message in str(e.value) and "t.csv" in str(e.value) and "\n" not in str(e.value)


def test_compression_that_never_reaches_dk_is_a_data_error(tmp_path):
    """A compression test whose plate stops before the yarn reaches dk is rejected with a clear message."""
    text = "# yarns: 10\n# plate_length_mm: 25\ndisplacement_mm,force_N\n" + "".join(
        f"{u / 100},{u}\n" for u in range(10)
    )
    with pytest.raises(DataError, match="never compressing d0 = 0.951 to dk = 0.334"):
        fit_compression(_write(tmp_path, text), d0=0.951, dk=0.334)


def test_yarn_record_says_what_is_measured_and_derives_the_rest():
    """Every quantity a solver reads is in ``yarn_properties``, marked measured, estimate or derived."""
    cot = get_registry()["yarn"]["cotton"]
    rows = {p.symbol: p for p in yarn_properties(cot)}
    assert rows["dk"].status == "measured" and rows["E_A"].status == "estimate"
    assert rows["G_A"].status == "derived" and rows["G_A"].value == pytest.approx(0.12 / 2.6)
    assert rows["EI"].status == "derived" and rows["EI"].value == pytest.approx(1200 * np.pi * 0.444**4 / 64)
    # φk = (tex/ρ)/(π dk²/4): 59 tex of cotton (1.52 g/cm³) in a 0.444 mm yarn
    phi = 59e-3 / 1.52 / (np.pi * 0.444**2 / 4)
    assert rows["φk"].value == pytest.approx(phi) and rows["J_min"].status == "derived"
    assert rows["J_min"].value == pytest.approx(phi / (np.pi / (2 * np.sqrt(3))))
    assert rows["E_core"].value == 1200.0
    pearl = {p.symbol: p for p in yarn_properties(get_registry()["yarn"]["pearl-cotton"])}
    assert pearl["EI"].status == "measured" and pearl["EI"].value == 0.0708
    given = Yarn(
        name="y",
        d0=0.5,
        dk=0.4,
        E_axial=100,
        E_transverse=0.01,
        compaction_limit=0.4,
        measured=["compaction_limit"],
    )
    assert (
        given.compaction == 0.4
        and {p.symbol: p for p in yarn_properties(given)}["J_min"].status == "measured"
    )
    assert Yarn(name="y", d0=0.5, dk=0.4, E_axial=100, E_transverse=0.01).compaction == 0.5  # nothing known


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"measured": ["E_axial", "colour"]}, "measured: unknown field 'colour'"),
        ({"tex": 500.0, "fibre_density": 1.5}, "tex: 500 tex of fibre of 1.5 g/cm³ does not fit"),
        ({"compaction_limit": 1.5}, "compaction_limit"),
    ],
)
def test_yarn_record_refuses_impossible_packings(fields, message):
    with pytest.raises(ConfigError) as e:
        resolve_yarn(get_registry(), {"like": "cotton", **fields}, "yarns.x")
    assert message in str(e.value) and "\n" not in str(e.value)


def test_compaction_barrier_matches_finite_differences_and_stops_at_the_limit():
    """W_c, P and A of the compaction barrier: P = ∂W/∂F and A = ∂P/∂F inside the band and on its
    quadratic continuation; zero above x₁ = (1 + c)/2; d²W/dx² = E_core mid-band and 69 E_core below."""
    from knitframe_yarns.law import compaction_barrier

    c, E = 0.3, 50.0
    a = np.array([[1.0, 0.0, 0.0]] * 4)
    # squeeze across the fibre (y) to section ratios x ≈ 0.29 (past the limit), 0.35, 0.5, 0.9, with shear
    x = np.array([0.29, 0.35, 0.5, 0.9])
    F = np.array([[[1.05, 0.02, 0.0], [0.01, s, 0.03], [0.0, 0.0, 1.0]] for s in x])
    W, P, A = compaction_barrier(F, a, c, E)
    assert W[3] == 0.0 and np.all(P[3] == 0.0) and np.all(W[:3] > 0) and np.isfinite(W[0])
    h = 1e-6
    for k in range(3):
        for L in range(3):
            Fp, Fm = F.copy(), F.copy()
            Fp[:, k, L] += h
            Fm[:, k, L] -= h
            (Wp, Pp, _), (Wm, Pm, _) = compaction_barrier(Fp, a, c, E), compaction_barrier(Fm, a, c, E)
            np.testing.assert_allclose(P[:, k, L], (Wp - Wm) / (2 * h), rtol=1e-6, atol=1e-9)
            np.testing.assert_allclose(A[..., k, L], (Pp - Pm) / (2 * h), rtol=1e-5, atol=1e-6)

    # the modulus d²W/dx² along a pure squeeze: E_core at x_m = (c + x₁)/2, 69 E_core past the limit
    def modulus(x0):
        ws = [
            compaction_barrier(np.diag([1.0, x0 + d, 1.0])[None], a[:1], c, E)[0][0] for d in (-1e-4, 0, 1e-4)
        ]
        return (ws[0] - 2 * ws[1] + ws[2]) / 1e-8

    assert modulus(0.5 * (c + 0.5 * (1 + c))) == pytest.approx(E, rel=1e-4)
    assert modulus(0.25) == pytest.approx(69.3 * E, rel=1e-2)


def test_both_solvers_read_the_compaction_limit_and_core_modulus_of_the_record():
    """The rod's contact core is J_min·dk with the yarn's core modulus; the solid's barrier the same J_min."""
    from knitframe_contact.rod_penalty import RodPenalty
    from knitframe_solvers.rod import rod_stiffness

    reg = get_registry()
    cot = reg["yarn"]["cotton"]
    law = RodPenalty().for_yarn(cot)
    assert law.core == pytest.approx(cot.compaction)
    assert RodPenalty(core=0.4).for_yarn(cot).core == 0.4  # an explicit core stays
    soft = rod_stiffness(Yarn(**{**cot.to_dict(), "core_modulus": 12.0}), reg, RodPenalty())
    assert soft["k_core"] == pytest.approx(rod_stiffness(cot, reg, RodPenalty())["k_core"] / 100)
    model = reg["yarn_model"]["transverse_isotropic"].from_yarn(cot)
    assert model.compaction == pytest.approx(cot.compaction) and model.core_modulus == 1200.0


def test_effective_bending_is_the_timoshenko_stiffness_of_the_record():
    """EI_eff = EI/(1 + EI k²/(κ G_A A)): the solid section for a stiff shear modulus, κ G_A A/k² for a
    soft one, a measured bending stiffness unchanged; for pearl cotton the derived value is within 25 %
    of the measured one at its stitch length."""
    from knitframe.yarn import SHEAR_COEFFICIENT, effective_bending

    reg = get_registry()
    cot = reg["yarn"]["cotton"]
    k = 2 * np.pi / 4.7
    area = np.pi * cot.dk**2 / 4
    assert effective_bending(cot, 4.7) == pytest.approx(
        cot.EI / (1 + cot.EI * k**2 / (SHEAR_COEFFICIENT * cot.G_A * area))
    )
    assert effective_bending(cot, 4.7) == pytest.approx(SHEAR_COEFFICIENT * cot.G_A * area / k**2, rel=2e-3)
    pet = reg["yarn"]["pet"]
    assert effective_bending(pet, 1e3) == pytest.approx(pet.EI, rel=1e-5)
    pearl = reg["yarn"]["pearl-cotton"]
    assert effective_bending(pearl, 11.28) == 0.0708
    derived = effective_bending(Yarn(**{**pearl.to_dict(), "bending_stiffness": None}), 11.28)
    assert derived == pytest.approx(0.0708, rel=0.25)
