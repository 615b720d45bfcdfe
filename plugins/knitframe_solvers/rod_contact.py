"""Yarn–yarn contact and friction terms for rods: a double integral over the two centerlines.

Two yarns whose centerlines are x(s) and y(t) (s, t arc length in the reference state) store

    E = ∫∫ φ(|x(s) − y(t)|) ds dt                                                    (N·mm)

with φ(r) a contact-law energy density (N/mm) that vanishes for r ≥ dk (Kaldor, James &
Marschner 2008, "Simulating knitted cloth at the yarn level"). Crossing yarns then touch over a
patch and parallel yarns along a line, with no closest-point projection: E is as smooth as φ
however the yarns slide, wrap or cross, and no contact is counted twice at a polyline vertex.

On a pair of straight segments, points (p0, p1) and (q0, q1) stacked as (m, 4, 3), the integral
is an n×n Gauss–Legendre rule in the segment parameters (ξ_a, ξ_b) ∈ [0, 1]² weighted by the rest
lengths l_i l_j. A point pair c = J x, J = [(1 − ξ_a) I, ξ_a I, −(1 − ξ_b) I, −ξ_b I] has fixed
weights, so with r = |c| and n = c/r

    ∇E = Σ w_ab φ′(r) Jᵀn,     ∇²E = Σ w_ab Jᵀ [φ″ n nᵀ + (φ′/r)(I − n nᵀ)] J.

Two limits of the integral give the contact law's meaning, used to calibrate it and to test it:
perpendicular crossing lines at centre distance d push apart with F(d) = 2π d φ(d) (the
integrand is radial in the plane of (s, t)), and parallel lines carry the line load
f(d) = −ψ′(d) with ψ(d) = ∫ φ(√(d² + τ²)) dτ (N per mm of yarn).
"""

from __future__ import annotations

import numpy as np

__all__ = ["gauss_points", "quadrature_contact", "friction_energy", "pair_weights", "line_energy"]

_EYE = np.eye(3)


