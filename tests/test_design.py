"""Garment design: analytic checks, constraints on every design, the paper's scenario, and the
three entry points (command, config stage, API) giving the same design."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hostile.conftest import assert_refused, snapshot

import knitframe
from knitframe.garment.core import compression_class, design
from knitframe.garment.library import FabricEntry, FabricLibrary, builtin_library
from knitframe.garment.limb import Limb, example_arm
from knitframe.garment.optimise import runs
from knitframe.garment.tube import MMHG_PER_MPA, Tube


def objective(name: str, **options):
    return knitframe.get_registry()["design_objective"][name](**options)


def entry(name: str, a: float, b: float, theta_deg: float, *, pitch=(1.2, 0.9), limit=10.0, yarn="cotton"):
    return FabricEntry(
        name=name,
        pattern="jersey",
        yarn=yarn,
        stitch_length=None,
        arc_length=None,
        model="hgo",
        params={"a": a, "b": b, "theta_deg": theta_deg},
        course_pitch=pitch[0],
        wale_pitch=pitch[1],
        max_tension=limit,
        source="test values",
    )


def hgo_course_tension(a, b, theta, lam1, lam2):
    """The paper's model written out by hand: P1 = 2a (I4 − 1) exp(b (I4 − 1)²) · 2 λ1 cos²θ."""
    i4 = lam1**2 * math.cos(theta) ** 2 + lam2**2 * math.sin(theta) ** 2
    return max(2 * a * (i4 - 1) * math.exp(b * (i4 - 1) ** 2) * 2 * lam1 * math.cos(theta) ** 2, 0.0)


def assert_valid(d, min_courses: float) -> None:
    """Every region is one connected band, none below the minimum size, no element over its limit."""
    regions = d.regions()
    rows = d.fabric[:, 0]
    if d.method == "optimal":
        assert np.all(d.fabric == rows[:, None]), "a band design changes fabric only between courses"
        assert len(regions) == len(runs(rows)), "each run of rows is one region"
    first = np.concatenate([[0], np.cumsum(d.courses)])
    for r in regions:
        assert r["courses"][1] - r["courses"][0] >= min_courses - 1e-9, r
        assert first[r["rows"][1]] - first[r["rows"][0]] == pytest.approx(
            r["courses"][1] - r["courses"][0], abs=2e-3
        )
    tmax = np.array([e.max_tension for e in d.library.entries])[d.fabric]
    assert np.all(d.T1 <= tmax * (1 + 1e-9)) and d.limits_respected and not d.over_limit.any()


def test_cylinder_with_one_fabric_gives_uniform_strain_tension_and_p_equal_T_over_R():
    """On a cylinder of radius R and a smaller tube, one fabric gives uniform λ1, T and p = T/R exactly."""
    R, Ct = 40.0, 200.0
    limb = Limb.from_measurements([0.0, 300.0], [2 * math.pi * R] * 2, n_stations=21, n_around=48)
    lib = FabricLibrary("one", (entry("f", 0.05, 1.0, 40.0),))
    d = design(limb, lib, objective("stress_variance"), tube=Tube("paper", circumference=Ct), min_courses=0)
    lam = 2 * math.pi * R / Ct
    assert np.allclose(d.lam1, lam, rtol=1e-12) and np.allclose(d.lam2, 1.0, rtol=1e-12)
    T = hgo_course_tension(0.05, 1.0, math.radians(40.0), lam, 1.0)
    assert np.allclose(d.T1, T, rtol=1e-12)
    assert np.allclose(d.pressure_equivalent, T / R * MMHG_PER_MPA, rtol=1e-12)
    assert np.allclose(d.pressure_local, T / R * MMHG_PER_MPA, rtol=1e-6)
    assert d.value == pytest.approx(0.0, abs=1e-20)
    assert_valid(d, 0)


