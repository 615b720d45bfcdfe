"""The length scale on which a cell's yarns bend: the Rayleigh wavenumber of their curvature."""

from __future__ import annotations

import numpy as np

from knitframe.geometry.cell import UnitCell, strands

__all__ = ["bending_wavenumber"]


def _d_ds(f: np.ndarray, ds: np.ndarray) -> np.ndarray:
    """df/ds by central differences on a periodic sequence with arc length ds per sample."""
    span = 0.5 * np.roll(ds, -1) + ds + 0.5 * np.roll(ds, 1)
    return (np.roll(f, -1, axis=0) - np.roll(f, 1, axis=0)) / span[:, None]


def bending_wavenumber(cell: UnitCell, n: int = 2048) -> float:
    """The Rayleigh wavenumber of the yarns' curvature, 1/mm:

        k_R² = Σ_strands ∮ |κ′(s)|² ds / Σ_strands ∮ |κ(s)|² ds,

    κ = dT/ds the curvature vector of the centre line, T its unit tangent, s its arc length. A
    sinusoid of small amplitude and wavenumber q gives q, a circle of radius R gives 1/R. It is
    the wavenumber at which a Timoshenko yarn, bending energy ½ EI ∫|κ|² ds and axial shear
    ½ (EI)²/(κ_s G_A A) ∫|κ′|² ds, bends with EI / (1 + EI k_R²/(κ_s G_A A)).

    Each strand (a cycle of ``end_pairs``) is sampled at ``n`` midpoints per yarn and
    differentiated by periodic central differences along it: the tangent is periodic across the
    cell, so the result is second-order accurate in 1/n. ValueError for a straight cell (∮|κ|² = 0).
    """
    num = den = 0.0
    for strand in strands(cell):
        tangents, speeds = [], []
        for i in strand:
            c = cell.yarns[i]
            dt = (c.t1 - c.t0) / n
            t = c.t0 + dt * (np.arange(n) + 0.5)
            d = np.asarray(c.derivative(t), dtype=np.float64)
            speed = np.linalg.norm(d, axis=1)
            tangents.append(d / speed[:, None])
            speeds.append(speed * dt)  # ds per sample
        T = np.concatenate(tangents)
        ds = np.concatenate(speeds)

        kappa = _d_ds(T, ds)
        dkappa = _d_ds(kappa, ds)
        num += float(np.sum(np.einsum("ij,ij->i", dkappa, dkappa) * ds))
        den += float(np.sum(np.einsum("ij,ij->i", kappa, kappa) * ds))
    if not den > 0.0:
        raise ValueError(f"{cell.pattern}: the yarns are straight; they have no bending wavenumber")
    return float(np.sqrt(num / den))
