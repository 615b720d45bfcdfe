"""The rod solver's multistability rule: the lowest-energy start is returned and recorded; two step
counts end on one branch or say where they switched.

The relaxed energy compared between starts is the cell's total elastic energy at zero tension,
E = E_stretch + E_bend + E_contact (N·mm per cell). A load step k is a branch jump when the free
stretch changes by :math:`|\\Delta\\lambda_{free}| > \\max(3\\,|\\Delta\\lambda_{load}|, 0.02)`.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from knitframe import get_registry
from knitframe.errors import ConfigError
from knitframe.records import Fabric, LoadPath, Scene
from knitframe.schema import build
from knitframe_solvers.rod import START_SET, RodSolver, is_jump, locate_jumps

EFFECTS = ("large_deformation", "bending", "contact", "prestress")


def simulate(fabric: Fabric, load: LoadPath, **options):
    """One rod run with its warnings silenced (a branch jump warns; the tests read the provenance)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return RodSolver(**options).simulate(fabric, Scene(load=load, effects=EFFECTS))


@pytest.fixture(scope="module")
def jersey_two_starts():
    """Jersey SL11 cotton, one equibiaxial step of 3 %, from the nominal start alone and from the first two starts."""
    fab = Fabric(pattern="jersey", yarn=get_registry()["yarn"]["cotton"], stitch_length=11)
    load = LoadPath(kind="equibiaxial", max_strain=0.03, steps=1)
    return simulate(fab, load, starts=1), simulate(fab, load, starts=2)


def test_starts_are_recorded_and_the_lowest_energy_one_is_returned(jersey_two_starts):
    """Both starts are in the provenance with their energies; the run continues from the lower one.

    Jersey SL11 cotton is bistable: the straight-yarn pre-stress relaxes to the knit-like state
    (λ ≈ 0.95, 1.02) and the knitted rest shape to a state of much lower energy, with the wale
    pitch collapsed (λ2 ≈ 0.5). The chosen start's E and relaxed lattice are the run's.
    """
    single, multi = jersey_two_starts
    starts = multi.provenance.extra["starts"]
    assert [s["name"] for s in starts] == [START_SET[0].name, START_SET[1].name]
    assert all(s["converged"] for s in starts)
    energies = [s["energy_Nmm"] for s in starts]
    lowest = int(np.argmin(energies))
    assert multi.provenance.extra["start_chosen"] == starts[lowest]["name"]
    assert multi.provenance.extra["relaxed_energy_Nmm"] == pytest.approx(energies[lowest], rel=1e-12)
    assert multi.provenance.extra["relaxed_stretch"] == pytest.approx(starts[lowest]["relaxed_stretch"], rel=1e-12)
    # the two starts reach different states, so returning the wrong one would show
    assert max(energies) > 1.2 * min(energies)
    # with one start the nominal state is returned, and its energy is the nominal entry's
    assert single.provenance.extra["starts"][0]["name"] == "nominal" and len(single.provenance.extra["starts"]) == 1
    assert single.provenance.extra["relaxed_energy_Nmm"] == pytest.approx(energies[0], rel=1e-9)
    assert multi.provenance.extra["relaxed_energy_Nmm"] <= single.provenance.extra["relaxed_energy_Nmm"]


@pytest.mark.parametrize("value", [0, len(START_SET) + 1, -1, "many", 1.5, True])
def test_bad_starts_value_is_a_one_line_error_naming_the_option(value):
    """``starts`` is "auto" or a whole number of starts from the documented set."""
    with pytest.raises(ConfigError) as err:
        build(RodSolver, {"starts": value}, "solver")
    text = str(err.value)
    assert "solver.starts" in text and "\n" not in text


def test_auto_and_counts_are_accepted():
    assert build(RodSolver, {"starts": "auto"}, "solver").starts == "auto"
    assert build(RodSolver, {"starts": len(START_SET)}, "solver").starts == len(START_SET)


def test_a_snap_inside_a_step_is_located():
    """A jump kept at the smallest increment is attached to the load step that holds its loaded stretch."""
    rows = np.column_stack([1.0 + 0.03 * np.arange(1, 6), [0.99, 0.98, 0.90, 0.89, 0.88], np.ones(5), np.zeros(5)])
    snap = {"loaded": [1.0840, 1.0845], "free": [0.975, 0.905], "how": "smallest increment"}
    load = LoadPath(kind="uniaxial", direction="course")
    (jump,) = locate_jumps([], [snap], rows, load)
    assert jump["step"] == 3 and jump["at_loaded_stretch"] == [1.0840, 1.0845] and jump["free"] == "wale"
    assert bool(is_jump(0.0005, 0.07)) and not bool(is_jump(0.03, 0.03, 1.5))


GARTER = dict(pattern="garter", arc_length=11.28)


def garter_runs(**options):
    """Garter, pearl cotton, free-sides pull along the course to 30 %, in 10 and in 20 steps."""
    fab = Fabric(yarn=get_registry()["yarn"]["pearl-cotton"], **GARTER)
    return [simulate(fab, LoadPath(kind="uniaxial", direction="course", max_strain=0.3, steps=steps), starts=1,
                     **options) for steps in (10, 20)]


def test_two_step_counts_end_on_one_branch_or_say_where_they_switched():
    """Without branch following (fast): the two step counts end in one state, or a run flags its jump.

    The cell snaps through on the way (its free wale stretch drops by 0.06 within one step). Both
    runs must end in the same state (tension and free stretch within 1 %), or a run that changed
    branch must say so in ``branch_jumps``.
    """
    runs = garter_runs(follow_branch=False)
    (a, b) = runs
    same = (abs(a.T1[-1] - b.T1[-1]) <= 0.01 * abs(b.T1[-1]) and abs(a.lambda2[-1] - b.lambda2[-1]) <= 0.01)
    flagged = [r.provenance.extra["branch_jumps"] for r in runs]
    assert same or any(flagged)
    for r, jumps in zip(runs, flagged):
        for j in jumps:  # a flag says where: the step, the free side and the stretches before and after
            assert 1 <= j["step"] <= len(r) and j["free"] == "wale" and abs(j["to"] - j["from"]) > 0.02


@pytest.mark.slow
def test_following_the_branch_gives_one_path_and_one_snap_for_two_step_counts():
    """With ``follow_branch`` (default) both step counts follow the same branch and snap at the same place.

    The last converged loaded stretch λa before the snap agrees within the 10-step run's smallest
    increment, 0.03 / 64; the final tension agrees to 1 %. (77 s on a busy 2-core machine.)
    """
    a, b = garter_runs()
    assert a.T1[-1] == pytest.approx(b.T1[-1], rel=0.01) and a.lambda2[-1] == pytest.approx(b.lambda2[-1], abs=0.01)
    ja, jb = ([j for j in r.provenance.extra["branch_jumps"] if "at_loaded_stretch" in j] for r in (a, b))
    assert len(ja) == len(jb) >= 1
    for x, y in zip(ja, jb):
        assert abs(x["at_loaded_stretch"][0] - y["at_loaded_stretch"][0]) <= 0.03 / 64
