r"""Safety and robustness of a design: the pressure ceiling, a target level that is never free, the
pressure bands under a changing limb, an uncertain pitch and the tests' scatter, and local peaks.

**Bands.** For a design with course stretch :math:`\lambda_1` and pressure
:math:`p = T_1(\lambda_1, \lambda_2)/r` at a station:

- the limb's circumference changes by a factor :math:`1 + s`, :math:`|s| \le x` (swelling, a
  flexed muscle): :math:`p_s = T_1(\lambda_1 (1+s), \lambda_2)/(r (1+s))`;
- the fabric's relaxed course pitch is off by :math:`1 + e`, :math:`|e| \le \epsilon` (a Munden
  estimate, a swatch measured loosely): :math:`p_e = T_1(\lambda_1/(1+e), \lambda_2)/r`;
- the fabric's tests scatter by a relative half-spread σ about their mean:
  :math:`p (1 \pm \sigma)`.

Each band is the least and the largest station mean over a grid of s (or e) that includes both ends
and 0: the tension law is monotone in the stretch, so the ends bound it.
"""

from __future__ import annotations

import math
import warnings

import attrs
import numpy as np

from knitframe.errors import ConfigError, KnitframeWarning
from knitframe.garment.laplace import laplace_mmhg
from knitframe.garment.prescription import CLASS_TARGETS

__all__ = [
    "DEFAULT_CEILING",
    "check_safety",
    "check_target",
    "default_level",
    "robust_scenarios",
    "circumference_band",
    "pitch_band",
    "scatter_band",
    "local_peaks",
    "suspect",
]

#: no design's station mean pressure may exceed this, mmHg, unless the user raises it
DEFAULT_CEILING = 60.0
#: the class a pressure objective without a target level takes
DEFAULT_CLASS = "II"
#: points of the band grids (odd: includes 0)
BAND_POINTS = 5


def check_safety(ceiling: float, tolerance: float) -> None:
    """One-line errors for a ceiling or a limb tolerance that cannot be used."""
    if not (isinstance(ceiling, (int, float)) and math.isfinite(ceiling) and ceiling > 0):
        raise ConfigError("design.ceiling_mmHg", f"must be a finite number > 0 (mmHg), got {ceiling!r}")
    if not (isinstance(tolerance, (int, float)) and 0.0 <= tolerance < 0.5):
        raise ConfigError(
            "design.limb_tolerance", f"must be a fraction in [0, 0.5) (0.03 = ±3 %), got {tolerance!r}"
        )


def default_level(objective, notes: list[str]):
    """A pressure objective with a free level takes the default class's target, with a notice.

    A free level would let the optimiser pick any pressure, however high; a relative *pressure*
    objective that cannot take a target is refused.
    """
    if objective.quantity != "pressure" or not objective.relative:
        return objective
    target = CLASS_TARGETS[DEFAULT_CLASS]
    if not (attrs.has(type(objective)) and "target_mmHg" in attrs.fields_dict(type(objective))):
        raise ConfigError(
            "design.objective",
            f"'{objective.name}' has no target level; a pressure objective needs one (target_mmHg)",
        )
    message = (
        f"{objective.name} had no target level: it takes class {DEFAULT_CLASS}'s {target:g} mmHg; give "
        "target_mmHg (--target-mmHg) or a class (--class) to choose"
    )
    warnings.warn(message, KnitframeWarning, stacklevel=3)
    notes.append(message)
    return attrs.evolve(objective, target_mmHg=target)


def check_target(objective, position: np.ndarray, ceiling: float) -> None:
    """Refuse, in one line, a pressure target above the ceiling (the user must raise the ceiling)."""
    from knitframe.interfaces import DesignObjective, declared

    target = declared(objective, DesignObjective, "target")(position)
    if objective.quantity == "pressure" and target is not None and float(np.max(target)) > ceiling:
        raise ConfigError(
            "design.objective.target_mmHg",
            f"asks for {float(np.max(target)):g} mmHg, above the safety ceiling of {ceiling:g} mmHg; raise "
            "design.ceiling_mmHg (--ceiling-mmHg) to ask for it",
        )


def robust_scenarios(geo, limbs, tolerance: float, robust: bool, n_stations: int) -> list:
    """The other geometries a robust design must also fit: the limb scaled by 1 ± tolerance, and the
    other scans (resampled to the same stations)."""
    from knitframe.garment.knitted import scaled_geometry
    from knitframe.garment.tube import element_geometry

    out = []
    if robust and tolerance > 0:
        out += [scaled_geometry(geo, 1.0 - tolerance), scaled_geometry(geo, 1.0 + tolerance)]
    for k, other in enumerate(limbs or ()):
        if other.n_stations != n_stations or other.n_around != geo.shape[1]:
            raise ConfigError(
                f"design.limbs[{k}]",
                f"has {other.n_stations} stations × {other.n_around} points; the limb has "
                f"{n_stations} × {geo.shape[1]}: resample both alike (design.stations, design.around)",
            )
        out.append(element_geometry(other))
    return out


