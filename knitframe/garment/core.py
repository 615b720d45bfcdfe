"""Garment design: assign a fabric from a library to every region of a tube worn on a limb.

:func:`design` is the one entry point (the ``[design]`` stage and ``knitframe design`` call it).
Two methods:

- ``"optimal"`` (default): course bands (stripes, knittable without intarsia), each at least
  ``min_courses`` long, chosen by an exact solver (:mod:`knitframe.garment.optimise`) for the
  objective plugin, never over a fabric's limit;
- ``"paper"``: the paper's procedure, per element in 2-D (paper mode only): start with the base
  fabric (cotton), switch elements over its limit to the most compliant fabric, choose each
  element's fabric so the tension is as uniform as possible (iterated to a fixed point), then merge
  regions smaller than the minimum size into their neighbours until every region is contiguous
  and large enough. A heuristic, kept to compare with.
"""

from __future__ import annotations

import time
import warnings
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError, KnitframeWarning
from knitframe.garment.assign import _assign, _evaluate
from knitframe.garment.optimise import check_options
from knitframe.garment.paper import _periodic_labels
from knitframe.garment.tube import MMHG_PER_MPA, ElementGeometry, Tube, element_geometry
from knitframe.interfaces import DesignObjective, declared

__all__ = ["Design", "design", "compression_class", "CLASSES"]

#: RAL-GZ 387 compression classes, mmHg (lower, upper); between them a pressure has no class
CLASSES = (("I", 18.0, 21.0), ("II", 23.0, 32.0), ("III", 34.0, 46.0), ("IV", 49.0, np.inf))


def compression_class(p: float) -> str:
    """The RAL-GZ 387 class of a pressure in mmHg: I 18–21, II 23–32, III 34–46, IV ≥ 49."""
    for name, lo, hi in CLASSES:
        if lo <= p <= hi:
            return name
    if p < CLASSES[0][1]:
        return "below I"
    below = [name for name, lo, _ in CLASSES if lo > p][0]
    above = [name for name, _, hi in CLASSES if hi < p][-1]
    return f"between {above} and {below}"