def test_cone_design_matches_the_hand_computed_two_fabric_optimum():
    """On a cone, the graduated design picks per row the fabric whose pressure is nearer the target, as by
    hand."""
    C0, C1, L, Ct = 160.0, 300.0, 400.0, 150.0
    limb = Limb.from_measurements([0.0, L], [C0, C1], n_stations=41, n_around=32)
    stiff, soft = (0.04, 1.0, 35.0), (0.004, 0.5, 40.0)
    lib = FabricLibrary("two", (entry("stiff", *stiff), entry("soft", *soft)))
    prof = objective("pressure_profile", target_mmHg=30.0, at=[0.0, 1.0], ratios=[1.0, 0.5])
    d = design(limb, lib, prof, tube=Tube("paper", circumference=Ct, length=L), min_courses=0)
    expected = []
    for i in range(40):
        z = (i + 0.5) * L / 40
        C = C0 + (C1 - C0) * z / L  # circumferences interpolate linearly between two measurements
        target = 30.0 * (1.0 - 0.5 * z / L)
        errors = []
        for a, b, th in (stiff, soft):
            p = hgo_course_tension(a, b, math.radians(th), C / Ct, 1.0) / (C / (2 * math.pi)) * MMHG_PER_MPA
            errors.append(((p - target) / target) ** 2)
        expected.append(int(np.argmin(errors)))
    assert d.fabric[:, 0].tolist() == expected
    assert 0 < sum(expected) < 40, "the optimum uses both fabrics"
    assert_valid(d, 0)


def test_scanned_cylinder_gives_the_parametric_design_within_one_percent(tmp_path):
    """An STL cylinder made with trimesh designs the same sleeve as the parametric cylinder, within 1 %."""
    import trimesh

    R, L = 45.0, 320.0
    mesh = trimesh.creation.cylinder(radius=R, height=L, sections=256)
    mesh.apply_translation([0, 0, L / 2])
    mesh.export(tmp_path / "cyl.stl")
    scan = Limb.from_scan(tmp_path / "cyl.stl", axis=[0, 0, 1], trim=0.05, n_stations=21, n_around=48)
    para = Limb.from_measurements(
        [0.0, scan.positions[-1]], [2 * math.pi * R] * 2, n_stations=21, n_around=48
    )
    lib = FabricLibrary("two", (entry("stiff", 0.04, 1.0, 35.0), entry("soft", 0.004, 0.5, 40.0)))
    prof = objective("pressure_uniformity", target_mmHg=20.0)
    a = design(scan, lib, prof, tube=Tube("knitting", needles=220), min_courses=5)
    b = design(para, lib, prof, tube=Tube("knitting", needles=220), min_courses=5)
    assert np.array_equal(a.fabric, b.fabric)
    assert a.T1.mean() == pytest.approx(b.T1.mean(), rel=0.01)
    assert a.pressure_equivalent.mean() == pytest.approx(b.pressure_equivalent.mean(), rel=0.01)
    assert a.value == pytest.approx(b.value, rel=0.01, abs=1e-4)


def test_knitting_mode_a_looser_stitch_knits_a_wider_tube():
    """On the same needles a fabric of larger course pitch is stretched less, by the ratio of the pitches."""
    limb = Limb.from_measurements([0.0, 200.0], [200.0, 200.0], n_stations=11, n_around=16)
    lib = FabricLibrary(
        "two",
        (
            entry("tight", 0.04, 1.0, 40.0, pitch=(1.0, 0.8)),
            entry("loose", 0.04, 1.0, 40.0, pitch=(1.25, 1.0)),
        ),
    )
    from knitframe.garment.assign import _fabric_fields
    from knitframe.garment.tube import element_geometry

    lam1, lam2, T1, _, courses, _ = _fabric_fields(
        lib, Tube("knitting", needles=160), element_geometry(limb), 200.0, None
    )
    assert np.allclose(lam1[0], 1.25) and np.allclose(lam1[1], 1.0)
    assert np.all(T1[0] > 0) and np.allclose(T1[1], 0.0)  # the loose tube is not stretched at all
    assert np.allclose(courses[:, 0] * 0.8, 20.0) and np.allclose(courses[:, 1] * 1.0, 20.0)


