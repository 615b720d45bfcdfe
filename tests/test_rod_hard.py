"""Hard cases of the rod solver: each converges or stops with a NumericalError diagnostic, never NaN."""

from __future__ import annotations

import numpy as np
import pytest
from knitframe_solvers.rod_branches import DROP_FLOOR

from knitframe import get_registry
from knitframe.errors import NumericalError
from knitframe.records import Fabric, LoadPath, Scene

EFFECTS = ("large_deformation", "bending", "contact", "prestress")


def outcome(pattern, sl, yarn, load, **options):
    """The Response of a run, or None after a NumericalError that carries a diagnostic; never NaN."""
    reg = get_registry()
    fabric = Fabric(pattern=pattern, yarn=reg["yarn"][yarn], stitch_length=sl)
    try:
        r = reg["solver"]["rod"](**options).simulate(fabric, Scene(load=load, effects=EFFECTS))
    except NumericalError as e:
        assert str(e).startswith(f"rod solver ({pattern}, {yarn}): ") and len(str(e)) > 60, str(e)
        print(f"{pattern} SL{sl} {yarn} {load.kind}: stopped: {e}")
        return None
    for arr in (r.lambda1, r.lambda2, r.T1, r.T2):
        assert np.all(np.isfinite(arr))
    print(
        f"{pattern} SL{sl} {yarn} {load.kind} {load.direction if load.kind == 'uniaxial' else ''}: "
        f"{len(r)} steps, λ = ({r.lambda1[-1]:.3f}, "
        f"{r.lambda2[-1]:.3f}), T = ({r.T1[-1]:.4g}, {r.T2[-1]:.4g}) N/mm, "
        f"{r.provenance.extra['prestress_start']} "
        f"pre-stress start, {r.provenance.wall_time:.1f} s"
    )
    return r


def check_physical(r, load, monotonic=True):
    """Stretched sides pull (harder and harder when ``monotonic``, except at a flagged snap), a free side
    carries no tension.

    Without ``monotonic`` a pulled side may end slack: a loose knit of a thin yarn can open its
    loops by 50 % for a tension of 1e-5 EA per mm.
    """
    names = ["course", "wale"] if load.kind == "equibiaxial" else [load.direction]
    pulled = [r.T1 if d == "course" else r.T2 for d in names]
    # a snap to another equilibrium branch (the stiff PET cell is multistable between 3 and 12 %, and which
    # branch it takes depends on round-off) may drop a tension: then the run flags it among its branch jumps
    # (step 1-based, direction), unless the fall is below the snap test's floor, DROP_FLOOR × the path's
    # largest tension (0.08 N/mm on the PET path)
    flagged = {(j["step"], j.get("direction")) for j in r.provenance.extra.get("branch_jumps", [])}
    floor = DROP_FLOOR * max(np.abs(r.T1).max(), np.abs(r.T2).max())
    for T, d in zip(pulled, names, strict=True):
        assert T[-1] > (0.0 if monotonic else -1e-5 * r.provenance.extra["EA_N"])
        if monotonic:
            assert np.all(T > 0)
            fall = -np.diff(T)
            unflagged = [
                j + 2 for j in np.flatnonzero(fall >= 0) if (j + 2, d) not in flagged and fall[j] > floor
            ]
            assert not unflagged, (d, unflagged, T, flagged)
    if load.kind == "uniaxial":
        free = r.T2 if load.direction == "course" else r.T1
        # the Newton tolerance (1e-9 EA on the reactions) is the floor when the pulled side is slack
        assert np.abs(free).max() < 1e-6 * np.abs(pulled[0]).max() + 1e-9 * r.provenance.extra["EA_N"]


CASES = [
    ("jersey", 10, "cotton", LoadPath(kind="equibiaxial", max_strain=0.3, steps=10)),
    ("jersey", 11, "cotton", LoadPath(kind="uniaxial", direction="course", max_strain=1.0, steps=20)),
    ("jersey", 11, "pet", LoadPath(kind="equibiaxial", max_strain=0.3, steps=10)),
    ("rib", 11, "cotton", LoadPath(kind="uniaxial", direction="wale", max_strain=0.3, steps=10)),
    ("garter", 11, "cotton", LoadPath(kind="uniaxial", direction="wale", max_strain=0.3, steps=10)),
]


