"""Geometry shared by the solid contact laws: gaps with exact derivatives, the candidate search, friction.

The contact surface of a tetrahedral mesh is made of linear triangles or quadratic (P2) facets.
The gap of a point p to the plane of a master triangle (a, b, c) is, with d = p − a,
e1 = b − a, e2 = c − a, m = e1 × e2, μ = |m|::

    g = (d · m) / μ                                   (mm; < 0 means penetration)

:func:`plane_gap` returns g with its exact gradient and Hessian in (p, a, b, c). On a curved
quadratic facet x(ξ) = Σ N_i(ξ) x_i the gap is measured from the closest point ξ*,
g = n(ξ*)·(p − x(ξ*)) (:func:`project_p2`, :func:`facet_gap`, with the exact second derivative
of the projection).

Candidate pairs come from a KD-tree broad phase between groups of query points (the quadrature
points of a slave facet, or single nodes) and the master elements' centroids, including the
periodic images k1 L1 + k2 L2 placed under the current F̄ (:class:`knitframe.numerics.periodic.Lattice`);
each pair is kept only when a bounding sphere of the element lies within the search reach of the
point. Pairs of a yarn with a piece of itself closer than an exclusion length along the strand
are dropped with the strand bookkeeping of :class:`knitframe.numerics.contact_search.SegmentTopology`.
Element gradients and Hessians are scattered to q = [u (3N), h (6)] with
:class:`knitframe.numerics.periodic.PointMap`.

Friction (:class:`FrictionState`, :func:`friction_terms`) is the lagged, regularised Coulomb law
shared by both solid laws: the pairs in contact at the last converged state are frozen with their
normal force, normal and the master's material point, and the slip of each slave point against
that material point is resisted by a smooth potential whose force reaches μ·λ.
"""

from __future__ import annotations

import attrs
import numpy as np
from scipy.spatial import cKDTree

from knitframe.errors import NumericalError
from knitframe.numerics.contact_search import IMAGES, SegmentTopology
from knitframe.numerics.periodic import Lattice, PointMap

__all__ = [
    "plane_gap",
    "barycentric",
    "point_triangle_distance",
    "nearest",
    "node_normals",
    "penalty_terms",
    "penalty_depth",
    "combine",
    "rim_edges",
    "assemble",
    "SolidSurface",
    "Candidates",
    "bezier_points",
    "distance_bound",
    "select_pairs",
    "Selection",
    "p2_shape",
    "p2_coefficients",
    "project_p2",
    "P2Projection",
    "facet_gap",
    "p2_gap_derivatives",
    "FrictionState",
    "friction_potential",
    "friction_terms",
    "facet_size",
    "nagata_facets",
    "chain_facet_derivatives",
]


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


def node_normals(x: np.ndarray, triangles: np.ndarray, identify: np.ndarray | None = None) -> np.ndarray:
    """Angle-weighted unit normals (N, 3) at the nodes of a triangle surface (zero off the surface).

    n_a ∝ Σ_t α_t,a n_t over the triangles t at node a, α_t,a the interior angle of t at a
    (Thürmer & Wüthrich 1998): unlike area weights, it does not depend on how the facets were
    split into triangles (a quad's two halves share its corner angle), so on a prism or a swept
    tube the normal at a node is the symmetric one. With ``identify`` (N,), nodes that stand for
    the same node (a periodic seam's end nodes and their start nodes, images of each other by a
    translation) sum their triangles and share one normal, so that the Nagata patches on both
    sides of the seam meet.
    """
    P = x[triangles]  # (T, 3, 3)
    m = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    nt = m / np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-300)
    out = np.zeros_like(x)
    for k in range(3):
        e1 = P[:, (k + 1) % 3] - P[:, k]
        e2 = P[:, (k + 2) % 3] - P[:, k]
        angle = np.arctan2(np.linalg.norm(np.cross(e1, e2), axis=1), _dot(e1, e2))
        np.add.at(out, triangles[:, k], angle[:, None] * nt)
    if identify is not None:
        total = np.zeros_like(out)
        np.add.at(total, identify, out)
        out = total[identify]
    nrm = np.linalg.norm(out, axis=1, keepdims=True)
    return out / np.where(nrm > 0, nrm, 1.0)


def nagata_facets(
    Xt: np.ndarray, nt: np.ndarray, regularisation: float = 1e-2, blocks: bool = True
) -> tuple[np.ndarray, np.ndarray | None]:
    """Quadratic patches over flat triangles that follow given nodal normals (Nagata 2005).

    Each edge (i, j) of a triangle Xt (m, 3, 3) becomes the quadratic curve whose end tangents
    lie in the planes normal to the nodal normals n_i, n_j (nt, (m, 3, 3), unit): its Bézier
    control point is the chord midpoint plus w = W d, d = x_j − x_i, with the least-norm w in
    span(n_i, n_j) that solves n_i·w = −n_i·d/2 and n_j·w = n_j·d/2::

        W = ½ N (M + δI)⁻¹ diag(−1, 1) Nᵀ,   N = [n_i n_j],  M = NᵀN   (δ = ``regularisation``)

    and the patch's Lagrange mid-edge point is ½(x_i + x_j) + ½ W d. On a circle the mid-edge
    point lands within 0.1 % of the radius for 33° between the nodes (the flat chord misses by
    4 %); on a plane (equal normals, n·d = 0) the patch is the flat triangle. Both facets that
    share an edge build the same curve from the same two normals, so the patched surface is
    continuous. For fixed normals the six patch points are linear in the corners,
    X6_k = Σ_c A_kc x_c, with constant 3×3 blocks A (m, 6, 3, 3, 3) [k, c]; A's blocks of a
    row sum to I, so a periodic-image shift carries over to the patch unchanged.

    Returns X6 (m, 6, 3) (corners, then the mid-edge points of 01, 12, 20) and A (None without
    ``blocks``).
    """
    m = Xt.shape[0]
    eye = np.eye(3)
    A = np.zeros((m, 6, 3, 3, 3)) if blocks else None
    for c in range(3 if blocks else 0):
        A[:, c, c] = eye
    X6 = np.empty((m, 6, 3))
    X6[:, :3] = Xt
    for k, (i, j) in zip((3, 4, 5), ((0, 1), (1, 2), (2, 0))):
        ni, nj = nt[:, i], nt[:, j]
        c = _dot(ni, nj)
        a, det = 1.0 + regularisation, (1.0 + regularisation) ** 2 - c * c
        # C = (M + δI)⁻¹ diag(−1, 1)
        C00, C01, C10, C11 = -a / det, -c / det, c / det, a / det
        W = 0.5 * (
            C00[:, None, None] * ni[:, :, None] * ni[:, None, :]
            + C01[:, None, None] * ni[:, :, None] * nj[:, None, :]
            + C10[:, None, None] * nj[:, :, None] * ni[:, None, :]
            + C11[:, None, None] * nj[:, :, None] * nj[:, None, :]
        )
        if blocks:
            A[:, k, i] = 0.5 * (eye - W)
            A[:, k, j] = 0.5 * (eye + W)
        X6[:, k] = 0.5 * (Xt[:, i] + Xt[:, j]) + 0.5 * np.einsum("mab,mb->ma", W, Xt[:, j] - Xt[:, i])
    return X6, A


