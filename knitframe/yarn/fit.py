"""Yarn parameters from tension and compression tests, and the Hertz line contact they rely on.

Test files are CSV (see docs/yarns.md) with ``# key: value`` header lines and two columns::

    # test: tension
    # gauge_length_mm: 50
    displacement_mm,force_N
    0.0,0.0
    ...

* **Tension** (one yarn, gauge length L0): the linear part of the force-displacement curve
  (between 20 % and 80 % of the peak force, before the peak) is fitted by F = k (u - u0), where
  u0 is the slack taken up before the yarn carries load. E_axial = k L0 / (π d²/4), with d the
  knitted diameter so that a rod of radius dk/2 has the measured EA; the failure strain is
  (u_peak - u0) / L0.
* **Compression** (``yarns`` parallel yarns under a plate of length ``plate_length_mm``; the
  displacement is the plate travel from first contact at thickness d0): the line load per yarn
  is f = F / (yarns · plate_length). The *pre-compression* f_k is the line load at which the
  thickness reaches dk (u_k = d0 - dk). Beyond it the yarn is taken as an elastic cylinder of
  diameter dk between two rigid plates: u - u_k = 2 δ_flat(f - f_k; dk/2, E_T, ν)
  (:func:`line_contact_approach`). E_T and f_k are the least-squares fit (in travel) of that
  law to the points within ``window`` x dk of travel beyond u_k.

Every problem with a file raises a one-line :class:`~knitframe.errors.DataError`.
"""

from __future__ import annotations

from pathlib import Path

import attrs
import numpy as np

from knitframe.csvio import read_table
from knitframe.errors import DataError, NumericalError
from knitframe.records import Yarn

__all__ = [
    "COLUMNS",
    "TensionFit",
    "CompressionFit",
    "read_test",
    "fit_tension",
    "fit_compression",
    "fit_yarn",
    "pretension",
    "line_contact_approach",
    "line_contact_load",
    "line_contact_stiffness",
]

COLUMNS = ("displacement_mm", "force_N")


def line_contact_approach(
    f: np.ndarray, radius: float, E: float, nu: float, *, rigid_partner: bool = False
) -> np.ndarray:
    """Approach δ of the axes of two identical parallel elastic cylinders under line load f (2D Hertz).

    Puttock & Thwaite (1969), Johnson (Contact Mechanics, 1985, §5.6): each body contributes
    δ_i = (2f/π) (1 - ν²)/E (ln(4R/b) - 1/2), with contact half-width b = √(4 f R* / (π E*)),
    R* = R/2 and 1/E* = 2(1 - ν²)/E; δ = δ_1 + δ_2. With ``rigid_partner`` the other body is a
    rigid flat: R* = R, E* = E/(1 - ν²) and δ = δ_1. Valid while b ≪ R.

    Parameters
    ----------
    f : (n,) line load, N/mm (negative values count as 0).
    radius : cylinder radius R, mm.  E : Young's modulus, MPa.  nu : Poisson ratio.

    Returns
    -------
    (n,) approach, mm.
    """
    f = np.maximum(np.asarray(f, dtype=np.float64), 0.0)
    k = (1.0 - nu * nu) / E
    r_eff, e_star = (radius, 1.0 / k) if rigid_partner else (0.5 * radius, 0.5 / k)
    b = np.sqrt(4.0 * f * r_eff / (np.pi * e_star))
    with np.errstate(divide="ignore", invalid="ignore"):
        per_body = np.where(
            f > 0, 2.0 * f / np.pi * k * (np.log(4.0 * radius / np.where(b > 0, b, 1.0)) - 0.5), 0.0
        )
    return per_body if rigid_partner else 2.0 * per_body


def line_contact_load(
    delta: np.ndarray, radius: float, E: float, nu: float, *, rigid_partner: bool = False
) -> np.ndarray:
    """Line load f (N/mm) at approach ``delta`` (mm): the inverse of :func:`line_contact_approach`.

    δ(f) increases while b < 4R/e, where the law ends; beyond that a NumericalError is raised.
    Solved by vectorised bisection on ln f to 1e-13.
    """
    d = np.asarray(delta, dtype=np.float64)
    k = (1.0 - nu * nu) / E
    r_eff, e_star = (radius, 1.0 / k) if rigid_partner else (0.5 * radius, 0.5 / k)
    f_max = (4.0 * radius / np.e) ** 2 * np.pi * e_star / (4.0 * r_eff)
    d_max = float(line_contact_approach(np.array([f_max]), radius, E, nu, rigid_partner=rigid_partner)[0])
    if np.any(d > d_max):
        raise NumericalError(
            f"line contact: approach {float(d.max()):.3g} mm is beyond the Hertz law's range ({d_max:.3g} mm)"
        )
    lo = np.full(d.shape, np.log(f_max) - 80.0)
    hi = np.full(d.shape, np.log(f_max))
    while np.any(hi - lo > 1e-13):
        mid = 0.5 * (lo + hi)
        big = line_contact_approach(np.exp(mid), radius, E, nu, rigid_partner=rigid_partner) > d
        hi = np.where(big, mid, hi)
        lo = np.where(big, lo, mid)
    return np.where(d > 0, np.exp(0.5 * (lo + hi)), 0.0)


