r"""The knitting-mode design: every row's fabric and needle count, chosen together and exactly.

A row i knitted in fabric f on N needles stretches around the limb by

.. math:: \lambda_1 = \frac{C_i}{N\,c_f}, \qquad \lambda_2 = \frac{e^{(2)}_{ij}}{k_{if}\, w_f},

with :math:`C_i` the row's circumference, :math:`c_f, w_f` the fabric's relaxed course and wale
pitches and :math:`k_{if}` its courses (chosen for the target axial stretch, as in
:class:`~knitframe.garment.tube.Tube`). The fabric's reduced model gives the tensions and Laplace's
law the pressure. For every (row, fabric, needle count) this module tabulates the objective's row
cost and whether the row is allowed: every element within the fabric's limits, and the row's mean
pressure (equivalent radius) at most the safety ceiling. :func:`solve_knitted` hands the table to
the exact dynamic programme of :mod:`knitframe.garment.optimise_shaped`.

**Robust designs.** Given several *scenarios* of the limb (the limb scaled by 1 ± x in
circumference, or other scans of it resampled to the same rows), the garment (fabrics, needles,
courses) is one, and a row's cost is its worst over the scenarios; a row is allowed only where it
is allowed in every scenario. The sum of row-wise worst cases is still additive, so the optimum
stays exact.
"""

from __future__ import annotations

import itertools
import math

import attrs
import numpy as np

from knitframe.garment.laplace import laplace_mmhg
from knitframe.garment.optimise import NoAssignment, solve_bands, solve_levels
from knitframe.garment.optimise_shaped import ShapedSolution, solve_shaped
from knitframe.garment.shaping import MachineRules, allowed_change
from knitframe.garment.tube import ElementGeometry, Tube

__all__ = ["needle_range", "row_courses", "knitted_fields", "solve_knitted", "scaled_geometry"]

#: the most fabric subsets enumerated for ``max_fabrics`` on a shaped tube (each solved exactly)
MAX_SUBSETS = 512


def scaled_geometry(geo: ElementGeometry, s: float) -> ElementGeometry:
    """The limb's geometry with every section scaled by ``s`` around its centre (lengths along kept)."""
    return attrs.evolve(
        geo,
        e1=geo.e1 * s,
        area=geo.area * s,
        curvature=geo.curvature / s,
        equivalent_radius=geo.equivalent_radius * s,
        circumference=geo.circumference * s,
    )


def row_courses(tube: Tube, geo: ElementGeometry, wale_pitch: np.ndarray) -> np.ndarray:
    """(R, F) integer courses of every row in every fabric, for the tube's target axial stretch."""
    w = np.asarray(wale_pitch, dtype=np.float64)
    return np.maximum(1.0, np.round(geo.row_length[:, None] / (tube.axial_stretch * w[None, :]))).astype(
        np.int64
    )


def needle_range(library, geos: list[ElementGeometry], tube: Tube, rules: MachineRules) -> np.ndarray:
    """The needle counts worth trying: from the most stretched (every fabric at its largest stretch, or
    3) to just slack (λ1 = 0.95) on the limb's sections, within the machine's range."""
    if tube.needles is not None:
        return np.array([int(tube.needles)])
    c = np.array([e.course_pitch for e in library.entries])
    smax = [e.max_stretch for e in library.entries if e.max_stretch is not None]
    top = max(smax) if smax else 3.0
    cmin = min(float(g.circumference.min()) for g in geos)
    cmax = max(float(g.circumference.max()) for g in geos)
    lo = max(rules.min_needles, int(math.floor(cmin / (c.max() * top))))
    hi = min(rules.max_needles, int(math.ceil(cmax / (c.min() * 0.95))))
    if hi < lo:
        lo = hi = min(max(lo, rules.min_needles), rules.max_needles)
    return np.arange(lo, hi + 1)


def knitted_fields(entry, geo: ElementGeometry, needles, courses, wale_pitch: float):
    """λ1, λ2, T1, T2 of one fabric on rows of ``needles`` (shape (n, 1, 1) or (R, 1)) needles.

    ``courses`` is the rows' (R,) course count in this fabric. Tensions are never negative.
    """
    A = geo.shape[1]
    lam1 = geo.e1 / ((np.asarray(needles, dtype=np.float64) / A) * entry.course_pitch)
    lam2 = np.broadcast_to(geo.e2 / (np.asarray(courses, dtype=np.float64)[:, None] * wale_pitch), lam1.shape)
    T1, T2 = entry.tensions(lam1, lam2)
    return lam1, lam2, np.maximum(T1, 0.0), np.maximum(T2, 0.0)


def _field(objective, T1: np.ndarray, geo: ElementGeometry, pressure: str) -> np.ndarray:
    """The objective's per-element field of tensions T1 (..., R, A)."""
    if objective.quantity == "tension":
        return T1
    radius = 1.0 / np.maximum(geo.curvature, 0.0) if pressure == "local" else geo.equivalent_radius[:, None]
    with np.errstate(divide="ignore"):
        return laplace_mmhg(T1, radius)


def _tables(library, objective, geos, needles, courses, pressure: str, ceiling: float):
    """Per scenario, the objective's field (F, n, R, A); and allowed (R, F, n) over all scenarios."""
    F, n = len(library.entries), len(needles)
    R = geos[0].shape[0]
    fields = [np.empty((F, n, *g.shape)) for g in geos]
    allowed = np.ones((R, F, n), dtype=bool)
    nn = needles[:, None, None]
    for f, e in enumerate(library.entries):
        for s, g in enumerate(geos):
            lam1, _, T1, _ = knitted_fields(e, g, nn, courses[:, f], e.wale_pitch)
            ok = np.isfinite(T1) & (T1 <= e.max_tension) & (lam1 <= (e.max_stretch or np.inf))
            mean_p = laplace_mmhg(T1, g.equivalent_radius[:, None]).mean(axis=2)  # (n, R)
            allowed[:, f, :] &= (ok.all(axis=2) & (mean_p <= ceiling)).T
            fields[s][f] = _field(objective, T1, g, pressure)
    return fields, allowed


