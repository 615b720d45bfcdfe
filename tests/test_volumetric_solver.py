"""Solver ``volumetric``: periodic cell, macro reactions, outputs, checkpoint/resume (straight-yarn cell)."""

from __future__ import annotations

import sys
from typing import ClassVar

import attrs
import numpy as np
import pytest
from knitframe_solvers.volumetric import VolumetricSolver

from knitframe import hookimpl
from knitframe.errors import GeometryError, NumericalError
from knitframe.geometry import Centerline, UnitCell
from knitframe.plugins import get_registry, load_registry, reset_registry
from knitframe.records import Fabric, LoadPath, Scene, Yarn

L1, L2, R = 1.2, 1.0, 0.1


def _row(name: str, y: float) -> Centerline:
    return Centerline(
        name,
        lambda t: np.stack([t, y + 0 * t, 0 * t], 1),
        lambda t: np.stack([1 + 0 * t, 0 * t, 0 * t], 1),
        0.0,
        L1,
        [L1, 0, 0],
    )


@attrs.frozen
class StraightRows:
    """Test pattern: two straight yarns along the course, half a wale apart, far from touching."""

    name: ClassVar[str] = "straight-rows"
    description: ClassVar[str] = "two straight rows (tests)"

    def cell(self, fabric: Fabric) -> UnitCell:
        return UnitCell(
            "straight-rows",
            (_row("row0", 0.25 * L2), _row("row1", 0.75 * L2)),
            [L1, 0, 0],
            [0, L2, 0],
            0.5 * fabric.yarn.dk,
            ((0, 0), (1, 1)),
            (("k",), ("k",)),
            L1,
            L1,
            0.5 * L2,
        )


@hookimpl
def register_patterns(register):
    register(StraightRows)


@pytest.fixture(autouse=True)
def registry_with_straight_rows():
    """The process registry plus this module's test pattern (after the suite's fresh-registry fixture)."""
    reset_registry(load_registry(extra={"straight_rows_test": sys.modules[__name__]}))
    yield get_registry()
    reset_registry(None)


YARN = Yarn(name="test", d0=2 * R, dk=2 * R, E_axial=1000.0, E_transverse=10.0, nu=0.3)
FABRIC = Fabric(pattern="straight-rows", yarn=YARN, arc_length=L1)
STRETCH = Scene(
    load=LoadPath(kind="uniaxial", direction="course", max_strain=0.002, steps=2),
    effects={"large_deformation", "anisotropy"},
)


def test_solver_is_registered_with_its_effects():
    """The solver plugin declares the effects and loads it models."""
    cls = get_registry()["solver"]["volumetric"]
    assert cls is VolumetricSolver
    assert {"contact", "prestress", "large_deformation", "self_contact"} <= cls.effects
    assert "friction" in cls.effects
    assert "uniaxial-course" in cls.loads


@pytest.mark.parametrize("order", [1, 2])
def test_course_tension_of_straight_yarns(order):
    """Stretching straight yarns along the course gives T1 = 2 E_A ε π r² / |L2| (two yarns per wale
    period)."""
    from knitframe.numerics.mesh import cell_mesh, mesh_quality

    r = VolumetricSolver(order=order, seed=0.75).simulate(FABRIC, STRETCH)
    eps = r.lambda1 - 1.0
    # the meshed section: a polygon for P1, curved for P2
    section = mesh_quality(cell_mesh(StraightRows().cell(FABRIC), seed=0.75, order=order))["volume"] / (
        2 * L1
    )
    expected = 2 * YARN.E_axial * eps * section / L2
    assert np.allclose(r.T1, expected, rtol=0.01)
    assert np.allclose(r.T2, 0.0, atol=1e-6 * r.T1.max())  # free side
    assert r.lambda2[-1] == pytest.approx(1.0)  # nothing ties the rows along the wale
    assert r.provenance.converged and r.provenance.solver == "volumetric"


def test_vtu_output_per_step(tmp_path):
    """Each converged step writes a VTU with displacement, contact pressure and max principal stress."""
    import meshio

    scene = attrs.evolve(STRETCH, outputs=frozenset({"response", "vtu"}))
    VolumetricSolver(order=1, seed=0.75).simulate(FABRIC, scene, output_dir=tmp_path)
    files = sorted(tmp_path.glob("solid-*.vtu"))
    assert len(files) == 2 and (tmp_path / "solid.pvd").exists()
    m = meshio.read(files[-1])
    assert {"displacement", "contact_pressure"} <= set(m.point_data)
    smax = m.cell_data["max_principal_stress"][0]
    assert smax.max() == pytest.approx(YARN.E_axial * 0.002, rel=0.05)


