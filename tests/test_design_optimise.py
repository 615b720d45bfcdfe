"""The course-band optimiser against brute force, and the level search of uniformity objectives."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from knitframe.garment.optimise import runs, solve_bands_dp, solve_bands_milp, solve_levels


def brute_force(cost, courses, min_courses, max_fabrics=None):
    """Every assignment of R rows to F fabrics, the best one that meets the constraints."""
    R, F = cost.shape
    best = (np.inf, None)
    for rows in itertools.product(range(F), repeat=R):
        rows = np.array(rows)
        if max_fabrics is not None and len(set(rows.tolist())) > max_fabrics:
            continue
        if any(courses[s:e, f].sum() < min_courses - 1e-9 for s, e, f in runs(rows)):
            continue
        c = cost[np.arange(R), rows].sum()
        if c < best[0]:
            best = (c, rows)
    return best


def random_problem(rng):
    R, F = int(rng.integers(2, 7)), int(rng.integers(1, 4))
    cost = rng.random((R, F))
    cost[rng.random((R, F)) < 0.15] = np.inf  # over the limit
    courses = rng.integers(1, 4, (R, F)).astype(float)
    return cost, courses, float(rng.integers(0, 6))


@pytest.mark.parametrize("seed", range(30))
def test_dynamic_programming_finds_the_brute_force_optimum(seed):
    """On random small problems with limits and a minimum run, DP returns the exhaustive optimum."""
    cost, courses, m = random_problem(np.random.default_rng(seed))
    expected, _ = brute_force(cost, courses, m)
    if not np.isfinite(expected):
        with pytest.raises(ValueError):
            solve_bands_dp(cost, courses, m)
        return
    sol = solve_bands_dp(cost, courses, m)
    assert sol.cost == pytest.approx(expected, rel=1e-12)
    assert cost[np.arange(len(sol.rows)), sol.rows].sum() == pytest.approx(expected, rel=1e-12)
    assert all(courses[s:e, f].sum() >= m - 1e-9 for s, e, f in runs(sol.rows))


@pytest.mark.parametrize("seed", range(20))
def test_milp_with_a_fabric_limit_finds_the_brute_force_optimum(seed):
    """With at most K fabrics, the HiGHS integer program returns the exhaustive optimum and a zero gap."""
    rng = np.random.default_rng(100 + seed)
    cost, courses, m = random_problem(rng)
    K = int(rng.integers(1, cost.shape[1] + 1))
    expected, _ = brute_force(cost, courses, m, K)
    if not np.isfinite(expected):
        with pytest.raises(ValueError):
            solve_bands_milp(cost, courses, m, K)
        return
    sol = solve_bands_milp(cost, courses, m, K)
    assert sol.cost == pytest.approx(expected, rel=1e-9, abs=1e-12)
    assert len(set(sol.rows.tolist())) <= K and sol.gap <= 1e-6 and "proven optimal" in sol.guarantee


def test_runs_splits_an_assignment_into_regions():
    """runs() gives each maximal run of one fabric with its first and end rows."""
    assert runs(np.array([2, 2, 0, 0, 0, 2])) == [(0, 2, 2), (2, 5, 0), (5, 6, 2)]


def test_level_search_minimises_the_coefficient_of_variation():
    """Searching the level τ with exact inner assignments finds the CV-optimal assignment of a small
    problem."""
    rng = np.random.default_rng(7)
    R, F = 6, 3
    T = rng.uniform(0.5, 2.0, (R, F))  # one value per row and fabric (one element per row)
    w = rng.uniform(1.0, 2.0, R)
    courses = np.ones((R, F))

    def cv(rows):
        x = T[np.arange(R), rows]
        mean = np.dot(w, x) / w.sum()
        return np.sqrt(np.dot(w, (x - mean) ** 2) / w.sum()) / mean

    best = min(cv(np.array(r)) for r in itertools.product(range(F), repeat=R))
    sol = solve_levels(lambda tau: w[:, None] * (T / tau - 1.0) ** 2, courses, np.geomspace(0.5, 2.0, 16), cv)
    assert cv(sol.rows) == pytest.approx(best, rel=1e-9)