def pair_weights(s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(..., 4) weights w with c = Σ w_i x_i: [(1 − s), s, −(1 − t), −t]."""
    s, t = np.asarray(s, dtype=np.float64), np.asarray(t, dtype=np.float64)
    return np.stack([1.0 - s, s, t - 1.0, -t], axis=-1)


def gauss_points(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tensor Gauss–Legendre rule on [0, 1]²: ξ_a (n²,), ξ_b (n²,) and weights (n²,) summing to 1."""
    x, w = np.polynomial.legendre.leggauss(n)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    a, b = np.meshgrid(x, x, indexing="ij")
    return a.reshape(-1), b.reshape(-1), np.outer(w, w).reshape(-1)


def quadrature_contact(
    p: np.ndarray,
    lengths: np.ndarray,
    law,
    dk: float,
    k: float,
    k_core: float | None,
    rule: tuple[np.ndarray, np.ndarray, np.ndarray],
    order: int = 2,
):
    """Contact energy of segment pairs by the double integral of a rod contact law's density.

    Parameters
    ----------
    p : (m, 4, 3) points p0, p1 of segment i and q0, q1 of segment j, mm
    lengths : (m,) product of the two rest lengths l_i l_j, mm²
    law : rod contact-law plugin; ``law.normal(r, dk, k, k_core)`` is φ and its derivatives
    dk : contact distance, mm
    k, k_core : penalty and core stiffness of the density, N/mm³
    rule : :func:`gauss_points` output
    order : 0 energy, 1 + gradient, 2 + Hessian

    Returns
    -------
    E (m,) N·mm, g (m, 4, 3) N, H (m, 4, 3, 4, 3) N/mm (None below ``order``), and the
    closest sampled point-pair distance of each pair (m,) mm.
    """
    xa, xb, wq = rule
    w = pair_weights(xa, xb)  # (Q, 4)
    c = np.matmul(w, p)  # (m, Q, 3): c_mq = Σ_i w_qi p_mi
    r = np.linalg.norm(c, axis=2)
    mult = lengths[:, None] * wq[None, :]
    e, e1, e2 = law.normal(r, dk, k, k_core)
    E = np.sum(mult * e, axis=1)
    r_min = r.min(axis=1) if r.size else np.zeros(len(p))
    if order == 0:
        return E, None, None, r_min
    rs = np.maximum(r, 1e-300)
    n = c / rs[..., None]
    g = np.matmul(w.T, (mult * e1)[..., None] * n)  # (m, 4, 3): Σ_q w_qi f_mq
    if order == 1:
        return E, g, None, r_min
    nn = n[..., :, None] * n[..., None, :]
    A = (mult * e2)[..., None, None] * nn + (mult * e1 / rs)[..., None, None] * (_EYE - nn)
    # H_micjd = Σ_q w_qi w_qj A_mqcd, as one matrix product (Q contracted): (16, Q) @ (m, Q, 9)
    Q, m = len(w), len(p)
    ww = (w[:, :, None] * w[:, None, :]).reshape(Q, 16)
    H = np.matmul(ww.T, A.reshape(m, Q, 9)).reshape(m, 4, 4, 3, 3).transpose(0, 1, 3, 2, 4)
    return E, g, H, r_min


def line_energy(law, d: float, dk: float, k: float, k_core: float | None, derivative: int = 0) -> float:
    """ψ(d) = ∫ φ(√(d² + τ²)) dτ of two parallel lines and its first or second derivative in d.

    ψ is the energy per unit length (N) of two parallel yarns at centre distance d; −ψ′ is their
    line load (N/mm) and ψ″ their line contact stiffness (N/mm²). Integrated with
    :func:`scipy.integrate.quad` over |τ| < √(dk² − d²), where φ is non-zero.
    """
    from scipy.integrate import quad

    if d >= dk:
        return 0.0
    span = np.sqrt(dk * dk - d * d)

    def integrand(tau: float) -> float:
        r = np.hypot(d, tau)
        e, e1, e2 = (float(np.asarray(a).reshape(-1)[0]) for a in law.normal(np.array([r]), dk, k, k_core))
        if derivative == 0:
            return e
        if derivative == 1:
            return e1 * d / r
        return e2 * (d / r) ** 2 + e1 * tau * tau / r**3

    return 2.0 * quad(integrand, 0.0, span, epsabs=0.0, epsrel=1e-10, limit=200)[0]


def friction_energy(
    p: np.ndarray,
    s: np.ndarray,
    t: np.ndarray,
    c_lag: np.ndarray,
    normal: np.ndarray,
    lam: np.ndarray,
    law,
    dk: float,
    order: int = 2,
    group: np.ndarray | None = None,
):
    """Lagged friction pseudo-potential of point pairs on segment pairs p (m, 4, 3).

    The material points at parameters (s, t) have slipped by Δc = J x − c_lag since the lag;
    the tangential slip is u = (I − n nᵀ) Δc with the lagged unit normal n (m, 3). ``lam`` (m,)
    is the lagged normal force of each point pair, N. Returns ``(D (m,), g (m, 4, 3), H (m, 4, 3, 4, 3))``.

    With ``group`` (m,), non-decreasing segment-pair numbers 0 … G − 1 of the point pairs (whose p then
    repeat), g and H are summed per segment pair: (G, 4, 3) and (G, 4, 3, 4, 3), with

        g_s = Σ_{q∈s} w_q ⊗ Pᵀ∇D_q,     H_s = Σ_{q∈s} (w_q w_qᵀ) ⊗ (Pᵀ ∇²D_q P),

    the sums over each group's point pairs taken as one batched matrix product (zero-padded to the
    largest group) instead of forming every point pair's (4, 3, 4, 3) block.
    """
    w = pair_weights(s, t)
    c = np.matmul(w[:, None, :], p)[:, 0]  # Σ_i w_mi p_mi
    P = _EYE[None] - normal[:, :, None] * normal[:, None, :]
    u = np.matmul(P, (c - c_lag)[..., None])[..., 0]
    D, gu, Hu = law.friction_potential(u, lam, dk)
    if order == 0:
        return D, None, None
    gc = np.matmul(gu[:, None, :], P)[:, 0]  # ∂D/∂c = Pᵀ ∇u D
    pad = None if group is None else _padding(group)
    if pad is None:
        g = w[:, :, None] * gc[:, None, :]
    else:
        g = np.matmul(pad(w).transpose(0, 2, 1), pad(gc))  # (G, 4, 3)
    if order == 1:
        return D, g, None
    Hc = np.matmul(np.matmul(P.transpose(0, 2, 1), Hu), P)  # Pᵀ Hu P
    ww = (w[:, :, None] * w[:, None, :]).reshape(-1, 16)
    if pad is None:
        H = ww.reshape(-1, 4, 4)[:, :, None, :, None] * Hc[:, None, :, None, :]
    else:
        HH = np.matmul(pad(ww).transpose(0, 2, 1), pad(Hc.reshape(-1, 9)))  # (G, 16, 9)
        H = HH.reshape(-1, 4, 4, 3, 3).transpose(0, 1, 3, 2, 4)
    return D, g, H


def _padding(group: np.ndarray):
    """``pad(a)``: rows a (m, …) of the groups laid out as (G, n_max, …), zero where a group is shorter."""
    m = len(group)
    starts = np.flatnonzero(np.diff(group, prepend=-1))
    counts = np.diff(np.append(starts, m))
    slot = np.arange(m) - np.repeat(starts, counts)
    shape = (len(starts), int(counts.max(initial=1)))

    def pad(a: np.ndarray) -> np.ndarray:
        out = np.zeros(shape + a.shape[1:])
        out[group, slot] = a
        return out

    return pad