def line_contact_stiffness(f: np.ndarray, radius: float, E: float, nu: float) -> np.ndarray:
    """Tangent stiffness df/dδ (N/mm per mm of length) of two identical parallel cylinders at line load f.

    From δ(f) = (4f/π)(1 − ν²)/E (ln(4R/b) − 1/2) of :func:`line_contact_approach` with b ∝ √f:
    dδ/df = (4/π)(1 − ν²)/E (ln(4R/b) − 1).
    """
    f = np.asarray(f, dtype=np.float64)
    k = (1.0 - nu**2) / E
    b = np.sqrt(4.0 * np.maximum(f, 1e-300) * 0.5 * radius * 2.0 * k / np.pi)
    return 1.0 / (4.0 / np.pi * k * (np.log(4.0 * radius / b) - 1.0))


def pretension(line_load: float, curvature_radius: float) -> float:
    """Yarn tension (N) that presses a yarn wrapped on radius ``curvature_radius`` (mm) with ``line_load``
    (N/mm).

    Belt (capstan) equilibrium without friction: f = T / ρ, so T = f ρ. With the pre-compression
    from :func:`fit_compression` this is the pre-tension that squeezes d0 to dk in a loop of radius ρ.
    """
    return float(line_load) * float(curvature_radius)


def read_test(path: str | Path, kind: str) -> tuple[np.ndarray, np.ndarray, dict[str, str], object]:
    """Displacement (mm), force (N), header metadata and the table of a ``kind`` test file."""
    table = read_table(path, COLUMNS)
    meta: dict[str, str] = {}
    for line in table.comments:
        if ":" in line:
            key, val = line.split(":", 1)
            meta[key.strip().lower()] = val.strip()
    if "test" in meta and meta["test"].lower() != kind:
        raise DataError(table.path, f"header says '# test: {meta['test']}', expected a {kind} test")
    u, F = table["displacement_mm"], table["force_N"]
    if len(u) < 5:
        raise DataError(table.path, f"needs at least 5 data rows, got {len(u)}")
    return u, F, meta, table


def _meta_number(table, meta: dict[str, str], key: str, given: float | None) -> float:
    if given is not None:
        value = float(given)
    elif key in meta:
        try:
            value = float(meta[key])
        except ValueError:
            raise DataError(table.path, f"header '# {key}: {meta[key]}' is not a number") from None
    else:
        raise DataError(table.path, f"missing header line '# {key}: <value>'")
    if not (np.isfinite(value) and value > 0):
        raise DataError(table.path, f"'{key}' must be > 0, got {value:g}")
    return value


@attrs.frozen
class TensionFit:
    """Result of :func:`fit_tension`."""

    #: MPa
    E_axial: float
    #: -
    failure_strain: float
    #: displacement before the yarn carries load, mm
    slack: float
    #: k = EA / L0, N/mm
    stiffness: float
    #: points in the linear window
    points: int
    #: force residual in the window, N
    rmse: float
    file: str


@attrs.frozen
class CompressionFit:
    """Result of :func:`fit_compression`."""

    #: MPa
    E_transverse: float
    #: line load per yarn that brings d0 to dk, N/mm
    precompression: float
    #: precompression / dk, MPa
    pressure: float
    #: points in the fitted window
    points: int
    #: displacement residual in the window, mm
    rmse: float
    file: str


def fit_tension(path: str | Path, *, diameter: float, gauge_length: float | None = None) -> TensionFit:
    """Axial modulus, slack and failure strain from a tension test file.

    Parameters
    ----------
    path : CSV with ``displacement_mm,force_N`` (header ``# gauge_length_mm`` unless given).
    diameter : float
        Diameter of the modelled cross-section (normally dk), mm.
    gauge_length : float, optional
        Free length L0 between the clamps, mm.
    """
    u, F, meta, table = read_test(path, "tension")
    L0 = _meta_number(table, meta, "gauge_length_mm", gauge_length)
    ipk = int(np.argmax(F))
    fpk = float(F[ipk])
    if fpk <= 0:
        raise DataError(table.path, "force never becomes positive", column="force_N")
    pre_u, pre_F = u[: ipk + 1], F[: ipk + 1]
    win = (pre_F >= 0.2 * fpk) & (pre_F <= 0.8 * fpk)
    if np.count_nonzero(win) < 3:
        raise DataError(
            table.path, "fewer than 3 points between 20 % and 80 % of the peak force before the peak"
        )
    k, c = np.polyfit(pre_u[win], pre_F[win], 1)
    if k <= 0:
        raise DataError(
            table.path, f"force falls with displacement in the linear window (slope {k:.3g} N/mm)"
        )
    u0 = -c / k
    rmse = float(np.sqrt(np.mean((pre_F[win] - k * (pre_u[win] - u0)) ** 2)))
    area = np.pi * diameter**2 / 4.0
    return TensionFit(
        E_axial=float(k * L0 / area),
        failure_strain=float((u[ipk] - u0) / L0),
        slack=float(u0),
        stiffness=float(k),
        points=int(np.count_nonzero(win)),
        rmse=rmse,
        file=table.path.name,
    )


