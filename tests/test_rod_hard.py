"""Hard cases of the rod solver: each converges or stops with a NumericalError diagnostic, never NaN."""

from __future__ import annotations

import numpy as np
import pytest

from knitframe import get_registry
from knitframe.errors import NumericalError
from knitframe.records import Fabric, LoadPath, Scene

EFFECTS = ("large_deformation", "bending", "contact", "prestress")


def outcome(pattern, sl, yarn, load):
    reg = get_registry()
    fabric = Fabric(pattern=pattern, yarn=reg["yarn"][yarn], stitch_length=sl)
    try:
        r = reg["solver"]["rod"]().simulate(fabric, Scene(load=load, effects=EFFECTS))
    except NumericalError as e:
        assert str(e).strip(), "a failure must carry a diagnostic"
        return None
    for arr in (r.lambda1, r.lambda2, r.T1, r.T2):
        assert np.all(np.isfinite(arr))
    return r


@pytest.mark.slow
@pytest.mark.parametrize("case", [
    ("jersey", 10, "cotton", LoadPath(kind="equibiaxial", max_strain=0.3, steps=10)),
    ("jersey", 11, "cotton", LoadPath(kind="uniaxial", direction="course", max_strain=1.0, steps=20)),
    ("jersey", 11, "pet", LoadPath(kind="equibiaxial", max_strain=0.3, steps=10)),
    ("rib", 11, "cotton", LoadPath(kind="uniaxial", direction="wale", max_strain=0.3, steps=10)),
    ("garter", 11, "cotton", LoadPath(kind="uniaxial", direction="wale", max_strain=0.3, steps=10)),
], ids=["SL10-tight", "100-percent", "stiff-PET", "rib-curling", "garter-curling"])
def test_hard_case_converges_or_stops_with_a_diagnostic(case):
    """SL10 interference, 100 % stretch, stiff PET and curling rib/garter end converged or with a NumericalError."""
    outcome(*case)
