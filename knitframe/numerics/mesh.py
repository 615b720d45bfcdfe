"""Volumetric tube meshes of yarn centerlines: swept cross-sections split into tetrahedra.

A yarn of radius r around a centerline C(s) (s = arc length) is meshed by sweeping one
triangulated unit disc (meshed once by gmsh, element size ``seed``·r) along C on a
rotation-minimising frame (N, B)::

    x(s, ξ, η) = C(s) + r (ξ N(s) + η B(s)),        (ξ, η) in the unit disc

Layers are equally spaced in arc length, about ``seed``·r apart. Each prism between two layers is
split into three tetrahedra by the *minimum vertex index* rule (every quadrilateral face is cut
by the diagonal through its smallest global vertex index), which makes neighbouring prisms agree
on their shared faces, so there are no hanging faces. Everything after the frame recursion is
vectorised over layers and elements.

Why a sweep and not gmsh's OCC pipe: the pipe along looping centerlines was slow and fragile, and a
sweep gives end faces that coincide node for node by construction when the frame's twist is
closed around each yarn cycle of the unit cell (end of yarn i continues as the start of yarn j
shifted by L1).

P2 meshes are isoparametric (``skfem.MeshTet2``): mid-edge nodes are placed on the exact swept
geometry (half-layer frames, mid-section points pushed onto the circle on the lateral surface),
so the tube surface is curved rather than polygonal.
"""

from __future__ import annotations

import functools
import time
from typing import Any

import attrs
import numpy as np

from knitframe.errors import GeometryError

__all__ = [
    "Section",
    "CellMesh",
    "section_mesh",
    "arc_length_samples",
    "cell_mesh",
    "mesh_quality",
    "surface_facets",
    "split_facets",
]


@attrs.frozen(eq=False)
class Section:
    """Triangulated unit disc: the cross-section swept along every yarn."""

    #: (n, 2) coordinates in the unit disc, -
    points: np.ndarray
    #: (m, 3) vertex indices, counter-clockwise
    triangles: np.ndarray
    #: (n,) bool, vertex on the unit circle
    boundary: np.ndarray
    #: (k, 2) sorted vertex pairs of the circle's edges
    boundary_edges: np.ndarray


