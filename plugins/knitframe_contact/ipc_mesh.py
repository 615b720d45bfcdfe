"""The periodic collision mesh of the ``ipc`` contact law: the cell's surface and its images for ipctk.

The cell's surface and its periodic images (the shifts F̄·S_k of :mod:`knitframe.numerics.periodic`,
S_k = k1 L1 + k2 L2) form one collision mesh whose vertices are (node, image) pairs
(:class:`PeriodicCollisionMesh`); vertex positions are affine in q = [u (3N), h (6)] through
the constant sparse map ``P``. The mesh also keeps each edge's periodic class, so that the
broad phase counts each periodic class of pairs once, and the own-material filter of
self-contact. :func:`collision_mesh` caches one mesh per surface.
"""

from __future__ import annotations

import contextlib
import itertools
from collections.abc import Iterator
from typing import Any

import numpy as np
import scipy.sparse as sp

from knitframe.errors import NumericalError
from knitframe.numerics.periodic import N_MACRO, macro_index

#: staggered binnings of the own-material exclusion (pairs within (1 − 1/n) × exclusion along a strand
#: excluded)
EXCLUSION_BINNINGS = 4

__all__ = ["PeriodicCollisionMesh", "collision_mesh", "ipctk_module", "one_thread", "EXCLUSION_BINNINGS"]


def ipctk_module():
    """The ipctk module, or a NumericalError that says how to install it."""
    try:
        import ipctk
    except ImportError as e:  # the volumetric extra
        raise NumericalError("contact law 'ipc' needs ipctk: pip install \"knitframe[volumetric]\"") from e
    return ipctk


@contextlib.contextmanager
def one_thread() -> Iterator[Any]:
    """ipctk (the module) held to one thread inside the block, its thread count restored after it.

    On several threads ipctk's results depend on how the work fell to them: the broad phase lists its
    candidates, and the collisions built from them, in an order that varies from run to run, and the
    energy, gradient and Hessian are sums over thread-local parts; so the contact forces, and through the
    Newton path a whole curve, differ between two runs in the last bits and then further. On one thread
    they are the same bit for bit.
    """
    ipctk = ipctk_module()
    threads = ipctk.get_num_threads()
    if threads == 1:
        yield ipctk
        return
    ipctk.set_num_threads(1)
    try:
        yield ipctk
    finally:
        ipctk.set_num_threads(threads)


