"""Swept tube meshes of a unit cell's yarns (:func:`cell_mesh`, :class:`CellMesh`), step by step.

The sweep of the package docstring: sampling each yarn in arc length, closed rotation-minimising
frames, the swept vertices and prisms split into tetrahedra, the P2 mid-edge nodes on the exact
swept geometry, the lateral surface and the node pairs of the end faces.
"""

from __future__ import annotations

import time
from typing import Any

import attrs
import numpy as np

from knitframe.errors import GeometryError
from knitframe.numerics.mesh.facets import surface_facets
from knitframe.numerics.mesh.section import Section, arc_length_samples, section_mesh

__all__ = ["CellMesh", "cell_mesh"]


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