def chain_facet_derivatives(
    dg: np.ndarray, Hg: np.ndarray | None, A: np.ndarray
) -> tuple[np.ndarray, np.ndarray | None]:
    """Gap derivatives in (slave points, 6 patch points) → (slave points, 3 corners) through X6 = A x.

    dg (m, ks + 6, 3), Hg (m, ks + 6, 3, ks + 6, 3) and A from :func:`nagata_facets`; with B the
    block matrix [I 0; 0 A]: ∂g/∂x = Bᵀ ∂g/∂X and ∂²g/∂x² = Bᵀ (∂²g/∂X²) B (exact: B is constant).
    """
    m, K = dg.shape[:2]
    ks = K - 6
    B = np.zeros((m, K, 3, ks + 3, 3))
    for a in range(ks):
        B[:, a, :, a, :] = np.eye(3)
    B[:, ks:, :, ks:, :] = A.transpose(0, 1, 3, 2, 4)
    Bf = B.reshape(m, 3 * K, 3 * (ks + 3))
    dg_new = np.einsum("mk,mkl->ml", dg.reshape(m, 3 * K), Bf).reshape(m, ks + 3, 3)
    if Hg is None:
        return dg_new, None
    H = Hg.reshape(m, 3 * K, 3 * K)
    H_new = np.matmul(Bf.transpose(0, 2, 1), np.matmul(H, Bf)).reshape(m, ks + 3, 3, ks + 3, 3)
    return dg_new, H_new


@attrs.frozen(eq=False)
class Candidates:
    """Pairs (query point, master element at an image) found by the broad phase."""

    #: (m,) index into the query points
    point: np.ndarray
    #: (m,) master element (linear triangle, or facet with ``quadratic``)
    triangle: np.ndarray
    #: (m, 2) integer image of the master element
    image: np.ndarray
    #: (m, 3) current image shift F̄·S_k, mm
    shift: np.ndarray


def _open_edges(corners: np.ndarray, master: np.ndarray) -> np.ndarray:
    """(E, 3) flags: edge (01, 12, 20) of element e is used by exactly one master element (all False off the master set)."""
    out = np.zeros(corners.shape, bool)
    if len(master) == 0:
        return out
    c = corners[master]
    edges = np.stack([c[:, [0, 1]], c[:, [1, 2]], c[:, [2, 0]]], axis=1)  # (m, 3, 2)
    key = np.sort(edges, axis=2).reshape(-1, 2)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    out[master] = (counts[inverse.ravel()] == 1).reshape(-1, 3)
    return out


@attrs.frozen(eq=False)
class SolidSurface:
    """The contact surface of a solid mesh, with the bookkeeping for self-contact and images.

    ``facets`` are the boundary facets (3 nodes for P1, 6 for P2: corners then edge nodes);
    ``slave`` / ``master`` select which of them act on each side (the same set for two-pass
    self-contact of yarns). ``triangles`` are the facets split into linear triangles (a quadratic
    facet gives four). Nodes carry a strand topology (see
    :class:`knitframe.numerics.contact_search.SegmentTopology`, here one entry per node): pairs on one
    strand copy closer than ``exclusion`` along it are the yarn's own material, not contacts.
    Bodies that are not yarns use their own strand with ``cycle`` 0 and arc 0, so they never
    contact themselves. Build with :meth:`build`.
    """

    n_nodes: int
    #: (N, 3) reference node coordinates, mm
    X: np.ndarray
    #: (F, 3 or 6) node indices, normals outward
    facets: np.ndarray
    #: (Fs,) slave facets
    slave: np.ndarray
    #: (Fm,) master facets
    master: np.ndarray
    #: per node
    topology: SegmentTopology
    #: arc length along a strand within which pairs are ignored, mm
    exclusion: float
    #: periodic lattice (None: no images)
    lattice: Lattice | None
    #: (T, 3) linear triangles of all facets
    triangles: np.ndarray
    #: triangles of the slave facets
    tri_slave: np.ndarray
    #: triangles of the master facets
    tri_master: np.ndarray
    #: (F,) reference facet areas, mm²
    area: np.ndarray
    #: nodes of the slave facets
    slave_nodes: np.ndarray
    #: (N,) reference slave area per node (a third of each slave triangle), mm²
    tributary: np.ndarray
    #: (F, 3) master facets' edges (corners 01, 12, 20) on the master surface's open boundary
    open_facet: np.ndarray
    #: (T, 3) the same for the linear triangles of the master facets
    open_triangle: np.ndarray
    #: (N,) the node each node stands for across a periodic seam (None: itself)
    identify: np.ndarray | None = None

    def open_rim(self, element: np.ndarray, quadratic: bool) -> np.ndarray:
        """(m, 3) open-boundary flags of the edges of master elements (facets with ``quadratic``, else triangles)."""
        return (self.open_facet if quadratic else self.open_triangle)[element]

    @classmethod
    def build(
        cls,
        X: np.ndarray,
        facets: np.ndarray,
        slave: np.ndarray,
        master: np.ndarray,
        topology: SegmentTopology,
        exclusion: float,
        lattice: Lattice | None = None,
        identify: np.ndarray | None = None,
    ) -> SolidSurface:
        """Surface over reference nodes X (N, 3); areas and tributary areas from X.

        ``identify`` (N,): the node each node stands for when counting the master surface's
        edges (a periodic mesh's end nodes → their matched start nodes), so that an edge on a
        periodic seam, continued by the image's facets, is not an open boundary.
        """
        from knitframe.numerics.mesh import split_facets

        facets = np.asarray(facets, np.int64)
        F = len(facets)
        tri = split_facets(facets)
        per = len(tri) // max(F, 1)
        tri_of = lambda f: (np.arange(per)[:, None] * F + np.asarray(f)[None, :]).ravel()  # noqa: E731
        t_area = 0.5 * np.linalg.norm(
            np.cross(X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]), axis=1
        )
        area = t_area.reshape(per, F).sum(axis=0) if F else np.zeros(0)
        ts = tri_of(slave)
        trib = np.zeros(len(X))
        for k in range(3):
            np.add.at(trib, tri[ts, k], t_area[ts] / 3.0)
        ident = np.arange(len(X)) if identify is None else np.asarray(identify, np.int64)
        return cls(
            len(X),
            np.asarray(X, np.float64),
            facets,
            np.asarray(slave, np.int64),
            np.asarray(master, np.int64),
            topology,
            float(exclusion),
            lattice,
            tri,
            ts,
            tri_of(master),
            area,
            np.unique(facets[slave]),
            trib,
            _open_edges(ident[facets[:, :3]], np.asarray(master, np.int64)),
            _open_edges(ident[tri], tri_of(master)),
            None if identify is None else ident,
        )

    def candidates(
        self,
        points: np.ndarray,
        point_node: np.ndarray,
        x: np.ndarray,
        h: np.ndarray | None,
        reach: float,
        *,
        quadratic: bool = False,
        group: int = 1,
    ) -> Candidates:
        """Master elements (with images) that may lie within ``reach`` of each point.

        The master elements are the linear triangles of the master facets, or with ``quadratic``
        the master facets themselves (``Candidates.triangle`` then holds facet indices). A pair
        is kept when |p − c_e| ≤ reach + ρ_e, with c_e the element's centroid and ρ_e the radius
        of a sphere about it that holds the element (its corners for a triangle, the Bézier
        control points of a quadratic facet, whose convex hull holds the curved facet): every
        element point closer than ``reach`` to p is found. The points come in consecutive
        groups of ``group`` (the quadrature points of one slave facet); the KD-tree search runs
        between the groups' centres and the element centroids, then expands to the points.

        Parameters
        ----------
        points : (P, 3) current query points, mm; P a multiple of ``group``.
        point_node : (P,) a node of the query point's own facet, for the self-contact rule.
        x : (N, 3) current node coordinates, mm.
        h : (6,) macro DOFs, or None.
        reach : search distance, mm.
        quadratic : search the master facets (P2) rather than their linear triangles.
        group : points per group (default 1: every point on its own).
        """
        ids = self.master if quadratic else self.tri_master
        elem = (self.facets if quadratic else self.triangles)[ids]
        Xe = x[elem]
        cen = Xe.mean(axis=1)
        hull = bezier_points(Xe) if quadratic else Xe
        rho = np.sqrt(np.max(np.sum((hull - cen[:, None, :]) ** 2, axis=2), axis=1, initial=0.0))
        images = IMAGES if self.lattice is not None else IMAGES[:1]
        shifts = (
            self.lattice.shift(images, np.zeros(6) if h is None else h)
            if self.lattice is not None
            else np.zeros((1, 3))
        )
        n_g = len(points) // group
        pg = points.reshape(n_g, group, 3)
        gc = pg.mean(axis=1)
        g_rho = np.sqrt(np.max(np.sum((pg - gc[:, None, :]) ** 2, axis=2), axis=1, initial=0.0))
        cut = reach + float(rho.max(initial=0.0)) + float(g_rho.max(initial=0.0))
        # element images whose centroid is within the cut of the points' bounding box
        img = cen[None] + shifts[:, None]  # (n_img, n_e, 3)
        if n_g:
            lo, hi = gc.min(axis=0) - cut, gc.max(axis=0) + cut
            k_img, e = np.nonzero(np.all((img >= lo) & (img <= hi), axis=2))
        else:
            k_img, e = np.zeros(0, np.int64), np.zeros(0, np.int64)
        found = cKDTree(gc).sparse_distance_matrix(cKDTree(img[k_img, e]), cut, output_type="ndarray")
        gi = found["i"].astype(np.int64)
        j = found["j"].astype(np.int64)
        close = found["v"] <= reach + g_rho[gi] + rho[e[j]]
        gi, j = gi[close], j[close]
        # expand the groups to their points, keep the points whose own sphere test passes
        p = (gi[:, None] * group + np.arange(group)).ravel()
        j = np.repeat(j, group)
        ke, kk = e[j], k_img[j]
        d2 = np.sum((points[p] - img[kk, ke]) ** 2, axis=1)
        close = d2 <= (reach + rho[ke]) ** 2
        p, ke, kk = p[close], ke[close], kk[close]
        topo = self.topology
        n_s = point_node[p]
        n_m = elem[ke, 0]
        same = (topo.strand[n_s] == topo.strand[n_m]) & (images[kk, 1] == 0)
        s_idx = np.flatnonzero(same)
        base_s, arc_s = topo.unrolled(n_s[s_idx], np.zeros(len(s_idx), np.int64))
        base_m, arc_m = topo.unrolled(n_m[s_idx], images[kk[s_idx], 0])
        keep = np.ones(len(p), bool)
        keep[s_idx[(base_s == base_m) & (np.abs(arc_s - arc_m) < self.exclusion)]] = False
        p, ke, kk = p[keep], ke[keep], kk[keep]
        return Candidates(p, ids[ke], images[kk], shifts[kk])


