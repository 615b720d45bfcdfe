"""Shaped knitted tubes: the needle count follows the limb under the machine's rules, the optimiser is
exact, every design keeps its invariants, the safety ceiling and bands hold, and the command reports."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from hostile.conftest import assert_refused, snapshot
from test_design import objective

from knitframe.errors import ConfigError, KnitframeWarning
from knitframe.garment.core import design
from knitframe.garment.library import FabricLibrary, builtin_library
from knitframe.garment.limb import Limb, example_arm
from knitframe.garment.optimise import NoAssignment
from knitframe.garment.optimise_shaped import solve_shaped
from knitframe.garment.prescription import CUFF
from knitframe.garment.safety import DEFAULT_CEILING
from knitframe.garment.shaping import MachineRules, allowed_change, check_course_needles

#: Laplace's law by hand: T (N/mm) / r (mm) is MPa; 1 mmHg = 133.322 Pa, so 1 MPa = 7500.6 mmHg
MMHG_PER_MPA = 1e6 / 133.322
LIBRARY = builtin_library()


def cylinder(circumference: float, length: float = 400.0, **kwargs) -> Limb:
    return Limb.from_measurements([0.0, length], [circumference] * 2, **kwargs)


def station_means(d) -> np.ndarray:
    return d.pressure_equivalent.mean(axis=1)


def hand_pressure(entry, lam1, lam2, radius) -> np.ndarray:
    """Station pressure (mmHg) of a fabric at stretches (λ1, λ2) on a radius, by Laplace's law."""
    lam1 = np.asarray(lam1, dtype=np.float64)
    T1 = np.maximum(entry.tensions(lam1, np.full_like(lam1, lam2))[0], 0.0)
    return T1 / radius * MMHG_PER_MPA


# -- needle counts on simple limbs --------------------------------------------------------------------


@pytest.mark.parametrize(
    "name, options",
    [
        ("pressure_uniformity", {"target_mmHg": 20.0}),
        ("pressure_profile", {"target_mmHg": 20.0, "graduation": "flat"}),
    ],
)
def test_cylinder_with_a_flat_target_needs_no_shaping(name, options):
    """On a cylinder with a flat 20 mmHg target every row has the same needle count, fabric and pressure."""
    d = design(cylinder(250.0, n_stations=41, n_around=32), LIBRARY, objective(name, **options))
    assert len(set(d.row_needles.tolist())) == 1 and len(np.unique(d.fabric)) == 1
    assert len(set(d.needles_per_course().tolist())) == 1
    p = station_means(d)
    assert np.ptp(p) <= 1e-12 * p.mean()
    assert p.mean() == pytest.approx(20.0, rel=0.05)


CONE_FABRICS = [FabricLibrary(e.name, (e,)) for e in LIBRARY.entries] + [LIBRARY]


@pytest.mark.parametrize("library", CONE_FABRICS, ids=[lib.name for lib in CONE_FABRICS])
def test_cone_needle_count_follows_the_circumference(library):
    """On a linear cone with a flat target every row's needle count is the best for its fabric, computed
    by hand: next to C_i/(c λ*) where λ* gives the target, rising with the cone for one fabric."""
    C0, C1, L, rows = 160.0, 300.0, 400.0, 40
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", KnitframeWarning)  # a rib's few needles step coarsely
        d = design(
            Limb.from_measurements([0.0, L], [C0, C1], n_stations=rows + 1, n_around=32),
            library,
            objective("pressure_uniformity", target_mmHg=20.0),
        )
    z = (np.arange(rows) + 0.5) * L / rows
    C = C0 + (C1 - C0) * z / L  # the row's mean circumference
    r = C / (2 * math.pi)
    slant = math.hypot(L / rows, (C1 - C0) / rows / (2 * math.pi))  # a row's length along the cone
    counts = np.arange(8, 541)
    for i, f in enumerate(d.fabric[:, 0]):
        e = library.entries[int(f)]
        k = max(1, round(slant / e.wale_pitch))  # courses for the axial stretch 1
        lam2 = slant / (k * e.wale_pitch)
        lam1 = C[i] / (counts * e.course_pitch)
        p = hand_pressure(e, lam1, lam2, r[i])
        T1 = p * r[i] / MMHG_PER_MPA
        ok = (T1 <= e.max_tension) & (lam1 <= (e.max_stretch or np.inf)) & (p <= DEFAULT_CEILING)
        assert d.row_needles[i] == counts[ok][np.argmin((p[ok] - 20.0) ** 2)], i
        lo, hi = 1.0, e.max_stretch or 3.0  # λ* by bisection: the stretch that gives 20 mmHg here
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if hand_pressure(e, [mid], lam2, r[i])[0] < 20.0 else (lo, mid)
        assert abs(d.row_needles[i] - C[i] / (e.course_pitch * lo)) < 1.0, i
        assert d.courses[i] == k
    step = allowed_change(d.courses[:-1], d.rules)
    assert np.all(np.abs(np.diff(d.row_needles)) <= step)
    if len(library.entries) == 1:
        assert np.all(np.diff(d.row_needles) >= 0) and d.row_needles[-1] > d.row_needles[0]


