r"""The assignment of fabrics to the course bands of a knitted tube, solved exactly.

A tube knitted in the round changes fabric most easily between courses (stripes), so a region is
a run of consecutive element rows with one fabric. Given the additive cost :math:`c_{if}` of giving
row *i* fabric *f* (the objective's per-element terms summed over the row; :math:`+\infty` where the
fabric would exceed its limit) and the courses :math:`n_{if}` that row holds in fabric *f*, find

.. math:: \min_{f_0 \dots f_{R-1}} \sum_i c_{i f_i}

subject to: every run of one fabric holds at least ``min_courses`` courses, and (optionally) at
most *K* distinct fabrics are used.

- Without *K*: dynamic programming over runs (:func:`solve_bands_dp`), exact: the global optimum.
  ``best[e, f]`` is the least cost of rows 0..e whose last run, of fabric f, ends at e; each ``e``
  minimises over the run's start s, vectorised over (s, f): O(R² F).
- With *K*: an integer program solved by HiGHS through :func:`scipy.optimize.milp`
  (:func:`solve_bands_milp`); it reports HiGHS's relative optimality gap (0: proven optimal).

For objectives whose target is a free level τ (uniform stress or pressure, whatever its value),
:func:`solve_levels` minimises over τ too: each τ is an exact assignment problem, and τ is searched
on a logarithmic grid, then refined by golden-section search around the best grid point.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError

__all__ = [
    "NoAssignment",
    "BandSolution",
    "solve_bands",
    "solve_bands_dp",
    "solve_bands_milp",
    "solve_levels",
    "runs",
]


class NoAssignment(ValueError):
    """No assignment meets the limits and the constraints."""


@attrs.frozen
class BandSolution:
    """Fabric index of each element row, the cost, and what the solver guarantees."""

    #: (R,) fabric index per element row
    rows: np.ndarray
    #: the minimised sum of row costs
    cost: float
    #: "dynamic programming" or "MILP (HiGHS)"
    method: str
    #: relative optimality gap; 0 for a proven global optimum
    gap: float = 0.0
    #: τ of a relative objective
    level: float | None = None

    @property
    def guarantee(self) -> str:
        if self.method == "dynamic programming":
            return "global optimum over course bands (dynamic programming, exact)"
        return (
            "global optimum over course bands (MILP, HiGHS: proven optimal)"
            if self.gap <= 1e-9
            else f"within a relative gap of {self.gap:.2g} of the optimum over course bands (MILP, HiGHS)"
        )


def runs(rows: np.ndarray) -> list[tuple[int, int, int]]:
    """Consecutive runs of one fabric: ``(first_row, last_row + 1, fabric)``."""
    rows = np.asarray(rows)
    cut = np.flatnonzero(np.diff(rows)) + 1
    starts = np.concatenate([[0], cut])
    ends = np.concatenate([cut, [len(rows)]])
    return [(int(s), int(e), int(rows[s])) for s, e in zip(starts, ends, strict=False)]


def _check(cost: np.ndarray, courses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    cost = np.asarray(cost, dtype=np.float64)
    courses = np.asarray(courses, dtype=np.float64)
    if cost.ndim != 2 or cost.shape != courses.shape or cost.size == 0:
        raise ValueError(
            f"cost and courses must be (rows, fabrics) arrays of one shape, got {cost.shape}, {courses.shape}"
        )
    if (
        np.any(np.isnan(cost))
        or np.any(cost == -np.inf)
        or np.any(~np.isfinite(courses))
        or np.any(courses <= 0)
    ):
        raise ValueError("costs must be finite or +inf, and courses finite and > 0")
    return cost, courses


def solve_bands_dp(cost: np.ndarray, courses: np.ndarray, min_courses: float = 0.0) -> BandSolution:
    """Exact minimum over course-band assignments by dynamic programming (see the module docstring).

    Parameters
    ----------
    cost : (R, F) array
        Cost of giving row i fabric f; ``+inf`` where not allowed.
    courses : (R, F) array
        Courses row i holds in fabric f (> 0).
    min_courses : float
        Least number of courses of every run.
    """
    cost, courses = _check(cost, courses)
    R, F = cost.shape
    bad = ~np.isfinite(cost)
    CC = np.vstack([np.zeros(F), np.cumsum(np.where(bad, 0.0, cost), axis=0)])  # (R+1, F)
    NN = np.vstack([np.zeros(F), np.cumsum(courses, axis=0)])
    BB = np.vstack([np.zeros(F, dtype=np.int64), np.cumsum(bad, axis=0)])
    best = np.full((R, F), np.inf)
    start = np.zeros((R, F), dtype=np.int64)
    # min over f' != f of best[s-1, f']: the best and second best of each row, with the best's index
    m1 = np.full(R + 1, np.inf)
    m2 = np.full(R + 1, np.inf)
    a1 = np.full(R + 1, -1)
    m1[0] = m2[0] = 0.0  # before row 0: nothing, at no cost, and any fabric may follow
    tol = 1e-9 * max(1.0, float(min_courses))
    for e in range(R):
        s = np.arange(e + 1)
        seg = CC[e + 1] - CC[s]  # (e+1, F)
        ok = (BB[e + 1] - BB[s] == 0) & (NN[e + 1] - NN[s] >= min_courses - tol)
        prev = np.where(a1[s, None] == np.arange(F)[None, :], m2[s, None], m1[s, None])
        total = np.where(ok, prev + seg, np.inf)
        k = np.argmin(total, axis=0)
        best[e] = total[k, np.arange(F)]
        start[e] = k
        order = np.argsort(best[e], kind="stable")
        m1[e + 1], a1[e + 1] = best[e, order[0]], order[0]
        m2[e + 1] = best[e, order[1]] if F > 1 else np.inf
    f = int(np.argmin(best[R - 1]))
    total = float(best[R - 1, f])
    if not np.isfinite(total):
        raise NoAssignment("no assignment meets the limits and the minimum region size")
    rows = np.empty(R, dtype=np.int64)
    e = R - 1
    while e >= 0:  # back-track the runs
        s = int(start[e, f])
        rows[s : e + 1] = f
        if s == 0:
            break
        prev = best[s - 1].copy()
        prev[f] = np.inf
        f = int(np.argmin(prev))
        e = s - 1
    return BandSolution(rows, total, "dynamic programming")


def solve_bands_milp(
    cost: np.ndarray,
    courses: np.ndarray,
    min_courses: float = 0.0,
    max_fabrics: int | None = None,
    *,
    time_limit: float = 10.0,
) -> BandSolution:
    r"""The same problem with at most ``max_fabrics`` distinct fabrics, as an integer program (HiGHS).

    Binary variables: :math:`x_{if}` (row i has fabric f), :math:`s_{if}` (a run of f starts at
    row i), :math:`y_f` (f is used). Constraints: :math:`\sum_f x_{if} = 1`;
    :math:`s_{if} \ge x_{if} - x_{i-1,f}`; a run that starts at i covers the :math:`t_{if}` rows
    needed to reach ``min_courses`` (:math:`\sum_{k<t} x_{i+k,f} \ge t_{if} s_{if}`, and no run may
    start where it cannot); :math:`x_{if} \le y_f`, :math:`\sum_f y_f \le K`; :math:`x_{if} = 0`
    where the cost is infinite.
    """
    import scipy.sparse as sp
    from scipy.optimize import Bounds, LinearConstraint, milp

    cost, courses = _check(cost, courses)
    R, F = cost.shape
    nx = R * F
    X = lambda i, f: i * F + f  # noqa: E731
    S = lambda i, f: nx + i * F + f  # noqa: E731
    Y = lambda f: 2 * nx + f  # noqa: E731
    n = 2 * nx + F
    c = np.zeros(n)
    finite = np.isfinite(cost)
    c[:nx] = np.where(finite, cost, 0.0).reshape(-1)
    ub = np.ones(n)
    ub[:nx] = finite.reshape(-1).astype(float)
    rows_i, cols_i, vals, lo, hi = [], [], [], [], []

    def add(entries: list[tuple[int, float]], lower: float, upper: float) -> None:
        r = len(lo)
        for col, v in entries:
            rows_i.append(r)
            cols_i.append(col)
            vals.append(v)
        lo.append(lower)
        hi.append(upper)

    for i in range(R):
        add([(X(i, f), 1.0) for f in range(F)], 1.0, 1.0)
    NN = np.vstack([np.zeros(F), np.cumsum(courses, axis=0)])
    tol = 1e-9 * max(1.0, float(min_courses))
    for f in range(F):
        for i in range(R):
            prev = [] if i == 0 else [(X(i - 1, f), 1.0)]
            add([(S(i, f), 1.0), (X(i, f), -1.0)] + prev, 0.0, np.inf)  # s >= x_i - x_{i-1}
            add([(X(i, f), 1.0), (Y(f), -1.0)], -np.inf, 0.0)
            reach = np.flatnonzero(NN[i + 1 :, f] - NN[i, f] >= min_courses - tol)
            if not len(reach):
                ub[S(i, f)] = 0.0
                continue
            t = int(reach[0]) + 1
            if t > 1:
                add([(X(i + k, f), 1.0) for k in range(t)] + [(S(i, f), -float(t))], 0.0, np.inf)
    if max_fabrics is not None:
        add([(Y(f), 1.0) for f in range(F)], 1.0, float(max_fabrics))
    A = sp.csr_matrix((vals, (rows_i, cols_i)), shape=(len(lo), n))
    res = milp(
        c,
        constraints=LinearConstraint(A, lo, hi),
        integrality=np.ones(n),
        bounds=Bounds(0, ub),
        options={"time_limit": time_limit, "disp": False},
    )
    if res.x is None:
        raise NoAssignment(
            "no assignment meets the limits, the minimum region size and the fabric count "
            f"(HiGHS: {res.message})"
        )
    x = np.round(res.x[:nx]).reshape(R, F)
    rows = np.argmax(x, axis=1)
    gap = float(getattr(res, "mip_gap", 0.0) or 0.0)
    return BandSolution(rows, float(cost[np.arange(R), rows].sum()), "MILP (HiGHS)", gap=max(gap, 0.0))


def solve_bands(
    cost: np.ndarray, courses: np.ndarray, min_courses: float = 0.0, max_fabrics: int | None = None
) -> BandSolution:
    """Dynamic programming, or the integer program when the number of fabrics is limited."""
    if max_fabrics is not None and max_fabrics < np.asarray(cost).shape[1]:
        return solve_bands_milp(cost, courses, min_courses, max_fabrics)
    return solve_bands_dp(cost, courses, min_courses)


def solve_levels(
    row_cost: Callable[[float], np.ndarray],
    courses: np.ndarray | None,
    levels: np.ndarray,
    evaluate: Callable[[Any], float],
    *,
    min_courses: float = 0.0,
    max_fabrics: int | None = None,
    refine: int = 12,
    solve: Callable[[np.ndarray], Any] | None = None,
) -> Any:
    """Minimise over a free level τ as well: exact assignment for each τ, τ on a grid then refined.

    ``row_cost(τ)`` gives the costs at level τ; ``evaluate(rows)`` the true objective of an
    assignment, which picks the winner (for the CV objectives, the level sum is a monotone
    function of the CV, see :func:`knitframe_objectives.stress_variance.level_cost`). ``solve(cost)``
    replaces :func:`solve_bands` (with ``courses``, ``min_courses`` and ``max_fabrics``) for another
    exact assignment, such as a shaped tube's; ``evaluate`` then gets its whole solution.
    """
    levels = np.unique(np.asarray(levels, dtype=np.float64))
    levels = levels[np.isfinite(levels) & (levels > 0)]
    if not len(levels):
        raise NoAssignment("no positive level to search")
    cache: dict[float, tuple[float, BandSolution]] = {}

    def trial(tau: float) -> float:
        if tau not in cache:
            try:
                cost = row_cost(tau)
                sol = solve(cost) if solve else solve_bands(cost, courses, min_courses, max_fabrics)
            except NoAssignment:
                cache[tau] = (math.inf, None)  # type: ignore[assignment]
            else:
                cache[tau] = (evaluate(sol if solve else sol.rows), attrs.evolve(sol, level=tau))
        return cache[tau][0]

    scores = np.array([trial(float(t)) for t in levels])
    if not np.any(np.isfinite(scores)):
        raise NoAssignment("no assignment meets the limits and the minimum region size")
    k = int(np.argmin(scores))
    lo = math.log(levels[max(k - 1, 0)])
    hi = math.log(levels[min(k + 1, len(levels) - 1)])
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    for _ in range(refine if hi > lo else 0):  # golden section on log τ around the best grid point
        if trial(math.exp(a)) <= trial(math.exp(b)):
            hi, b = b, a
            a = hi - g * (hi - lo)
        else:
            lo, a = a, b
            b = lo + g * (hi - lo)
    best = min(cache.values(), key=lambda v: v[0])
    return best[1]


def check_options(min_courses: float, max_fabrics: int | None, n_fabrics: int) -> None:
    """One-line errors for impossible constraint settings (named as in the config)."""
    if not (np.isfinite(min_courses) and min_courses >= 0):
        raise ConfigError("design.min_courses", f"must be a finite number >= 0, got {min_courses}")
    if max_fabrics is not None and not 1 <= max_fabrics:
        raise ConfigError("design.max_fabrics", f"must be >= 1, got {max_fabrics}")
    if n_fabrics < 1:
        raise ConfigError("design.library", "holds no fabric")