def solve_knitted(
    library,
    objective,
    tube: Tube,
    geos: list[ElementGeometry],
    rules: MachineRules,
    *,
    pressure: str = "equivalent",
    min_courses: float = 10.0,
    max_fabrics: int | None = None,
    ceiling: float = np.inf,
    level: float | None = None,
) -> tuple[ShapedSolution, np.ndarray, np.ndarray]:
    """The exact knitting-mode design on ``geos[0]`` (robust over every geometry in ``geos``).

    Returns the solution (``needles`` already in stitches), the needle range tried and the courses
    (R, F). ``level`` fixes the level of a relative objective (searched when None).
    """
    geo = geos[0]
    needles = needle_range(library, geos, tube, rules)
    courses = row_courses(tube, geo, [e.wale_pitch for e in library.entries])
    change = (
        allowed_change(courses, rules) if tube.shaping and tube.needles is None else np.zeros_like(courses)
    )
    fields, allowed = _tables(library, objective, geos, needles, courses, pressure, ceiling)
    blocked = ~allowed.any(axis=(1, 2))
    if blocked.any():
        i = int(np.flatnonzero(blocked)[0])
        _, within = _tables(library, objective, geos, needles, courses, pressure, np.inf)
        why = (
            f"every fabric and needle count ({needles[0]}–{needles[-1]}) gives a mean pressure above the "
            f"ceiling of {ceiling:g} mmHg there (raise design.ceiling_mmHg if that is meant)"
            if within[i].any()
            else f"every fabric is over its limit there on {needles[0]}–{needles[-1]} needles"
        )
        raise NoAssignment(
            f"no design fits the row at {geo.z[i]:.0f} mm along the limb (circumference "
            f"{geo.circumference[i]:.0f} mm): {why}"
        )
    area = [g.area for g in geos]
    pos = np.broadcast_to(geo.position[:, None], geo.shape)

    def row_cost(tau: float | None) -> np.ndarray:
        c = np.max(
            [objective.element_cost(V, a, pos, tau).sum(axis=3) for V, a in zip(fields, area, strict=True)],
            axis=0,
        )
        return np.where(allowed, np.moveaxis(c, 2, 0), np.inf)  # (R, F, n)

    def solve(cost: np.ndarray) -> ShapedSolution:
        if max_fabrics is None or max_fabrics >= cost.shape[1]:
            return solve_shaped(cost, courses, change, min_courses)
        if cost.shape[2] == 1:  # one needle count: the integer program of the band assignment
            sol = solve_bands(cost[:, :, 0], courses, min_courses, max_fabrics)
            return ShapedSolution(
                sol.rows, np.zeros(len(sol.rows), dtype=np.int64), sol.cost, sol.method, sol.gap
            )
        subsets = list(itertools.combinations(range(cost.shape[1]), max_fabrics))
        if len(subsets) > MAX_SUBSETS:
            raise NoAssignment(
                f"max_fabrics = {max_fabrics} of {cost.shape[1]} fabrics is {len(subsets)} subsets to solve "
                f"on a shaped tube (at most {MAX_SUBSETS}); raise design.max_fabrics or use a smaller library"
            )
        best = None
        for sub in subsets:
            idx = np.array(sub)
            try:
                sol = solve_shaped(cost[:, idx], courses[:, idx], change[:, idx], min_courses)
            except NoAssignment:
                continue
            if best is None or sol.cost < best.cost:
                best = attrs.evolve(sol, rows=idx[sol.rows])
        if best is None:
            raise NoAssignment("no assignment meets the limits with at most design.max_fabrics fabrics")
        return best

    def evaluate(sol: ShapedSolution) -> float:
        R = len(sol.rows)
        v = fields[0][sol.rows, sol.needles, np.arange(R)]
        return float(objective.evaluate(v, geo.area, pos))

    if not objective.relative or level is not None:
        sol = solve(row_cost(level))
    else:
        ok = fields[0][np.transpose(allowed, (1, 2, 0))].ravel()
        ok = ok[np.isfinite(ok) & (ok > 0)]
        if not len(ok):
            raise NoAssignment("every fabric is slack or over its limit everywhere")
        levels = np.geomspace(np.percentile(ok, 2), np.percentile(ok, 98), 24)
        sol = solve_levels(row_cost, None, levels, evaluate, solve=solve)
    return attrs.evolve(sol, needles=needles[sol.needles]), needles, courses


def design_fields(
    library, geo: ElementGeometry, rows: np.ndarray, row_needles: np.ndarray, courses: np.ndarray
):
    """(R, A) λ1, λ2, T1, T2 of the chosen fabric and needles of every row."""
    R, A = geo.shape
    out = [np.empty((R, A)) for _ in range(4)]
    for f in np.unique(rows):
        e = library.entries[int(f)]
        sel = rows == f
        sub = attrs.evolve(
            geo,
            e1=geo.e1[sel],
            e2=geo.e2[sel],
            area=geo.area[sel],
            curvature=geo.curvature[sel],
            equivalent_radius=geo.equivalent_radius[sel],
            position=geo.position[sel],
            z=geo.z[sel],
            circumference=geo.circumference[sel],
        )
        vals = knitted_fields(e, sub, row_needles[sel][:, None], courses[sel, f], e.wale_pitch)
        for o, v in zip(out, vals, strict=True):
            o[sel] = v
    return tuple(out)
