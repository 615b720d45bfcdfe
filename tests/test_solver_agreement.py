"""Rod against volumetric on a small cell: the same yarn record gives the same answer where both model the
same thing.

Two straight yarns along the course, far apart (the test pattern of ``test_volumetric_solver``): under a
uniaxial course stretch ε both carry T1 = 2·E_A·A·ε / |L2| (A = π dk²/4), the axial path of the yarn
record. The rod and the P2 solid agree with each other and with it. Where the two solvers model different
yarns (bending through axial shear, transverse compression at contacts) they do not agree yet:
docs/validation.md, section 2.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest
import test_volumetric_solver as cells

from knitframe.plugins import load_registry, reset_registry
from knitframe.records import LoadPath, Scene


@pytest.fixture(autouse=True)
def straight_rows():
    reset_registry(load_registry(extra={"straight_rows_test": sys.modules[cells.__name__]}))
    yield
    reset_registry(None)


def test_rod_and_volumetric_agree_on_the_axial_path_of_one_yarn_record():
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