# -- the robustness bands by hand -----------------------------------------------------------------------


@pytest.mark.parametrize("x, e", [(0.03, 0.05), (0.08, 0.02)])
def test_bands_on_a_cylinder_match_laplace_by_hand(x, e):
    """On a cylinder the circumference band is T1(λ1(1+s), λ2)/(r(1+s)) and the pitch band T1(λ1/(1+e),
    λ2)/r over s, e from −x to +x, by hand; the ends alone bound both (the law is monotone)."""
    C = 250.0
    d = design(
        cylinder(C, n_stations=21, n_around=32),
        LIBRARY,
        objective("pressure_uniformity", target_mmHg=20.0),
        tolerance=x,
        pitch_error=e,
    )
    entry = LIBRARY.entries[int(d.fabric[0, 0])]
    r = C / (2 * math.pi)
    lam1 = C / (d.row_needles[0] * entry.course_pitch)
    lam2 = float(d.lam2[0, 0])
    assert np.allclose(d.lam1, lam1, rtol=1e-12) and np.allclose(d.lam2, lam2, rtol=1e-12)
    bands = d.bands()
    for key, half, pressure in (
        ("circumference", x, lambda s: hand_pressure(entry, [lam1 * (1 + s)], lam2, r * (1 + s))[0]),
        ("pitch", e, lambda s: hand_pressure(entry, [lam1 / (1 + s)], lam2, r)[0]),
    ):
        grid = [pressure(s) for s in np.linspace(-half, half, 5)]
        ends = [pressure(s) for s in (-half, 0.0, half)]
        for expected in (grid, ends):
            assert np.allclose(bands[key][:, 0], min(expected), rtol=1e-10, atol=0), key
            assert np.allclose(bands[key][:, 1], max(expected), rtol=1e-10, atol=0), key
    assert bands["circumference"][0, 0] < station_means(d)[0] < bands["circumference"][0, 1]


# -- the shaped optimiser against brute force ---------------------------------------------------------


def brute_force(cost, courses, change, min_courses) -> float:
    """The least cost over every (fabric, needles) of every row that meets the run and shaping rules."""
    R, F, n = cost.shape
    pick = np.indices((F * n,) * R).reshape(R, -1).T  # every sequence of (fabric, needles) states
    f, N = np.divmod(pick, n)
    ok = feasible(f, N, courses, change, min_courses)
    return float(np.where(ok, cost[np.arange(R), f, N].sum(axis=1), np.inf).min())


def feasible(f, N, courses, change, min_courses) -> np.ndarray:
    """(S,) whether each of S sequences (rows of ``f`` and ``N``) keeps every fabric run at least
    ``min_courses`` long and every needle change within ``change`` of its row."""
    f, N = np.atleast_2d(f), np.atleast_2d(N)
    R = f.shape[1]
    ok = np.all(np.abs(np.diff(N, axis=1)) <= change[np.arange(R - 1), f[:, :-1]], axis=1)
    k = courses[np.arange(R), f]
    run = k[:, 0]
    for i in range(1, R):
        new = f[:, i] != f[:, i - 1]
        ok &= ~new | (run >= min_courses - 1e-9)
        run = np.where(new, k[:, i], run + k[:, i])
    return ok & (run >= min_courses - 1e-9)


