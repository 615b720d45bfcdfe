"""Measured limbs: tape circumferences at distances along the limb, checked and turned into sections.

:meth:`~knitframe.garment.limb.Limb.from_measurements` builds its limb from these: elliptic sections
of exact perimeter at stations where every measurement falls on a station.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.interpolate import PchipInterpolator

from knitframe.errors import ConfigError
from knitframe.garment.limb.sections import ellipse_points, ellipse_semi_axes, perpendicular

__all__ = ["check_counts", "measured_sections"]


def check_counts(n_stations: int, n_around: int) -> None:
    """Refuse fewer than 2 stations or 8 points around (a ConfigError naming the option)."""
    if isinstance(n_stations, bool) or not isinstance(n_stations, (int, np.integer)) or n_stations < 2:
        raise ConfigError("n_stations", f"must be an integer >= 2, got {n_stations!r}")
    if isinstance(n_around, bool) or not isinstance(n_around, (int, np.integer)) or n_around < 8:
        raise ConfigError("n_around", f"must be an integer >= 8, got {n_around!r}")


def _check_measurements(pos: np.ndarray, circ: np.ndarray) -> None:
    """Refuse fewer than 2 measurements, mismatched counts, non-finite, unsorted or non-positive ones."""
    if pos.size < 2:
        raise ConfigError("positions_mm", f"needs at least 2 measurements, got {pos.size}")
    if circ.size != pos.size:
        raise ConfigError("circumferences_mm", f"needs one value per position ({pos.size}), got {circ.size}")
    for key, arr in (("positions_mm", pos), ("circumferences_mm", circ)):
        if not np.all(np.isfinite(arr)):
            raise ConfigError(key, "must be finite numbers")
    if np.any(np.diff(pos) <= 0.0):
        i = int(np.argmax(np.diff(pos) <= 0.0))
        raise ConfigError("positions_mm", f"must be strictly increasing, got {pos[i]:g} then {pos[i + 1]:g}")
    if np.any(circ <= 0.0):
        i = int(np.argmax(circ <= 0.0))
        raise ConfigError("circumferences_mm", f"must be > 0, got {circ[i]:g} at {pos[i]:g} mm")


def _check_ellipticity(ell: np.ndarray, pos: np.ndarray, n_stations: int) -> None:
    """Refuse ratios outside (0, 1], a count that is neither 1 nor one per measurement, too few stations."""
    if ell.size not in (1, pos.size):
        raise ConfigError("ellipticity", f"needs one value or one per position ({pos.size}), got {ell.size}")
    if not np.all(np.isfinite(ell)) or np.any(ell <= 0.0) or np.any(ell > 1.0):
        raise ConfigError("ellipticity", f"minor/major ratio must be in (0, 1], got {ell.tolist()}")
    if n_stations < pos.size:
        raise ConfigError(
            "n_stations", f"must be at least the number of measurements ({pos.size}), got {n_stations}"
        )


def _stations(
    pos: np.ndarray, circ: np.ndarray, ell: np.ndarray, n_stations: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Station positions (mm), circumferences (mm) and minor/major ratios, each (n_stations,).

    The stations are equally spaced from the first to the last measurement, the one nearest each
    measurement moved onto it; C and k are PCHIP-interpolated between the measurements and exact at
    them.
    """
    grid = np.linspace(pos[0], pos[-1], n_stations)
    spacing = (pos[-1] - pos[0]) / (n_stations - 1)
    idx = np.rint((pos - pos[0]) / spacing).astype(np.int64)
    if np.any(np.diff(idx) == 0):
        i = int(np.argmax(np.diff(idx) == 0))
        raise ConfigError(
            "positions_mm",
            f"measurements at {pos[i]:g} and {pos[i + 1]:g} mm are closer than the "
            f"station spacing {spacing:.3g} mm; use more stations (n_stations)",
        )
    grid[idx] = pos
    c_st = PchipInterpolator(pos, circ)(grid)
    c_st[idx] = circ
    k_st = (
        np.full(n_stations, ell[0])
        if ell.size == 1
        else np.clip(PchipInterpolator(pos, ell)(grid), 1e-6, 1.0)
    )
    if ell.size > 1:
        k_st[idx] = ell
    return grid, c_st, k_st


def measured_sections(
    positions_mm: Sequence[float],
    circumferences_mm: Sequence[float],
    ellipticity: float | Sequence[float],
    n_stations: int,
    n_around: int,
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Sections (n_stations, n_around, 3) mm, axis direction (3,) and notes of a measured limb.

    See :meth:`~knitframe.garment.limb.Limb.from_measurements`: elliptic sections of perimeter C
    and ratio k, major axis along f1 = +x, on a straight axis along +z through the origin.
    """
    pos = np.asarray(positions_mm, dtype=np.float64).reshape(-1)
    circ = np.asarray(circumferences_mm, dtype=np.float64).reshape(-1)
    check_counts(n_stations, n_around)
    _check_measurements(pos, circ)
    ell = np.asarray(ellipticity, dtype=np.float64).reshape(-1)
    _check_ellipticity(ell, pos, n_stations)

    grid, c_st, k_st = _stations(pos, circ, ell, n_stations)
    a, b = ellipse_semi_axes(c_st, k_st)
    z = grid - pos[0]
    d = np.array([0.0, 0.0, 1.0])
    f1 = perpendicular(d)  # +x
    f2 = np.cross(f1, d)  # -y: loops counter-clockwise seen along +z
    sections = np.empty((n_stations, n_around, 3))
    for i in range(n_stations):  # one vectorised ellipse per station
        xy = ellipse_points(float(a[i]), float(b[i]), n_around)
        sections[i] = z[i] * d + np.outer(xy[:, 0], f1) + np.outer(xy[:, 1], f2)
    notes = []
    if pos[0] != 0.0:
        notes.append(f"station 0 is the first measurement, {pos[0]:g} mm from the wrist/ankle")
    return sections, d, tuple(notes)
