"""Penalty terms of the solid contact laws: the energy ½ ε w ψ(⟨−g⟩) and its derivatives per pair."""

from __future__ import annotations

import numpy as np

__all__ = ["penalty_depth", "penalty_terms"]


def penalty_depth(
    g: np.ndarray, band: tuple[float, float] | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ψ(d), ψ'(d), ψ''(d) of the penetration d = ⟨−g⟩ (mm², mm, -): the penalty energy is ½ ε w ψ.

    ψ = d² up to the band's start d1; across the band (d1, d2) it fades out, ψ = d² S(t),
    S = 1 − 3t² + 2t³, t = (d − d1)/(d2 − d1), so that ψ and ψ' reach 0 at d2 (the contact
    reach, beyond which a pair is not kept). Without a band ψ = d² throughout.
    """
    d = np.maximum(-g, 0.0)
    psi, d_psi, dd_psi = d * d, 2.0 * d, 2.0 * (d > 0)
    if band is not None:
        d1, d2 = band
        width = d2 - d1
        t = np.clip((d - d1) / width, 0.0, 1.0)
        S = 1.0 - 3.0 * t**2 + 2.0 * t**3
        dS = np.where((t > 0) & (t < 1), (-6.0 * t + 6.0 * t**2) / width, 0.0)
        ddS = np.where((t > 0) & (t < 1), (-6.0 + 12.0 * t) / width**2, 0.0)
        psi, d_psi, dd_psi = d * d * S, 2.0 * d * S + d * d * dS, dd_psi * S + 4.0 * d * dS + d * d * ddS
    return psi, d_psi, dd_psi


def penalty_terms(
    g: np.ndarray,
    dg: np.ndarray,
    Hg: np.ndarray | None,
    weight: np.ndarray,
    stiffness: float,
    order: int,
    band: tuple[float, float] | None = None,
) -> tuple[float, np.ndarray | None, np.ndarray | None]:
    """Energy ½ ε w ψ(⟨−g⟩), its element gradients (m, k, 3) and Hessians (m, k, 3, k, 3) for active pairs.

    ``weight`` (m,) is the slave area each gap stands for (mm²), ``stiffness`` ε in N/mm³; ψ = d²
    (the classical ½ ε w ⟨−g⟩²), faded out across ``band`` (:func:`penalty_depth`). With
    d = −g: ∂E = −½ ε w ψ' ∂g and ∂²E = ½ ε w (ψ'' ∂g ⊗ ∂g − ψ' ∂²g).
    """
    psi, d_psi, dd_psi = penalty_depth(g, band)
    E = 0.5 * stiffness * float(np.sum(weight * psi))
    if order == 0:
        return E, None, None
    c = 0.5 * stiffness * weight
    grad = (-c * d_psi)[:, None, None] * dg
    if order == 1:
        return E, grad, None
    m, k = dg.shape[:2]
    d = dg.reshape(m, 3 * k)
    hess = ((c * dd_psi)[:, None, None] * (d[:, :, None] * d[:, None, :])).reshape(m, k, 3, k, 3)
    if Hg is not None:
        hess -= (c * d_psi)[:, None, None, None, None] * Hg
    return E, grad, hess
