"""The assignment of fabrics to a tube: every fabric's fields on every element, the objective's field,
the exact course-band solve, the needle search, and the method that puts them together."""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError
from knitframe.garment.laplace import laplace_mmhg
from knitframe.garment.optimise import BandSolution, NoAssignment, solve_bands, solve_levels
from knitframe.garment.paper import _paper_method
from knitframe.garment.tube import ElementGeometry, Tube


def _evaluate(objective, T1: np.ndarray, geo: ElementGeometry, pressure_basis: str) -> np.ndarray:
    """The objective's field for tensions T1 (any leading shape, last two (R, A))."""
    from knitframe.garment.knitted import _field

    return _field(objective, T1, geo, pressure_basis)


def _fabric_fields(
    library, tube: Tube, geo: ElementGeometry, distal: float, needles: int | None, ceiling: float = np.inf
):
    """λ1, λ2, T1, T2 of shape (F, R, A), courses (R, F) and the feasibility (F, R, A): within the
    fabric's limits, in a row whose mean pressure (equivalent radius) is at most ``ceiling``."""
    entries = library.entries
    c = np.array([e.course_pitch for e in entries])
    w = np.array([e.wale_pitch for e in entries])
    lam1, lam2, courses = tube.stretches(geo, c, w, distal, needles)
    T1 = np.empty(lam1.shape)
    T2 = np.empty(lam1.shape)
    for f, e in enumerate(entries):
        t1, t2 = e.tensions(lam1[f], lam2[f])
        T1[f], T2[f] = np.maximum(t1, 0.0), np.maximum(t2, 0.0)  # slack fabric carries no compression
    tmax = np.array([e.max_tension for e in entries])[:, None, None]
    smax = np.array([e.max_stretch or np.inf for e in entries])[:, None, None]
    feasible = np.isfinite(T1) & (T1 <= tmax) & (lam1 <= smax)
    row_p = laplace_mmhg(T1, geo.equivalent_radius[:, None]).mean(axis=2, keepdims=True)
    feasible &= row_p <= ceiling
    return np.asarray(lam1), np.asarray(lam2), T1, T2, courses, feasible


def _solve_bands(
    objective,
    V: np.ndarray,
    feasible: np.ndarray,
    geo: ElementGeometry,
    courses: np.ndarray,
    min_courses: float,
    max_fabrics: int | None,
) -> BandSolution:
    """Exact course-band assignment for the objective's per-element field V (F, R, A)."""
    area = geo.area[None]
    pos = np.broadcast_to(geo.position[:, None], geo.shape)[None]
    blocked = ~feasible.all(axis=2).T  # (R, F): a row in fabric f with any element over the limit

    def row_cost(level: float | None) -> np.ndarray:
        c = objective.element_cost(V, area, pos, level).sum(axis=2).T
        return np.where(blocked, np.inf, c)

    def evaluate(rows: np.ndarray) -> float:
        v = V[rows, np.arange(len(rows))]
        return objective.evaluate(v, geo.area, np.broadcast_to(geo.position[:, None], geo.shape))

    if not objective.relative:
        return solve_bands(row_cost(None), courses, min_courses, max_fabrics)
    ok = V[feasible & (V > 0)]
    if not len(ok):
        raise NoAssignment("every fabric is slack or over its limit everywhere")
    levels = np.geomspace(np.percentile(ok, 2), np.percentile(ok, 98), 24)
    return solve_levels(row_cost, courses, levels, evaluate, min_courses=min_courses, max_fabrics=max_fabrics)


def _no_fit_message(library, feasible: np.ndarray, lam1: np.ndarray, geo: ElementGeometry) -> str:
    rows_ok = feasible.all(axis=2).any(axis=0)  # (R,): some fabric fits the whole row
    if rows_ok.all():
        return "no assignment meets the limits with regions of at least design.min_courses courses"
    i = int(np.flatnonzero(~rows_ok)[0])
    return (
        f"no fabric in library '{library.name}' can be worn at {geo.z[i]:.0f} mm along the limb "
        f"(circumference {geo.circumference[i]:.0f} mm, course stretch {lam1[:, i].min():.2f} to "
        f"{lam1[:, i].max():.2f}): every one is over its limit; add a more compliant fabric or use "
        "more needles"
    )