@pytest.mark.parametrize(
    "name, options",
    [
        ("stress_variance", {}),
        ("pressure_uniformity", {"target_mmHg": 20}),
        ("pressure_uniformity", {}),
        ("pressure_profile", {"target_mmHg": 25}),
    ],
)
@pytest.mark.parametrize("mode", ["knitting", "paper"])
def test_every_design_respects_its_constraints(name, options, mode):
    """For each objective and tube mode on the example arm, regions are contiguous bands, large enough, and
    within limits."""
    d = design(example_arm(), builtin_library(), objective(name, **options), tube=Tube(mode), min_courses=12)
    assert_valid(d, 12)
    assert np.isfinite(d.value) and d.value <= (d.baseline["objective"] or np.inf) + 1e-12


def test_max_fabrics_is_respected_and_reported():
    """With at most two fabrics, the design uses at most two and says what its solver guarantees."""
    d = design(
        example_arm(n_stations=21),
        builtin_library(),
        objective("pressure_profile"),
        tube=Tube("knitting", needles=150),
        min_courses=10,
        max_fabrics=2,
    )
    assert len(np.unique(d.fabric)) <= 2 and "MILP" in d.guarantee
    assert_valid(d, 10)


def test_papers_scenario_cotton_over_its_limit_is_switched_and_the_stress_cv_falls(capsys):
    """On the example arm (upper arm ≈ 2× wrist) all cotton exceeds its limit; the design fixes that and
    lowers the stress CV."""
    arm = example_arm()
    assert arm.circumference[-1] / arm.circumference[0] == pytest.approx(2.0, rel=0.05)
    lib = builtin_library()
    for method in ("paper", "optimal"):
        d = design(arm, lib, objective("stress_variance"), tube=Tube("paper"), method=method, min_courses=10)
        base = d.baseline
        assert "cotton" in base["fabric"] and base["elements_over_limit"] > 0
        assert d.limits_respected and set(np.unique(d.fabric)) != {lib.names.index(base["fabric"])}
        assert d.stress_cv() < base["stress_cv"]
        with capsys.disabled():
            print(
                f"\n{method}: stress CV {base['stress_cv']:.3f} (all {base['fabric']}, "
                f"{base['elements_over_limit']} elements over its limit) -> {d.stress_cv():.3f}, "
                f"{len(d.regions())} regions"
            )
        if method == "optimal":
            assert_valid(d, 10)


def test_compression_classes_follow_ral_gz_387():
    """Pressures fall in the RAL-GZ 387 classes I 18–21, II 23–32, III 34–46, IV ≥ 49, with the gaps named."""
    assert [compression_class(p) for p in (10, 18, 21, 22, 25, 33, 40, 47, 60)] == [
        "below I",
        "I",
        "I",
        "between I and II",
        "II",
        "between II and III",
        "III",
        "between III and IV",
        "IV",
    ]