def bezier_points(Xf: np.ndarray) -> np.ndarray:
    """Bézier control points (m, 6, 3) of quadratic facets Xf (m, 6, 3): corners, and 2 x_ij − (x_i + x_j)/2 on edges.

    The curved facet lies in the convex hull of these points.
    """
    out = Xf.copy()
    for e, (a, b) in zip((3, 4, 5), ((0, 1), (1, 2), (2, 0))):
        out[:, e] = 2.0 * Xf[:, e] - 0.5 * (Xf[:, a] + Xf[:, b])
    return out


def distance_bound(p: np.ndarray, Xe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A lower bound (m,) of the distance from points p (m, 3) to triangles or quadratic facets Xe (m, 3 or 6, 3), mm.

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
    d11, d12, d22 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
    r1, r2 = _dot(d, e1), _dot(d, e2)
    det = d11 * d22 - d12 * d12  # |e1 × e2|²
    l1 = (d22 * r1 - d12 * r2) / det
    l2 = (d11 * r2 - d12 * r1) / det
    l0 = 1.0 - l1 - l2
    # |d|² = g² + |in-plane part|², the in-plane part being l1 e1 + l2 e2
    g2 = np.maximum(_dot(d, d) - (l1 * r1 + l2 * r2), 0.0)
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
        bow = np.stack([np.sqrt(_dot(b, b)) for b in bows], axis=1)
        bound = bound - np.minimum(bow.sum(axis=1), 4.0 / 3.0 * bow.max(axis=1))
    return bound, np.column_stack([l0, l1, l2])


#: largest cosine between a master element's normal and a query point's own normal for a pair (60° off parallel)
OPPOSING = 0.5


@attrs.frozen(eq=False)
class Selection:
    """The master element chosen for each query point (see :func:`select_pairs`)."""

    #: (s,) rows of the candidates, one per point that has an opposing element within reach
    rows: np.ndarray
    #: (s,) signed gap, mm
    g: np.ndarray
    #: closest points on quadratic facets (rows), else None
    projection: P2Projection | None


def select_pairs(
    p: np.ndarray,
    point: np.ndarray,
    element: np.ndarray,
    Xe: np.ndarray,
    normal: np.ndarray,
    reach: float,
    *,
    prescreen: float = 0.2,
    open_rim: np.ndarray | None = None,
    facing: float = OPPOSING,
    corner_normals: np.ndarray | None = None,
) -> Selection:
    """For every query point, the nearest opposing master element of its candidates.

    A candidate (point p, element at its image, nodes Xe) qualifies when the element's normal at
    the closest point is not turned the same way as the point's own ``normal`` (the cosine of
    their angle below ``facing``, default :data:`OPPOSING` = 0.5: a pair is refused only when the
    two normals are within 60° of parallel, where the element is the back of the other body; with
    a bound at 0, the flank of a crossing yarn, whose normal stands at right angles to the
    surface it presses into, flipped in and out of contact from one Newton iterate to the next)
    and the distance is below ``reach``. Per point the rank is the distance (for flat triangles
    plus 2·reach when the closest point is on the element's rim rather than a projection into
    it: their gap is the plane's); equal ranks (an edge or corner shared by several elements, or
    coplanar neighbours; equal within 1e-10·reach, so that round-off does not decide) go to the
    element whose plane faces the point most (largest |g|), then to the lower ``element``.
    The gap is the plane gap of a linear triangle (:func:`plane_gap`) or, on quadratic facets,
    the signed distance g = ±|p − x(ξ*)| to the closest point ξ* (:func:`project_p2`), with the
    sign of n·(p − x*); inside the facet (or on its rim with p − x* along n) that is n·(p − x*).
    Where ξ* is on the rim otherwise, the unit vector ±(p − x*)/|p − x*| is returned as the
    projection's normal n, the gap's gradient direction. Ranked by distance alone, the gap is the signed distance to the master surface and
    stays continuous when the nearest facet changes, also between facets that share only a
    corner (a pair switching between such facets made the energy jump when the gap beyond the
    rim was measured to the facet's polynomial continuation). Only beyond an edge on the master
    surface's open boundary (``open_rim`` (n, 3): the candidates' edges 01, 12, 20 that no other
    master facet continues), the gap is measured to the facet's polynomial continuation, as a
    plane continues a flat triangle, where that has a closest point within 0.5 of the triangle
    whose normal stays within 60° of the corners' plane; the signed distance to an open edge
    would count a point beside the surface as inside the body. The sign of a rim point's gap is
    that of n·(p − x*) with the facet's own normal n, or, given ``corner_normals`` (n, 3, 3: the
    nodal normals at the candidates' corners that shape Nagata patches), with the nodal normals
    interpolated linearly to ξ*: on an edge that is the same vector from both facets sharing it
    (an edge pseudo-normal), so the sign does not depend on which of them is chosen; with the
    facet's own normal, a point in the tangent plane of a facet at its edge had n·(p − x*) ≈ 0
    and its gap flipped between ±distance with round-off. A curved element whose normal at
    the closest point is turned against its corners' plane (a strongly bowed facet folding over
    near its rim) does not qualify.

    Distances are computed where needed only: first for the candidates into which the point
    projects (barycentric coordinates on the corners' plane ≥ −``prescreen``), then for the rest
    unless their :func:`distance_bound` exceeds reach, or the distance of an element already
    found that the point projects into (such a candidate cannot rank first). The choice is the
    one over all candidates.
    """
    quadratic = Xe.shape[1] == 6
    bound, lam = distance_bound(p, Xe)
    near = bound < reach
    first = np.flatnonzero(near & (lam.min(axis=1) >= -prescreen))

    def narrow(rows):
        if quadratic:
            pr = project_p2(p[rows], Xe[rows], lam=lam[rows])
            return pr.dist, pr.n, pr.interior, pr.g, pr
        x = Xe[rows]
        dist, inside, g = point_triangle_distance(p[rows], x[:, 0], x[:, 1], x[:, 2], gap=True)
        return dist, np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), inside, g, None

    # a curved facet's normal at the closest point must keep the orientation of its corners' plane: where a
    # strongly bowed facet folds over near its rim the normal flips, and the "gap" there is not a gap
    m_flat = np.cross(Xe[:, 1] - Xe[:, 0], Xe[:, 2] - Xe[:, 0]) if quadratic else None

    def unfolded(n, rows, limit=0.0):
        return _dot(n, m_flat[rows]) > limit * np.linalg.norm(n, axis=1) * np.linalg.norm(
            m_flat[rows], axis=1
        )

    def facing_ok(n, rows):
        return _dot(n, normal[rows]) < facing * np.linalg.norm(n, axis=1) * np.linalg.norm(
            normal[rows], axis=1
        )

    res1 = narrow(first)
    ok1 = facing_ok(res1[1], first) & (res1[0] < reach)
    if quadratic:
        ok1 &= unfolded(res1[1], first)
    best = np.full(int(point.max(initial=-1)) + 1, np.inf)
    good = np.flatnonzero(ok1 & res1[2])
    win = good[nearest(point[first[good]], res1[0][good])]
    best[point[first[win]]] = res1[0][win]
    rest = near.copy()
    rest[first] = False
    rest = np.flatnonzero(rest & (bound <= best[point]))
    res2 = narrow(rest)
    ok2 = facing_ok(res2[1], rest) & (res2[0] < reach)
    if quadratic:
        ok2 &= unfolded(res2[1], rest)
    rows = np.concatenate([first, rest])
    dist, inside, g = (
        np.concatenate([a, b]) for a, b in ((res1[0], res2[0]), (res1[2], res2[2]), (res1[3], res2[3]))
    )
    ok = np.flatnonzero(np.concatenate([ok1, ok2]))
    # ranks within rounding of each other are ties: compare them on a grid of 1e-10·reach, so
    # that the choice between coplanar neighbours does not flip with round-off
    q = 1e-10 * reach
    rank = np.floor((dist + (0.0 if quadratic else np.where(inside, 0.0, 2.0 * reach))) / q)
    face = np.floor(-np.abs(g) / q)
    chosen = ok[nearest(point[rows[ok]], rank[ok], face[ok], element[rows[ok]])]
    proj, g = None, g[chosen]
    if quadratic:
        fields = [f.name for f in attrs.fields(P2Projection)]
        proj = {f: np.concatenate([getattr(res1[4], f), getattr(res2[4], f)])[chosen] for f in fields}
        # a closest point on the rim: the gap is the signed distance ±|p − x*| (sign of n·(p − x*)),
        # and the unit direction of p − x* takes the normal's place. The gap is then the signed
        # distance to the master surface wherever the point is, continuous when the nearest point
        # passes from one curved facet to another, including facets that share no edge
        rim = np.flatnonzero(~proj["interior"])
        r = p[rows[chosen]] - proj["x"]  # from the closest point to the query point
        # on the rim but along the normal (a point right over an edge or corner): the facet's own gap
        normal_only = np.linalg.norm(
            r[rim] - proj["g"][rim, None] * proj["n"][rim], axis=1
        ) <= 1e-10 * np.maximum(proj["dist"][rim], reach)
        proj["interior"][rim[normal_only]] = True
        rim = rim[~normal_only]
        if open_rim is not None and rim.size:
            # beyond an open edge of the master surface (no facet continues it) the gap is measured to
            # the facet's polynomial continuation, as a plane continues a flat triangle, where that has a
            # closest point near the facet that is not folded over (normal within 60° of the corners' plane)
            xi = proj["xi"][rim]
            beyond = np.flatnonzero(np.any(rim_edges(xi) & open_rim[rows[chosen[rim]]], axis=1))
            if beyond.size:
                rb = rows[chosen[rim[beyond]]]
                ext = project_p2(p[rb], Xe[rb], extend=True, start=xi[beyond])
                valid = ext.interior & unfolded(ext.n, rb, 0.5)
                use = rim[beyond[valid]]
                for f in fields:
                    proj[f][use] = getattr(ext, f)[valid]
                g[use] = ext.g[valid]
                rim = np.setdiff1d(rim, use)
        if rim.size:
            d = proj["dist"][rim]
            r = r[rim]
            side = g[rim]
            if corner_normals is not None:
                xi = proj["xi"][rim]
                bary = np.column_stack([1.0 - xi.sum(axis=1), xi])
                side = _dot(r, np.einsum("mk,mkc->mc", bary, corner_normals[rows[chosen[rim]]]))
            sign = np.where(side < 0.0, -1.0, 1.0)
            ok_d = d > 1e-12 * reach
            unit = np.where(
                ok_d[:, None], r / np.where(ok_d, d, 1.0)[:, None], proj["n"][rim] * sign[:, None]
            )
            proj["n"][rim] = sign[:, None] * unit
            g[rim] = proj["g"][rim] = sign * d
        proj = P2Projection(**proj)
    return Selection(rows[chosen], g, proj)