def test_shaped_optimiser_finds_the_brute_force_optimum():
    """On 200 random small problems (limits, courses, change limits, minimum runs) the dynamic programme
    returns the exhaustive optimum, and its rows and needles cost that and meet the rules."""
    rng = np.random.default_rng(2026)
    solved = refused = 0
    for _ in range(200):
        R, F, n = (int(v) for v in rng.integers(1, [5, 4, 5], endpoint=True))
        cost = rng.random((R, F, n))
        cost[rng.random(cost.shape) < 0.2] = np.inf
        courses = rng.integers(1, 5, (R, F), endpoint=True)
        change = rng.integers(0, 3, (R, F), endpoint=True)
        m = float(rng.choice([rng.integers(0, 9), rng.uniform(0, 9)]))
        best = brute_force(cost, courses, change, m)
        if not np.isfinite(best):
            with pytest.raises(NoAssignment):
                solve_shaped(cost, courses, change, m)
            refused += 1
            continue
        sol = solve_shaped(cost, courses, change, m)
        assert sol.cost == pytest.approx(best, rel=1e-12, abs=1e-12)
        assert cost[np.arange(R), sol.rows, sol.needles].sum() == pytest.approx(best, rel=1e-12, abs=1e-12)
        assert feasible(sol.rows, sol.needles, courses, change, m).all()
        solved += 1
    assert solved >= 100 and refused >= 10


# -- invariants of every design -------------------------------------------------------------------------