def test_killed_run_resumes_to_the_same_result(tmp_path):
    """A run stopped after its first step resumes from the checkpoint and ends where an uninterrupted run
    ends."""
    solver = VolumetricSolver(order=1, seed=0.75)
    full = solver.simulate(FABRIC, STRETCH)

    class Kill(Exception):
        pass

    def killer(done, total, message):
        if done >= 1:
            raise Kill

    with pytest.raises(Kill):
        solver.simulate(FABRIC, STRETCH, checkpoint_dir=tmp_path, progress=killer)
    assert list(tmp_path.glob("step-*.npz"))
    seen = []
    resumed = solver.simulate(
        FABRIC, STRETCH, checkpoint_dir=tmp_path, progress=lambda d, t, m: seen.append(m)
    )
    assert seen == ["load step 2/2"]  # only the missing step was computed
    assert np.allclose(resumed.T1, full.T1, rtol=1e-9) and np.allclose(resumed.lambda1, full.lambda1)
    # a contact law with other options (here its default master surface) is another run: not resumed
    other = VolumetricSolver(order=1, seed=0.75, contact_law={"kind": "mortar", "smoothing": "none"})
    seen.clear()
    other.simulate(FABRIC, STRETCH, checkpoint_dir=tmp_path, progress=lambda d, t, m: seen.append(m))
    assert seen == ["load step 1/2", "load step 2/2"]


def test_trace_records_every_newton_solve():
    """``trace`` gets one record per Newton solve with its iteration history; the last residual is the
    converged one."""
    records = []
    resp = VolumetricSolver(order=1, seed=0.75).simulate(FABRIC, STRETCH, trace=records.append)
    loads = [r for r in records if r["phase"] == "load" and r["record"] == "solve"]
    assert [r["t"] for r in loads] == [1.0, 2.0] and all(r["converged"] for r in loads)
    for r in loads:
        last = r["history"][-1]
        assert r["iterations"] == len(r["history"]) - 1
        assert last["residual"] <= max(resp.provenance.extra["tolerance_N"], 5e-3 * last["flux"])
        assert all("flux" in h for h in r["history"])
        # the same iterations were traced one by one, in order, since the previous solve's record
        k = records.index(r)
        start = max((i for i in range(k) if records[i]["record"] == "solve"), default=-1) + 1
        its = records[start:k]
        assert all(x["record"] == "iteration" and x["t"] == r["t"] for x in its)
        assert [x["it"] for x in its] == [h["it"] for h in r["history"]]
        assert [x["residual"] for x in its] == [h["residual"] for h in r["history"]]
        assert all(x["wall_s"] >= 0.0 and x["material_s"] >= 0.0 and x["n_hessian"] >= 1 for x in its)
    # each iteration's share of the counters: together they are the run's
    every = [x for x in records if x["record"] == "iteration"]
    counts = resp.provenance.extra["newton_evaluations"]
    assert sum(x["n_linear_solves"] for x in every) == counts["linear_solves"]
    assert sum(x["n_hessian"] for x in every) == counts["hessian"]


def test_held_contact_search_needs_steps_below_half_the_reach():
    """A Newton step cap over half the contact reach would let held candidates miss a contact: refused in one
    line."""
    from knitframe.errors import ConfigError

    scene = attrs.evolve(STRETCH, effects=frozenset({"large_deformation", "anisotropy", "contact"}))
    with pytest.raises(ConfigError, match="max_step"):
        VolumetricSolver(
            order=1, seed=0.75, contact_law="mortar", newton={"max_step": 0.3, "reach": 0.5}
        ).simulate(FABRIC, scene)
    r = VolumetricSolver(
        order=1,
        seed=0.75,
        contact_law="mortar",
        newton={"max_step": 0.3, "reach": 0.5, "contact_search": "evaluation"},
    ).simulate(FABRIC, scene)
    assert r.provenance.converged