def test_command_stage_and_api_give_the_same_design(tmp_path, cli):
    """`knitframe design --example`, a [design] config and knitframe.design() write the same design."""
    proc = cli("design", "--example", "--target-mmHg", "25", "--out", "cli", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    cli = json.loads((tmp_path / "cli" / "design.json").read_text())
    summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert sorted(summary["outputs"]) == [
        "design.json",
        "design.vtu",
        "knit-map.csv",
        "knit-map.png",
        "pressure.png",
    ]
    for name in ("knit-map.png", "pressure.png"):
        assert (tmp_path / "cli" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = (tmp_path / "cli" / "knit-map.csv").read_text().splitlines()
    assert len(rows) == 1 + 40 * 64 and rows[0].startswith("row,column,course_start")
    (tmp_path / "d.toml").write_text(
        '[design]\nlimb = "example"\nobjective = { kind = "pressure_profile", target_mmHg = 25.0 }\n'
    )
    staged = json.loads(
        (knitframe.run(tmp_path / "d.toml", tmp_path / "stage").out / "design.json").read_text()
    )
    api = knitframe.design("example", objective={"kind": "pressure_profile", "target_mmHg": 25.0})
    for other in (staged, api.to_json()):
        assert other["objective"]["value"] == pytest.approx(cli["objective"]["value"], rel=1e-12)
        assert other["regions"] == cli["regions"] and other["tube"] == cli["tube"]
    assert cli["limits_respected"] is True and len(cli["stations"]) == 40
    assert {"distal", "largest", "top"} <= set(cli["standard_positions"])


def test_third_party_objective_plugs_in_through_the_hook():
    """An objective registered by another package is found by name and drives the design."""
    import types

    import attrs

    from knitframe.plugins import load_registry

    @attrs.frozen
    class MaxPressure:
        name = "max_pressure"
        description = "keep the highest pressure low"
        quantity = "pressure"
        relative = False

        def score(self, tension, area, radius=None):
            return float(np.max(tension))

        def element_cost(self, value, area, position, level=None):
            return np.asarray(area) * np.asarray(value) ** 4

        def evaluate(self, value, area, position):
            return float(np.max(value))

    plugin = types.ModuleType("third")

    @knitframe.hookimpl
    def register_design_objectives(register):
        register(MaxPressure)

    plugin.register_design_objectives = register_design_objectives
    reg = load_registry({"third": plugin})
    d = design(
        example_arm(n_stations=21),
        builtin_library(),
        reg["design_objective"]["max_pressure"](),
        tube=Tube("knitting", needles=50),
        min_courses=5,
    )
    soft = min(range(len(d.library.entries)), key=lambda f: d.library.entries[f].tensions(1.3, 1.0)[0])
    assert d.value == pytest.approx(d.pressure_equivalent.max()) and soft in np.unique(d.fabric)


BAD = [
    ("empty-scan", "arm.stl", lambda p: (p / "arm.stl").write_bytes(b""), ["arm.stl"]),
    ("garbage-scan", "arm.stl", lambda p: (p / "arm.stl").write_bytes(b"\x00\x01garbage" * 20), ["arm.stl"]),
    ("missing-scan", "LIMB", lambda p: None, ["nope.stl"]),
    ("unknown-objective", "--objective", lambda p: None, ["--example", "--objective", "softest"]),
    ("negative-target", "--target-mmHg", lambda p: None, ["--example", "--target-mmHg", "-5"]),
    ("nan-target", "--target-mmHg", lambda p: None, ["--example", "--target-mmHg", "nan"]),
    ("ratios-not-numbers", "--ratios", lambda p: None, ["--example", "--ratios", "1,half"]),
    ("too-few-needles", "--needles", lambda p: None, ["--example", "--needles", "2"]),
    ("negative-min-courses", "--min-courses", lambda p: None, ["--example", "--min-courses", "-1"]),
    ("zero-fabrics", "--max-fabrics", lambda p: None, ["--example", "--max-fabrics", "0"]),
    ("missing-library", "--library", lambda p: None, ["--example", "--library", "nolib.json"]),
    ("no-limb", "LIMB", lambda p: None, []),
    ("two-limbs", "LIMB", lambda p: None, ["--example", "x.stl"]),
    ("circumferences-without-positions", "--positions", lambda p: None, ["--circumferences", "160,300"]),
    ("paper-method-knitting-mode", "design.method", lambda p: None, ["--example", "--method", "paper"]),
]


@pytest.mark.parametrize("case, field, make, args", BAD, ids=[c[0] for c in BAD])
def test_bad_design_input_is_one_line_and_writes_nothing(tmp_path, cli, case, field, make, args):
    """Bad limbs, libraries and options are refused in one line naming the option, and nothing is written."""
    make(tmp_path)
    before = snapshot(tmp_path)
    proc = cli("design", *args, "--out", "out", cwd=tmp_path)
    assert_refused(proc, field, before=before, folder=tmp_path)