def p2_shape(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic triangle shape functions N (m, 6) and derivatives dN/dξ (m, 6, 2) at ξ (m, 2).

    Node order: corners (0, 0), (1, 0), (0, 1), then edge midpoints 01, 12, 20.
    """
    s, t = xi[:, 0], xi[:, 1]
    l0 = 1.0 - s - t
    N = np.empty((len(s), 6))
    N[:, 0] = l0 * (2 * l0 - 1)
    N[:, 1] = s * (2 * s - 1)
    N[:, 2] = t * (2 * t - 1)
    N[:, 3] = 4 * l0 * s
    N[:, 4] = 4 * s * t
    N[:, 5] = 4 * t * l0
    dN = np.zeros((len(s), 6, 2))
    dN[:, 0, 0] = dN[:, 0, 1] = -(4 * l0 - 1)
    dN[:, 1, 0] = 4 * s - 1
    dN[:, 2, 1] = 4 * t - 1
    dN[:, 3, 0] = 4 * (l0 - s)
    dN[:, 3, 1] = -4 * s
    dN[:, 4, 0] = 4 * t
    dN[:, 4, 1] = 4 * s
    dN[:, 5, 0] = -4 * t
    dN[:, 5, 1] = 4 * (l0 - t)
    return N, dN


def p2_coefficients(Xf: np.ndarray) -> tuple[np.ndarray, ...]:
    """Monomial coefficients (a0 … a5), each (m, 3), of x(s, t) = a0 + a1 s + a2 t + a3 s² + a4 st + a5 t².

    From the Lagrange nodes Xf (m, 6, 3): a0 = x0, a1 = −3x0 − x1 + 4x3, a2 = −3x0 − x2 + 4x5,
    a3 = 2x0 + 2x1 − 4x3, a4 = 4(x0 − x3 + x4 − x5), a5 = 2x0 + 2x2 − 4x5.
    """
    x0, x1, x2, x3, x4, x5 = (Xf[:, i] for i in range(6))
    return (
        x0,
        -3 * x0 - x1 + 4 * x3,
        -3 * x0 - x2 + 4 * x5,
        2 * x0 + 2 * x1 - 4 * x3,
        4 * (x0 - x3 + x4 - x5),
        2 * x0 + 2 * x2 - 4 * x5,
    )


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


@attrs.frozen(eq=False)
class P2Projection:
    """Closest points of points p on quadratic facets (see :func:`project_p2`)."""

    #: (m, 2) parametric point ξ* in the reference triangle
    xi: np.ndarray
    #: (m, 3) facet point x(ξ*), mm
    x: np.ndarray
    #: (m, 3) tangent ∂x/∂ξ1 at ξ*, mm
    xs: np.ndarray
    #: (m, 3) tangent ∂x/∂ξ2 at ξ*, mm
    xt: np.ndarray
    #: (m, 3) unit normal xs × xt / |xs × xt| (orientation of the corner order)
    n: np.ndarray
    #: (m,) gap n·(p − x), mm
    g: np.ndarray
    #: (m,) |p − x|, mm
    dist: np.ndarray
    #: (m,) ξ* is an unclipped stationary point (p − x ⟂ the facet)
    interior: np.ndarray


def project_p2(
    p: np.ndarray,
    Xf: np.ndarray,
    iterations: int = 30,
    tol: float = 1e-13,
    lam: np.ndarray | None = None,
    *,
    extend: bool = False,
    start: np.ndarray | None = None,
) -> P2Projection:
    """Closest points of p (m, 3) on quadratic facets Xf (m, 6, 3), ξ* in the reference triangle.

    Projected Newton's method on f(ξ) = ½|p − x(ξ)|² from the projection onto the corners'
    plane. With r = p − x(ξ), x_α = ∂x/∂ξ_α and the constant second derivatives x_αβ of the
    quadratic map, the step solves (x_α·x_β − r·x_αβ) Δξ_β = r·x_α (the Gauss-Newton matrix
    x_α·x_β where that is not positive definite). On the triangle's rim the constraints that the
    descent direction r·x_α pushes against are held: along an edge the step is the Newton step of
    f restricted to the edge, at a corner there is none; ξ is clipped to the triangle after each
    step; the start is the plane projection or, if closer, the nearest point of a 28-point lattice
    on the triangle. A step that raises f is halved until it does not, each trial clipped to the
    triangle (a full step of the indefinite or Gauss-Newton model can leave the basin of the
    closest point for a far local minimum on the rim, and the gap then jumps with p); a row that
    finds no lower f is not converged. Rows stop once |Δξ| ≤ ``tol`` (the convergence is
    quadratic, inside and along edges), at most ``iterations``. The point is ``interior`` when it
    converged off the rim: there p − x is along n and the gap n·(p − x) is a smooth function of p and the nodes. ``lam`` (m, 3): the
    barycentric coordinates of p on the corners' plane if already known (the start).

    With ``extend`` the facet's polynomial map is continued beyond the triangle (as a plane
    continues a flat triangle) and Newton runs unconstrained from ``start`` (m, 2); a row is
    ``interior`` when it converges to a minimum with ξ within 0.5 of the triangle.
    """
    m = len(p)
    a0, a1, a2, a3, a4, a5 = p2_coefficients(Xf)
    if start is not None:
        xi = np.array(start, dtype=np.float64)
    else:
        if lam is None:
            lam = barycentric(p, Xf[:, 0], Xf[:, 1], Xf[:, 2])
        xi, _ = _clip_triangle(lam[:, 1:].copy())
        xi = _best_start(p, a0, a1, a2, a3, a4, a5, xi)
    converged = np.zeros(m, bool)
    failed = np.zeros(m, bool)
    act = np.arange(m)
    for _ in range(iterations):
        if act.size == 0:
            break
        s, t = xi[act, 0], xi[act, 1]
        b0, b1, b2, b3, b4, b5, pa = a0[act], a1[act], a2[act], a3[act], a4[act], a5[act], p[act]
        sc, tc = s[:, None], t[:, None]
        xs = b1 + 2.0 * b3 * sc + b4 * tc
        xt = b2 + b4 * sc + 2.0 * b5 * tc
        r = pa - _p2_point((b0, b1, b2, b3, b4, b5), sc, tc)
        G11, G12, G22 = _dot(xs, xs), _dot(xs, xt), _dot(xt, xt)
        H11, H12, H22 = G11 - 2.0 * _dot(r, b3), G12 - _dot(r, b4), G22 - 2.0 * _dot(r, b5)
        det = H11 * H22 - H12 * H12
        gn = ~((H11 > 0) & (det > 1e-12 * G11 * G22))  # not positive definite: Gauss-Newton step
        H11, H12, H22 = np.where(gn, G11, H11), np.where(gn, G12, H12), np.where(gn, G22, H22)
        det = H11 * H22 - H12 * H12
        f1, f2 = _dot(r, xs), _dot(r, xt)  # descent direction −∇f
        ds = (H22 * f1 - H12 * f2) / det
        dt = (H11 * f2 - H12 * f1) / det
        if extend:
            new = np.column_stack([s + ds, t + dt])
            out = gn | (new.min(axis=1) < -0.5) | (new.sum(axis=1) > 1.5)  # no minimum near the triangle
            failed[act[out]] = True
        else:
            # rim constraints the descent pushes against: s ≥ 0, t ≥ 0, s + t ≤ 1
            bs, bt, bst = (s <= 0.0) & (f1 < 0), (t <= 0.0) & (f2 < 0), (s + t >= 1.0 - 1e-14) & (f1 + f2 > 0)
            nb = bs.astype(np.int8) + bt + bst
            # one held constraint: Newton along its edge, tangent τ = (0, 1), (1, 0) or (−1, 1)
            ts = np.where(bs, 0.0, np.where(bt, 1.0, -1.0))
            tt = np.where(bt, 0.0, 1.0)
            curv = ts * ts * H11 + 2.0 * ts * tt * H12 + tt * tt * H22
            curv = np.where(curv > 0, curv, ts * ts * G11 + 2.0 * ts * tt * G12 + tt * tt * G22)
            step = (ts * f1 + tt * f2) / np.where(curv > 0, curv, 1.0)
            edge = nb == 1
            ds = np.where(edge, step * ts, np.where(nb > 1, 0.0, ds))
            dt = np.where(edge, step * tt, np.where(nb > 1, 0.0, dt))
            new, _ = _clip_triangle(np.column_stack([s + ds, t + dt]))
            out = np.zeros(len(s), bool)
        # globalised: a step must not raise f (the step is halved otherwise, each trial clipped to the
        # triangle); a full step of the indefinite or Gauss-Newton model can leave the basin of the
        # closest point for a far local minimum on the rim, and the gap then jumps with p
        f0 = 0.5 * _dot(r, r)
        full = np.max(np.abs(new - xi[act]), axis=1)
        new, stuck = _descend(
            pa, b0, b1, b2, b3, b4, b5, xi[act], np.column_stack([ds, dt]), f0, ~out, clip=not extend
        )
        # no point along a step longer than tol lowers f: not a minimum, so not converged
        out |= stuck & (full > tol)
        moved = np.max(np.abs(new - xi[act]), axis=1)
        xi[act[~out]] = new[~out]
        done = (moved <= tol) & ~out
        converged[act[done]] = True
        act = act[~(done | out)]
    s, t = xi[:, 0:1], xi[:, 1:2]
    x = _p2_point((a0, a1, a2, a3, a4, a5), s, t)
    xs = a1 + 2.0 * a3 * s + a4 * t
    xt = a2 + a4 * s + 2.0 * a5 * t
    nv = np.cross(xs, xt)
    nn = np.linalg.norm(nv, axis=1)
    if not np.all(nn > 0):
        raise NumericalError("solid contact: a quadratic facet is degenerate (zero area element)")
    n = nv / nn[:, None]
    r = p - x
    if extend:
        inner = ~failed
    else:
        inner = (xi[:, 0] > 0.0) & (xi[:, 1] > 0.0) & (xi[:, 0] + xi[:, 1] < 1.0 - 1e-14)
    return P2Projection(xi, x, xs, xt, n, _dot(n, r), np.linalg.norm(r, axis=1), converged & inner)


def _p2_point(a, s, t):
    """x(ξ) = a0 + a1 s + a2 t + a3 s² + a4 s t + a5 t² of a quadratic facet's coefficients a (:func:`p2_coefficients`)."""
    a0, a1, a2, a3, a4, a5 = a
    return a0 + (a1 + a3 * s + a4 * t) * s + (a2 + a5 * t) * t