def fit_compression(
    path: str | Path,
    *,
    d0: float,
    dk: float,
    nu: float = 0.3,
    yarns: float | None = None,
    plate_length: float | None = None,
    window: float = 0.2,
) -> CompressionFit:
    """Pre-compression (d0 -> dk) and transverse modulus from a compression test file.

    Parameters
    ----------
    path : CSV with ``displacement_mm,force_N``; headers ``# yarns`` and ``# plate_length_mm``
        unless given. Displacement is the plate travel from first contact at thickness d0.
    d0, dk : free and knitted diameters, mm.
    nu : Poisson ratio of the transverse law.
    window : float
        Fit E_T on travel beyond dk up to ``window`` x dk (where the line-contact law holds).
    """
    u, F, meta, table = read_test(path, "compression")
    n = _meta_number(table, meta, "yarns", yarns)
    Lp = _meta_number(table, meta, "plate_length_mm", plate_length)
    if dk > d0:
        raise DataError(table.path, f"dk = {dk:g} mm is larger than d0 = {d0:g} mm")
    order = np.argsort(u, kind="stable")
    u, f = u[order], F[order] / (n * Lp)
    uk = d0 - dk
    if u[-1] < uk:
        raise DataError(
            table.path, f"the plate travels {u[-1]:g} mm, never compressing d0 = {d0:g} to dk = {dk:g} mm"
        )
    fk0 = max(float(np.interp(uk, u, f)), 0.0)
    sel = (u > uk) & (u <= uk + window * dk)
    if np.count_nonzero(sel) < 5:
        raise DataError(table.path, f"fewer than 5 points within {window:g} dk of travel beyond dk")
    us, fs = u[sel], f[sel]
    if not np.ptp(fs) > 0:
        raise DataError(table.path, "force does not change beyond dk", column="force_N")

    from scipy.optimize import least_squares

    R = 0.5 * dk

    def travel(params: np.ndarray) -> np.ndarray:
        E, fk = np.exp(params[0]), params[1]
        return uk + 2.0 * line_contact_approach(fs - fk, R, E, nu, rigid_partner=True)

    # δ ∝ 1/E up to the slowly varying log term: start from the E that matches the mean travel
    E1 = float(
        np.mean(2.0 * line_contact_approach(fs - fk0, R, 1.0, nu, rigid_partner=True)) / np.mean(us - uk)
    )
    if not (np.isfinite(E1) and E1 > 0):
        raise DataError(table.path, "force does not grow with plate travel beyond dk", column="force_N")
    res = least_squares(
        lambda p: travel(p) - us,
        x0=[np.log(E1), fk0],
        bounds=([np.log(E1) - 10.0, 0.0], [np.log(E1) + 10.0, max(float(fs.max()), fk0 + 1e-300)]),
        x_scale=[1.0, max(float(np.ptp(fs)), 1e-300)],
        xtol=1e-12,
        ftol=1e-12,
    )
    E_T, fk = float(np.exp(res.x[0])), float(res.x[1])
    rmse = float(np.sqrt(np.mean(res.fun**2)))
    return CompressionFit(
        E_transverse=E_T,
        precompression=fk,
        pressure=fk / dk,
        points=int(np.count_nonzero(sel)),
        rmse=rmse,
        file=table.path.name,
    )


def fit_yarn(
    name: str,
    *,
    d0: float,
    dk: float,
    tension: str | Path,
    compression: str | Path | None = None,
    nu: float = 0.3,
    model: str | None = None,
) -> Yarn:
    """A Yarn whose E_axial and failure strain come from ``tension`` and E_transverse from ``compression``.

    Without a compression test the yarn is isotropic (E_transverse = E_axial). ``source``
    records the files and fit quality.
    """
    t = fit_tension(tension, diameter=dk)
    src = f"fitted: tension {t.file} (E_axial {t.E_axial:.4g} MPa, {t.points} points, rmse {t.rmse:.3g} N)"
    E_T = t.E_axial
    if compression is not None:
        c = fit_compression(compression, d0=d0, dk=dk, nu=nu)
        E_T = min(c.E_transverse, t.E_axial)
        src += (
            f"; compression {c.file} (E_transverse {c.E_transverse:.4g} MPa, "
            f"pre-compression {c.precompression:.4g} N/mm, "
            f"{c.points} points, rmse {c.rmse:.3g} mm)"
        )
    kind = model or ("transverse_isotropic" if compression is not None else "isotropic")
    return Yarn(
        name=name,
        d0=d0,
        dk=dk,
        E_axial=t.E_axial,
        E_transverse=E_T,
        nu=nu,
        failure_strain=t.failure_strain,
        model=kind,
        source=src,
    )
