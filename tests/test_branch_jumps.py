"""A load step that snaps to another equilibrium branch is flagged, not passed off as a smooth curve."""

from __future__ import annotations

import numpy as np

from knitframe.records import LoadPath
from knitframe_solvers.rod import branch_jumps


def rows(l1, l2):
    """(λ1, λ2, T1, T2) rows with a rising course tension and no wale tension."""
    l1, l2 = np.asarray(l1, float), np.asarray(l2, float)
    return np.column_stack([l1, l2, np.linspace(0.1, 1.0, len(l1)), np.zeros(len(l1))])


def test_smooth_lateral_contraction_is_no_jump():
    """A free side that contracts smoothly, even at a Poisson ratio of 1.5, is not flagged."""
    l1 = 1.0 + 0.03 * np.arange(1, 11)
    assert branch_jumps(rows(l1, 1.0 - 1.5 * (l1 - 1.0)), LoadPath(kind="uniaxial", direction="course")) == []


def test_a_snap_of_the_free_side_is_flagged_at_its_step():
    """The free wale stretch falling 0.84 -> 0.43 in the last step of a course pull is reported at that step."""
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
