"""A load step that snaps to another equilibrium branch is flagged, not passed off as a smooth curve."""

from __future__ import annotations

import numpy as np
import pytest
from knitframe_solvers.rod_branches import branch_jumps

from knitframe.records import LoadPath


def rows(l1, l2):
    """(λ1, λ2, T1, T2) rows with a rising course tension and no wale tension."""
    l1, l2 = np.asarray(l1, float), np.asarray(l2, float)
    return np.column_stack([l1, l2, np.linspace(0.1, 1.0, len(l1)), np.zeros(len(l1))])


def test_smooth_lateral_contraction_is_no_jump():
    """A free side that contracts smoothly, even at a Poisson ratio of 1.5, is not flagged."""
    l1 = 1.0 + 0.03 * np.arange(1, 11)
    assert branch_jumps(rows(l1, 1.0 - 1.5 * (l1 - 1.0)), LoadPath(kind="uniaxial", direction="course")) == []


def test_a_snap_of_the_free_side_is_flagged_at_its_step():
    """The free wale stretch falling 0.84 -> 0.43 in the last step of a course pull is reported at that
    step."""
    l1 = 1.0 + 0.03 * np.arange(1, 11)
    l2 = np.concatenate([np.linspace(0.98, 0.84, 9), [0.43]])
    (jump,) = branch_jumps(rows(l1, l2), LoadPath(kind="uniaxial", direction="course"))
    assert jump["step"] == 10 and jump["free"] == "wale"
    assert jump["from"] == 0.84 and jump["to"] == 0.43


def test_the_free_side_of_a_wale_pull_is_the_course():
    """Under a wale pull the course stretch is the free one that is watched."""
    l2 = 1.0 + 0.03 * np.arange(1, 6)
    l1 = np.array([0.99, 0.98, 0.70, 0.69, 0.68])
    (jump,) = branch_jumps(rows(l1, l2), LoadPath(kind="uniaxial", direction="wale"))
    assert jump["step"] == 3 and jump["free"] == "course"


def test_equibiaxial_paths_have_no_free_side_to_watch():
    """An equibiaxial path is not checked for a free-side jump."""
    l = 1.0 + 0.03 * np.arange(1, 6)
    assert branch_jumps(rows(l, l), LoadPath(kind="equibiaxial")) == []


def test_a_tension_that_falls_while_its_stretch_grows_is_a_snap():
    """Equibiaxial: a step whose tension falls by more than 10 % (and 1 % of the largest) is flagged; smooth
    curves are not."""
    from knitframe_solvers.rod_branches import tension_drops

    lam = 1.0 + np.linspace(0.05, 0.5, 10)
    T1 = 10.0 * (lam - 1.0) ** 2 + (lam - 1.0)
    T2 = 2.0 * T1
    eq = LoadPath(kind="equibiaxial", max_strain=0.5, steps=10)
    assert tension_drops(np.column_stack([lam, lam, T1, T2]), eq) == []
    T2_snap = T2.copy()
    T2_snap[8:] = [
        0.105,
        0.2,
    ]  # rib SL12 cotton: the wale tension fell 7.33 -> 0.105 N/mm between 40 and 45 %
    (drop,) = tension_drops(np.column_stack([lam, lam, T1, T2_snap]), eq)
    assert drop == {
        "step": 9,
        "direction": "wale",
        "from": pytest.approx(T2[7]),
        "to": 0.105,
        "kind": "tension drop",
    }
    small = T1.copy()
    small[4] = 0.95 * small[3]  # a 5 % dip is below the 10 % threshold
    assert tension_drops(np.column_stack([lam, lam, small, T2]), eq) == []
    tiny = T1.copy()
    tiny[0], tiny[1] = (
        1e-4,
        -1e-4,
    )  # a fall of 2e-4 N/mm when the path reaches 3 N/mm: below 1 % of the largest
    assert tension_drops(np.column_stack([lam, lam, tiny, T2]), eq) == []
    # uniaxial: only the loaded direction (the free side's jumps are branch_jumps' business)
    assert (
        tension_drops(np.column_stack([lam, lam, T1, T2_snap]), LoadPath(kind="uniaxial", direction="course"))
        == []
    )
    (drop,) = tension_drops(
        np.column_stack([lam, lam, T2_snap, T1]), LoadPath(kind="uniaxial", direction="course")
    )
    assert drop["step"] == 9 and drop["direction"] == "course"


def test_a_pulled_cell_that_sticks_then_slips_is_flagged():
    """Pearl-cotton garter along the course with friction (rod, 2026-11-27): the tension rose to 0.011 N/mm
    at 5 %, fell to -0.005 at 10 % while the free side moved by less than a jump."""
    from knitframe_solvers.rod_branches import branch_jumps, tension_drops

    lam1 = np.array([1.05, 1.10, 1.15, 1.20])
    lam2 = np.array([0.967, 0.922, 0.826, 0.809])
    T1 = np.array([0.01076, -0.00545, -0.00135, 0.00325])
    load = LoadPath(kind="uniaxial", direction="course", max_strain=0.2, steps=4)
    rows = np.column_stack([lam1, lam2, T1, np.zeros(4)])
    assert branch_jumps(rows, load) == []  # at most 0.096 of free against 0.05 loaded: under 3x, no jump
    (drop,) = tension_drops(rows, load)
    assert drop == {"step": 2, "direction": "course", "from": 0.01076, "to": -0.00545, "kind": "tension drop"}