@attrs.frozen(eq=False)
class Design:
    """A designed garment: the fabric of every element and the fields it gives on the limb."""

    #: the Limb
    limb: Any
    #: the FabricLibrary
    library: Any
    #: the objective plugin instance
    objective: Any
    #: the tube as made (needles filled in for knitting mode)
    tube: Tube
    method: str
    geometry: ElementGeometry
    #: (R, A) library index of every element
    fabric: np.ndarray
    #: (R, A) course stretch
    lam1: np.ndarray
    #: (R, A) wale stretch
    lam2: np.ndarray
    #: (R, A) course tension, N/mm
    T1: np.ndarray
    #: (R, A) wale tension, N/mm
    T2: np.ndarray
    #: (R,) courses knitted in each element row
    courses: np.ndarray
    #: the objective of this design
    value: float
    #: what the solver guarantees
    guarantee: str
    #: the single-fabric garment (the base fabric everywhere), for comparison
    baseline: dict[str, Any]
    #: which radius the pressure objective used: "equivalent" or "local"
    pressure_basis: str
    wall_time: float = 0.0
    notes: tuple[str, ...] = ()

    @property
    def pressure_equivalent(self) -> np.ndarray:
        """(R, A) Laplace pressure with the section's equivalent radius C/2π, mmHg."""
        return self.T1 / self.geometry.equivalent_radius[:, None] * MMHG_PER_MPA

    @property
    def pressure_local(self) -> np.ndarray:
        """(R, A) Laplace pressure with the local radius of curvature (0 where concave), mmHg."""
        return self.T1 * np.maximum(self.geometry.curvature, 0.0) * MMHG_PER_MPA

    @property
    def pressure(self) -> np.ndarray:
        return self.pressure_local if self.pressure_basis == "local" else self.pressure_equivalent

    @property
    def limits_respected(self) -> bool:
        return bool(self.over_limit.sum() == 0)

    @property
    def over_limit(self) -> np.ndarray:
        """(R, A) True where an element exceeds its fabric's tension or stretch limit."""
        lib = self.library
        tmax = np.array([e.max_tension for e in lib.entries])[self.fabric]
        smax = np.array([e.max_stretch or np.inf for e in lib.entries])[self.fabric]
        return (self.T1 > tmax * (1 + 1e-9)) | (self.lam1 > smax * (1 + 1e-9))

    def regions(self) -> list[dict[str, Any]]:
        """Contiguous regions: fabric, element rows and columns, courses, and wale (stitch) range."""
        out = []
        labels, n = _periodic_labels(self.fabric)
        first_course = np.concatenate([[0], np.cumsum(self.courses)])
        for k in range(1, n + 1):
            rows, cols = np.nonzero(labels == k)
            f = int(self.fabric[rows[0], cols[0]])
            entry = self.library.entries[f]
            r0, r1 = int(rows.min()), int(rows.max()) + 1
            out.append(
                {
                    "fabric": entry.name,
                    "pattern": entry.pattern,
                    "yarn": entry.yarn,
                    "stitch_length": entry.stitch_length,
                    "rows": [r0, r1],
                    "columns": sorted({int(c) for c in cols})
                    if len(set(cols)) < self.fabric.shape[1]
                    else "all",
                    "elements": int(len(rows)),
                    "courses": [round(float(first_course[r0]), 3), round(float(first_course[r1]), 3)],
                    "position_mm": [
                        float(self.geometry.z[r0] - 0.5 * self.geometry.row_length[r0]),
                        float(self.geometry.z[r1 - 1] + 0.5 * self.geometry.row_length[r1 - 1]),
                    ],
                }
            )
        return out

    def stations(self) -> list[dict[str, Any]]:
        """Per element row: position, circumference, tension, pressure mean/min/max and class."""
        g = self.geometry
        pe, pl = self.pressure_equivalent, self.pressure_local
        rows = []
        for i in range(g.shape[0]):
            p = float(pe[i].mean())
            rows.append(
                {
                    "row": i,
                    "position_mm": float(g.z[i]),
                    "position": float(g.position[i]),
                    "circumference_mm": float(g.circumference[i]),
                    "fabric": self.library.entries[int(np.bincount(self.fabric[i]).argmax())].name,
                    "lambda1": float(self.lam1[i].mean()),
                    "lambda2": float(self.lam2[i].mean()),
                    "tension_N_per_mm": float(self.T1[i].mean()),
                    "pressure_mmHg": {
                        "equivalent": p,
                        "local_mean": float(pl[i].mean()),
                        "local_min": float(pl[i].min()),
                        "local_max": float(pl[i].max()),
                    },
                    "class": compression_class(p),
                }
            )
        return rows

    def standard_positions(self) -> dict[str, dict[str, float]]:
        """Pressure at the distal end (wrist or ankle), the largest circumference and the top."""
        g = self.geometry
        where = {"distal": 0, "largest": int(np.argmax(g.circumference)), "top": g.shape[0] - 1}
        pe, pl = self.pressure_equivalent, self.pressure_local
        return {
            k: {
                "position_mm": float(g.z[i]),
                "circumference_mm": float(g.circumference[i]),
                "pressure_equivalent_mmHg": float(pe[i].mean()),
                "pressure_local_mean_mmHg": float(pl[i].mean()),
                "pressure_local_max_mmHg": float(pl[i].max()),
                "class": compression_class(float(pe[i].mean())),
            }
            for k, i in where.items()
        }

    def stress_cv(self) -> float:
        return _cv(self.T1, self.geometry.area)

    def to_json(self) -> dict[str, Any]:
        """The content of ``design.json``."""
        t = self.tube
        return {
            "objective": {
                "name": self.objective.name,
                "options": attrs.asdict(self.objective) if attrs.has(type(self.objective)) else {},
                "value": self.value,
                "quantity": self.objective.quantity,
                "pressure_basis": self.pressure_basis,
            },
            "method": self.method,
            "guarantee": self.guarantee,
            "tube": {
                "mode": t.mode,
                "circumference_mm": t.circumference,
                "length_mm": t.length,
                "needles": t.needles,
                "axial_stretch": t.axial_stretch,
                "courses": int(self.courses.sum()),
            },
            "limb": {
                "name": self.limb.name,
                "source": self.limb.source,
                "stations": len(self.limb.positions),
                "around": int(self.fabric.shape[1]),
                "length_mm": float(self.limb.positions[-1]),
                "notes": list(self.limb.notes),
            },
            "library": {
                "name": self.library.name,
                "source": self.library.source,
                "fabrics": [e.name for e in self.library.entries],
            },
            "regions": self.regions(),
            "stations": self.stations(),
            "standard_positions": self.standard_positions(),
            "stress_cv": self.stress_cv(),
            "limits_respected": self.limits_respected,
            "elements_over_limit": int(self.over_limit.sum()),
            "baseline": self.baseline,
            "notes": list(self.notes),
            "wall_time_s": self.wall_time,
        }


