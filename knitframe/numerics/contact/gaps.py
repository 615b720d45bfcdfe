"""Gaps of points to linear triangles: the plane gap with exact derivatives, distances and bounds.

The gap of a point p to the plane of a master triangle (a, b, c) is, with d = p − a,
e1 = b − a, e2 = c − a, m = e1 × e2, μ = |m|::

    g = (d · m) / μ                                   (mm; < 0 means penetration)

:func:`plane_gap` returns g with its exact gradient and Hessian in (p, a, b, c);
:func:`barycentric` gives the projection's barycentric coordinates,
:func:`point_triangle_distance` the unsigned distance to the triangle, and
:func:`distance_bound` a cheap lower bound of the distance to a flat or quadratic facet (the
pairing's prescreen).
"""

from __future__ import annotations

import numpy as np

from knitframe.numerics.contact._algebra import dot

__all__ = ["plane_gap", "barycentric", "distance_bound", "point_triangle_distance"]


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]× (m, 3, 3) with [v]× w = v × w."""
    z = np.zeros(v.shape[0])
    return np.stack(
        [
            np.stack([z, -v[:, 2], v[:, 1]], 1),
            np.stack([v[:, 2], z, -v[:, 0]], 1),
            np.stack([-v[:, 1], v[:, 0], z], 1),
        ],
        axis=1,
    )


# z = (d, e1, e2) = A x with x = (p, a, b, c)
_A = np.zeros((3, 4))
_A[0, 0], _A[0, 1] = 1.0, -1.0
_A[1, 2], _A[1, 1] = 1.0, -1.0
_A[2, 3], _A[2, 1] = 1.0, -1.0


def plane_gap(
    p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, order: int = 2
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Signed distance of points p to the planes of triangles (a, b, c), with exact derivatives.

    Parameters
    ----------
    p, a, b, c : (m, 3) mm; the triangle's normal (b − a) × (c − a) points to positive gaps.
    order : 0, 1 or 2 derivatives.

    Returns
    -------
    g : (m,) mm;  dg : (m, 4, 3) ∂g/∂(p, a, b, c);  Hg : (m, 4, 3, 4, 3) second derivatives, 1/mm.
    """
    d, e1, e2 = p - a, b - a, c - a
    m = np.cross(e1, e2)
    mu = np.linalg.norm(m, axis=1)
    n = m / mu[:, None]
    V = np.einsum("ij,ij->i", d, m)
    g = V / mu
    if order == 0:
        return g, None, None
    dV = np.stack([m, np.cross(e2, d), np.cross(d, e1)], axis=1)  # (m, 3 vars, 3)
    dmu = np.stack([np.zeros_like(n), np.cross(e2, n), np.cross(n, e1)], axis=1)
    dg_z = dV / mu[:, None, None] - (V / mu**2)[:, None, None] * dmu
    dg = np.einsum("zx,mzi->mxi", _A, dg_z)
    if order == 1:
        return g, dg, None
    # second derivatives in z = (d, e1, e2)
    m1, m2 = -_skew(e2), _skew(e1)  # ∂m/∂e1, ∂m/∂e2
    P = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
    Dm = np.zeros((d.shape[0], 3, 3, 3))  # (m, 3 comps of m, 3 vars, 3)
    Dm[:, :, 1, :] = m1
    Dm[:, :, 2, :] = m2
    H_mu = np.einsum("mkzi,mkl,mlyj->mziyj", Dm, P, Dm) / mu[:, None, None, None, None]
    sn = _skew(n)
    H_mu[:, 1, :, 2, :] += -sn
    H_mu[:, 2, :, 1, :] += sn
    H_V = np.zeros_like(H_mu)
    H_V[:, 0, :, 1, :] = -_skew(e2)
    H_V[:, 1, :, 0, :] = _skew(e2)
    H_V[:, 0, :, 2, :] = _skew(e1)
    H_V[:, 2, :, 0, :] = -_skew(e1)
    sd = _skew(d)
    H_V[:, 1, :, 2, :] = -sd
    H_V[:, 2, :, 1, :] = sd
    outer = np.einsum("mzi,myj->mziyj", dV, dmu)
    H_z = (
        H_V / mu[:, None, None, None, None]
        - (outer + outer.transpose(0, 3, 4, 1, 2)) / (mu**2)[:, None, None, None, None]
        + (2.0 * V / mu**3)[:, None, None, None, None] * np.einsum("mzi,myj->mziyj", dmu, dmu)
        - (V / mu**2)[:, None, None, None, None] * H_mu
    )
    Hg = np.einsum("zx,mziyj,yw->mxiwj", _A, H_z, _A)
    return g, dg, Hg