#: barycentric lattice (order 6, 28 points) of the start search on curved facets
_START_GRID = np.array([(i / 6.0, j / 6.0) for i in range(7) for j in range(7 - i)])


def _best_start(p, a0, a1, a2, a3, a4, a5, xi) -> np.ndarray:
    """The start of the closest-point search: ``xi`` or the point of a 28-point lattice on the
    triangle with the smallest distance, whichever is closer. On a strongly bowed facet the
    distance has several local minima and flat indefinite regions; from the plane projection
    alone Newton can take 20 iterations to leave them, or settle on a far minimum."""
    s, t = _START_GRID[None, :, 0:1], _START_GRID[None, :, 1:2]
    x = _p2_point(tuple(a[:, None] for a in (a0, a1, a2, a3, a4, a5)), s, t)
    f = np.einsum("mkc,mkc->mk", p[:, None] - x, p[:, None] - x)
    k = f.argmin(axis=1)
    s0, t0 = xi[:, 0:1], xi[:, 1:2]
    r0 = p - _p2_point((a0, a1, a2, a3, a4, a5), s0, t0)
    use = f[np.arange(len(p)), k] < _dot(r0, r0)
    out = xi.copy()
    out[use] = _START_GRID[k[use]]
    return out


def _descend(p, a0, a1, a2, a3, a4, a5, xi, step, f0, rows, *, clip: bool, halvings: int = 30):
    """Points ξ + α·``step`` (clipped to the triangle with ``clip``) of the selected ``rows``, α = 1, ½, ¼, …,
    the first at which f(ξ) = ½|p − x(ξ)|² does not exceed f0 (within round-off); a row that finds none
    keeps ξ and is flagged in the returned mask ``stuck``. The trials are clipped one by one rather than
    halving the way to the clipped full step: near an edge that chord is not a descent direction, and the
    iteration crept along it for 25 iterations (the accepted steps were round-off)."""
    new = xi.copy()
    todo = np.flatnonzero(rows)
    alpha = 1.0
    for _ in range(halvings + 1):
        if todo.size == 0:
            break
        trial = xi[todo] + alpha * step[todo]
        if clip:
            trial, _ = _clip_triangle(trial)
        s, t = trial[:, 0:1], trial[:, 1:2]
        r = p[todo] - _p2_point(tuple(a[todo] for a in (a0, a1, a2, a3, a4, a5)), s, t)
        ok = 0.5 * _dot(r, r) <= f0[todo] * (1.0 + 1e-12) + 1e-300
        new[todo[ok]] = trial[ok]
        todo = todo[~ok]
        alpha *= 0.5
    stuck = np.zeros(len(xi), bool)
    stuck[todo] = True
    return new, stuck


