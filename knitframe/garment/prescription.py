"""Prescriptions as a clinician writes them: a compression class or a target, and a graduation.

- **Classes** (RAL-GZ 387, mmHg at the distal measuring point, the ankle or the wrist): I 18–21,
  II 23–32, III 34–46, IV ≥ 49. A class's default target is its middle; class IV has no upper
  bound, so its default target is 55 mmHg, below the default safety ceiling of 60.
- **Graduations**: the target falls along the limb as ``ratios`` of the distal target at positions
  ``at`` (0 = distal end, 1 = top), linear in between. Named graduations (:data:`GRADUATIONS`):

  - ``"linear"``: 100 % at the distal end to 60 % at the top (a 25 → 15 mmHg arm sleeve);
  - ``"arm-sleeve"``: 100 / 70 / 40 % at the distal end, the middle and the top, the profile of a
    measured graduated arm sleeve (21.8 / 15.2 / 8.8 mmHg from forearm to shoulder);
  - ``"flat"``: 100 % everywhere (uniform compression, as for a shrinker).

  RAL-GZ 387/1 (stockings) and 387/2 (arm sleeves) require that the pressure fall continuously from
  the distal end upwards; a design reports whether it does (:func:`graduation_report`).
- **Tolerance**: a station meets the prescription when its pressure is within ``tolerance``
  (relative, 20 % by default) of its target.
"""

from __future__ import annotations

import numpy as np

from knitframe.errors import FieldError

__all__ = [
    "CLASSES",
    "GRADUATIONS",
    "class_target",
    "compression_class",
    "graduation",
    "graduation_report",
    "CUFF",
    "prescription_json",
]

#: RAL-GZ 387 compression classes, mmHg (lower, upper); between them a pressure has no class
CLASSES = (("I", 18.0, 21.0), ("II", 23.0, 32.0), ("III", 34.0, 46.0), ("IV", 49.0, np.inf))
#: default target of each class, mmHg (the middle; IV: 55, below the 60 mmHg ceiling)
CLASS_TARGETS = {"I": 19.5, "II": 27.5, "III": 40.0, "IV": 55.0}
#: named graduations: (positions 0 distal .. 1 top, ratios of the distal target)
GRADUATIONS = {
    "linear": ([0.0, 1.0], [1.0, 0.6]),
    "arm-sleeve": ([0.0, 0.5, 1.0], [1.0, 0.7, 0.4]),
    "flat": ([0.0, 1.0], [1.0, 1.0]),
}
#: the cuffs: rows within this fraction of the length from either end, left out of "away from the cuffs"
CUFF = 0.05
#: a rise of the probe-averaged pressure from one station to the next by more than this (mmHg) breaks the
#: graduation
RISE_MMHG = 0.5
#: the graduation is judged on the pressure averaged over this length (mm) around each station, the size
#: of an interface-pressure probe (about 5 cm across): the ripple of single needle steps is finer
PROBE_MM = 50.0


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


def class_target(name: str, field: str = "compression_class") -> float:
    """The default target (mmHg) of a class given as "I".."IV" (or 1..4); FieldError otherwise."""
    key = {"1": "I", "2": "II", "3": "III", "4": "IV"}.get(str(name).strip(), str(name).strip().upper())
    if key not in CLASS_TARGETS:
        raise FieldError(field, f"must be one of I, II, III, IV (RAL-GZ 387), got {name!r}")
    return CLASS_TARGETS[key]


def class_range(name: str) -> tuple[float, float]:
    """(lower, upper) mmHg of a class."""
    key = {"1": "I", "2": "II", "3": "III", "4": "IV"}.get(str(name).strip(), str(name).strip().upper())
    return next((lo, hi) for n, lo, hi in CLASSES if n == key)


def graduation(name: str, field: str = "graduation") -> tuple[list[float], list[float]]:
    """The (at, ratios) of a named graduation; FieldError listing the names otherwise."""
    if name not in GRADUATIONS:
        raise FieldError(field, f"must be one of {', '.join(GRADUATIONS)}, got {name!r}")
    at, ratios = GRADUATIONS[name]
    return list(at), list(ratios)


def probe_average(z: np.ndarray, p: np.ndarray, length: float = PROBE_MM) -> np.ndarray:
    """(R,) the pressure averaged over the stations within ``length``/2 of each station (mm)."""
    z = np.asarray(z, dtype=np.float64)
    near = np.abs(z[:, None] - z[None, :]) <= 0.5 * length
    return (near * np.asarray(p, dtype=np.float64)[None, :]).sum(axis=1) / near.sum(axis=1)


def graduation_report(
    position: np.ndarray, z: np.ndarray, pressure: np.ndarray, target: np.ndarray, tolerance: float
) -> dict:
    """How a design's station pressures meet a prescription.

    ``position`` (R,) 0 distal .. 1 top, ``z`` (R,) mm along the limb, ``pressure`` (R,) station means
    (mmHg), ``target`` (R,). Returns the per-station verdicts, the RMS and worst relative errors over
    all stations and away from the cuffs (:data:`CUFF`), and, where the target falls along the limb,
    whether the pressure falls steadily from the distal end: the pressure averaged over a probe's
    length (:func:`probe_average`) never rises by more than :data:`RISE_MMHG` from one station to the
    next (None for a flat target).
    """
    p = np.asarray(pressure, dtype=np.float64)
    t = np.asarray(target, dtype=np.float64)
    err = (p - t) / t
    inside = np.abs(err) <= tolerance + 1e-12
    body = (position >= CUFF) & (position <= 1.0 - CUFF)
    rise = np.diff(probe_average(z, p))
    worst_rise = int(np.argmax(rise)) + 1 if len(rise) else 0
    graduated = bool(len(t) > 1 and t[-1] < t[0])

    def stats(sel) -> dict:
        if not sel.any():
            return {"rms_error": None, "worst_error": None, "stations_inside": 0, "stations": 0}
        return {
            "rms_error": float(np.sqrt(np.mean(err[sel] ** 2))),
            "worst_error": float(np.max(np.abs(err[sel]))),
            "stations_inside": int(inside[sel].sum()),
            "stations": int(sel.sum()),
        }

    return {
        "tolerance": float(tolerance),
        "inside": inside,
        "error": err,
        "target": t,
        "all": stats(np.ones_like(inside)),
        "away_from_cuffs": stats(body),
        "falls_steadily": (bool(len(rise) == 0 or rise.max() <= RISE_MMHG) if graduated else None),
        "probe_mm": PROBE_MM,
        "largest_rise_mmHg": float(max(rise.max(), 0.0)) if len(rise) else 0.0,
        "largest_rise_row": worst_rise,
    }


def prescription_json(d) -> dict | None:
    """The ``prescription`` table of design.json: the report without its per-station arrays, the class
    asked for and the class the distal station reached."""
    rx = d.prescription()
    if rx is None:
        return None
    out = {k: v for k, v in rx.items() if k not in ("inside", "error", "target")}
    cls = getattr(d.objective, "compression_class", None)
    out["compression_class"] = cls
    out["distal_class"] = compression_class(float(d.pressure_equivalent[0].mean()))
    return out
