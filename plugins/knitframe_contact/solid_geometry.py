"""Geometry shared by the solid contact laws: triangle gaps with exact derivatives and the candidate search.

The contact surface of a tetrahedral mesh is a set of linear triangles (a quadratic facet counts
as its four linear sub-facets). The gap of a point p to the plane of the master triangle (a, b, c)
is, with d = p − a, e1 = b − a, e2 = c − a, m = e1 × e2, μ = |m|::

    g = (d · m) / μ                                   (mm; < 0 means penetration)

:func:`plane_gap` returns g with its exact gradient and Hessian in (p, a, b, c). Candidate pairs
come from a KD-tree on the master triangles' centroids, including the periodic images
k1 L1 + k2 L2 placed under the current F̄ (:class:`knitframe.periodic.Lattice`); pairs of a yarn
with a piece of itself closer than an exclusion length along the strand are dropped with the
strand bookkeeping of :class:`knitframe.contact_search.SegmentTopology`. Element gradients and
Hessians are scattered to q = [u (3N), h (6)] with :class:`knitframe.periodic.PointMap`.
"""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np
from scipy.spatial import cKDTree

from knitframe.contact_search import IMAGES, SegmentTopology
from knitframe.periodic import Lattice

__all__ = [
    "plane_gap", "barycentric", "point_triangle_distance", "nearest", "node_normals", "penalty_terms", "scatter",
    "SolidSurface", "Candidates", "p2_shape", "project_p2", "facet_gap",
]


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]× (m, 3, 3) with [v]× w = v × w."""
    z = np.zeros(v.shape[0])
    return np.stack(
        [np.stack([z, -v[:, 2], v[:, 1]], 1), np.stack([v[:, 2], z, -v[:, 0]], 1), np.stack([-v[:, 1], v[:, 0], z], 1)],
        axis=1,
    )


# z = (d, e1, e2) = A x with x = (p, a, b, c)
_A = np.zeros((3, 4))
_A[0, 0], _A[0, 1] = 1.0, -1.0
_A[1, 2], _A[1, 1] = 1.0, -1.0
_A[2, 3], _A[2, 1] = 1.0, -1.0


def plane_gap(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, order: int = 2
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


def node_normals(x: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted unit normals (N, 3) at the nodes of a triangle surface (zero off the surface)."""
    m = np.cross(x[triangles[:, 1]] - x[triangles[:, 0]], x[triangles[:, 2]] - x[triangles[:, 0]])
    out = np.zeros_like(x)
    for k in range(3):
        np.add.at(out, triangles[:, k], m)
    nrm = np.linalg.norm(out, axis=1, keepdims=True)
    return out / np.where(nrm > 0, nrm, 1.0)


@attrs.frozen(eq=False)
class Candidates:
    """Pairs (query point, master triangle at an image) found by the broad phase."""

    point: np.ndarray  #: (m,) index into the query points
    triangle: np.ndarray  #: (m,) master triangle
    image: np.ndarray  #: (m, 2) integer image of the master triangle
    shift: np.ndarray  #: (m, 3) current image shift F̄·S_k, mm