def _clip_triangle(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ξ clipped to the reference triangle (in place), and which rows were clipped."""
    neg = xi < 0.0
    xi = np.maximum(xi, 0.0, out=xi)
    s = xi.sum(axis=1)
    over = s > 1.0
    xi[over] /= s[over, None]
    return xi, np.any(neg, axis=1) | over


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
    b[:, 0, 0] = 2.0 * _dot(pr.n, a3)
    b[:, 0, 1] = b[:, 1, 0] = _dot(pr.n, a4)
    b[:, 1, 1] = 2.0 * _dot(pr.n, a5)
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


def rim_edges(xi: np.ndarray) -> np.ndarray:
    """(m, 3) flags: the parametric point ξ (m, 2) lies on the triangle's edge 01 (t = 0), 12 (s + t = 1), 20 (s = 0)."""
    return np.column_stack([xi[:, 1] <= 0.0, xi.sum(axis=1) >= 1.0 - 1e-14, xi[:, 0] <= 0.0])


def _rim_gap_hessian(
    pr: P2Projection,
    rows: np.ndarray,
    U: np.ndarray,
    V: np.ndarray,
    a3: np.ndarray,
    a4: np.ndarray,
    a5: np.ndarray,
) -> np.ndarray:
    """∂²g (k, K, 3, K, 3) of the signed distance at closest points on the rim (see :func:`p2_gap_derivatives`)."""
    k, K = U.shape
    g, n = pr.g[rows], pr.n[rows]
    on = rim_edges(pr.xi[rows])
    edge = on.sum(axis=1) == 1
    # the edge's direction in ξ: 01 (t = 0) → (1, 0), 12 (s + t = 1) → (−1, 1), 20 (s = 0) → (0, 1)
    tau = np.where(on[:, [0]], [1.0, 0.0], np.where(on[:, [1]], [-1.0, 1.0], [0.0, 1.0]))
    x_tau = tau[:, :1] * pr.xs[rows] + tau[:, 1:] * pr.xt[rows]
    x_tt = 2.0 * tau[:, :1] ** 2 * a3 + 2.0 * tau[:, :1] * tau[:, 1:] * a4 + 2.0 * tau[:, 1:] ** 2 * a5
    r = g[:, None] * n
    A = _dot(x_tau, x_tau) - _dot(r, x_tt)
    P = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
    H = np.einsum("ma,mb,mij->maibj", U, U, P)
    V_tau = tau[:, 0, None] * V[:, 0] + tau[:, 1, None] * V[:, 1]  # (k, K)
    e = U[:, :, None] * x_tau[:, None, :] + V_tau[:, :, None] * r[:, None, :]
    use = edge & (A > 1e-12 * _dot(x_tau, x_tau))
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


def nearest(point: np.ndarray, dist: np.ndarray, *ties: np.ndarray) -> np.ndarray:
    """Row of the smallest ``dist`` for every distinct value of ``point`` (vectorised arg-min per group).

    Equal distances (a point nearest to an edge or corner shared by several elements) are
    decided by the smallest of ``ties[0]``, then ``ties[1]`` …, then by the row order.
    """
    if point.size == 0:
        return np.zeros(0, np.int64)
    order = np.lexsort((*reversed(ties), dist, point))
    _, first = np.unique(point[order], return_index=True)
    return order[first]


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


def combine(
    key: np.ndarray, grad: list[np.ndarray] | None, hess: list[np.ndarray] | None
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Sum the element terms of rows that share ``key`` (same nodes and images) before scattering.

    ``grad`` and ``hess`` are lists of arrays whose rows, one after the other, match ``key``
    (None for none). Returns the first row of each group (to pick its nodes and images) and the
    summed gradients and Hessians; fewer, larger elements make a smaller sparse assembly. The
    sums are sparse (groups × rows) 0/1 matrix products: one pass over the element arrays.
    """
    import scipy.sparse as sp

    _, first, inv = np.unique(key, return_index=True, return_inverse=True)

    def total(parts):
        if parts is None:
            return None
        out, off = np.zeros((len(first), int(np.prod(parts[0].shape[1:])))), 0
        for a in parts:
            m = len(a)
            if m:
                A = sp.csr_matrix((np.ones(m), (inv[off : off + m], np.arange(m))), shape=(len(first), m))
                out = out + A @ a.reshape(m, -1)
            off += m
        return out.reshape((len(first),) + parts[0].shape[1:])

    return first, total(grad), total(hess)


def assemble(
    n_nodes: int,
    lattice: Lattice | None,
    E: float,
    terms: list[tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]],
    order: int,
):
    """Global (E, gradient (n_dof,), Hessian CSR) of element terms ``(nodes, images, grad, hess)``.

    Each term has m elements of k points: nodes (m, k), images (m, k, 2), grad (m, k, 3) and
    hess (m, k, 3, k, 3). The gradient is scattered through :class:`knitframe.numerics.periodic.PointMap`
    (u_a and, at a periodic image, h through the reference shift S of the point: p = x + F̄·S).
    The Hessian is assembled in 3×3 node blocks: an element with a point at an image gets the
    six macro DOFs h as two more "nodes" (n_nodes, n_nodes + 1, matching the DOF order
    q = [u (3N), h (6)]), with the blocks Jᵀ H J of J = [I | M], M (3k, 6) the image weights;
    the blocks of all terms are summed by (row, column) node and converted to CSR once.
    """
    import scipy.sparse as sp

    n = 3 * n_nodes + 6
    if order == 0:
        return E, None, None
    G = np.zeros(n)
    blocks: list[tuple[np.ndarray, np.ndarray]] = []
    for nodes, images, grad, hess in terms:
        if len(nodes) == 0:
            continue
        pm = PointMap(n_nodes, nodes, images, lattice)
        G += pm.gradient(grad)
        if order < 2:
            continue
        m, k = nodes.shape
        sel = pm.imaged
        plain = ~sel
        blocks.append((pm.nodes[plain], hess[plain]))
        if np.any(sel):
            ms, k3 = int(sel.sum()), 3 * k
            Hl = hess[sel].reshape(ms, k3, k3)
            S = pm.weights[sel][..., 1:].reshape(ms, k3, 2)
            M = np.zeros((ms, k3, 6))
            for c in range(3):
                M[:, c::3, 2 * c : 2 * c + 2] = S[:, c::3, :]
            HM = Hl @ M
            Hx = np.empty((ms, k3 + 6, k3 + 6))
            Hx[:, :k3, :k3] = Hl
            Hx[:, :k3, k3:] = HM
            Hx[:, k3:, :k3] = HM.transpose(0, 2, 1)
            Hx[:, k3:, k3:] = M.transpose(0, 2, 1) @ HM
            nx = np.column_stack([pm.nodes[sel], np.full(ms, n_nodes), np.full(ms, n_nodes + 1)])
            blocks.append((nx, Hx.reshape(ms, k + 2, 3, k + 2, 3)))
    if order == 1:
        return E, G, None
    nb = n_nodes + 2
    rows, cols, data = [], [], []
    for nodes, hess in blocks:
        m, k = nodes.shape
        rows.append(np.broadcast_to(nodes[:, :, None], (m, k, k)).ravel())
        cols.append(np.broadcast_to(nodes[:, None, :], (m, k, k)).ravel())
        data.append(hess.transpose(0, 1, 3, 2, 4).reshape(-1, 3, 3))
    if not rows:
        return E, G, sp.csr_matrix((n, n))
    key = np.concatenate(rows) * nb + np.concatenate(cols)
    data = np.concatenate(data)
    srt = np.argsort(key, kind="stable")
    key = key[srt]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    vals = np.add.reduceat(data[srt], start, axis=0)
    ukey = key[start]
    indptr = np.zeros(nb + 1, np.int64)
    np.cumsum(np.bincount(ukey // nb, minlength=nb), out=indptr[1:])
    H = sp.bsr_matrix((vals, ukey % nb, indptr), shape=(n, n)).tocsr()
    return E, G, H


# -- friction ------------------------------------------------------------------------------------------------


def facet_size(surface: SolidSurface) -> np.ndarray:
    """Reference size of every facet (F,): the mean length of its three corner-to-corner edges, mm."""
    X = surface.X[surface.facets[:, :3]]
    return (
        np.linalg.norm(X[:, 1] - X[:, 0], axis=1)
        + np.linalg.norm(X[:, 2] - X[:, 1], axis=1)
        + np.linalg.norm(X[:, 0] - X[:, 2], axis=1)
    ) / 3.0


@attrs.frozen(eq=False)
class FrictionState:
    """Contact pairs of the last converged state, frozen for the lagged friction of the next increment.

    A pair is a slave point (a node for ``penalty``, a quadrature point of a slave facet for
    ``mortar``) pressed with normal force λ against a master element at an image. The slave
    point's position and the master's material point under it are both linear in the nodes,
    c = Σ_a w_a p_a over the pair's points p_a = x_a (+ the image shift F̄·S_k on the master
    side), with weights ``weights``: the slave shape functions, then minus the master's at the
    frozen parametric point ``xi``. ``offset`` is c at the frozen state.
    """

    #: (m,) slave node (penalty) or slave facet (mortar)
    slave: np.ndarray
    #: (m,) quadrature point on the slave facet (mortar), −1 for a node
    point: np.ndarray
    #: (m,) master element: linear triangle, or facet on quadratic mortar surfaces
    master: np.ndarray
    #: (m, 2) integer image of the master element
    image: np.ndarray
    #: (m, 2) parametric point of the projection on the master element, -
    xi: np.ndarray
    #: (m,) normal force λ = ε·w·⟨−g⟩ of the pair at the frozen state, N
    force: np.ndarray
    #: (m, 3) unit master normal at the projection
    normal: np.ndarray
    #: (m,) reference size of the slave element, mm
    size: np.ndarray
    #: (m, k) nodes of the pair: slave side, then master side
    nodes: np.ndarray
    #: (m, k, 2) images of those nodes
    images: np.ndarray
    #: (m, k) c = Σ_a w_a p_a, slave point minus master material point
    weights: np.ndarray
    #: (m, 3) c at the frozen state, mm
    offset: np.ndarray

    def __len__(self) -> int:
        return int(self.force.shape[0])


def friction_potential(
    u: np.ndarray, mu_lam: np.ndarray, eps: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Regularised Coulomb potential D (m,), its gradient (m, 3) and Hessian (m, 3, 3) in the slip u (m, 3).

    With y = |u|/ε_s::

        D = μλ ε_s f0(y),   f0(y) = y² − y³/3 (y < 1),  y − 1/3 (y ≥ 1)
        ∇D = μλ φ(y) û,     φ(y) = 2y − y² (y < 1),  1 (y ≥ 1)

    so the friction force rises smoothly (C¹) from 0 with the stick stiffness 2μλ/ε_s and reaches
    the Coulomb force μλ at the slip ε_s. ``mu_lam`` (m,) is μλ (N) and ``eps`` (m,) ε_s (mm).
    D is convex in u; no division by |u| happens at zero slip.
    """
    n = np.linalg.norm(u, axis=1)
    y = n / eps
    stick = y < 1.0
    D = mu_lam * eps * np.where(stick, y**2 - y**3 / 3.0, y - 1.0 / 3.0)
    safe = np.where(n > 0, n, 1.0)
    uh = u / safe[:, None]
    coef = np.where(stick, mu_lam * (2.0 - y) / eps, mu_lam / safe)
    g = coef[:, None] * u
    eye = np.eye(3)
    uu = uh[:, :, None] * uh[:, None, :]
    H_stick = (mu_lam / eps)[:, None, None] * ((2.0 - y)[:, None, None] * eye - y[:, None, None] * uu)
    H_slip = (mu_lam / safe)[:, None, None] * (eye - uu)
    return D, g, np.where(stick[:, None, None], H_stick, H_slip)


def friction_terms(
    state: FrictionState,
    x: np.ndarray,
    h: np.ndarray | None,
    lattice: Lattice | None,
    mu: float,
    slip: float,
    order: int,
) -> tuple[float, np.ndarray | None, np.ndarray | None, dict]:
    """Lagged regularised Coulomb friction of frozen pairs: energy, element gradients and Hessians.

    For each pair the relative position c = Σ_a w_a p_a of the slave point and the master's
    material point (at the frozen parametric point, with the current image shift F̄·S_k) has
    slipped by c − c₀ since the frozen state; its tangential part with respect to the frozen
    normal n is u_T = (I − n nᵀ)(c − c₀), and::

        D = Σ_pairs μ λ ε_s f0(|u_T| / ε_s),       ε_s = slip · ℓ

    (:func:`friction_potential`, ℓ the pair's element ``size``). c is linear in the nodes, so
    ∂D/∂p_a = w_a P ∇D and ∂²D/∂p_a∂p_b = w_a w_b P ∇²D P, exactly. Returns E (N·mm), grad
    (m, k, 3), hess (m, k, 3, k, 3) and {"slipping": pairs past ε_s, "force": Σ|∇D| N}.
    """
    p = x[state.nodes]
    if lattice is not None:
        p = p + lattice.shift(state.images, np.zeros(6) if h is None else h)
    c = np.einsum("mk,mki->mi", state.weights, p)
    nrm = state.normal
    d = c - state.offset
    u = d - _dot(d, nrm)[:, None] * nrm
    eps = slip * state.size
    D, gu, Hu = friction_potential(u, mu * state.force, eps)
    E = float(np.sum(D))
    if not np.isfinite(E):
        raise NumericalError("solid contact: non-finite friction energy")
    gc = gu - _dot(gu, nrm)[:, None] * nrm  # P ∇D
    info = {
        "slipping": int(np.count_nonzero(np.linalg.norm(u, axis=1) >= eps)),
        "friction_force": float(np.sum(np.linalg.norm(gc, axis=1))),
    }
    if order == 0:
        return E, None, None, info
    w = state.weights
    grad = w[:, :, None] * gc[:, None, :]
    if order == 1:
        return E, grad, None, info
    P = np.eye(3)[None] - nrm[:, :, None] * nrm[:, None, :]
    Hc = P @ Hu @ P
    ww = w[:, :, None] * w[:, None, :]
    hess = ww[:, :, None, :, None] * Hc[:, None, :, None, :]
    return E, grad, hess, info
