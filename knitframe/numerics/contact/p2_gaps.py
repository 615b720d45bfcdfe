"""Gaps of points to quadratic facets at the closest point, with exact derivatives.

On a curved quadratic facet x(ξ) = Σ N_i(ξ) x_i the gap is measured from the closest point ξ*
(:func:`knitframe.numerics.contact.p2.project_p2`), g = n(ξ*)·(p − x(ξ*));
:func:`p2_gap_derivatives` gives its gradient and Hessian, with the exact second derivative of
the projection, and :func:`facet_gap` projects and differentiates in one call.
"""

from __future__ import annotations

import numpy as np

from knitframe.numerics.contact._algebra import dot
from knitframe.numerics.contact.p2 import P2Projection, p2_coefficients, p2_shape, project_p2, rim_edges

__all__ = ["p2_gap_derivatives", "facet_gap"]


def _adjugate(A: np.ndarray) -> np.ndarray:
    """Adjugate (m, 2, 2) of 2×2 matrices A (m, 2, 2): A⁻¹ = adj(A) / det(A)."""
    out = np.empty_like(A)
    out[:, 0, 0], out[:, 1, 1] = A[:, 1, 1], A[:, 0, 0]
    out[:, 0, 1], out[:, 1, 0] = -A[:, 0, 1], -A[:, 1, 0]
    return out


def p2_gap_derivatives(
    pr: P2Projection, Xf: np.ndarray, weights: np.ndarray | None = None, order: int = 2
) -> tuple[np.ndarray, np.ndarray | None]:
    """Gradient and Hessian of the gap g = n(ξ*)·(p − x(ξ*)) to quadratic facets at their closest points.

    The query point is p = Σ_k w_k y_k of ``weights`` (m, ks) and points y_k (ks = 1, w = 1 for p
    itself); the variables are (y_1 … y_ks, x_1 … x_6), K = ks + 6 points. With U = (w, −N(ξ*))
    and V_α = (0, ∂N/∂ξ_α) the weights of the points in p − x and in the tangents x_α::

        ∂g/∂y_a = U_a n                      (the ∂ξ* terms vanish: p − x ⟂ x_α at ξ*)

    and with G_αβ = x_α·x_β, b_αβ = n·x_αβ, A = G − g b (the Hessian of ½|p − x|² in ξ, which
    defines dξ* = A⁻¹ (x_α·d(p − x) + g n·dx_α) by the implicit function theorem), the linear
    forms e_α = U ⊗ x_α and h_α = V_α ⊗ n, and M = G⁻¹ b A⁻¹::

        ∂²g = −Σ_αβ [ A⁻¹_αβ (e_α ⊗ h_β + h_β ⊗ e_α + g h_α ⊗ h_β) + M_αβ e_α ⊗ e_β ]

    exact at an interior closest point. Where the closest point is on the facet's rim, the gap
    is the signed distance g = ±|r|, r = p − x(ξ*), and ``pr.n`` holds r/g (see
    :func:`select_pairs`); ∂g/∂y_a = U_a n again, and with P = I − n nᵀ::

        ∂²g = [ U ⊗ U P − e ⊗ e / A ] / g,   e_a = U_a x_τ + V_τ,a r,   A = x_τ·x_τ − r·x_ττ

    on an edge of the triangle (τ its parameter, V_τ = ∂²N/∂ξ∂τ's weights of x_τ; from the
    stationarity r·x_τ = 0 by the implicit function theorem), and ∂²g = U ⊗ U P / g at a corner.
    Where A is not positive (definite), or the closest point is neither inside nor on the rim
    (the projection did not converge), the second derivative is set to zero (the Gauss-Newton
    form of the penalty Hessian). Returns dg (m, K, 3) and Hg (m, K, 3, K, 3) (None for
    ``order`` < 2).
    """
    m = len(pr.g)
    w = np.ones((m, 1)) if weights is None else weights
    N, dN = p2_shape(pr.xi)
    U = np.concatenate([w, -N], axis=1)  # (m, K)
    dg = U[:, :, None] * pr.n[:, None, :]
    if order < 2:
        return dg, None
    ks = w.shape[1]
    K = ks + 6
    _, _, _, a3, a4, a5 = p2_coefficients(Xf)
    xa = np.stack([pr.xs, pr.xt], axis=1)  # (m, 2, 3)
    G = np.einsum("mai,mbi->mab", xa, xa)
    b = np.empty((m, 2, 2))
    b[:, 0, 0] = 2.0 * dot(pr.n, a3)
    b[:, 0, 1] = b[:, 1, 0] = dot(pr.n, a4)
    b[:, 1, 1] = 2.0 * dot(pr.n, a5)
    A = G - pr.g[:, None, None] * b
    detA = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] ** 2
    detG = G[:, 0, 0] * G[:, 1, 1] - G[:, 0, 1] ** 2
    smooth = pr.interior & (A[:, 0, 0] > 0) & (detA > 1e-12 * G[:, 0, 0] * G[:, 1, 1])
    detA = np.where(smooth, detA, 1.0)
    Ai = _adjugate(A) / detA[:, None, None]
    Gi = _adjugate(G) / detG[:, None, None]
    Ai[~smooth] = 0.0
    M = Gi @ b @ Ai
    V = np.zeros((m, 2, K))
    V[:, :, ks:] = dN.transpose(0, 2, 1)
    e = U[:, None, :, None] * xa[:, :, None, :]  # (m, 2, K, 3)
    hh = V[..., None] * pr.n[:, None, None, :]  # (m, 2, K, 3)
    et = np.einsum("mab,mbki->maki", Ai, e)  # Σ_β A⁻¹_αβ e_β  (A symmetric)
    em = np.einsum("mba,mbki->maki", M, e)  # Σ_β M_βα e_β
    ht = np.einsum("mab,mbki->maki", Ai, hh) * pr.g[:, None, None, None]
    L = np.concatenate([et, hh, em, ht], axis=1).reshape(m, 8, 3 * K)
    R = np.concatenate([hh, et, e, hh], axis=1).reshape(m, 8, 3 * K)
    Hg = -np.matmul(L.transpose(0, 2, 1), R).reshape(m, K, 3, K, 3)
    rim = np.flatnonzero(~pr.interior & (np.abs(pr.g) > 0))
    if rim.size:
        Hg[rim] = _rim_gap_hessian(pr, rim, U[rim], V[rim], a3[rim], a4[rim], a5[rim])
    return dg, Hg