class PeriodicCollisionMesh:
    """The cell's surface with its periodic images as one ipctk collision mesh.

    Vertices are (canonical node, image k) pairs, those of the central image first
    (``n_center``); ``node`` and ``image`` hold them. ``P`` maps q = [u (3N), h (6)] to the
    stacked vertex positions minus ``V_rest`` (mm).
    """

    def __init__(self, surface, ring: int = 2, margin: float = 0.35):
        ipctk = ipctk_module()
        X = surface.X
        N = surface.n_nodes
        canon = np.arange(N) if surface.identify is None else np.asarray(surface.identify, np.int64)
        lat = surface.lattice
        tri = np.asarray(surface.triangles, np.int64)
        k_node, images, grow = _lattice_images(X, N, canon, tri, lat, ring, margin)
        node, kk, center, faces = _image_faces(X, canon, tri, k_node, images, lat, grow)
        used = np.zeros(len(node), bool)
        used[faces.ravel()] = True
        used |= center
        order = np.flatnonzero(used)[np.argsort(~center[used], kind="stable")]  # central image first
        rank = np.full(len(node), -1, np.int64)
        rank[order] = np.arange(len(order))
        self.node = node[order]
        self.image = kk[order]
        self.n_center = int(center.sum())
        self.faces = rank[faces].astype(np.int32)
        shift = np.zeros((len(self.node), 3)) if lat is None else lat.reference_shift(self.image)
        #: the vertices' reference image shifts S_k (V, 3), mm: fixed, kept for :meth:`positions`
        self.reference_shift = shift
        self.V_rest = X[self.node] + shift
        self.n_nodes = N
        self.P = _dof_map(self.node, self.image, N, lat)
        self.PT = self.P.T.tocsr()
        self.lattice = lat
        edges = ipctk.edges(self.faces)
        self.mesh = ipctk.CollisionMesh(self.V_rest, edges, self.faces)
        self.mesh.can_collide = ipctk.make_static_obstacle_filter(self.n_center)
        own = self.own_material_filter(surface)
        if own is not None:
            self.mesh.can_collide = self.mesh.can_collide & own
        self.edges = np.asarray(self.mesh.edges)
        self._classify_edges(N)
        #: the last broad-phase search (positions, candidates, d̂, reuse reach) kept by
        #: SolidIPC._collisions, and how many searches ran
        self.held = None
        self.searches = 0
        # mean edge length of the cell's own surface (each triangle edge once per triangle), mm
        corners = X[tri]
        self.edge_length = float(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).mean())

    def _classify_edges(self, N: int) -> None:
        """Each edge's periodic class (``edge_class``: its two canonical nodes and their relative image),
        the image of its first end (``edge_image``) and whether it is owned (``edge_owned``)."""
        # the owner: the translate whose first end (the smaller canonical node) lies in the central image
        a, b = self.edges[:, 0], self.edges[:, 1]
        swap = (self.node[a] > self.node[b]) | ((self.node[a] == self.node[b]) & (b < a))
        first, second = np.where(swap, b, a), np.where(swap, a, b)
        rel = self.image[second] - self.image[first]
        w = 2 * int(np.abs(rel).max(initial=0)) + 1
        self.edge_class = (
            ((self.node[first] * N + self.node[second]) * w + rel[:, 0] + w // 2) * w + rel[:, 1] + w // 2
        )
        self.edge_image = self.image[first]
        self.edge_owned = np.all(self.image[first] == 0, axis=1)

    def own_material_filter(self, surface, n_bins: int = EXCLUSION_BINNINGS):
        """ipctk filter of the pairs of a yarn with its own material: vertices of one strand copy within
        the surface's ``exclusion`` along it never collide (None when nothing is excluded).

        A vertex (node n, image k) lies on strand copy (strand, k₂, base) at unrolled arc a
        (:meth:`knitframe.numerics.contact_search.SegmentTopology.unrolled`). ipctk filters by vertex patches
        (equivalence classes), so the exclusion is ``n_bins`` staggered binnings of a into bins of
        length ℓ = exclusion, offset by ℓ/n_bins: a pair is excluded when its two vertices share a bin
        in any binning. A pair |Δa| < (1 − 1/n_bins)·ℓ apart shares one (its interval holds at most
        n_bins − 1 bin boundaries, each of another binning); a pair ≥ ℓ apart shares none. So pairs
        within 0.75 × exclusion (n_bins = 4) are always excluded and pairs beyond it never, as the
        ``penalty`` and ``mortar`` laws exclude them: where a transversely soft tube is squashed, its
        surface folds onto itself, and barrier pairs between the folds (a tube's own material, not a
        contact) had stalled the Newton steps. ipctk keeps an edge–edge or face–vertex candidate when
        any of its vertex pairs may collide, so pairs straddling a bin are kept.
        """
        ipctk = ipctk_module()
        topo, excl = surface.topology, float(surface.exclusion)
        if topo is None or not excl > 0.0:
            return None
        base, arc = topo.unrolled(self.node, self.image[:, 0])
        copy = np.column_stack([topo.strand[self.node], self.image[:, 1], base])
        if not np.isfinite(excl):  # no self-contact: a strand copy never meets itself
            _, pid = np.unique(copy, axis=0, return_inverse=True)
            return ipctk.make_vertex_patches_filter(pid.astype(np.int32).reshape(-1, 1))
        out = None
        for j in range(n_bins):
            bins = np.floor(arc / excl + j / n_bins).astype(np.int64)
            _, pid = np.unique(np.column_stack([copy, bins]), axis=0, return_inverse=True)
            f = ipctk.make_vertex_patches_filter(pid.astype(np.int32).reshape(-1, 1))
            out = f if out is None else out & f
        return out

    def positions(self, x: np.ndarray, h: np.ndarray | None) -> np.ndarray:
        """Vertex positions (nv, 3) for node positions x (N, 3) and macro DOFs h."""
        V = np.asarray(x)[self.node]
        if self.lattice is not None:  # the images' shifts F̄·S_k = S_k + H·S_k (Lattice.shift, S_k kept)
            S = self.reference_shift
            V = V + (S + self.lattice.affine(S, np.zeros(N_MACRO) if h is None else h))
        return np.asfortranarray(V)

    def displacement(self, dx: np.ndarray, dh: np.ndarray | None) -> np.ndarray:
        """Vertex displacements (nv, 3) for node displacements dx (N, 3) and a macro step dh."""
        dV = np.asarray(dx)[self.node]
        if self.lattice is not None and dh is not None:  # the images' shifts move by ΔH·S_k
            dV = dV + self.lattice.affine(self.reference_shift, dh)
        return dV

    def candidates(self, V: np.ndarray, inflation: float):
        """Broad-phase candidates within ``inflation`` of each other, one representative per periodic class.

        A point–triangle pair is kept when its point lies in the central image (each class of
        pairs has exactly one such translate). An edge–edge pair {e1, e2} is kept in the translate
        where the edge of the smaller canonical id (its end nodes and their relative image) is
        owned, i.e. has its first end node (the smaller canonical node) in the central image;
        between an edge and its own image, the translate whose second edge lies on the positive
        side. The energy then counts each periodic pair once, whatever the reduced pair type
        (point–edge, point–point) its distance takes: a weight per reduced pair would jump where
        the type switches.
        """
        ipctk = ipctk_module()
        cand = ipctk.Candidates()
        cand.build(self.mesh, V, inflation)
        out = ipctk.Candidates()
        fv = cand.fv_candidates  # each access converts ipctk's whole vector to a new list
        if fv:
            keep = _ids(fv, ipctk.FaceVertexCandidate.vertex_id) < self.n_center
            out.fv_candidates = list(itertools.compress(fv, keep.tolist()))
        ee = cand.ee_candidates
        if ee:
            a = _ids(ee, ipctk.EdgeEdgeCandidate.edge0_id)
            b = _ids(ee, ipctk.EdgeEdgeCandidate.edge1_id)
            ca, cb = self.edge_class[a], self.edge_class[b]
            oa, ob = self.edge_owned[a], self.edge_owned[b]
            d = self.edge_image[b] - self.edge_image[a]
            pos = (d[:, 0] > 0) | ((d[:, 0] == 0) & (d[:, 1] > 0))
            neg = (d[:, 0] < 0) | ((d[:, 0] == 0) & (d[:, 1] < 0))
            keep = np.where(ca < cb, oa, np.where(ca > cb, ob, (oa & pos) | (ob & neg)))
            out.ee_candidates = list(itertools.compress(ee, keep.tolist()))
        if cand.ev_candidates or cand.vv_candidates:  # pragma: no cover - only for codimensional meshes
            raise NumericalError(
                "ipc: edge–vertex and vertex–vertex candidates (codimensional surfaces) are not supported"
            )
        return out


def _ids(objs: list, attribute: property) -> np.ndarray:
    """(len(objs),) int64 array of one integer attribute of ipctk candidates, read through the property's
    getter (no attribute lookup per object, no intermediate tuples)."""
    return np.fromiter(map(attribute.fget, objs), np.int64, len(objs))


_CACHE: dict[int, tuple[Any, PeriodicCollisionMesh]] = {}


def collision_mesh(surface) -> PeriodicCollisionMesh:
    """The (cached) periodic collision mesh of a solid contact surface."""
    hit = _CACHE.get(id(surface))
    if hit is not None and hit[0] is surface:
        return hit[1]
    pcm = PeriodicCollisionMesh(surface)
    if len(_CACHE) > 8:
        _CACHE.clear()
    _CACHE[id(surface)] = (surface, pcm)
    return pcm


def _lattice_images(
    X: np.ndarray, N: int, canon: np.ndarray, tri: np.ndarray, lat, ring: int, margin: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """The lattice images of a periodic surface (see :class:`PeriodicCollisionMesh`).

    Returns each node's image relative to the node it stands for (N, 2), the images (n, 2) within
    ``ring`` whose copy of the surface overlaps the surface's bounding box grown by ``margin`` of the
    longer lattice vector (nearest first), and that growth (mm). Without a lattice: no shift and the
    central image alone.
    """
    if lat is None:
        return np.zeros((N, 2), np.int64), np.zeros((1, 2), np.int64), 0.0
    L = np.column_stack([lat.L1[:2], lat.L2[:2]])
    k_node = np.rint(np.linalg.solve(L, (X - X[canon])[:, :2].T).T).astype(np.int64)
    if np.abs(lat.reference_shift(k_node) - (X - X[canon])).max() > 1e-6 * (1.0 + np.abs(X).max()):
        raise NumericalError("ipc: an identified node is not a lattice image of the node it stands for")
    used = np.unique(canon[tri])
    lo, hi = X[used].min(axis=0), X[used].max(axis=0)
    grow = margin * max(np.linalg.norm(lat.L1), np.linalg.norm(lat.L2))
    r = range(-ring, ring + 1)
    cand = np.array([(a, b) for a in r for b in r], np.int64)
    S = lat.reference_shift(cand)
    overlap = np.all(
        (lo[None, :2] + S[:, :2] <= hi[:2] + grow) & (hi[None, :2] + S[:, :2] >= lo[:2] - grow),
        axis=1,
    )
    images = cand[overlap]
    images = images[np.argsort(np.abs(images).sum(axis=1), kind="stable")]
    return k_node, images, grow


def _image_faces(
    X: np.ndarray,
    canon: np.ndarray,
    tri: np.ndarray,
    k_node: np.ndarray,
    images: np.ndarray,
    lat,
    grow: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The vertices (canonical node, image) of every image's triangles and the triangles over them.

    Returns the vertices' canonical nodes (V,) and images (V, 2), whether each lies in the central
    image (V,), and the triangles (F, 3) over the vertices, without those far from the central image.
    """
    # every image's triangles, their corners mapped to (canonical node, image)
    c_all = np.broadcast_to(canon[tri][None], (len(images),) + tri.shape)
    k_all = images[:, None, None, :] + k_node[tri][None]
    span = int(np.abs(k_all).max(initial=0)) + 1
    width = 2 * span + 1
    key = (c_all * width + (k_all[..., 0] + span)) * width + (k_all[..., 1] + span)
    uniq, inv = np.unique(key.ravel(), return_inverse=True)
    node = uniq // (width * width)
    kk = np.column_stack([(uniq // width) % width - span, uniq % width - span])
    center = (kk[:, 0] == 0) & (kk[:, 1] == 0)
    faces = inv.reshape(-1, 3)
    if lat is not None:
        # image triangles far from the central image only cost time: keep those with a corner in
        # the central image or within the margin of its bounding box (reference positions)
        Vr = X[node] + lat.reference_shift(kk)
        lo, hi = Vr[center].min(axis=0) - grow, Vr[center].max(axis=0) + grow
        near = center | np.all((Vr >= lo) & (Vr <= hi), axis=1)
        faces = faces[near[faces].any(axis=1)]
    return node, kk, center, faces


def _dof_map(node: np.ndarray, image: np.ndarray, N: int, lat) -> sp.csr_matrix:
    """P (3V, 3N + 6): the vertex positions V = X + u + S_k + H·S_k of vertices (``node``, ``image``)
    minus their rest positions, as a linear map of q = [u (3N), h (6)]."""
    nv = len(node)
    rows = np.arange(3 * nv)
    cols = (3 * node[:, None] + np.arange(3)[None, :]).ravel()
    blocks = [sp.csr_matrix((np.ones(3 * nv), (rows, cols)), shape=(3 * nv, 3 * N + N_MACRO))]
    if lat is not None:
        S = lat.reference_shift(image)  # ∂V_i/∂H_ij = S_k,j
        r_, c_, d_ = [], [], []
        for i in range(3):
            for j in range(2):
                r_.append(3 * np.arange(nv) + i)
                c_.append(np.full(nv, 3 * N + macro_index(i, j)))
                d_.append(S[:, j])
        blocks.append(
            sp.csr_matrix(
                (np.concatenate(d_), (np.concatenate(r_), np.concatenate(c_))),
                shape=(3 * nv, 3 * N + N_MACRO),
            )
        )
    return sum(blocks[1:], blocks[0]).tocsr()
