"""Segment–segment contact and friction terms for rods, with analytic gradients and Hessians.

A contact element is a pair of segments, points (p0, p1) and (q0, q1) stacked as (m, 4, 3).
Their closest distance is d = min over (s, t) ∈ [0, 1]² of |c|, c = p0 + s a − q0 − t b with
a = p1 − p0, b = q1 − q0. Writing c = J x, J = [(1−s) I, s I, −(1−t) I, −t I], the envelope
theorem gives ∇(d²) = 2 Jᵀc, and the implicit-function theorem on the free parameters θ
(those strictly inside (0, 1)) gives

    ∇²(d²) = 2 (JᵀJ − B C⁻¹ Bᵀ),   B = [J_sᵀc + Jᵀa, J_tᵀc − Jᵀb],   C = [[a·a, −a·b], [−a·b, b·b]]

with J_s = [−I, I, 0, 0], J_t = [0, 0, I, −I]; clamped parameters drop their row and column.
The contact energy is e(d) from a contact-law plugin, so ∇E = e′∇d and
∇²E = e″∇d∇dᵀ + e′∇²d.
"""

from __future__ import annotations

import numpy as np

__all__ = ["distance", "contact_energy", "friction_energy", "pair_weights"]

_EYE = np.eye(3)


def pair_weights(s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(m, 4) weights w with c = Σ w_i x_i: [(1 − s), s, −(1 − t), −t]."""
    return np.stack([1.0 - s, s, t - 1.0, -t], axis=1)


def distance(p: np.ndarray, s: np.ndarray, t: np.ndarray, order: int = 2):
    """Closest distance d (m,) of segment pairs p (m, 4, 3) at their closest parameters (s, t).

    Returns ``(d, ∇d (m, 4, 3), ∇²d (m, 4, 3, 4, 3))``; derivatives are None below ``order``.
    """
    w = pair_weights(s, t)
    c = np.einsum("mi,mic->mc", w, p)
    d = np.linalg.norm(c, axis=1)
    if order == 0:
        return d, None, None
    gq = 2.0 * w[:, :, None] * c[:, None, :]  # ∇(d²)
    gd = gq / (2.0 * d)[:, None, None]
    if order == 1:
        return d, gd, None
    m = len(d)
    a = p[:, 1] - p[:, 0]
    b = p[:, 3] - p[:, 2]
    Hq = 2.0 * np.einsum("mi,mj,cd->micjd", w, w, _EYE)
    free_s = (s > 0.0) & (s < 1.0)
    free_t = (t > 0.0) & (t < 1.0)
    Bm = np.zeros((m, 4, 3, 2))
    js = np.array([-1.0, 1.0, 0.0, 0.0])
    jt = np.array([0.0, 0.0, 1.0, -1.0])
    Bm[..., 0] = js[None, :, None] * c[:, None, :] + w[:, :, None] * a[:, None, :]
    Bm[..., 1] = jt[None, :, None] * c[:, None, :] - w[:, :, None] * b[:, None, :]
    Bm[..., 0] *= free_s[:, None, None]
    Bm[..., 1] *= free_t[:, None, None]
    aa = np.einsum("mc,mc->m", a, a)
    bb = np.einsum("mc,mc->m", b, b)
    ab = np.einsum("mc,mc->m", a, b)
    C = np.empty((m, 2, 2))
    C[:, 0, 0] = np.where(free_s, aa, 1.0)
    C[:, 1, 1] = np.where(free_t, bb, 1.0)
    C[:, 0, 1] = C[:, 1, 0] = np.where(free_s & free_t, -ab, 0.0)
    Cinv = np.linalg.inv(C)
    Hq -= 2.0 * np.einsum("mick,mkl,mjdl->micjd", Bm, Cinv, Bm)
    Hd = Hq / (2.0 * d)[:, None, None, None, None] - np.einsum(
        "mic,mjd->micjd", gq, gq) / (4.0 * d**3)[:, None, None, None, None]
    return d, gd, Hd


def contact_energy(p: np.ndarray, s: np.ndarray, t: np.ndarray, law, dk: float, k: float, order: int = 2,
                   k_core: float | None = None):
    """Contact energy of segment pairs p (m, 4, 3) under a rod contact law.

    Returns ``(E (m,) N·mm, g (m, 4, 3) N, H (m, 4, 3, 4, 3) N/mm, d (m,) mm)``.
    """
    d, gd, Hd = distance(p, s, t, order)
    e, e1, e2 = law.normal(d, dk, k, k_core)
    if order == 0:
        return e, None, None, d
    g = e1[:, None, None] * gd
    if order == 1:
        return e, g, None, d
    H = e2[:, None, None, None, None] * np.einsum("mic,mjd->micjd", gd, gd) + e1[:, None, None, None, None] * Hd
    return e, g, H, d


def friction_energy(p: np.ndarray, s: np.ndarray, t: np.ndarray, c_lag: np.ndarray, normal: np.ndarray,
                    lam: np.ndarray, law, dk: float, order: int = 2):
    """Lagged friction pseudo-potential of contact pairs p (m, 4, 3).

    The material points at the lagged (s, t) have slipped by Δc = J x − c_lag; the tangential
    slip is u = (I − n nᵀ) Δc with the lagged unit normal n (m, 3). Returns
    ``(D (m,), g (m, 4, 3), H (m, 4, 3, 4, 3))``.
    """
    w = pair_weights(s, t)
    c = np.einsum("mi,mic->mc", w, p)
    P = _EYE[None] - normal[:, :, None] * normal[:, None, :]
    u = np.einsum("mcd,md->mc", P, c - c_lag)
    D, gu, Hu = law.friction_potential(u, lam, dk)
    if order == 0:
        return D, None, None
    gc = np.einsum("mcd,mc->md", P, gu)  # ∂D/∂c = P ∇u D
    g = w[:, :, None] * gc[:, None, :]
    if order == 1:
        return D, g, None
    Hc = np.einsum("mac,mcd,mdb->mab", P, Hu, P)
    H = np.einsum("mi,mj,mcd->micjd", w, w, Hc)
    return D, g, H