def _assign(
    library,
    objective,
    tube: Tube,
    geo: ElementGeometry,
    distal: float,
    options: dict[str, Any],
    notes: list[str],
) -> tuple[np.ndarray, Tube, str, tuple[np.ndarray, ...]]:
    """The (R, A) fabric of every element by ``options["method"]``, the tube as made, the guarantee,
    and every fabric's fields ``(λ1, λ2, T1, T2, courses, feasible)``; notes are appended to ``notes``.

    ``options`` holds the ``method``, ``pressure``, ``min_courses``, ``max_fabrics`` and ``base_i``
    (the index of the base fabric) of :func:`~knitframe.garment.core.design`.
    """
    pressure, min_courses, max_fabrics = options["pressure"], options["min_courses"], options["max_fabrics"]
    ceiling = options.get("ceiling", np.inf)
    where = np.broadcast_to(geo.position[:, None], geo.shape)

    def solve(n: int | None):
        lam1, lam2, T1, T2, courses, feasible = _fabric_fields(library, tube, geo, distal, n, ceiling)
        V = _evaluate(objective, T1, geo, pressure)
        sol = _solve_bands(objective, V, feasible, geo, courses, min_courses, max_fabrics)
        value = objective.evaluate(V[sol.rows, np.arange(len(sol.rows))], geo.area, where)
        return sol, (lam1, lam2, T1, T2, courses, feasible, V), float(value)

    if options["method"] == "paper":
        lam1, lam2, T1, T2, courses, feasible = _fabric_fields(library, tube, geo, distal, None, ceiling)
        min_elements = max(1, int(np.ceil(min_courses / courses.mean())))
        fab, more = _paper_method(objective, library, T1, feasible, geo, options["base_i"], min_elements)
        notes += more
        guarantee = "none: the paper's per-element heuristic (steps 5–7)"
        return fab, tube, guarantee, _chosen(fab, (lam1, lam2, T1, T2), courses), _base(options, T1, feasible)
    if tube.mode == "knitting":
        from knitframe.garment.knitted import design_fields, solve_knitted

        try:
            sol, _, courses = solve_knitted(
                library,
                objective,
                tube,
                [geo, *options.get("scenarios", [])],
                options["rules"],
                pressure=pressure,
                min_courses=min_courses,
                max_fabrics=max_fabrics,
                ceiling=options.get("ceiling", np.inf),
            )
        except NoAssignment as e:
            raise ConfigError("design", str(e)) from None
        lam1, lam2, T1, T2 = design_fields(library, geo, sol.rows, sol.needles, courses)
        made = attrs.evolve(tube, needles=int(sol.needles[0]))
        fab = np.repeat(sol.rows[:, None], geo.shape[1], axis=1)
        guarantee = sol.guarantee + (
            f"; level τ = {sol.level:.4g} searched on a grid and refined" if sol.level is not None else ""
        )
        R = len(sol.rows)
        chosen = (lam1, lam2, T1, T2, courses[np.arange(R), sol.rows].astype(float), sol.needles)
        b = options["base_i"]
        lb, _, Tb, _ = design_fields(library, geo, np.full(R, b), sol.needles, courses)
        e = library.entries[b]
        over = int(((Tb > e.max_tension) | (lb > (e.max_stretch or np.inf))).sum())
        return fab, made, guarantee, chosen, (Tb, over)
    try:
        sol, fields, _ = solve(None)
    except NoAssignment:
        lam1, _, _, _, _, feasible = _fabric_fields(library, tube, geo, distal, None, ceiling)
        raise ConfigError("design", _no_fit_message(library, feasible, lam1, geo)) from None
    made = attrs.evolve(
        tube,
        circumference=tube.circumference or distal,
        length=tube.length or float(geo.row_length.sum()),
    )
    fab = np.repeat(sol.rows[:, None], geo.shape[1], axis=1)
    guarantee = sol.guarantee + (
        f"; level τ = {sol.level:.4g} searched on a grid and refined" if sol.level is not None else ""
    )
    lam1, lam2, T1, T2, courses, feasible, _ = fields
    return fab, made, guarantee, _chosen(fab, (lam1, lam2, T1, T2), courses), _base(options, T1, feasible)


def _chosen(fab: np.ndarray, fields, courses: np.ndarray):
    """(R, A) λ1, λ2, T1, T2 of the assignment ``fab`` from every fabric's (F, R, A) fields, the (R,)
    courses of each row (its first element's fabric) and no needle counts (paper mode)."""
    R, A = fab.shape
    ii, jj = np.arange(R)[:, None], np.arange(A)[None, :]
    picked = tuple(X[fab, ii, jj] for X in fields)
    return (*picked, courses[np.arange(R), fab[:, 0]].astype(float), None)


def _base(options, T1: np.ndarray, feasible: np.ndarray):
    """The base fabric's tension everywhere and its count of elements over the limit."""
    b = options["base_i"]
    return T1[b], int((~feasible[b]).sum())