@attrs.frozen(eq=False)
class SolidSurface:
    """The contact surface of a solid mesh, with the bookkeeping for self-contact and images.

    ``facets`` are the boundary facets (3 nodes for P1, 6 for P2: corners then edge nodes);
    ``slave`` / ``master`` select which of them act on each side (the same set for two-pass
    self-contact of yarns). ``triangles`` are the facets split into linear triangles (a quadratic
    facet gives four). Nodes carry a strand topology (see
    :class:`knitframe.contact_search.SegmentTopology`, here one entry per node): pairs on one
    strand copy closer than ``exclusion`` along it are the yarn's own material, not contacts.
    Bodies that are not yarns use their own strand with ``cycle`` 0 and arc 0, so they never
    contact themselves. Build with :meth:`build`.
    """

    n_nodes: int
    X: np.ndarray  #: (N, 3) reference node coordinates, mm
    facets: np.ndarray  #: (F, 3 or 6) node indices, normals outward
    slave: np.ndarray  #: (Fs,) slave facets
    master: np.ndarray  #: (Fm,) master facets
    topology: SegmentTopology  #: per node
    exclusion: float  #: arc length along a strand within which pairs are ignored, mm
    lattice: Lattice | None  #: periodic lattice (None: no images)
    triangles: np.ndarray  #: (T, 3) linear triangles of all facets
    tri_slave: np.ndarray  #: triangles of the slave facets
    tri_master: np.ndarray  #: triangles of the master facets
    area: np.ndarray  #: (F,) reference facet areas, mm²
    slave_nodes: np.ndarray  #: nodes of the slave facets
    tributary: np.ndarray  #: (N,) reference slave area per node (a third of each slave triangle), mm²

    @classmethod
    def build(cls, X: np.ndarray, facets: np.ndarray, slave: np.ndarray, master: np.ndarray,
              topology: SegmentTopology, exclusion: float, lattice: Lattice | None = None) -> "SolidSurface":
        """Surface over reference nodes X (N, 3); areas and tributary areas from X."""
        from knitframe.mesh import split_facets

        facets = np.asarray(facets, np.int64)
        F = len(facets)
        tri = split_facets(facets)
        per = len(tri) // max(F, 1)
        tri_of = lambda f: (np.arange(per)[:, None] * F + np.asarray(f)[None, :]).ravel()  # noqa: E731
        t_area = 0.5 * np.linalg.norm(np.cross(X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]), axis=1)
        area = t_area.reshape(per, F).sum(axis=0) if F else np.zeros(0)
        ts = tri_of(slave)
        trib = np.zeros(len(X))
        for k in range(3):
            np.add.at(trib, tri[ts, k], t_area[ts] / 3.0)
        return cls(len(X), np.asarray(X, np.float64), facets, np.asarray(slave, np.int64), np.asarray(master, np.int64), topology,
                   float(exclusion), lattice, tri, ts, tri_of(master), area, np.unique(facets[slave]), trib)

    def candidates(self, points: np.ndarray, point_node: np.ndarray, x: np.ndarray, h: np.ndarray | None,
                   reach: float, *, quadratic: bool = False) -> Candidates:
        """Master elements (with images) whose centroid lies within ``reach`` + their size of each point.

        The master elements are the linear triangles of the master facets, or with ``quadratic``
        the master facets themselves (``Candidates.triangle`` then holds facet indices).

        Parameters
        ----------
        points : (P, 3) current query points, mm.
        point_node : (P,) a node of the query point's own facet, for the self-contact rule.
        x : (N, 3) current node coordinates, mm.
        h : (6,) macro DOFs, or None.
        reach : search distance, mm.
        """
        ids = self.master if quadratic else self.tri_master
        elem = (self.facets if quadratic else self.triangles)[ids]
        cen = x[elem].mean(axis=1)
        size = float(np.max(np.linalg.norm(x[elem] - cen[:, None, :], axis=2), initial=0.0))
        images = IMAGES if self.lattice is not None else IMAGES[:1]
        shifts = self.lattice.shift(images, np.zeros(6) if h is None else h) if self.lattice is not None \
            else np.zeros((1, 3))
        img = (cen[None] + shifts[:, None]).reshape(-1, 3)
        found = cKDTree(points).sparse_distance_matrix(cKDTree(img), reach + size, output_type="ndarray")
        p = found["i"].astype(np.int64)
        j = found["j"].astype(np.int64)
        nm = len(elem)
        t = ids[j % nm]
        k = images[j // nm]
        sh = shifts[j // nm]
        topo = self.topology
        n_s = point_node[p]
        n_m = elem[j % nm, 0]
        base_s, arc_s = topo.unrolled(n_s, np.zeros(len(p), np.int64))
        base_m, arc_m = topo.unrolled(n_m, k[:, 0])
        same = (topo.strand[n_s] == topo.strand[n_m]) & (k[:, 1] == 0) & (base_s == base_m)
        keep = ~(same & (np.abs(arc_s - arc_m) < self.exclusion))
        return Candidates(p[keep], t[keep], k[keep], sh[keep])


def p2_shape(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic triangle shape functions N (m, 6) and derivatives dN/dξ (m, 6, 2) at ξ (m, 2).

    Node order: corners (0, 0), (1, 0), (0, 1), then edge midpoints 01, 12, 20.
    """
    s, t = xi[:, 0], xi[:, 1]
    l0, l1, l2 = 1.0 - s - t, s, t
    N = np.stack([l0 * (2 * l0 - 1), l1 * (2 * l1 - 1), l2 * (2 * l2 - 1), 4 * l0 * l1, 4 * l1 * l2, 4 * l2 * l0], 1)
    # dλ/dξ: λ0 → (−1, −1), λ1 → (1, 0), λ2 → (0, 1)
    d0, d1, d2 = np.array([-1.0, -1.0]), np.array([1.0, 0.0]), np.array([0.0, 1.0])
    dN = np.stack([
        (4 * l0 - 1)[:, None] * d0, (4 * l1 - 1)[:, None] * d1, (4 * l2 - 1)[:, None] * d2,
        4 * (l1[:, None] * d0 + l0[:, None] * d1), 4 * (l2[:, None] * d1 + l1[:, None] * d2),
        4 * (l0[:, None] * d2 + l2[:, None] * d0),
    ], axis=1)
    return N, dN


def project_p2(p: np.ndarray, Xf: np.ndarray, iterations: int = 8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest points of p (m, 3) on quadratic facets Xf (m, 6, 3) by Gauss-Newton, clipped to the triangle.

    Returns ξ (m, 2), the facet point x(ξ) (m, 3) and the unit normal n(ξ) (m, 3) (orientation of
    the corner order).
    """
    lam = barycentric(p, Xf[:, 0], Xf[:, 1], Xf[:, 2])
    xi = lam[:, 1:].copy()
    for _ in range(iterations):  # Gauss-Newton steps, each vectorised over all points
        xi = _clip_triangle(xi)
        N, dN = p2_shape(xi)
        x = np.einsum("mi,mik->mk", N, Xf)
        J = np.einsum("mia,mik->mka", dN, Xf)  # (m, 3, 2)
        JtJ = np.einsum("mka,mkb->mab", J, J)
        rhs = np.einsum("mka,mk->ma", J, p - x)
        xi = xi + np.linalg.solve(JtJ, rhs[..., None])[..., 0]
    xi = _clip_triangle(xi)
    N, dN = p2_shape(xi)
    x = np.einsum("mi,mik->mk", N, Xf)
    J = np.einsum("mia,mik->mka", dN, Xf)
    n = np.cross(J[:, :, 0], J[:, :, 1])
    return xi, x, n / np.linalg.norm(n, axis=1, keepdims=True)


def _clip_triangle(xi: np.ndarray) -> np.ndarray:
    xi = np.maximum(xi, 0.0)
    s = xi.sum(axis=1)
    over = s > 1.0
    xi[over] /= s[over, None]
    return xi


def facet_gap(p: np.ndarray, Xf: np.ndarray, order: int = 1) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Gap g = n·(p − x(ξ*)) of points p (m, 3) to quadratic facets Xf (m, 6, 3) at the closest point ξ*.

    The gradient is exact at an interior closest point: ∂g/∂p = n, ∂g/∂x_i = −N_i(ξ*) n (the
    terms in ∂ξ*/∂x vanish because p − x(ξ*) ⟂ the facet there). Returns g (m,), dg (m, 7, 3)
    with respect to (p, x_1 … x_6), and the distance |p − x(ξ*)| (m,).
    """
    xi, x, n = project_p2(p, Xf)
    r = p - x
    g = np.einsum("mk,mk->m", n, r)
    dist = np.linalg.norm(r, axis=1)
    if order == 0:
        return g, None, dist
    N, _ = p2_shape(xi)
    dg = np.concatenate([n[:, None, :], -N[:, :, None] * n[:, None, :]], axis=1)
    return g, dg, dist


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - a - t[:, None] * ab, axis=1)


def point_triangle_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, tol: float = 0.0
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m,) from points to triangles, and whether the projection lies inside (barycentric ≥ −tol)."""
    lam = barycentric(p, a, b, c)
    inside = np.all(lam >= -tol, axis=1)
    g = plane_gap(p, a, b, c, order=0)[0]
    edge = np.minimum(np.minimum(_segment_distance(p, a, b), _segment_distance(p, b, c)), _segment_distance(p, c, a))
    return np.where(inside, np.abs(g), edge), inside


def nearest(point: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Row of the smallest ``dist`` for every distinct value of ``point`` (vectorised arg-min per group)."""
    if point.size == 0:
        return np.zeros(0, np.int64)
    order = np.lexsort((dist, point))
    _, first = np.unique(point[order], return_index=True)
    return order[first]


def penalty_terms(g: np.ndarray, dg: np.ndarray, Hg: np.ndarray | None, weight: np.ndarray, stiffness: float,
                  order: int) -> tuple[float, np.ndarray | None, np.ndarray | None]:
    """Energy ½ ε w ⟨−g⟩², its element gradients (m, k, 3) and Hessians (m, k, 3, k, 3) for active pairs.

    ``weight`` (m,) is the slave area each gap stands for (mm²), ``stiffness`` ε in N/mm³.
    """
    pen = np.minimum(g, 0.0)
    E = 0.5 * stiffness * float(np.sum(weight * pen**2))
    if order == 0:
        return E, None, None
    c = stiffness * weight
    grad = (c * pen)[:, None, None] * dg
    if order == 1:
        return E, grad, None
    on = (g < 0).astype(float)
    hess = (c * on)[:, None, None, None, None] * np.einsum("mai,mbj->maibj", dg, dg)
    if Hg is not None:
        hess = hess + (c * pen)[:, None, None, None, None] * Hg
    return E, grad, hess


def scatter(pm: Any, E: float, grad: np.ndarray | None, hess: np.ndarray | None, order: int):
    """Global (E, gradient (n_dof,), Hessian CSR) of element terms through a PointMap."""
    import scipy.sparse as sp

    n = pm.n_dof
    g = pm.gradient(grad) if order >= 1 and grad is not None and len(grad) else (np.zeros(n) if order >= 1 else None)
    H = None
    if order == 2:
        if hess is not None and len(hess):
            r, c, v = pm.hessian_coo(hess)
            H = sp.csr_matrix((v, (r, c)), shape=(n, n))
        else:
            H = sp.csr_matrix((n, n))
    return E, g, H