@functools.lru_cache(maxsize=16)
def section_mesh(h: float) -> Section:
    """Unit disc meshed by gmsh with target element size ``h`` (fraction of the radius).

    Boundary vertices are projected exactly onto the unit circle, triangles are oriented
    counter-clockwise and vertices are renumbered in reverse Cuthill-McKee order so that the
    swept mesh has a small bandwidth.
    """
    try:
        import gmsh
    except ImportError:  # pragma: no cover - gmsh is a dependency
        raise GeometryError("meshing needs gmsh: pip install gmsh") from None
    if not 0.02 <= h <= 1.5:
        raise GeometryError(f"mesh seed must be in [0.02, 1.5] radii, got {h}")
    started = gmsh.isInitialized()
    if not started:
        gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("knitframe-section")
        gmsh.model.occ.addDisk(0.0, 0.0, 0.0, 1.0, 1.0)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.Algorithm", 6)  # Frontal-Delaunay: near-equilateral triangles
        gmsh.model.mesh.generate(2)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, _, enodes = gmsh.model.mesh.getElements(2)
        gmsh.model.remove()
    finally:
        if not started:
            gmsh.finalize()
    pts_all = xyz.reshape(-1, 3)[:, :2]
    lookup = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    lookup[tags.astype(np.int64)] = np.arange(tags.size)
    tri = lookup[np.asarray(enodes[0], dtype=np.int64).reshape(-1, 3)]
    used = np.unique(tri)
    remap = np.full(pts_all.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    pts, tri = pts_all[used], remap[tri]
    # Reverse Cuthill-McKee keeps the swept system's bandwidth small for the direct solvers.
    import scipy.sparse as sp
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    n = pts.shape[0]
    e = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    adj = sp.coo_matrix((np.ones(e.shape[0]), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    perm = np.asarray(reverse_cuthill_mckee(adj + adj.T, symmetric_mode=True))
    inv = np.empty(n, dtype=np.int64)
    inv[perm] = np.arange(n)
    pts, tri = pts[perm], inv[tri]
    d1, d2 = pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]]
    area2 = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    tri[area2 < 0] = tri[area2 < 0][:, [0, 2, 1]]
    edges = np.sort(tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    bedges = uniq[count == 1]
    boundary = np.zeros(n, dtype=bool)
    boundary[bedges.ravel()] = True
    pts[boundary] /= np.linalg.norm(pts[boundary], axis=1, keepdims=True)
    for a in (pts, tri, boundary, bedges):
        a.setflags(write=False)
    return Section(pts, tri, boundary, bedges)


def arc_length_samples(centerline: Any, n: int, *, resolution: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Parameters t_k of n + 1 points equally spaced in arc length, and their arc lengths s_k.

    The arc length s(t) = ∫ |r'(τ)| dτ is integrated with Simpson's rule on ``resolution`` · n
    sub-intervals and inverted by monotone interpolation; points are then exact on the curve.

    Returns
    -------
    t, s : (n + 1,) arrays; t[0] = t0, t[-1] = t1, s in mm.
    """
    m = 2 * max(resolution * n, 256)
    tf = np.linspace(centerline.t0, centerline.t1, m + 1)
    speed = np.linalg.norm(np.asarray(centerline.derivative(tf), dtype=np.float64), axis=1)
    dt = tf[2] - tf[0]
    pieces = dt / 6.0 * (speed[:-2:2] + 4.0 * speed[1:-1:2] + speed[2::2])
    s_even = np.concatenate([[0.0], np.cumsum(pieces)])
    t_even = tf[::2]
    total = s_even[-1]
    if not np.isfinite(total) or total <= 0:
        raise GeometryError(
            f"yarn '{getattr(centerline, 'name', '?')}': centerline has no finite positive length"
        )
    s = np.linspace(0.0, total, n + 1)
    t = np.interp(s, s_even, t_even)
    t[0], t[-1] = centerline.t0, centerline.t1
    return t, s


@attrs.frozen(eq=False)
class CellMesh:
    """Tetrahedral mesh of the yarns of a unit cell, with the data the solid solver needs.

    "Nodes" are the mesh's interpolation points: the vertices for P1, the vertices followed by
    one point per edge for P2 (the order of ``skfem`` dofs, so vector dof ``3·node + k``).
    """

    #: skfem.MeshTet1 (order 1) or skfem.MeshTet2 (order 2)
    mesh: Any
    #: polynomial order, 1 or 2
    order: int
    #: tube radius, mm
    radius: float
    #: target element size as a fraction of the radius, -
    seed: float
    #: yarn names
    names: tuple[str, ...]
    #: (n_yarns,) centerline arc lengths, mm
    lengths: np.ndarray
    #: (N, 3) reference node coordinates, mm
    nodes: np.ndarray
    #: (N,) yarn index of each node
    node_body: np.ndarray
    #: (N,) arc length of the node's section along its yarn, mm
    node_arc: np.ndarray
    #: (N, 3) unit centerline tangent at the node's section
    node_tangent: np.ndarray
    #: (N, 3) node minus centerline point (transverse offset), mm
    node_offset: np.ndarray
    #: (n_elements,) yarn index of each tetrahedron
    element_body: np.ndarray
    #: (M, 3) P1 or (M, 6) P2 node indices of the lateral-surface facets, outward
    surface: np.ndarray
    #: (M,) yarn index of each surface triangle
    surface_body: np.ndarray
    #: (end nodes, start nodes, shift (3,)): x_end = x_start + shift
    end_pairs: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]
    #: :class:`knitframe.geometry.Clearance` found before meshing (None if unchecked)
    clearance: Any = None
    #: seconds spent per meshing step
    timings: dict[str, float] = attrs.Factory(dict)

    @property
    def n_nodes(self) -> int:
        return int(self.nodes.shape[0])

    @property
    def n_elements(self) -> int:
        return int(self.mesh.t.shape[1])

    def summary(self) -> str:
        """One-line description for provenance."""
        return (
            f"P{self.order} tetrahedra, seed r/{1 / self.seed:.3g}, {self.n_elements} elements, "
            f"{self.n_nodes} nodes, {3 * self.n_nodes} DOFs"
        )


def _prism_tets(tri: np.ndarray, n2d: int, n_layers: int) -> np.ndarray:
    """Tetrahedra (4, 3·m·n_layers) of swept prisms split by the minimum-vertex-index rule.

    With the 2-D vertices of a triangle sorted a < b < c and top copies a', b', c' (index + n2d,
    so every top index exceeds every bottom one), each quadrilateral face is cut through its
    smallest vertex: (a, b', ), (a, c'), (b, c'). The three tetrahedra that respect those cuts
    are (a, b, c, c'), (a, b, c', b') and (a, b', c', a').
    """
    a, b, c = np.sort(tri, axis=1).T
    off = (np.arange(n_layers) * n2d)[:, None]
    A, B, C = a + off, b + off, c + off
    A2, B2, C2 = A + n2d, B + n2d, C + n2d
    tets = np.stack(
        [
            np.stack([A, B, C, C2]),
            np.stack([A, B, C2, B2]),
            np.stack([A, B2, C2, A2]),
        ],
        axis=1,
    )  # (4, 3, n_layers, m)
    return tets.reshape(4, -1)


def _frames_at(cell: Any, ts: dict[int, np.ndarray], refine: int = 16) -> dict[int, tuple]:
    """Closed rotation-minimising frames of :func:`knitframe.geometry.frames` at parameters ``ts``.

    The geometry's frames are sampled uniformly in t, ``refine`` times finer than ``ts``; the
    normal is interpolated linearly in t, then made orthogonal to the exact tangent. At t0 and t1
    the geometry's own frames are returned unchanged, so paired end faces coincide.
    """
    from knitframe.geometry import frames

    n = refine * max(t.size for t in ts.values())
    out = {}
    for iy, fr in enumerate(frames(cell, n)):
        t = ts[iy]
        y = cell.yarns[iy]
        x = np.asarray(y.position(t), dtype=np.float64)
        d = np.asarray(y.derivative(t), dtype=np.float64)
        T = d / np.linalg.norm(d, axis=1, keepdims=True)
        N = np.stack([np.interp(t, fr.t, fr.normal[:, k]) for k in range(3)], axis=1)
        N -= np.einsum("ij,ij->i", N, T)[:, None] * T
        N /= np.linalg.norm(N, axis=1, keepdims=True)
        N[0], N[-1] = fr.normal[0], fr.normal[-1]
        T[0], T[-1] = fr.tangent[0], fr.tangent[-1]
        x[0], x[-1] = fr.x[0], fr.x[-1]
        out[iy] = (x, T, N, np.cross(T, N))
    return out


def _check_clearance(cell: Any, radius: float, min_distance: float | None, ts: dict[int, np.ndarray]) -> Any:
    """Refuse centerlines that cross (closer than ``min_distance``, default r) or fold (curvature
    radius < r)."""
    from knitframe.geometry import clearance

    for iy, t in ts.items():
        y = cell.yarns[iy]
        d1 = np.asarray(y.derivative(t), dtype=np.float64)
        eps = 1e-6 * (y.t1 - y.t0)
        d2 = (np.asarray(y.derivative(t + eps)) - np.asarray(y.derivative(t - eps))) / (2.0 * eps)
        kappa = np.linalg.norm(np.cross(d1, d2), axis=1) / np.linalg.norm(d1, axis=1) ** 3
        if kappa.max() * radius > 1.0:
            raise GeometryError(
                f"yarn '{y.name}' bends with radius {1.0 / kappa.max():.4g} mm, tighter than the tube radius "
                f"{radius:.4g} mm: the swept tube would fold over itself"
            )
    if len(cell.end_pairs) == 0:
        return None
    cl = clearance(cell)
    limit = radius if min_distance is None else float(min_distance)
    if cl.minimum < limit:
        a, b = (cell.yarns[i].name for i in cl.closest.yarns)
        raise GeometryError(
            f"centerlines of yarns '{a}' and '{b}' (image {cl.closest.image}) come "
            f"{cl.minimum:.4g} mm close, under the limit {limit:.4g} mm: the tubes cross; loosen the stitch "
            "or reduce the yarn radius"
        )
    return cl


def cell_mesh(
    cell: Any,
    *,
    radius: float | None = None,
    seed: float = 1.0 / 3.0,
    order: int = 1,
    check: bool = True,
    min_distance: float | None = None,
) -> CellMesh:
    """Mesh every yarn of a unit cell as a swept tube.

    Parameters
    ----------
    cell : :class:`knitframe.geometry.UnitCell` (yarn centerlines, L1, L2, end_pairs, radius).
    radius : tube radius r, mm; default ``cell.radius`` (dk/2).
    seed : element size as a fraction of r (r/3 by default, as in the paper).
    order : 1 (``MeshTet1``) or 2 (isoparametric ``MeshTet2``).
    check : refuse crossing or folding centerlines (:class:`~knitframe.errors.GeometryError`)
        before meshing; tubes that merely overlap (closer than 2r) are accepted, since the
        pre-stress step resolves that interference. The clearance found is in ``timings``'s
        companion ``CellMesh.clearance``.
    min_distance : centerline distance under which the tubes count as crossing, mm; default r.
    """
    import skfem

    yarns = cell.yarns
    radius = float(cell.radius if radius is None else radius)
    if order not in (1, 2):
        raise GeometryError(f"mesh order must be 1 or 2, got {order}")
    if not radius > 0:
        raise GeometryError(f"yarn radius must be > 0, got {radius}")
    end_pairs = tuple((int(i), int(j)) for i, j in cell.end_pairs)
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    sec = section_mesh(float(seed))
    timings["section"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    layers, ts, ss, lengths = _layer_samples(yarns, seed * radius)
    timings["sampling"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    clear = _check_clearance(cell, radius, min_distance, ts) if check else None
    timings["clearance"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    frames = _frames_at(cell, ts)
    timings["frames"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    v = _sweep(sec, layers, frames, ss, radius)
    mesh1 = skfem.MeshTet1(v["P"].T.copy(), v["tets"], sort_t=False)
    if order == 2:
        mid = _mid_edge_nodes(mesh1, sec, v, frames, ss, radius)
        nodes = np.vstack([v["P"], mid["x"]])
        arc, tang, offs, body = (np.concatenate([v[k], mid[k]]) for k in ("arc", "tang", "offs", "body"))
        mesh = skfem.MeshTet2(nodes.T.copy(), v["tets"], sort_t=False)
        lay_n = np.concatenate([v["lay"], 0.5 * mid["lmid2"]])
    else:
        mesh, nodes = mesh1, v["P"]
        arc, tang, offs, body = v["arc"], v["tang"], v["offs"], v["body"]
        lay_n = v["lay"].astype(float)
    timings["sweep"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    tri = _lateral_surface(mesh1, mesh, sec, v)
    pairs = _end_pairs(cell, end_pairs, nodes, body, lay_n, layers)
    timings["surface_and_pairs"] = time.perf_counter() - t0
    return CellMesh(
        mesh=mesh,
        order=order,
        radius=float(radius),
        seed=float(seed),
        names=tuple(y.name for y in yarns),
        lengths=np.asarray(lengths),
        nodes=nodes,
        node_body=body,
        node_arc=arc,
        node_tangent=tang,
        node_offset=offs,
        element_body=v["ebody"],
        surface=tri,
        surface_body=body[tri[:, 0]],
        end_pairs=tuple(pairs),
        clearance=clear,
        timings=timings,
    )


def _layer_samples(yarns: Any, h: float) -> tuple[list[int], dict, dict, list[float]]:
    """Layers of every yarn (about ``h`` mm apart, at least 3) and the parameters t and arc lengths s of
    twice as many samples (the layers and the half layers), with the yarns' arc lengths (mm)."""
    layers, ts, ss, lengths = [], {}, {}, []
    for iy, y in enumerate(yarns):
        _, s_probe = arc_length_samples(y, 64, resolution=16)
        layers.append(max(int(np.ceil(s_probe[-1] / h)), 3))
        t, s = arc_length_samples(y, 2 * layers[iy])
        ts[iy], ss[iy] = t, s
        lengths.append(s[-1])
    return layers, ts, ss, lengths


def _sweep(sec: Section, layers: list[int], frames: dict, ss: dict, radius: float) -> dict[str, np.ndarray]:
    """The swept vertices and tetrahedra of all yarns (vertices layer-major, section index minor).

    Returns a dict of the vertices' positions ``P`` (V, 3), arc lengths ``arc``, centerline
    tangents ``tang``, transverse offsets ``offs``, yarn ``body``, layer ``lay`` and section index
    ``sidx``, the tetrahedra ``tets`` (4, n_el) and their yarn ``ebody``.
    """
    n2d = sec.points.shape[0]
    P, arc, tang, offs, body, ebody, tets, lay, sidx = [], [], [], [], [], [], [], [], []
    vstart = 0
    for iy in range(len(layers)):
        x, T, N, B = frames[iy]
        xv, Tv, Nv, Bv = x[::2], T[::2], N[::2], B[::2]
        nl = layers[iy]
        off = radius * (
            sec.points[None, :, 0, None] * Nv[:, None, :] + sec.points[None, :, 1, None] * Bv[:, None, :]
        )
        P.append((xv[:, None, :] + off).reshape(-1, 3))
        offs.append(off.reshape(-1, 3))
        arc.append(np.repeat(ss[iy][::2], n2d))
        tang.append(np.repeat(Tv, n2d, axis=0))
        body.append(np.full((nl + 1) * n2d, iy))
        lay.append(np.repeat(np.arange(nl + 1), n2d))
        sidx.append(np.tile(np.arange(n2d), nl + 1))
        tets.append(_prism_tets(sec.triangles, n2d, nl) + vstart)
        ebody.append(np.full(3 * sec.triangles.shape[0] * nl, iy))
        vstart += (nl + 1) * n2d
    out = {
        k: np.concatenate(a)
        for k, a in zip(
            ("P", "arc", "tang", "offs", "body", "lay", "sidx"),
            (P, arc, tang, offs, body, lay, sidx),
            strict=True,
        )
    }
    out["tets"], out["ebody"] = np.concatenate(tets, axis=1), np.concatenate(ebody)
    return out


def _mid_edge_nodes(
    mesh1: Any, sec: Section, v: dict[str, np.ndarray], frames: dict, ss: dict, radius: float
) -> dict[str, np.ndarray]:
    """The P2 mid-edge nodes of the swept mesh ``mesh1`` on the exact swept geometry: half-layer frames,
    mid-section points pushed onto the circle on the lateral surface.

    Returns a dict of their positions ``x`` (n_edges, 3), arc lengths ``arc``, tangents ``tang``,
    offsets ``offs``, yarn ``body`` and twice their half-layer index ``lmid2``.
    """
    n2d = sec.points.shape[0]
    sidx, lay, body = v["sidx"], v["lay"], v["body"]
    edges = mesh1.edges  # (2, n_edges)
    ea, eb = edges
    yb = body[ea]
    lmid2 = lay[ea] + lay[eb]  # twice the half-layer index: index into the fine samples
    xi = 0.5 * (sec.points[sidx[ea]] + sec.points[sidx[eb]])
    same = sidx[ea] == sidx[eb]
    key = np.sort(np.stack([sidx[ea], sidx[eb]], 1), axis=1)
    bkey = sec.boundary_edges[:, 0] * n2d + sec.boundary_edges[:, 1]
    on_circle = np.isin(key[:, 0] * n2d + key[:, 1], bkey) | (same & sec.boundary[sidx[ea]])
    xi[on_circle] /= np.linalg.norm(xi[on_circle], axis=1, keepdims=True)
    xm = np.empty((edges.shape[1], 3))
    Tm = np.empty_like(xm)
    om = np.empty_like(xm)
    am = np.empty(edges.shape[1])
    for iy in range(len(ss)):  # per yarn, vectorised over its edges
        sel = yb == iy
        x, T, N, B = frames[iy]
        k = lmid2[sel]
        o = radius * (xi[sel, 0, None] * N[k] + xi[sel, 1, None] * B[k])
        xm[sel] = x[k] + o
        Tm[sel], om[sel], am[sel] = T[k], o, ss[iy][k]
    return {"x": xm, "arc": am, "tang": Tm, "offs": om, "body": yb, "lmid2": lmid2}


def _lateral_surface(mesh1: Any, mesh: Any, sec: Section, v: dict[str, np.ndarray]) -> np.ndarray:
    """The lateral surface's facets (M, 3 or 6), outward: the boundary facets of ``mesh1`` with all
    vertices on the circle, not lying in one end layer (node numbering of ``mesh``)."""
    sidx, lay = v["sidx"], v["lay"]
    bf_idx = mesh1.boundary_facets()
    bf = mesh1.facets[:, bf_idx]
    onc = sec.boundary[sidx[bf]].all(axis=0)
    cap = (lay[bf] == lay[bf[0]]).all(axis=0)
    return surface_facets(mesh, bf_idx[onc & ~cap])


def _end_pairs(
    cell: Any,
    end_pairs: tuple[tuple[int, int], ...],
    nodes: np.ndarray,
    body: np.ndarray,
    lay_n: np.ndarray,
    layers: list[int],
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """The end faces' node pairs: the last layer of yarn i against the first layer of yarn j (shifted
    by L1) for every end pair (i, j), paired by KD-tree; a GeometryError where they do not coincide."""
    from scipy.spatial import cKDTree

    yarns = cell.yarns
    pairs = []
    for i, j in end_pairs:
        end = np.flatnonzero((body == i) & (lay_n == layers[i]))
        start = np.flatnonzero((body == j) & (lay_n == 0))
        shift = np.asarray(cell.L1, dtype=np.float64)
        dist, idx = cKDTree(nodes[start] + shift).query(nodes[end])
        tol = 1e-9 * max(1.0, float(np.abs(nodes).max()))
        if end.size != start.size or dist.max() > tol:
            raise GeometryError(
                f"end face of yarn '{yarns[i].name}' does not match the start of '{yarns[j].name}' "
                f"shifted by L1 (max distance {dist.max():.3g} mm); the centerlines must continue into "
                "each other"
            )
        pairs.append((end, start[idx], shift.copy()))
    return pairs


def surface_facets(mesh: Any, facets: np.ndarray) -> np.ndarray:
    """Boundary ``facets`` as node arrays, normals outward: (M, 3) for P1, (M, 6) for P2.

    Node numbering as in :class:`CellMesh` (P2: vertices, then one node per edge). A quadratic
    facet lists its corners v0, v1, v2 and then its edge nodes e01, e12, e20.
    """
    facets = np.asarray(facets, dtype=np.int64)
    tri = mesh.facets[:, facets].T.copy()
    x = mesh.p.T
    # outward: away from the centroid of the facet's (only) tetrahedron
    tet = mesh.f2t[0, facets]
    inward = x[mesh.t[:, tet]].mean(axis=0) - x[tri].mean(axis=1)
    nrm = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
    flip = np.einsum("ij,ij->i", nrm, inward) > 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    if not isinstance(mesh, _mesh_tet2()):
        return tri
    nv = mesh.nvertices
    ekey = np.sort(mesh.edges, axis=0)
    ekey = ekey[0] * nv + ekey[1]
    order_e = np.argsort(ekey)

    def edge_node(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        k = np.minimum(a, b) * nv + np.maximum(a, b)
        return nv + order_e[np.searchsorted(ekey, k, sorter=order_e)]

    v0, v1, v2 = tri.T
    return np.column_stack([v0, v1, v2, edge_node(v0, v1), edge_node(v1, v2), edge_node(v2, v0)])


def split_facets(facets: np.ndarray) -> np.ndarray:
    """Linear triangles of facets (M, 3) → themselves, (M, 6) → their 4 sub-triangles (4M, 3), block-wise.

    Sub-triangle k of facet f is row k·M + f: the three corner triangles, then the middle one.
    """
    if facets.shape[1] == 3:
        return facets
    v0, v1, v2, e01, e12, e20 = facets.T
    return np.concatenate(
        [np.stack(s, axis=1) for s in ((v0, e01, e20), (e01, v1, e12), (e20, e12, v2), (e01, e12, e20))]
    )


def _mesh_tet2() -> type:
    import skfem

    return skfem.MeshTet2


def mesh_quality(cm: CellMesh) -> dict[str, float]:
    """Quality of a cell mesh: angles, aspect ratio, Jacobians and volume against π r² L.

    Returns a dict with ``min_dihedral_deg`` / ``max_dihedral_deg`` (over all tetrahedra, straight-
    sided corners), ``max_aspect_ratio`` (circumradius / (3 · inradius); 1 for a regular
    tetrahedron), ``min_jacobian_ratio`` (over elements, min/max of det J over the quadrature
    points of the isoparametric map; ≤ 0 means an inverted element), ``volume`` (mm³),
    ``volume_exact`` = π r² Σ L and ``volume_error`` (relative).
    """
    import skfem

    m = cm.mesh
    X = m.p[:, m.t]  # (3, 4, n_el)
    e1, e2, e3 = X[:, 1] - X[:, 0], X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]
    vol6 = np.abs(np.einsum("ie,ie->e", e1, np.cross(e2, e3, axis=0)))
    # face normals (outward up to sign) to get the six dihedral angles
    faces = [(1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)]
    normals, areas = [], []
    for f, opp in zip(faces, range(4), strict=True):
        a, b, c = X[:, f[0]], X[:, f[1]], X[:, f[2]]
        nrm = np.cross(b - a, c - a, axis=0)
        sgn = np.sign(np.einsum("ie,ie->e", nrm, X[:, opp] - a))
        nrm = -nrm * sgn
        ar = np.linalg.norm(nrm, axis=0)
        normals.append(nrm / ar)
        areas.append(0.5 * ar)
    angles = []
    for i in range(4):
        for j in range(i + 1, 4):
            cosang = -np.einsum("ie,ie->e", normals[i], normals[j])
            angles.append(np.degrees(np.arccos(np.clip(cosang, -1.0, 1.0))))
    angles = np.array(angles)
    inr = 3.0 * (vol6 / 6.0) / np.sum(areas, axis=0)
    # circumradius: |a²(b×c) + b²(c×a) + c²(a×b)| / (12 V) with edges from vertex 0
    num = (
        np.einsum("ie,ie->e", e1, e1) * np.cross(e2, e3, axis=0)
        + np.einsum("ie,ie->e", e2, e2) * np.cross(e3, e1, axis=0)
        + np.einsum("ie,ie->e", e3, e3) * np.cross(e1, e2, axis=0)
    )
    circ = np.linalg.norm(num, axis=0) / (2.0 * vol6)
    aspect = circ / (3.0 * inr)
    if cm.order == 2:
        basis = skfem.Basis(m, skfem.ElementTetP2(), intorder=4)
        detJ = basis.mapping.detDF(basis.X)
        jr = detJ.min(axis=1) / detJ.max(axis=1)
        jr = np.where(np.sign(detJ).min(axis=1) != np.sign(detJ).max(axis=1), -1.0, np.abs(jr))
        volume = float(np.sum(np.abs(detJ) * basis.W[None, :]))
    else:
        jr = np.ones(vol6.size)
        volume = float(vol6.sum() / 6.0)
    exact = float(np.pi * cm.radius**2 * np.sum(cm.lengths))
    return {
        "elements": float(cm.n_elements),
        "nodes": float(cm.n_nodes),
        "min_dihedral_deg": float(angles.min()),
        "max_dihedral_deg": float(angles.max()),
        "max_aspect_ratio": float(aspect.max()),
        "mean_aspect_ratio": float(aspect.mean()),
        "min_jacobian_ratio": float(jr.min()),
        "volume": volume,
        "volume_exact": exact,
        "volume_error": (volume - exact) / exact,
    }
