"""Rod against volumetric on a small cell: the same yarn record gives the same answer where both model the
same thing.

Two straight yarns along the course, far apart (the test pattern of ``test_volumetric_solver``): under a
uniaxial course stretch ε both carry T1 = 2·E_A·A·ε / |L2| (A = π dk²/4), the axial path of the yarn
record. The rod and the P2 solid agree with each other and with it.

On knitted cells both solvers read the same compaction limit J_min from the yarn record: the solid's
sections stay above it (without the barrier the cotton of jersey SL11 was squeezed to 7 % of its section).
On a cell that leaves the yarn room (jersey SL11 nylon) the rod and P2 agree to 6 % NRMSE; that run takes
minutes and is marked slow (docs/validation.md, section 1).
"""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest
import test_volumetric_solver as cells

from knitframe.curves import nrmse_between
from knitframe.plugins import get_registry, load_registry, reset_registry
from knitframe.records import Fabric, LoadPath, Scene
from knitframe.report import plot_sections


@pytest.fixture
def straight_rows():
    reset_registry(load_registry(extra={"straight_rows_test": sys.modules[cells.__name__]}))
    yield
    reset_registry(None)


def test_rod_and_volumetric_agree_on_the_axial_path_of_one_yarn_record(straight_rows):
    from knitframe_solvers.rod import RodSolver
    from knitframe_solvers.volumetric import VolumetricSolver

    scene = Scene(
        load=LoadPath(kind="uniaxial", direction="course", max_strain=0.002, steps=2),
        effects={"large_deformation"},
    )
    rod = RodSolver().simulate(cells.FABRIC, scene)
    solid = VolumetricSolver(order=2, seed=0.75).simulate(cells.FABRIC, scene)
    yarn = cells.FABRIC.yarn
    eps = np.array([0.001, 0.002])
    exact = 2.0 * yarn.E_axial * np.pi * yarn.dk**2 / 4.0 * eps / cells.L2
    np.testing.assert_allclose(rod.T1, exact, rtol=1e-3)  # small strain: the rod's axial law is linear in ε
    np.testing.assert_allclose(solid.T1, exact, rtol=0.01)  # the curved P2 section within 1 %
    assert np.max(np.abs(solid.T1 - rod.T1) / rod.T1) < 0.01
    assert np.all(np.abs(rod.T2) < 1e-9 * rod.T1.max()) and np.all(np.abs(solid.T2) < 1e-6 * solid.T1.max())


KNIT_EFFECTS = {
    "large_deformation",
    "bending",
    "contact",
    "self_contact",
    "prestress",
    "anisotropy",
    "friction",
}


def test_the_volumetric_yarn_stops_compacting_at_the_records_limit(tmp_path):
    """Jersey SL11 cotton, coarse P1 cell, pre-stress and one 5 % equibiaxial step: the smallest section
    ratio det F/|F a| stays at or above J_min = φk/φmax = 0.276 (the rod's contact core is at J_min·dk)."""
    from knitframe_solvers.volumetric import VolumetricSolver

    cot = get_registry()["yarn"]["cotton"]
    scene = Scene(
        load=LoadPath(kind="equibiaxial", max_strain=0.05, steps=1), effects=KNIT_EFFECTS - {"friction"}
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # P1 warns that it locks in bending
        r = VolumetricSolver(order=1, seed=1.0).simulate(
            Fabric(pattern="jersey", yarn=cot, stitch_length=11), scene
        )
    extra = r.provenance.extra
    assert extra["compaction_limit"] == pytest.approx(cot.compaction) == pytest.approx(0.2764, abs=1e-4)
    assert cot.compaction <= extra["min_section_ratio"] < 0.9  # squeezed, but not past the fibres' packing
    # the section ratio after the pre-stress and after the step, each over the yarn's volume
    pre, step = extra["section_ratio"]
    assert (pre["phase"], step["phase"]) == ("prestress", "load")
    assert (pre["lambda1"], pre["lambda2"]) == (1.0, 1.0)
    assert step["lambda1"] == pytest.approx(1.05) and step["lambda2"] == pytest.approx(1.05)
    for sec in (pre, step):
        assert sec["min"] <= sec["p05"] <= sec["median"] <= 1.2
    assert extra["min_section_ratio"] == min(pre["min"], step["min"])
    assert plot_sections(tmp_path / "section.png", [r]) is True
    assert (tmp_path / "section.png").read_bytes()[:4] == b"\x89PNG"
    assert plot_sections(tmp_path / "none.png", []) is False and not (tmp_path / "none.png").exists()


@pytest.mark.slow
def test_rod_and_volumetric_agree_on_jersey_nylon():
    """Jersey SL11 nylon, pre-stress, friction and equibiaxial 0 → 30 %: the rod's defaults against P2 at
    seed r, NRMSE ≤ 15 % (measured 6.0 %) and θ of the fitted hgo within 3° (measured 1.2°); 9 min."""
    from knitframe_solvers.rod import RodSolver
    from knitframe_solvers.volumetric import VolumetricSolver

    reg = get_registry()
    nylon = reg["yarn"]["nylon"]
    fabric = Fabric(pattern="jersey", yarn=nylon, stitch_length=11)
    scene = Scene(load=LoadPath(kind="equibiaxial", max_strain=0.3, steps=6), effects=KNIT_EFFECTS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        solid = VolumetricSolver(
            order=2, seed=1.0, contact_law={"kind": "ipc"}, contact_modulus=10 * nylon.E_transverse
        ).simulate(fabric, scene)
        rod = RodSolver().simulate(fabric, Scene(load=scene.load, effects=KNIT_EFFECTS - {"anisotropy"}))
    assert nrmse_between(solid, rod) <= 0.15
    fit = reg["fitter"]["lbfgs"]()
    thetas = [fit.fit(reg["homogenizer"]["hgo"](), [r]).to_json()["theta_deg"] for r in (solid, rod)]
    assert abs(thetas[0] - thetas[1]) <= 3.0