def _cv(x: np.ndarray, w: np.ndarray) -> float:
    w = np.broadcast_to(w, x.shape)
    mean = float(np.sum(w * x) / np.sum(w))
    return float(np.sqrt(np.sum(w * (x - mean) ** 2) / np.sum(w)) / mean) if mean > 0 else float("inf")


def _check_design(library, tube: Tube, method: str, pressure: str, min_courses, max_fabrics, base) -> int:
    """Refuse bad design options in one line; the index of the base fabric in the library."""
    check_options(min_courses, max_fabrics, len(library.entries))
    if method not in ("optimal", "paper"):
        raise ConfigError("design.method", f"must be 'optimal' or 'paper', got {method!r}")
    if pressure not in ("equivalent", "local"):
        raise ConfigError("design.pressure", f"must be 'equivalent' or 'local', got {pressure!r}")
    if method == "paper" and tube.mode != "paper":
        raise ConfigError(
            "design.method",
            "the paper's per-element method needs tube.mode = 'paper' (its "
            "2-D map needs intarsia; the knitting mode designs course bands)",
        )
    names = [e.name for e in library.entries]
    if base is None:
        return next((i for i, e in enumerate(library.entries) if "cotton" in e.yarn.lower()), 0)
    if base in names:
        return names.index(base)
    raise ConfigError(
        "design.base", f"no fabric '{base}' in library '{library.name}'; it has {', '.join(names)}"
    )


def _baseline(
    library, objective, T1b: np.ndarray, over: int, geo, base_i: int, pressure: str
) -> dict[str, Any]:
    """The one-fabric garment of the base fabric, for comparison: its stress CV, elements over the
    limit, largest tension and objective (None, with a note, where the objective is undefined)."""
    where = np.broadcast_to(geo.position[:, None], geo.shape)
    baseline = {
        "fabric": library.entries[base_i].name,
        "stress_cv": _cv(T1b, geo.area),
        "elements_over_limit": over,
        "max_tension_N_per_mm": float(T1b.max()),
        "limit_N_per_mm": library.entries[base_i].max_tension,
    }
    try:
        baseline["objective"] = float(
            objective.evaluate(_evaluate(objective, T1b, geo, pressure), geo.area, where)
        )
    except Exception as e:  # a uniform-stress objective is undefined for a slack garment
        baseline["objective"] = None
        baseline["objective_note"] = str(e)
    return baseline