def test_trace_summary_of_the_benchmark(tmp_path):
    """``bench_volumetric.py trace`` gives one row per traced solve, with the residual against the flux and
    no energy jump between accepted steps and iterates when nothing changes the pairing."""
    import json
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from bench_volumetric import bench_trace

    path = tmp_path / "trace.jsonl"
    scene = Scene(
        load=LoadPath(kind="uniaxial", direction="course", max_strain=0.2, steps=2),
        effects={"large_deformation", "anisotropy", "contact"},
    )
    with open(path, "w") as fh:
        VolumetricSolver(order=1, seed=0.75, contact_law="mortar").simulate(
            FABRIC, scene, trace=lambda r: fh.write(json.dumps(r, default=float) + "\n")
        )
    rows = bench_trace(type("Args", (), {"trace": str(path)})())
    assert [r["t"] for r in rows] == [1.0, 2.0] and all(r["converged"] for r in rows)
    assert all(r["iterations"] > 0 and float(r["largest pairing jump N·mm"]) == 0.0 for r in rows)


def test_overlapping_yarns_without_prestress_stop_with_a_diagnostic():
    """Yarns that overlap in the knitted state and no pre-stress: a one-line NumericalError, not NaN."""

    yarn = attrs.evolve(YARN, d0=0.7 * L2, dk=0.7 * L2)  # rows 0.5 L2 apart, diameter 0.7 L2
    fabric = attrs.evolve(FABRIC, yarn=yarn)
    scene = attrs.evolve(STRETCH, effects=frozenset({"large_deformation", "contact"}))
    with pytest.raises((NumericalError, GeometryError)) as err:
        VolumetricSolver(order=1, seed=0.75).simulate(fabric, scene)
    assert "\n" not in str(err.value)


