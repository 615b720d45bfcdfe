"""Shared operations on curves: averaging repeats, building uniaxial Responses, comparing two curves."""

from __future__ import annotations

import numpy as np

from knitframe.records import Provenance, Response

__all__ = ["average_repeats", "by_strain", "value_at", "uniaxial_response", "nrmse_between"]


def by_strain(strain: np.ndarray, *values: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(strain, *values)`` sorted by strain, every array in the same order (stable: repeats of one
    strain keep their order)."""
    order = np.argsort(strain, kind="stable")
    return (strain[order], *(np.asarray(v)[order] for v in values))


def value_at(strain: np.ndarray, values: np.ndarray, at: float) -> float | None:
    """The value at strain ``at``, linear between the points of the curve sorted by strain; None
    when ``at`` lies outside the strains the curve covers."""
    s, v = by_strain(np.asarray(strain, dtype=np.float64), np.asarray(values, dtype=np.float64))
    if not s[0] <= at <= s[-1]:
        return None
    return float(np.interp(at, s, v))


def average_repeats(
    strain: list[np.ndarray], lateral: list[np.ndarray], tension: list[np.ndarray], points: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean and sd of lateral strain and tension over repeats on a common axial-strain grid.

    Each repeat is sorted by axial strain and interpolated linearly onto ``points`` strains
    spanning the range every repeat covers. Returns ``(grid, lat_mean, lat_sd, T_mean, T_sd)``;
    the sd is the sample standard deviation (ddof = 1), zero for a single repeat.
    """
    lo = max(s.min() for s in strain)
    hi = min(s.max() for s in strain)
    if not hi > lo:
        raise ValueError("repeats share no strain range")
    grid = np.linspace(lo, hi, points)
    lat = np.empty((len(strain), points))
    ten = np.empty((len(strain), points))
    for k, repeat in enumerate(zip(strain, lateral, tension)):
        s, l, t = by_strain(*repeat)
        lat[k] = np.interp(grid, s, l)
        ten[k] = np.interp(grid, s, t)
    ddof = 1 if len(strain) > 1 else 0
    return grid, lat.mean(0), lat.std(0, ddof=ddof), ten.mean(0), ten.std(0, ddof=ddof)


def uniaxial_response(
    load: str,
    axial: np.ndarray,
    lateral: np.ndarray,
    tension: np.ndarray,
    lat_sd: np.ndarray | None,
    ten_sd: np.ndarray | None,
    n: int,
    label: str,
    prov: Provenance,
) -> Response:
    """Response of a free-sides uniaxial test from engineering strains and tension (N/mm).

    ``load`` is ``uniaxial-course`` (λ1 = 1 + axial, λ2 = 1 + lateral, T2 = 0) or ``uniaxial-wale``.
    """
    zero = np.zeros_like(tension)
    if load == "uniaxial-course":
        return Response(
            1 + axial,
            1 + lateral,
            tension,
            zero,
            load=load,
            label=label,
            n_samples=n,
            T1_sd=ten_sd,
            lambda2_sd=lat_sd,
            provenance=prov,
        )
    return Response(
        1 + lateral,
        1 + axial,
        zero,
        tension,
        load=load,
        label=label,
        n_samples=n,
        T2_sd=ten_sd,
        lambda1_sd=lat_sd,
        provenance=prov,
    )


def nrmse_between(ref: Response, r: Response) -> float:
    """Distance of curve ``r`` from the reference ``ref``, as the fits are scored::

        NRMSE = sqrt(mean_k (T_r(λ_k) − T_ref,k)²) / max_k |T_ref,k|

    over the reference's points k in both directions (course and wale), with ``r``'s tensions
    interpolated linearly at the reference's stretches (held constant beyond ``r``'s range).
    """
    scale = max(np.abs(ref.T1).max(), np.abs(ref.T2).max())
    err = []
    for lam_r, T_r, lam, T in (
        (ref.lambda1, ref.T1, r.lambda1, r.T1),
        (ref.lambda2, ref.T2, r.lambda2, r.T2),
    ):
        o = np.argsort(lam)
        err.append(np.interp(lam_r, lam[o], T[o]) - T_r)
    return float(np.sqrt(np.mean(np.concatenate(err) ** 2)) / scale)
