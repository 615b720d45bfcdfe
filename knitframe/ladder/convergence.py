"""Mesh convergence: the observed order and a Richardson estimate of the finest mesh's error.

A quantity f computed on meshes of size h₁ < h₂ < h₃ (finest first) is modelled as

    f(h) = f₀ + C·hᵖ,

with f₀ the mesh-converged value and p the observed order of convergence. The three solutions
fix the three unknowns: the ratio of successive differences

    R = (f₃ − f₂) / (f₂ − f₁) = (h₃ᵖ − h₂ᵖ) / (h₂ᵖ − h₁ᵖ)

is increasing in p, so p follows by bracketing (for a constant refinement ratio r it is
p = ln R / ln r); then C = (f₂ − f₁)/(h₂ᵖ − h₁ᵖ) and f₀ = f₁ − C·h₁ᵖ. The finest mesh's error
is |f₁ − f₀| / |f₀|, and Roache's grid-convergence index with the safety factor 1.25 is
GCI = 1.25·|f₂ − f₁| / |f₁| / (r₂₁ᵖ − 1), r₂₁ = h₂/h₁ (Roache 1994; Celik et al. 2008, J. Fluids
Eng. 130:078001, which this procedure follows).

When R ≤ 0 the solutions oscillate, and when R is below its value at p → 0 the differences grow
as the mesh is refined: neither has an order, and :func:`richardson` says so instead of
extrapolating. :func:`mesh_convergence` applies it to the curves of a ladder's volumetric rungs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import attrs
import numpy as np

__all__ = ["Richardson", "richardson", "mesh_convergence", "CONVERGENCE_COLUMNS"]

#: the observed order is searched in this range
ORDER_RANGE = (1e-3, 20.0)
#: a difference this small relative to the finest value counts as converged (no order to estimate)
SAME = 1e-12


@attrs.frozen
class Richardson:
    """The result of :func:`richardson` (every value float64; None where there is no order)."""

    #: the observed order p
    order: float | None
    #: f₀, the mesh-converged estimate
    extrapolated: float | None
    #: |f₁ − f₀| / |f₀|, the estimated relative error of the finest mesh
    error_finest: float | None
    #: Roache's grid-convergence index of the finest mesh (safety factor 1.25)
    gci_finest: float | None
    #: "converging", "converged", "oscillating" or "diverging"
    behaviour: str


def _ratio(p: float, h1: float, h2: float, h3: float) -> float:
    return (h3**p - h2**p) / (h2**p - h1**p)


def richardson(h: Sequence[float], f: Sequence[float]) -> Richardson:
    """Observed order and Richardson extrapolation from three solutions (module docstring).

    ``h``: three mesh sizes in any order (any unit; only their ratios count), all different;
    ``f``: the quantity on each. Raises ValueError for anything but three finite values each.
    """
    h_arr, f_arr = np.asarray(h, dtype=np.float64), np.asarray(f, dtype=np.float64)
    if h_arr.shape != (3,) or f_arr.shape != (3,):
        raise ValueError("richardson: give exactly three mesh sizes and three values")
    if not (np.all(np.isfinite(h_arr)) and np.all(np.isfinite(f_arr))):
        raise ValueError("richardson: mesh sizes and values must be finite")
    if np.any(h_arr <= 0) or len(np.unique(h_arr)) != 3:
        raise ValueError("richardson: the three mesh sizes must be positive and different")
    o = np.argsort(h_arr)
    (h1, h2, h3), (f1, f2, f3) = h_arr[o], f_arr[o]
    e21, e32 = f2 - f1, f3 - f2
    scale = max(abs(f1), abs(f2), abs(f3), np.finfo(float).tiny)
    if abs(e21) <= SAME * scale and abs(e32) <= SAME * scale:
        return Richardson(None, float(f1), 0.0, 0.0, "converged")
    if abs(e21) <= SAME * scale or e32 / e21 <= 0:
        return Richardson(None, None, None, None, "oscillating")
    R = e32 / e21
    lo, hi = ORDER_RANGE
    if R <= _ratio(lo, h1, h2, h3):
        return Richardson(None, None, None, None, "diverging")
    if R >= _ratio(hi, h1, h2, h3):
        p = hi
    else:
        for _ in range(200):  # bisection in log p: R(p) is increasing
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if _ratio(mid, h1, h2, h3) < R else (lo, mid)
            if hi / lo - 1.0 < 1e-12:
                break
        p = math.sqrt(lo * hi)
    C = e21 / (h2**p - h1**p)
    f0 = f1 - C * h1**p
    err = abs(f1 - f0) / abs(f0) if f0 != 0 else math.inf
    gci = 1.25 * abs(e21 / f1) / ((h2 / h1) ** p - 1.0) if f1 != 0 else math.inf
    return Richardson(float(p), float(f0), float(err), float(gci), "converging")


#: columns of ``convergence.csv``
CONVERGENCE_COLUMNS = (
    "family",
    "rungs",
    "direction",
    "strain",
    "T_finest",
    "T_middle",
    "T_coarsest",
    "order",
    "T_extrapolated",
    "error_finest",
    "gci_finest",
    "behaviour",
)


def mesh_convergence(
    rungs: Mapping[str, float], curves: Mapping[str, Any], load: str, family: str
) -> list[dict[str, Any]]:
    """Richardson at every load step of the three finest of ``rungs`` (name → mesh size h).

    ``curves`` maps each rung name to its Response (same scene, so the same load steps; a
    truncated curve limits the steps to those all three reached). One row per loaded direction
    and load step after the first, with :data:`CONVERGENCE_COLUMNS`. Empty with fewer than three
    rungs that finished.
    """
    from knitframe.ladder.compare import loaded_directions

    names = sorted((n for n in rungs if n in curves), key=lambda n: rungs[n])[:3]
    if len(names) < 3:
        return []
    rs = [curves[n] for n in names]
    rows: list[dict[str, Any]] = []
    for d in loaded_directions(load):
        lams = [np.asarray(r.lambda1 if d == 0 else r.lambda2) for r in rs]
        Ts = [np.asarray(r.T1 if d == 0 else r.T2) for r in rs]
        n = min(len(x) for x in lams)
        for i in range(n):
            if not all(abs(lam[i] - lams[0][i]) < 1e-9 for lam in lams):
                break  # the paths part (a truncated or cut-back run): stop at the last common step
            strain = float(lams[0][i] - 1.0)
            if strain <= 1e-9:
                continue
            vals = [float(T[i]) for T in Ts]
            r = richardson([rungs[m] for m in names], vals)
            rows.append(
                {
                    "family": family,
                    "rungs": " ".join(names),
                    "direction": ("course", "wale")[d],
                    "strain": strain,
                    "T_finest": vals[0],
                    "T_middle": vals[1],
                    "T_coarsest": vals[2],
                    "order": r.order,
                    "T_extrapolated": r.extrapolated,
                    "error_finest": r.error_finest,
                    "gci_finest": r.gci_finest,
                    "behaviour": r.behaviour,
                }
            )
    return rows


def _fmt(x: float | None, pct: bool = False) -> str:
    if x is None:
        return "–"
    return f"{100 * x:.3g} %" if pct else f"{x:.4g}"


def write_convergence(path, rows: Sequence[Mapping[str, Any]]) -> None:
    """``convergence.csv``: :data:`CONVERGENCE_COLUMNS`, one row per family, direction and load step."""
    import csv

    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(CONVERGENCE_COLUMNS)
        for r in rows:
            w.writerow(
                [
                    "" if r[c] is None else (f"{r[c]:.10g}" if isinstance(r[c], float) else r[c])
                    for c in CONVERGENCE_COLUMNS
                ]
            )


def convergence_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """The Markdown section of ``ladder.md``: the observed order and the finest mesh's error."""
    lines = []
    for family in dict.fromkeys(r["family"] for r in rows):
        mine = [r for r in rows if r["family"] == family]
        finest, middle, coarsest = mine[0]["rungs"].split()
        lines += [
            "",
            f"### Mesh convergence of {family}",
            "",
            f"Tension (N/mm) on {coarsest}, {middle} and {finest}; the observed order p and the "
            "Richardson estimate of the mesh-converged tension and of the finest mesh's error "
            "(knitframe.ladder.convergence).",
            "",
            "| direction | strain | coarsest | middle | finest | order p | extrapolated "
            "| error of the finest | GCI | behaviour |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in mine:
            lines.append(
                f"| {r['direction']} | {100 * r['strain']:.3g} % | {_fmt(r['T_coarsest'])} | "
                f"{_fmt(r['T_middle'])} | {_fmt(r['T_finest'])} | {_fmt(r['order'])} | "
                f"{_fmt(r['T_extrapolated'])} | {_fmt(r['error_finest'], True)} | "
                f"{_fmt(r['gci_finest'], True)} | {r['behaviour']} |"
            )
    return "\n".join(lines) + "\n"