def test_pipeline_resume_after_a_kill(tmp_path, monkeypatch):
    """``knitframe.run(..., resume=True)`` (the API twin of ``knitframe run --resume``) finishes a killed run
    identically."""
    import knitframe
    from knitframe.numerics.continuation import StepCheckpoints

    config = {
        "solver": {"kind": "volumetric", "order": 1, "seed": 0.75},
        "fabric": {
            "pattern": "straight-rows",
            "arc_length": L1,
            "yarn": {"name": "test", "d0": 2 * R, "dk": 2 * R, "E_axial": 1000.0, "E_transverse": 10.0},
        },
        "scene": {
            "effects": ["large_deformation", "anisotropy"],
            "load": {"kind": "uniaxial", "direction": "course", "max_strain": 0.002, "steps": 2},
        },
    }
    reference = knitframe.run(config, tmp_path / "ref").responses[0]
    # the simulate stage draws the section ratio the volumetric solver records
    assert [s["phase"] for s in reference.provenance.extra["section_ratio"]] == ["load", "load"]
    assert (tmp_path / "ref" / "section.png").read_bytes()[:4] == b"\x89PNG"
    save = StepCheckpoints.save

    def save_then_die(self, index, arrays, meta):
        save(self, index, arrays, meta)
        raise KeyboardInterrupt  # killed right after the first checkpoint was written

    monkeypatch.setattr(StepCheckpoints, "save", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        knitframe.run(config, tmp_path / "out")
    assert list((tmp_path / "out" / ".knitframe" / "checkpoints").rglob("step-*.npz"))
    monkeypatch.setattr(StepCheckpoints, "save", save)
    resumed = knitframe.run(config, tmp_path / "out", resume=True).responses[0]
    assert np.allclose(resumed.T1, reference.T1, rtol=1e-9) and np.allclose(
        resumed.lambda1, reference.lambda1
    )


def count_calls(monkeypatch, cls, name: str) -> list:
    """Patch method ``name`` of ``cls`` to append to the returned list at every call."""
    calls = []
    original = getattr(cls, name)

    def counting(self, *args, **kwargs):
        calls.append(1)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(cls, name, counting)
    return calls


@pytest.mark.parametrize("law", ["mortar", "penalty", "ipc"])
def test_contact_without_touching_pairs_changes_nothing(law):
    """Contact on, but the rows never touch: the laws see no pairs and the tension is that of the bare
    yarns."""
    bare = VolumetricSolver(order=1, seed=0.75).simulate(FABRIC, STRETCH)
    scene = attrs.evolve(STRETCH, effects=frozenset({"large_deformation", "anisotropy", "contact"}))
    with_contact = VolumetricSolver(order=1, seed=0.75, contact_law=law).simulate(FABRIC, scene)
    assert np.allclose(with_contact.T1, bare.T1, rtol=1e-9)


def test_friction_is_frozen_per_increment_only_when_asked(monkeypatch):
    """With the scene effect 'friction' the law's contact pairs are frozen at the start of every increment;
    without it the friction state is never computed."""
    from knitframe_contact.mortar import SolidMortar

    calls = count_calls(monkeypatch, SolidMortar, "friction_state")
    effects = {"large_deformation", "anisotropy", "contact"}
    solver = VolumetricSolver(order=1, seed=0.75, contact_law="mortar")
    solver.simulate(FABRIC, attrs.evolve(STRETCH, effects=frozenset(effects)))
    assert calls == []
    r = solver.simulate(FABRIC, attrs.evolve(STRETCH, effects=frozenset(effects | {"friction"})))
    assert len(calls) >= STRETCH.load.steps and r.provenance.converged


@pytest.mark.parametrize("search", ["iteration", "evaluation"])
def test_contact_search_once_per_newton_iteration(monkeypatch, search):
    """contact_search = "iteration": the broad-phase contact search runs at the Hessian evaluations only (one
    per Newton iterate), its candidates held through the line search; "evaluation" searches every time."""
    from knitframe.numerics.contact import SolidSurface

    calls = count_calls(monkeypatch, SolidSurface, "candidates")
    # a stretch large enough for the Poisson contraction to need Newton iterations with line searches
    scene = Scene(
        load=LoadPath(kind="uniaxial", direction="course", max_strain=0.2, steps=2),
        effects={"large_deformation", "anisotropy", "contact"},
    )
    r = VolumetricSolver(
        order=1, seed=0.75, contact_law="mortar", newton={"contact_search": search}
    ).simulate(FABRIC, scene)
    ev = r.provenance.extra["newton_evaluations"]
    assert r.provenance.converged and ev["energy"] > 0
    expected = ev["hessian"] if search == "iteration" else ev["energy"] + ev["gradient"] + ev["hessian"]
    assert len(calls) == expected


def test_barrier_contact_resolves_the_interference_of_the_prestress():
    """Rows 0.5 apart with dk = 0.52 overlap in the knitted state: the pre-stress grows them from apart into
    contact under the barrier (law ``ipc``); no step crosses, and the contact couples the rows across the
    wale. The free side's contraction λ2 is a soft mode, which projected Newton steps underestimate: at the
    default step test (0.01 r), and even at 1e-4 r, whether and which way that side moved depended on the path
    (λ2 = 0.99984 without and 1.00003 with extrapolated steps). Solved tightly (residual 1e-8, step 1e-6 r) it
    opens, λ2 = 1.00012-1.00014, with and without chord steps and extrapolated steps (at 1e-10 and 1e-8 r the
    same values); with chord steps after full steps as well, to λ2 = 1.000036 at the same tension."""
    fat = attrs.evolve(YARN, d0=0.52, dk=0.52)
    fabric = attrs.evolve(FABRIC, yarn=fat)
    scene = attrs.evolve(
        STRETCH, effects=frozenset({"large_deformation", "anisotropy", "contact", "prestress"})
    )
    tight = dict(
        order=1,
        seed=0.75,
        contact_law="ipc",
        prestress_steps=2,
        tolerance=1e-8,
        step_tolerance=1e-6,
    )
    flux_off = {"flux_tolerance": 0.0, "late_flux_tolerance": 0.0}
    # plain projected Newton, and with chord steps and extrapolated steps (which shortens steps, so chords
    # follow)
    plain = VolumetricSolver(**tight, newton={**flux_off, "chord": False}).simulate(
        fabric, scene, trace=(plain_records := []).append
    )
    r = VolumetricSolver(
        **tight,
        newton={**flux_off, "chord": True, "extrapolation": 8.0, "chord_after_full_steps": False},
    ).simulate(fabric, scene, trace=(records := []).append)
    assert r.provenance.converged and np.all(np.isfinite(r.T1))
    assert r.provenance.extra["prestress_start_radius_over_r"] < 1.0
    assert r.provenance.extra["max_penetration_over_r"] == 0.0
    assert r.provenance.extra["newton_evaluations"]["gradient"] > 0  # chord steps were tried
    assert any("extrapolated" in x for x in records if x["record"] == "iteration")
    assert plain.provenance.extra["newton_evaluations"]["gradient"] == 0
    assert not any("extrapolated" in x for x in plain_records if x["record"] == "iteration")
    # without contact nothing acts across the rows and the free wale side stays where it was; with it, the
    # flattened rows carry the course stretch's contraction across
    bare = VolumetricSolver(**tight, newton=flux_off).simulate(
        fabric, attrs.evolve(scene, effects=scene.effects - {"contact"})
    )
    assert bare.lambda2[-1] == pytest.approx(1.0, abs=1e-9) and r.lambda2[-1] - 1.0 > 5e-5
    assert np.allclose(r.lambda2, plain.lambda2, atol=3e-5)
    # chord steps after full steps too (the default) reach the residual test on a chord iterate: the same
    # tension, and the soft side opens, less far (λ2 = 1.000036; 1.000037 at a residual of 1e-10)
    full = VolumetricSolver(**tight, newton={**flux_off, "chord": True, "extrapolation": 8.0}).simulate(
        fabric, scene
    )
    assert full.lambda2[-1] - 1.0 > 2e-5 and np.allclose(full.T1, plain.T1, rtol=1e-5)
    assert np.allclose(r.T1, plain.T1, rtol=1e-3)
    assert np.all(np.abs(r.T2) < 1e-4 * np.abs(r.T1).max())  # the free side carries no tension


def test_intermediate_prestress_states_take_the_loose_tolerances():
    """The intermediate pre-stress states take path_tolerance_factor × the residual, flux and step tolerances;
    in a run where the residual and flux tests are out of reach, every solve that iterates ends by the step
    test within its own bound (the history's step is the Newton step over the cap)."""
    solver = VolumetricSolver(
        order=1,
        seed=0.75,
        contact_law="ipc",
        prestress_steps=2,
        tolerance=1e-12,
        newton={"flux_tolerance": 0.0, "late_flux_tolerance": 0.0},
    )
    opts, loose = solver.newton_options(FABRIC, 0.2, True)
    f = solver.newton.path_tolerance_factor
    assert opts.step_tol == solver.step_tolerance and opts.atol == pytest.approx(
        1e-12 * YARN.E_transverse * 0.04
    )
    assert (loose.step_tol, loose.atol) == pytest.approx((f * opts.step_tol, f * opts.atol))
    assert (
        attrs.evolve(loose, atol=opts.atol, step_tol=opts.step_tol) == opts
    )  # nothing else differs (flux ratios are 0)
    fabric = attrs.evolve(FABRIC, yarn=attrs.evolve(YARN, d0=0.52, dk=0.52))
    scene = attrs.evolve(
        STRETCH, effects=frozenset({"large_deformation", "anisotropy", "contact", "prestress"})
    )
    records = []
    assert solver.simulate(fabric, scene, trace=records.append).provenance.converged
    solves = [
        x for x in records if x["record"] == "solve" and len(x["history"]) > 1
    ]  # not the stress-free start
    assert solves
    for rec in solves:
        last = rec["history"][-1]
        tol = loose if rec["phase"] == "prestress" and rec["t"] < 1.0 else opts
        assert last.get("step_converged") and last["step"] <= tol.step_tol / solver.newton.max_step


def test_secant_predictor_starts_the_next_increment_near_its_solution():
    """Small strain, no contact: the yarns' fluctuation grows linearly with the load, so the secant predictor
    (the fluctuation and the free side's contraction extrapolated from the last two converged increments)
    starts the second and third increments far closer to their solution than the affine map alone; both end at
    the same tensions."""
    scene = attrs.evolve(
        STRETCH, load=LoadPath(kind="uniaxial", direction="course", max_strain=0.03, steps=3)
    )
    first = {}
    out = {}
    for predictor in ("affine", "secant"):
        records = []
        out[predictor] = VolumetricSolver(
            order=1, seed=0.75, newton={"predictor": predictor}, tolerance=1e-7
        ).simulate(FABRIC, scene, trace=records.append)
        first[predictor] = [
            x["history"][0]["residual"] for x in records if x["record"] == "solve" and x["phase"] == "load"
        ]
    assert first["secant"][0] == pytest.approx(first["affine"][0], rel=1e-9)  # no history yet: the same start
    assert first["secant"][1] < 0.1 * first["affine"][1] and first["secant"][2] < 0.1 * first["affine"][2]
    assert np.allclose(out["secant"].T1, out["affine"].T1, rtol=1e-4, atol=1e-9)


def test_a_converged_state_with_forces_far_above_the_flux_gets_a_note(monkeypatch):
    """The step test can pass while forces far above the force flux are left (the jammed SL10 cell: 29-800 ×):
    the Response's notes say which state and how far; a well-converged run has no such note."""
    import knitframe_solvers.volumetric_run as vol

    records = []
    clean = VolumetricSolver(order=1, seed=0.75).simulate(FABRIC, STRETCH, trace=records.append)
    assert "force flux" not in clean.provenance.notes
    last = [r["history"][-1] for r in records if r["record"] == "solve" and r["phase"] == "load"]
    ratio = max(h["residual"] / h["flux"] for h in last)
    monkeypatch.setattr(vol, "IMBALANCE_NOTE", 0.5 * ratio)  # as if the threshold were below this run's worst
    noted = VolumetricSolver(order=1, seed=0.75).simulate(FABRIC, STRETCH)
    assert "load 1 converged with a residual of" in noted.provenance.notes
    assert noted.provenance.converged and np.allclose(noted.T1, clean.T1)


@pytest.mark.parametrize("order", [1, 2])
def test_pull_back_of_the_tangent_is_the_triple_product(order):
    """model.pull_back(K) = Tᵀ (K + c I) T (the periodic map T, the foundation c), through its fixed-pattern
    map; a K on another pattern gets its own map."""
    import scipy.sparse as sp

    solver = VolumetricSolver(order=order, seed=0.75, newton={"stabilisation": 1e-2})
    model = solver.setup(FABRIC, STRETCH)
    assert (
        model.damping > 0 and model.T.shape[0] > model.T.shape[1]
    )  # the end nodes are slaves of the start nodes
    rng = np.random.default_rng(2)
    u = 1e-3 * rng.normal(size=model.forms.ndof)
    _, _, K = model.forms.evaluate(u, 1.0, 2)
    c = model.damping
    ref = (model.T.T @ (K + c * sp.identity(K.shape[0])) @ model.T).tocsr()
    for _ in range(2):  # the map is built at the first call and reused
        H = model.pull_back(K)
        assert abs(H - ref).max() <= 1e-13 * abs(ref).max()
    kept = model._pull_back
    _, _, K1 = model.forms.evaluate(2.0 * u, 1.0, 2)  # a new tangent on the same pattern keeps the map
    ref1 = (model.T.T @ (K1 + c * sp.identity(K1.shape[0])) @ model.T).tocsr()
    assert abs(model.pull_back(K1) - ref1).max() <= 1e-13 * abs(ref1).max() and model._pull_back is kept
    K2 = sp.csr_matrix(
        K.toarray() + np.diag(rng.normal(size=K.shape[0]))
    )  # another matrix on another pattern
    K2 = K2 + sp.csr_matrix(([1.0], ([0], [K.shape[0] - 1])), shape=K.shape)
    ref2 = (model.T.T @ (K2 + c * sp.identity(K.shape[0])) @ model.T).tocsr()
    assert abs(model.pull_back(K2) - ref2).max() <= 1e-13 * abs(ref2).max()


def test_p1_with_bending_warns_that_linear_tetrahedra_lock():
    """order = 1 with the bending effect: one KnitframeWarning and a provenance note; P2 has neither."""
    from knitframe.errors import KnitframeWarning

    scene = attrs.evolve(STRETCH, effects={"large_deformation", "anisotropy", "bending"})
    with pytest.warns(KnitframeWarning, match="linear tetrahedra lock in bending"):
        r = VolumetricSolver(order=1, seed=0.75).simulate(FABRIC, scene)
    assert "lock in bending" in r.provenance.notes
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", KnitframeWarning)
        VolumetricSolver(order=1, seed=0.75).simulate(FABRIC, STRETCH)  # no bending asked for: no warning


@pytest.mark.parametrize("law", ["penalty", "mortar"])
def test_signed_gap_laws_are_refused_past_the_strain_they_finish_before_any_work(law):
    """penalty and mortar past 10 % strain on a contact scene: a ConfigError naming solver.contact_law at
    validation."""
    from knitframe.errors import ConfigError

    solver = VolumetricSolver(order=1, seed=0.75, contact_law=law)
    far = Scene(
        load=LoadPath(kind="equibiaxial", max_strain=0.3, steps=6), effects={"large_deformation", "contact"}
    )
    with pytest.raises(
        ConfigError,
        match=rf"solver\.contact_law: '{law}' does not finish knitted cells past 10 % "
        r"strain \(the load reaches 30 %\)",
    ):
        solver.validate(FABRIC, far)
    solver.validate(FABRIC, attrs.evolve(far, load=LoadPath(kind="equibiaxial", max_strain=0.1, steps=2)))
    solver.validate(FABRIC, attrs.evolve(far, effects={"large_deformation"}))  # no contact asked for
    VolumetricSolver(order=1, seed=0.75, contact_law="ipc").validate(FABRIC, far)