def barycentric(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (m, 3) of the projections of p onto the planes of (a, b, c)."""
    e1, e2, d = b - a, c - a, p - a
    d11, d12, d22 = (np.einsum("ij,ij->i", x, y) for x, y in ((e1, e1), (e1, e2), (e2, e2)))
    r1, r2 = np.einsum("ij,ij->i", d, e1), np.einsum("ij,ij->i", d, e2)
    det = d11 * d22 - d12 * d12
    l1 = (d22 * r1 - d12 * r2) / det
    l2 = (d11 * r2 - d12 * r1) / det
    return np.stack([1.0 - l1 - l2, l1, l2], axis=1)


def distance_bound(p: np.ndarray, Xe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A lower bound (m,) of the distance from points p (m, 3) to triangles or quadratic facets Xe
    (m, 3 or 6, 3), mm.

    The distance to the corners' flat triangle is at least √(g² + ℓ²), with g the distance to
    its plane and ℓ = max_i(−λ_i h_i, 0) the in-plane distance beyond the edge opposite corner i
    (λ the barycentric coordinates of p's projection, h_i the triangle's heights); it is exact
    when p projects into the triangle. A quadratic facet is x(ξ) = x_lin(ξ) + Σ_edges 4 λ_i λ_j d_ij
    with d_ij = x_ij − (x_i + x_j)/2 the bow of edge ij; 4 λ_i λ_j ≤ 1 and Σ 4 λ_i λ_j ≤ 4/3, so
    each of its points is within δ = min(Σ|d_ij|, 4/3 max|d_ij|) of the flat triangle, and
    δ is taken off the bound. Returns the bound and the barycentric coordinates (m, 3).
    """
    x0 = Xe[:, 0]
    e1, e2, d = Xe[:, 1] - x0, Xe[:, 2] - x0, p - x0
    d11, d12, d22 = dot(e1, e1), dot(e1, e2), dot(e2, e2)
    r1, r2 = dot(d, e1), dot(d, e2)
    det = d11 * d22 - d12 * d12  # |e1 × e2|²
    l1 = (d22 * r1 - d12 * r2) / det
    l2 = (d11 * r2 - d12 * r1) / det
    l0 = 1.0 - l1 - l2
    # |d|² = g² + |in-plane part|², the in-plane part being l1 e1 + l2 e2
    g2 = np.maximum(dot(d, d) - (l1 * r1 + l2 * r2), 0.0)
    area2 = np.sqrt(det)
    e12 = d11 - 2.0 * d12 + d22  # |x2 − x1|²
    ell = np.maximum(
        np.maximum(-l0 * area2 / np.sqrt(e12), -l1 * area2 / np.sqrt(d22)), -l2 * area2 / np.sqrt(d11)
    )
    bound = np.sqrt(g2 + np.maximum(ell, 0.0) ** 2)
    if Xe.shape[1] == 6:
        bows = (
            Xe[:, 3] - 0.5 * (x0 + Xe[:, 1]),
            Xe[:, 4] - 0.5 * (Xe[:, 1] + Xe[:, 2]),
            Xe[:, 5] - 0.5 * (Xe[:, 2] + x0),
        )
        bow = np.stack([np.sqrt(dot(b, b)) for b in bows], axis=1)
        bound = bound - np.minimum(bow.sum(axis=1), 4.0 / 3.0 * bow.max(axis=1))
    return bound, np.column_stack([l0, l1, l2])


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(
        np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0
    )
    return np.linalg.norm(p - a - t[:, None] * ab, axis=1)


def point_triangle_distance(
    p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, tol: float = 0.0, gap: bool = False
) -> tuple[np.ndarray, ...]:
    """Distance (m,) from points to triangles, and whether the projection lies inside (barycentric ≥ −tol).

    With ``gap`` the signed plane gap (m,) of :func:`plane_gap` is returned too.
    """
    lam = barycentric(p, a, b, c)
    inside = np.all(lam >= -tol, axis=1)
    g = plane_gap(p, a, b, c, order=0)[0]
    edge = np.minimum(
        np.minimum(_segment_distance(p, a, b), _segment_distance(p, b, c)), _segment_distance(p, c, a)
    )
    dist = np.where(inside, np.abs(g), edge)
    return (dist, inside, g) if gap else (dist, inside)