def design(
    limb,
    library,
    objective,
    *,
    tube: Tube | None = None,
    method: str = "optimal",
    pressure: str = "equivalent",
    min_courses: float = 10.0,
    max_fabrics: int | None = None,
    base: str | None = None,
) -> Design:
    """Design a sleeve: the fabric of every element, its stretches, tensions and pressures.

    Parameters
    ----------
    limb : Limb
        The limb (a scan, measurements or the built-in example arm).
    library : FabricLibrary
        The candidate fabrics with their fitted models, relaxed pitches and limits.
    objective : DesignObjective
        A design objective plugin instance (``stress_variance``, ``pressure_uniformity``,
        ``pressure_profile`` or a third party's).
    tube : Tube
        The paper's wrist cylinder, or a knitting machine's needles (searched when not given).
    method : "optimal" or "paper"
    pressure : "equivalent" or "local"
        Which Laplace radius the pressure objectives use (both are reported).
    min_courses : float
        Least courses in each region.
    max_fabrics : int, optional
        At most this many distinct fabrics.
    base : str, optional
        The single fabric of the comparison garment and the paper method's start (default: the
        library's first cotton fabric, else its first).
    """
    t0 = time.perf_counter()
    tube = tube or Tube()
    base_i = _check_design(library, tube, method, pressure, min_courses, max_fabrics, base)
    geo = element_geometry(limb)
    distal = float(limb.circumference[0])
    notes: list[str] = list(limb.notes)

    where = np.broadcast_to(geo.position[:, None], geo.shape)
    options = {
        "method": method,
        "pressure": pressure,
        "min_courses": min_courses,
        "max_fabrics": max_fabrics,
        "base_i": base_i,
    }
    fab, made, guarantee, fields = _assign(library, objective, tube, geo, distal, options, notes)
    lam1, lam2, T1, T2, courses, feasible = fields
    if made.mode == "paper" and made.circumference is None:
        made = attrs.evolve(made, circumference=distal, length=float(geo.row_length.sum()))
    R, A = geo.shape
    ii, jj = np.arange(R)[:, None], np.arange(A)[None, :]
    pick = lambda X: X[fab, ii, jj]  # noqa: E731
    T1d = pick(T1)
    value = objective.evaluate(_evaluate(objective, T1d, geo, pressure), geo.area, where)
    rows_courses = courses[np.arange(R), fab[:, 0]]  # the course count of the row's first element
    over = int((~feasible[base_i]).sum())
    baseline = _baseline(library, objective, T1[base_i], over, geo, base_i, pressure)
    d = Design(
        limb,
        library,
        objective,
        made,
        method,
        geo,
        fab,
        pick(lam1),
        pick(lam2),
        T1d,
        pick(T2),
        rows_courses.astype(float),
        float(value),
        guarantee,
        baseline,
        pressure,
        time.perf_counter() - t0,
        tuple(notes),
    )
    for message in _suspect(d):
        warnings.warn(message, KnitframeWarning, stacklevel=2)
    return attrs.evolve(d, notes=d.notes + tuple(_suspect(d)))


def _suspect(d: Design) -> list[str]:
    """What a user must know about a design that is the best the library allows but still poor."""
    out = []
    target = declared(d.objective, DesignObjective, "target")(d.geometry.position)
    if d.objective.quantity == "pressure" and target is not None:
        want = target[:, None]
        err = float(
            np.sqrt(np.sum(d.geometry.area * ((d.pressure - want) / want) ** 2) / d.geometry.area.sum())
        )
        if err > 0.25:
            worst = int(np.argmax(np.abs(d.pressure.mean(axis=1) - want[:, 0])))
            out.append(
                f"the design misses the pressure target by {100 * err:.0f} % (RMS; worst at "
                f"{d.geometry.z[worst]:.0f} mm: {d.pressure[worst].mean():.1f} mmHg against "
                f"{want[min(worst, len(want) - 1), 0]:.1f}): library '{d.library.name}' cannot do better on "
                "this limb; add fabrics of other stitch lengths or patterns, or change the tube"
            )
    if d.T1.max() == 0:
        out.append("every element is slack: the tube is wider than the limb everywhere")
    return out