def _rim_gap_hessian(
    pr: P2Projection,
    rows: np.ndarray,
    U: np.ndarray,
    V: np.ndarray,
    a3: np.ndarray,
    a4: np.ndarray,
    a5: np.ndarray,
) -> np.ndarray:
    """∂²g (k, K, 3, K, 3) of the signed distance at closest points on the rim (see
    :func:`p2_gap_derivatives`)."""
    k, K = U.shape
    g, n = pr.g[rows], pr.n[rows]
    on = rim_edges(pr.xi[rows])
    edge = on.sum(axis=1) == 1
    # the edge's direction in ξ: 01 (t = 0) → (1, 0), 12 (s + t = 1) → (−1, 1), 20 (s = 0) → (0, 1)
    tau = np.where(on[:, [0]], [1.0, 0.0], np.where(on[:, [1]], [-1.0, 1.0], [0.0, 1.0]))
    x_tau = tau[:, :1] * pr.xs[rows] + tau[:, 1:] * pr.xt[rows]
    x_tt = 2.0 * tau[:, :1] ** 2 * a3 + 2.0 * tau[:, :1] * tau[:, 1:] * a4 + 2.0 * tau[:, 1:] ** 2 * a5
    r = g[:, None] * n
    A = dot(x_tau, x_tau) - dot(r, x_tt)
    P = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
    H = np.einsum("ma,mb,mij->maibj", U, U, P)
    V_tau = tau[:, 0, None] * V[:, 0] + tau[:, 1, None] * V[:, 1]  # (k, K)
    e = U[:, :, None] * x_tau[:, None, :] + V_tau[:, :, None] * r[:, None, :]
    use = edge & (A > 1e-12 * dot(x_tau, x_tau))
    coef = np.where(use, 1.0 / np.where(use, A, 1.0), 0.0)
    H -= coef[:, None, None, None, None] * np.einsum("mai,mbj->maibj", e, e)
    H /= g[:, None, None, None, None]
    H[(edge & ~use) | (on.sum(axis=1) == 0)] = 0.0  # not a strict minimum along the edge, or not on the rim
    return H


def facet_gap(
    p: np.ndarray, Xf: np.ndarray, order: int = 1
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray]:
    """Gap g = n·(p − x(ξ*)) of points p (m, 3) to quadratic facets Xf (m, 6, 3) at the closest point ξ*.

    Returns g (m,), dg (m, 7, 3) and Hg (m, 7, 3, 7, 3) with respect to (p, x_1 … x_6) (see
    :func:`p2_gap_derivatives`; None below the asked ``order``), and the distance |p − x(ξ*)| (m,).
    """
    pr = project_p2(p, Xf)
    if order == 0:
        return pr.g, None, None, pr.dist
    dg, Hg = p2_gap_derivatives(pr, Xf, None, order)
    return pr.g, dg, Hg, pr.dist