@pytest.mark.parametrize(
    "case", CASES, ids=["SL10-tight", "100-percent", "stiff-PET", "rib-curling", "garter-curling"]
)
def test_hard_case_converges_or_stops_with_a_diagnostic(case):
    """SL10 interference, 100 % stretch, stiff PET and curling rib/garter end converged (and physical) or with
    a NumericalError."""
    r = outcome(*case)
    if r is not None:
        assert r.provenance.converged and len(r) == case[3].steps
        check_physical(r, case[3])


def test_a_run_that_cannot_converge_stops_with_a_diagnostic_or_returns_its_converged_steps():
    """Starved of iterations the solver raises a one-run diagnostic; with on_failure = "truncate" it keeps
    what converged."""
    load = LoadPath(kind="equibiaxial", max_strain=0.3, steps=10)
    with pytest.raises(NumericalError, match=r"rod solver \(jersey, cotton\): .*Newton"):
        get_registry()["solver"]["rod"](max_iterations=3, newton={"min_step_fraction": 0.5}).simulate(
            Fabric(pattern="jersey", yarn=get_registry()["yarn"]["cotton"], stitch_length=12),
            Scene(load=load, effects=EFFECTS),
        )
    # a fabric squeezed to 40 % of its relaxed size has no room for its yarns: the path stops there
    r = outcome(
        "jersey",
        12,
        "cotton",
        LoadPath(kind="general", lambda1=(1.1, 0.4), lambda2=(1.1, 0.4)),
        on_failure="truncate",
        newton={"min_step_fraction": 0.25},
    )
    assert (
        r is not None
        and not r.provenance.converged
        and "stopped after 1 of 2 load steps" in r.provenance.notes
    )
    assert len(r) == 1 and r.T1[0] > 0


def test_auto_prestress_tries_the_knitted_start_after_the_straight_one_fails():
    """With prestress_start = "auto" a failed pre-stress from the straight yarn is tried again from the
    knitted shape."""
    reg = get_registry()
    fabric = Fabric(pattern="jersey", yarn=reg["yarn"]["cotton"], stitch_length=10)
    scene = Scene(load=LoadPath(kind="equibiaxial", max_strain=0.05, steps=1), effects=EFFECTS)
    hurried = {
        "starts": 1,  # the rest shapes of one start (the other starts: test_rod_multistart.py)
        "prestress_steps": 2,
        "newton": {"min_step_fraction": 0.25},
        # the solid section's bending and a core at 0.5 dk: with the cotton record's Timoshenko bending
        # and compaction limit (0.28 dk) even two steps pass
        "shear": "none",
        "contact_law": {"kind": "rod_penalty", "core": 0.5},
    }  # too few steps for this tight cell
    with pytest.raises(NumericalError, match=r"rod solver \(jersey, cotton\): pre-stress \(contact distance"):
        reg["solver"]["rod"](prestress_start="straight", **hurried).simulate(fabric, scene)
    with pytest.raises(
        NumericalError,
        match=r"rod solver \(jersey, cotton\): pre-stress \(straight start\).*; "
        r"after that pre-stress \(knitted start\)",
    ):
        reg["solver"]["rod"](prestress_start="auto", **hurried).simulate(fabric, scene)


@pytest.mark.slow
@pytest.mark.parametrize("pattern", ["jersey", "garter", "rib", "seed"])
@pytest.mark.parametrize("sl", [10, 11, 12])
@pytest.mark.parametrize("yarn", ["cotton", "pet", "nylon"])
def test_every_pattern_stitch_length_and_yarn_ends_converged_or_with_a_diagnostic(pattern, sl, yarn):
    """The whole table of patterns x SL10-12 x yarns, pulled equibiaxially and uniaxially both ways, never
    gives NaN.

    Loops of stiff yarns can snap through, so the tension need not grow at every step.
    """
    for load in (
        LoadPath(kind="equibiaxial", max_strain=0.3, steps=10),
        LoadPath(kind="uniaxial", direction="course", max_strain=0.5, steps=10),
        LoadPath(kind="uniaxial", direction="wale", max_strain=0.5, steps=10),
    ):
        r = outcome(pattern, sl, yarn, load)
        if r is not None:
            check_physical(r, load, monotonic=False)
