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
from knitframe.garment.laplace import laplace_mmhg
from knitframe.garment.optimise import check_options
from knitframe.garment.paper import _periodic_labels
from knitframe.garment.prescription import (
    CLASSES,
    compression_class,
    graduation_report,
    prescription_json,
)
from knitframe.garment.safety import (
    DEFAULT_CEILING,
    check_safety,
    check_target,
    default_level,
    robust_scenarios,
    suspect,
)
from knitframe.garment.shaping import MachineRules, course_needles
from knitframe.garment.tube import ElementGeometry, Tube, element_geometry
from knitframe.interfaces import DesignObjective, declared

__all__ = ["Design", "design", "compression_class", "CLASSES"]


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
    #: (R,) stitches of each row's first course (knitting mode), None in paper mode
    row_needles: np.ndarray | None = None
    #: the machine's shaping rules (knitting mode)
    rules: MachineRules | None = None
    #: the safety and robustness settings the design was made with
    safety: dict[str, Any] = attrs.Factory(dict)

    def needles_per_course(self) -> np.ndarray | None:
        """(C,) stitches of every course of the knitted tube (None in paper mode)."""
        if self.row_needles is None:
            return None
        return course_needles(self.row_needles, np.round(self.courses).astype(int), self.rules)

    @property
    def pressure_equivalent(self) -> np.ndarray:
        """(R, A) Laplace pressure with the section's equivalent radius C/2π, mmHg."""
        return laplace_mmhg(self.T1, self.geometry.equivalent_radius[:, None])

    @property
    def pressure_local(self) -> np.ndarray:
        """(R, A) Laplace pressure with the local radius of curvature (0 where concave), mmHg."""
        return laplace_mmhg(self.T1 * np.maximum(self.geometry.curvature, 0.0), 1.0)

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

    def prescription(self) -> dict[str, Any] | None:
        """How the station pressures meet the objective's target and tolerance (None without a target):
        see :func:`~knitframe.garment.prescription.graduation_report`."""
        target = declared(self.objective, DesignObjective, "target")(self.geometry.position)
        if self.objective.quantity != "pressure" or target is None:
            return None
        tol = float(getattr(self.objective, "tolerance", 0.2))
        return graduation_report(
            self.geometry.position, self.geometry.z, self.pressure.mean(axis=1), target, tol
        )

    def bands(self) -> dict[str, Any]:
        """Station pressure bands: limb circumference ±tolerance, course pitch ±pitch_error, and the
        tests' scatter where the library knows it (:mod:`knitframe.garment.safety`)."""
        from knitframe.garment.safety import circumference_band, pitch_band, scatter_band

        x = self.safety.get("limb_tolerance", 0.03)
        e = self.safety.get("pitch_error", 0.05)
        out = {"circumference": circumference_band(self, x), "pitch": pitch_band(self, e), "scatter": None}
        sb = scatter_band(self)
        if sb is not None:
            out["scatter"], out["scatter_unknown"] = sb
        return out

    def stations(self) -> list[dict[str, Any]]:
        """Per element row: position, circumference, needles, tension, pressure mean/min/max, class,
        the prescription's target and verdict, and the pressure bands."""
        g = self.geometry
        pe, pl = self.pressure_equivalent, self.pressure_local
        rx = self.prescription()
        target = declared(self.objective, DesignObjective, "target")(g.position)
        bands = self.bands()
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
                    "needles": None if self.row_needles is None else int(self.row_needles[i]),
                    "target_mmHg": None if target is None else float(target[i]),
                    "inside_tolerance": None if rx is None else bool(rx["inside"][i]),
                    "band_mmHg": {
                        k: None if v is None else [float(v[i, 0]), float(v[i, 1])]
                        for k, v in bands.items()
                        if k != "scatter_unknown"
                    },
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

    def local_peaks(self) -> list[dict[str, Any]]:
        """Stations whose local pressure peak exceeds the ceiling or ``peak_ratio`` × their mean."""
        from knitframe.garment.safety import local_peaks

        return local_peaks(self, self.safety.get("ceiling_mmHg", np.inf), self.safety.get("peak_ratio", 2.0))

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
                "shaping": t.shaping if t.mode == "knitting" else None,
                "rules": None if self.rules is None else self.rules.to_json(),
                "needles_range": None
                if self.row_needles is None
                else [int(self.row_needles.min()), int(self.row_needles.max())],
                "needles_per_course": None
                if self.row_needles is None
                else [int(n) for n in self.needles_per_course()],
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
            "prescription": prescription_json(self),
            "safety": {**self.safety, "local_peaks": self.local_peaks()},
            "pitches": {
                e.name: {
                    "course_pitch_mm": e.course_pitch,
                    "estimate": bool(getattr(e, "pitch_is_estimate", True)),
                }
                for e in (self.library.entries[int(f)] for f in np.unique(self.fabric))
            },
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
    rules: MachineRules | None = None,
    ceiling: float = DEFAULT_CEILING,
    tolerance: float = 0.03,
    robust: bool = False,
    limbs: list | None = None,
    pitch_error: float = 0.05,
    peak_ratio: float = 2.0,
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
    rules : MachineRules, optional
        Knitting mode: how the machine may shape the tube (default :class:`MachineRules`).
    ceiling : float
        No row's mean pressure (equivalent radius) may exceed this, mmHg (60 by default).
    tolerance : float
        Relative change of the limb's circumference the pressure band is reported for (±3 %), and
        the robust design is made for.
    robust : bool
        Design for the worst case over the limb scaled by 1 ± ``tolerance`` (and ``limbs``).
    limbs : list of Limb, optional
        Other scans of the same limb (relaxed, flexed, evening): the design is made for the worst
        case over all of them, row by row (the same number of stations).
    pitch_error : float
        Relative error of the fabrics' relaxed course pitch the pressure band is reported for (±5 %).
    peak_ratio : float
        Warn where a local pressure peak exceeds this multiple of its station's mean.
    """
    t0 = time.perf_counter()
    tube = tube or Tube()
    rules = rules or MachineRules()
    base_i = _check_design(library, tube, method, pressure, min_courses, max_fabrics, base)
    check_safety(ceiling, tolerance)
    geo = element_geometry(limb)
    distal = float(limb.circumference[0])
    notes: list[str] = list(limb.notes)
    objective = default_level(objective, notes)
    check_target(objective, geo.position, ceiling)
    scenarios = robust_scenarios(geo, limbs, tolerance, robust, limb.n_stations)

    where = np.broadcast_to(geo.position[:, None], geo.shape)
    options = {
        "method": method,
        "pressure": pressure,
        "min_courses": min_courses,
        "max_fabrics": max_fabrics,
        "base_i": base_i,
        "rules": rules,
        "ceiling": ceiling,
        "scenarios": scenarios,
    }
    fab, made, guarantee, chosen, (T1b, over) = _assign(library, objective, tube, geo, distal, options, notes)
    lam1, lam2, T1, T2, rows_courses, row_needles = chosen
    if made.mode == "paper" and made.circumference is None:
        made = attrs.evolve(made, circumference=distal, length=float(geo.row_length.sum()))
    value = objective.evaluate(_evaluate(objective, T1, geo, pressure), geo.area, where)
    baseline = _baseline(library, objective, T1b, over, geo, base_i, pressure)
    d = Design(
        limb,
        library,
        objective,
        made,
        method,
        geo,
        fab,
        lam1,
        lam2,
        T1,
        T2,
        rows_courses,
        float(value),
        guarantee,
        baseline,
        pressure,
        time.perf_counter() - t0,
        tuple(notes),
        row_needles=row_needles,
        rules=rules if made.mode == "knitting" else None,
        safety={
            "ceiling_mmHg": ceiling,
            "limb_tolerance": tolerance,
            "robust": robust,
            "scans": 1 + len(limbs or ()),
            "pitch_error": pitch_error,
            "peak_ratio": peak_ratio,
        },
    )
    more = suspect(d)
    for message in more:
        warnings.warn(message, KnitframeWarning, stacklevel=2)
    return attrs.evolve(d, notes=d.notes + tuple(more))