ADULT_ARM = ([0.0, 120.0, 220.0, 300.0, 430.0], [155.0, 230.0, 245.0, 270.0, 300.0])
CASES = {
    "example arm": (example_arm, {}, {}),
    "class III arm-sleeve": (example_arm, {"compression_class": "III", "graduation": "arm-sleeve"}, {}),
    "adult arm": (lambda: Limb.from_measurements(*ADULT_ARM), {}, {}),
    "leg class II": (
        lambda: Limb.from_measurements([0.0, 450.0], [210.0, 380.0]),
        {"compression_class": "II"},
        {},
    ),
    "robust": (example_arm, {}, {"robust": True}),
    "tighter rules": (example_arm, {}, {"rules": MachineRules(max_change=1, every=4)}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_every_shaped_design_keeps_its_invariants(case, capsys):
    """Every design shapes within the machine's rules course by course, keeps every element within its
    fabric's limits and every station under the ceiling, and meets its prescription (all stations within
    ±20 %, RMS at most 10 % away from the cuffs)."""
    make, options, kwargs = CASES[case]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", KnitframeWarning)  # local peaks at the flattened wrist
        d = design(make(), LIBRARY, objective("pressure_profile", **options), **kwargs)
    rules = kwargs.get("rules", MachineRules())
    assert d.rules == rules
    courses = np.round(d.courses).astype(int)
    assert np.allclose(d.courses, courses)
    assert np.all(np.abs(np.diff(d.row_needles)) <= allowed_change(courses[:-1], rules))
    per_course = d.needles_per_course()
    assert check_course_needles(per_course, rules) == []
    assert len(per_course) == courses.sum()
    assert np.array_equal(per_course[np.concatenate([[0], np.cumsum(courses)[:-1]])], d.row_needles)
    assert rules.min_needles <= d.row_needles.min() and d.row_needles.max() <= rules.max_needles
    tmax = np.array([e.max_tension for e in LIBRARY.entries])[d.fabric]
    smax = np.array([e.max_stretch or np.inf for e in LIBRARY.entries])[d.fabric]
    assert d.limits_respected and np.all(d.T1 <= tmax) and np.all(d.lam1 <= smax)
    assert station_means(d).max() <= DEFAULT_CEILING
    rx = d.prescription()
    away = rx["away_from_cuffs"]
    body = (d.geometry.position >= CUFF) & (d.geometry.position <= 1 - CUFF)
    assert away["stations"] == body.sum()
    with capsys.disabled():
        print(
            f"\n{case}: RMS {100 * away['rms_error']:.1f} %, worst {100 * away['worst_error']:.1f} % away "
            f"from the cuffs ({away['stations_inside']} of {away['stations']} inside; all stations "
            f"{rx['all']['stations_inside']} of {rx['all']['stations']}); needles "
            f"{d.row_needles.min()}–{d.row_needles.max()}, {len(d.regions())} regions, "
            f"{len(d.local_peaks())} local peaks, max station {station_means(d).max():.1f} mmHg"
        )
    assert rx["inside"].all(), np.flatnonzero(~rx["inside"])
    assert away["rms_error"] <= 0.10


# -- safety -------------------------------------------------------------------------------------------


def test_a_free_pressure_level_takes_class_two_not_a_dangerous_pressure():
    """pressure_uniformity without a target on a 35 mm-radius cylinder warns naming class II and designs
    near its 27.5 mmHg, every station under the 60 mmHg ceiling."""
    with pytest.warns(KnitframeWarning, match="class II"):
        d = design(
            cylinder(2 * math.pi * 35.0, 300.0, n_stations=21, n_around=32),
            LIBRARY,
            objective("pressure_uniformity"),
        )
    p = station_means(d)
    assert p.max() <= DEFAULT_CEILING
    assert d.objective.target_mmHg == 27.5 and np.allclose(p, 27.5, rtol=0.05)
    assert any("class II" in note for note in d.notes)


def test_the_ceiling_holds_every_station_and_refuses_a_target_above_it():
    """With the ceiling at the target, every station mean is at most the ceiling (the free optimum rounds
    above it); a free level whose class II target is above the ceiling is refused in one line."""
    limb = cylinder(250.0, n_stations=41, n_around=32)
    free = design(limb, LIBRARY, objective("pressure_uniformity", target_mmHg=20.0))
    assert station_means(free).max() > 20.0, "the needle steps round this cylinder's optimum above 20"
    capped = design(limb, LIBRARY, objective("pressure_uniformity", target_mmHg=20.0), ceiling=20.0)
    assert station_means(capped).max() <= 20.0
    with pytest.warns(KnitframeWarning, match="class II"), pytest.raises(ConfigError) as err:
        design(limb, LIBRARY, objective("pressure_uniformity"), ceiling=20.0)
    assert "\n" not in str(err.value) and "ceiling" in str(err.value) and "20" in str(err.value)


def test_a_bony_ridge_reports_local_peaks_and_warns_naming_the_station():
    """On a flat elliptic limb (minor/major 0.6) the local pressure at the ends of the major axis is over
    twice the station mean: each such station is a local peak, warned with its position."""
    limb = Limb.from_measurements([0.0, 300.0], [220.0, 220.0], ellipticity=0.6, n_stations=21, n_around=64)
    with pytest.warns(KnitframeWarning) as caught:
        d = design(limb, LIBRARY, objective("pressure_profile", target_mmHg=20.0, graduation="flat"))
    peaks = d.local_peaks()
    assert peaks and all(p["peak_mmHg"] > 2 * p["mean_mmHg"] for p in peaks)
    messages = [str(w.message) for w in caught]
    for p in peaks:
        assert any(f"at {p['position_mm']:.0f} mm" in m and "local pressure peak" in m for m in messages)
    round_limb = cylinder(220.0, 300.0, n_stations=21, n_around=64)
    assert design(round_limb, LIBRARY, objective("pressure_profile", target_mmHg=20.0)).local_peaks() == []


# -- robust designs -----------------------------------------------------------------------------------


def scenario_costs(d, scales) -> np.ndarray:
    """(S, R) each row's objective cost when the limb is scaled by each factor around its axis (the
    garment kept), +inf where the row would break a fabric's limit or the ceiling, by hand."""
    g = d.geometry
    pos = np.broadcast_to(g.position[:, None], g.shape)
    out = []
    for s in scales:
        lam1, r = d.lam1 * s, g.equivalent_radius[:, None] * s
        T1 = np.zeros_like(lam1)
        for f in np.unique(d.fabric):
            sel = d.fabric == f
            T1[sel] = np.maximum(LIBRARY.entries[int(f)].tensions(lam1[sel], d.lam2[sel])[0], 0.0)
        p = T1 / r * MMHG_PER_MPA
        tmax = np.array([e.max_tension for e in LIBRARY.entries])[d.fabric]
        smax = np.array([e.max_stretch or np.inf for e in LIBRARY.entries])[d.fabric]
        ok = np.all((T1 <= tmax) & (lam1 <= smax), axis=1) & (p.mean(axis=1) <= DEFAULT_CEILING)
        cost = d.objective.element_cost(p, g.area * s, pos).sum(axis=1)
        out.append(np.where(ok, cost, np.inf))
    return np.array(out)


def test_robust_design_is_no_worse_over_the_limb_tolerance(capsys):
    """The robust design's sum of row-wise worst costs over the limb scaled by 1 − x, 1, 1 + x is at most
    the nominal design's (the exact min-max programme guarantees it), and at the nominal limb at least."""
    x, arm, prof = 0.03, example_arm(), objective("pressure_profile")
    nominal = design(arm, LIBRARY, prof, tolerance=x)
    robust = design(arm, LIBRARY, prof, tolerance=x, robust=True)
    scales = (1 - x, 1.0, 1 + x)
    worst = {k: scenario_costs(d, scales) for k, d in (("nominal", nominal), ("robust", robust))}
    for d, costs in ((nominal, worst["nominal"]), (robust, worst["robust"])):
        assert costs[1].sum() / d.geometry.area.sum() == pytest.approx(d.value, rel=1e-9)
    assert np.isfinite(worst["robust"]).all()
    assert worst["robust"].max(axis=0).sum() <= worst["nominal"].max(axis=0).sum() * (1 + 1e-12)
    assert robust.value >= nominal.value * (1 - 1e-12), "the nominal design is the optimum on the limb"
    target = prof.target(nominal.geometry.position)
    with capsys.disabled():
        for name, d in (("nominal", nominal), ("robust", robust)):
            ends = [d.bands()["circumference"][:, k] / target - 1 for k in (0, 1)]
            inside = np.all(np.abs(ends) <= prof.tolerance, axis=0)
            print(
                f"\n{name}: sum of row-wise worst costs {worst[name].max(axis=0).sum():.1f}, "
                f"{inside.sum()} of {len(inside)} stations inside ±20 % at both ends of ±3 %, "
                f"worst {100 * np.abs(ends).max():.1f} %"
            )


# -- the command --------------------------------------------------------------------------------------


def test_command_designs_a_class_and_refuses_an_unknown_one(tmp_path, cli):
    """`design --example --class II` prints a station table and the stations within tolerance; `--class V`
    exits 2 with one line naming --class and writes nothing."""
    proc = cli("design", "--example", "--class", "II", "--out", "out", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "stations within" in proc.stdout and "target" in proc.stdout.splitlines()[0]
    written = json.loads((tmp_path / "out" / "design.json").read_text())
    assert written["prescription"]["compression_class"] == "II"
    assert len(proc.stdout.splitlines()) >= 1 + len(written["stations"])
    before = snapshot(tmp_path)
    bad = cli("design", "--example", "--class", "V", "--out", "bad", cwd=tmp_path)
    assert_refused(bad, "--class", before=before, folder=tmp_path)


def test_command_with_a_free_level_warns_and_stays_under_the_ceiling(tmp_path, cli):
    """`--objective pressure_uniformity` on a 35 mm-radius measured cylinder warns naming class II and no
    station is over 60 mmHg."""
    proc = cli(
        "design",
        "--objective",
        "pressure_uniformity",
        "--circumferences",
        "219.9,219.9",
        "--positions",
        "0,300",
        "--out",
        "out",
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert "class II" in proc.stderr and "warning" in proc.stderr
    stations = json.loads((tmp_path / "out" / "design.json").read_text())["stations"]
    assert max(s["pressure_mmHg"]["equivalent"] for s in stations) <= DEFAULT_CEILING
