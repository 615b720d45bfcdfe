"""The contact surface of a solid mesh and its broad phase.

:class:`SolidSurface` holds the boundary facets of a tetrahedral mesh (linear triangles or
quadratic P2 facets), which of them act as slave and master, reference areas, the strand
bookkeeping for self-contact and the periodic lattice. Its :meth:`SolidSurface.candidates` is
the broad phase: a KD-tree search between groups of query points (the quadrature points of a
slave facet, or single nodes) and the master elements' centroids, including the periodic
images k1 L1 + k2 L2 placed under the current F̄ (:class:`knitframe.numerics.periodic.Lattice`);
each pair is kept only when a bounding sphere of the element lies within the search reach of
the point. Pairs of a yarn with a piece of itself closer than an exclusion length along the
strand are dropped with the strand bookkeeping of
:class:`knitframe.numerics.contact_search.SegmentTopology`.
"""

from __future__ import annotations

import attrs
import numpy as np
from scipy.spatial import cKDTree

from knitframe.numerics.contact_search import IMAGES, SegmentTopology
from knitframe.numerics.periodic import Lattice

__all__ = ["Candidates", "SolidSurface", "bezier_points", "facet_size"]


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
    """(E, 3) flags: edge (01, 12, 20) of element e is used by exactly one master element (all False
    off the master set)."""
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
        """(m, 3) open-boundary flags of the edges of master elements (facets with ``quadratic``,
        else triangles)."""
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
        img = cen[None] + shifts[:, None]  # (n_img, n_e, 3)
        p, ke, kk = _sphere_pairs(points, group, img, rho, reach)
        keep = self._not_own_material(point_node[p], elem[ke, 0], images[kk])
        p, ke, kk = p[keep], ke[keep], kk[keep]
        return Candidates(p, ids[ke], images[kk], shifts[kk])

    def _not_own_material(self, n_s: np.ndarray, n_m: np.ndarray, image: np.ndarray) -> np.ndarray:
        """Which pairs of slave nodes n_s (m,) and master nodes n_m (m,) at master images ``image`` (m, 2)
        are not the yarn's own material: not on one strand copy closer than ``exclusion`` along it."""
        topo = self.topology
        same = (topo.strand[n_s] == topo.strand[n_m]) & (image[:, 1] == 0)
        s_idx = np.flatnonzero(same)
        base_s, arc_s = topo.unrolled(n_s[s_idx], np.zeros(len(s_idx), np.int64))
        base_m, arc_m = topo.unrolled(n_m[s_idx], image[s_idx, 0])
        keep = np.ones(len(n_s), bool)
        keep[s_idx[(base_s == base_m) & (np.abs(arc_s - arc_m) < self.exclusion)]] = False
        return keep


def _sphere_pairs(
    points: np.ndarray, group: int, img: np.ndarray, rho: np.ndarray, reach: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs of query points and element images within ``reach`` of the element's bounding sphere.

    ``points`` (P, 3) come in consecutive groups of ``group``; ``img`` (n_img, n_e, 3) holds the
    element centroids at each image and ``rho`` (n_e,) the radii of their bounding spheres. The KD-tree
    search runs between the groups' centres and the element centroids, then expands to the points.
    Returns the point rows, elements and image indices of the pairs (see
    :meth:`SolidSurface.candidates`).
    """
    n_g = len(points) // group
    pg = points.reshape(n_g, group, 3)
    gc = pg.mean(axis=1)
    g_rho = np.sqrt(np.max(np.sum((pg - gc[:, None, :]) ** 2, axis=2), axis=1, initial=0.0))
    cut = reach + float(rho.max(initial=0.0)) + float(g_rho.max(initial=0.0))
    # element images whose centroid is within the cut of the points' bounding box
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
    return p[close], ke[close], kk[close]


def bezier_points(Xf: np.ndarray) -> np.ndarray:
    """Bézier control points (m, 6, 3) of quadratic facets Xf (m, 6, 3): corners, and
    2 x_ij − (x_i + x_j)/2 on edges.

    The curved facet lies in the convex hull of these points.
    """
    out = Xf.copy()
    for e, (a, b) in zip((3, 4, 5), ((0, 1), (1, 2), (2, 0)), strict=True):
        out[:, e] = 2.0 * Xf[:, e] - 0.5 * (Xf[:, a] + Xf[:, b])
    return out


def facet_size(surface: SolidSurface) -> np.ndarray:
    """Reference size of every facet (F,): the mean length of its three corner-to-corner edges, mm."""
    X = surface.X[surface.facets[:, :3]]
    return (
        np.linalg.norm(X[:, 1] - X[:, 0], axis=1)
        + np.linalg.norm(X[:, 2] - X[:, 1], axis=1)
        + np.linalg.norm(X[:, 0] - X[:, 2], axis=1)
    ) / 3.0