def _tensions(d, lam1: np.ndarray) -> np.ndarray:
    """(R, A) course tension of the design's fabrics at course stretches ``lam1`` (never negative)."""
    T = np.zeros(lam1.shape)
    for f in np.unique(d.fabric):
        sel = d.fabric == f
        T[sel] = np.maximum(d.library.entries[int(f)].tensions(lam1[sel], d.lam2[sel])[0], 0.0)
    return T


def _band(d, factors: np.ndarray, stretch, radius) -> np.ndarray:
    """(R, 2) least and largest station mean pressure over ``factors``."""
    r = d.geometry.equivalent_radius[:, None]
    p = np.array([laplace_mmhg(_tensions(d, stretch(d.lam1, s)), radius(r, s)).mean(axis=1) for s in factors])
    return np.stack([p.min(axis=0), p.max(axis=0)], axis=1)


def circumference_band(d, x: float) -> np.ndarray:
    """(R, 2) station pressure band when the limb's circumference changes by ±x (see module doc)."""
    s = np.linspace(-x, x, BAND_POINTS)
    return _band(d, s, lambda lam, s: lam * (1 + s), lambda r, s: r * (1 + s))


def pitch_band(d, e: float) -> np.ndarray:
    """(R, 2) station pressure band when the fabrics' relaxed course pitch is off by ±e."""
    s = np.linspace(-e, e, BAND_POINTS)
    return _band(d, s, lambda lam, s: lam / (1 + s), lambda r, s: r)


def scatter_band(d) -> tuple[np.ndarray, list[str]] | None:
    """(R, 2) station pressure band from the scatter of each fabric's tests, and the fabrics without a
    known scatter; None when no fabric used knows it."""
    sigma = np.array([getattr(e, "tension_scatter", None) for e in d.library.entries], dtype=object)
    used = np.unique(d.fabric)
    known = [int(f) for f in used if sigma[f] is not None]
    if not known:
        return None
    sig = np.array([float(sigma[f]) if sigma[f] is not None else 0.0 for f in range(len(sigma))])[d.fabric]
    p = d.pressure_equivalent
    band = np.stack([(p * (1 - sig)).mean(axis=1), (p * (1 + sig)).mean(axis=1)], axis=1)
    missing = [d.library.entries[int(f)].name for f in used if sigma[f] is None]
    return band, missing


def local_peaks(d, ceiling: float, ratio: float) -> list[dict]:
    """Stations whose local pressure (local radius of curvature) exceeds the ceiling or ``ratio`` times
    the station mean: row, position, peak and mean, mmHg."""
    pl, pe = d.pressure_local, d.pressure_equivalent.mean(axis=1)
    peak = pl.max(axis=1)
    out = []
    for i in np.flatnonzero((peak > ceiling) | (peak > ratio * np.maximum(pe, 1e-12))):
        out.append(
            {
                "row": int(i),
                "position_mm": float(d.geometry.z[i]),
                "peak_mmHg": float(peak[i]),
                "mean_mmHg": float(pe[i]),
                "over": "ceiling" if peak[i] > ceiling else f"{ratio:g}× the station mean",
            }
        )
    return out


def suspect(d) -> list[str]:
    """What a user must know about a design: a prescription missed, a graduation that rises, a station
    over the ceiling, a local pressure peak, a slack tube."""
    out = []
    g = d.geometry
    rx = d.prescription()
    if rx is not None:
        miss = ~rx["inside"]
        if miss.any():
            worst = int(np.argmax(np.abs(rx["error"])))
            p = d.pressure.mean(axis=1)
            out.append(
                f"{int(miss.sum())} of {len(miss)} stations are outside the prescription's ±"
                f"{100 * rx['tolerance']:.0f} % (RMS miss {100 * rx['all']['rms_error']:.0f} %; worst at "
                f"{g.z[worst]:.0f} mm: {p[worst]:.1f} mmHg against {rx['target'][worst]:.1f})"
                + (
                    f": library '{d.library.name}' cannot do better on this limb; add fabrics or relax "
                    "the machine's rules"
                    if rx["all"]["rms_error"] > 0.25
                    else ""
                )
            )
        if rx["falls_steadily"] is False:
            i = rx["largest_rise_row"]
            out.append(
                f"the pressure (averaged over {rx['probe_mm']:g} mm, a probe's size) rises by "
                f"{rx['largest_rise_mmHg']:.1f} mmHg at {g.z[i]:.0f} mm: the graduation does not fall "
                "steadily from the distal end"
            )
    ceiling = d.safety.get("ceiling_mmHg", np.inf)
    pe = d.pressure_equivalent.mean(axis=1)
    if np.any(pe > ceiling):
        i = int(np.argmax(pe))
        out.append(
            f"station at {g.z[i]:.0f} mm has a mean pressure of {pe[i]:.1f} mmHg, above the ceiling "
            f"{ceiling:g}"
        )
    for peak in d.local_peaks():
        out.append(
            f"local pressure peak of {peak['peak_mmHg']:.1f} mmHg at {peak['position_mm']:.0f} mm (station "
            f"mean {peak['mean_mmHg']:.1f}): over {peak['over']}; a bony ridge there may need padding"
        )
    if d.T1.max() == 0:
        out.append("every element is slack: the tube is wider than the limb everywhere")
    return out
