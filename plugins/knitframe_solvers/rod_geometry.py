"""The rod discretisation: :class:`RodModel` (nodes, edges, bending triplets, directors) and its VTU file.

DOFs: ``q = [u (3 N), h (6)]`` — node displacements (mm) and the macro DOFs of
:mod:`knitframe.numerics.periodic` (H = F̄ − I); a shear-deformable model (:func:`with_directors`)
has ``q = [u (3 N), d − d₀ (3 E), h (6)]``, its edges' directors before the macro DOFs. An
element point is a node at a periodic image, so an edge that crosses the cell boundary joins the
last node of yarn i to the first node of its paired yarn j at image (1, 0). A model is built from
open polylines (:func:`open_rods`) or from a knitted unit cell (:func:`from_cell`); its energy is
:class:`knitframe_solvers.rod_model.RodEnergy`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.numerics.contact_search import SegmentTopology
from knitframe.numerics.periodic import N_MACRO, Lattice

__all__ = ["RodModel", "from_cell", "open_rods", "with_directors", "write_rod_vtu"]


@attrs.frozen(eq=False)
class RodModel:
    """Nodes, edges and bending triplets of a set of rods, possibly periodic."""

    #: (N, 3) reference node positions, mm
    X: np.ndarray
    #: (E, 2) node indices
    edges: np.ndarray
    #: (E, 2, 2) periodic image of each edge point
    edge_images: np.ndarray
    #: (B, 3) node indices (previous, vertex, next)
    triplets: np.ndarray
    #: (B, 3, 2)
    triplet_images: np.ndarray
    #: (E,) rest lengths, mm
    l0: np.ndarray
    #: (B,) Voronoi lengths, mm
    lbar: np.ndarray
    #: strand bookkeeping per edge
    topology: SegmentTopology
    #: (N,) yarn index of each node
    yarn: np.ndarray
    lattice: Lattice | None = None
    #: (D, 3) reference director of each edge of a shear-deformable rod (:func:`with_directors`), None: none
    directors: np.ndarray | None = None
    #: (B, 2) the edges before and after each bending vertex (with ``directors``)
    director_pairs: np.ndarray | None = None

    @property
    def n_nodes(self) -> int:
        return int(self.X.shape[0])

    @property
    def n_directors(self) -> int:
        return 0 if self.directors is None else int(self.directors.shape[0])

    @property
    def n_points(self) -> int:
        """Nodes and directors: the 3-vectors among the DOFs, before the macro DOFs."""
        return self.n_nodes + self.n_directors

    @property
    def n_dof(self) -> int:
        return 3 * self.n_points + N_MACRO

    def macro(self, q: np.ndarray) -> np.ndarray:
        """The macro DOFs h (6,) of state q."""
        return q[3 * self.n_points :]

    def director_vectors(self, q: np.ndarray) -> np.ndarray:
        """Current directors (D, 3) in state q (not normalised)."""
        n = self.n_nodes
        return self.directors + q[3 * n : 3 * self.n_points].reshape(-1, 3)

    @property
    def n_strands(self) -> int:
        return int(self.topology.cycle.shape[0])

    def curvature(self, q: np.ndarray) -> np.ndarray:
        """Discrete curvature magnitude |κb| = 2 tan(φ/2) at every vertex (B,) in state q."""
        x = self.positions(q)
        p = x[self.triplets]
        if self.lattice is not None:
            p = p + self.lattice.shift(self.triplet_images, self.macro(q))
        a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 1]
        c = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        return 2.0 * np.sqrt(np.maximum(1.0 - c, 0.0) / (1.0 + c))

    def aligned(self, q: np.ndarray) -> np.ndarray:
        """State q with every director set to its edge's current unit tangent (no shear); q if none."""
        if self.directors is None:
            return q
        p0, p1 = self.segments(q)
        t = p1 - p0
        t /= np.linalg.norm(t, axis=1)[:, None]
        out = q.copy()
        out[3 * self.n_nodes : 3 * self.n_points] = (t - self.directors).reshape(-1)
        return out

    def shear_angles(self, q: np.ndarray) -> np.ndarray:
        """Angle between each edge and its director (E,) in state q, degrees (directors required)."""
        p0, p1 = self.segments(q)
        t = p1 - p0
        d = self.director_vectors(q)
        c = np.einsum("ij,ij->i", t, d) / (np.linalg.norm(t, axis=1) * np.linalg.norm(d, axis=1))
        return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))

    def positions(self, q: np.ndarray) -> np.ndarray:
        """Current node positions (N, 3), mm."""
        return self.X + q[: 3 * self.n_nodes].reshape(-1, 3)

    def segments(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Current edge end points (E, 3) each, with image shifts applied."""
        x = self.positions(q)
        h = self.macro(q)
        p = x[self.edges]
        if self.lattice is not None:
            p = p + self.lattice.shift(self.edge_images, h)
        return p[:, 0], p[:, 1]


def _assemble(nodes: list[np.ndarray], images: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    return np.concatenate(nodes).astype(np.int64), np.concatenate(images).astype(np.int64)


def open_rods(polylines: list[np.ndarray]) -> RodModel:
    """Model of open (non-periodic) rods, one per polyline (n_i, 3) of vertices in mm."""
    X, edges, tri, strand, arc, yarn = [], [], [], [], [], []
    off = 0
    for r, pts in enumerate(polylines):
        pts = np.asarray(pts, dtype=np.float64)
        n = len(pts)
        X.append(pts)
        idx = off + np.arange(n)
        edges.append(np.stack([idx[:-1], idx[1:]], axis=1))
        tri.append(np.stack([idx[:-2], idx[1:-1], idx[2:]], axis=1))
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        arc.append(np.concatenate([[0.0], np.cumsum(seg)[:-1]]) + 0.5 * seg)
        strand.append(np.full(n - 1, r))
        yarn.append(np.full(n, r))
        off += n
    X = np.vstack(X)
    E = np.vstack(edges)
    T = np.vstack(tri) if tri else np.zeros((0, 3), np.int64)
    l0 = np.linalg.norm(X[E[:, 1]] - X[E[:, 0]], axis=1)
    lbar = 0.5 * (
        np.linalg.norm(X[T[:, 1]] - X[T[:, 0]], axis=1) + np.linalg.norm(X[T[:, 2]] - X[T[:, 1]], axis=1)
    )
    n_r = len(polylines)
    topo = SegmentTopology(
        np.concatenate(strand),
        np.zeros(len(E), np.int64),
        np.concatenate(arc),
        np.zeros(n_r, np.int64),
        np.zeros(n_r),
    )
    return RodModel(
        X,
        E,
        np.zeros((len(E), 2, 2), np.int64),
        T,
        np.zeros((len(T), 3, 2), np.int64),
        l0,
        lbar,
        topo,
        np.concatenate(yarn),
    )


def _uniform_arc_samples(curve, n: int) -> np.ndarray:
    """n parameters t in [t0, t1) equally spaced in arc length."""
    grid = np.linspace(curve.t0, curve.t1, 40 * n + 1)
    s = curve.arc_coordinate(grid)
    target = np.linspace(0.0, s[-1], n, endpoint=False)
    return np.interp(target, s, grid)


def from_cell(cell: Any, segments_per_stitch: int) -> RodModel:
    """Periodic rod model of a :class:`knitframe.geometry.UnitCell`.

    Each yarn (two stitches) gets ``2·segments_per_stitch`` segments equally spaced in arc
    length; its last node connects to the first node of its paired yarn at image (1, 0).
    Rest lengths are the chords of the knitted centerline, so the yarn length is that of the
    geometry.
    """
    from knitframe.geometry import strands

    lattice = Lattice(cell.L1, cell.L2)
    n_y = len(cell.yarns)
    counts = [2 * segments_per_stitch] * n_y
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    X = []
    for i, c in enumerate(cell.yarns):
        X.append(np.asarray(c.position(_uniform_arc_samples(c, counts[i])), dtype=np.float64))
    X = np.vstack(X)
    pair = dict(cell.end_pairs)
    edges, eimg, tri, timg, yarn = [], [], [], [], []
    for i in range(n_y):
        n = counts[i]
        idx = starts[i] + np.arange(n)
        nxt = np.append(idx[1:], starts[pair[i]])
        nimg = np.zeros((n, 2), np.int64)
        nimg[-1] = (1, 0)
        edges.append(np.stack([idx, nxt], axis=1))
        eimg.append(np.stack([np.zeros((n, 2), np.int64), nimg], axis=1))
        yarn.append(np.full(n, i))
    prev_of = {j: i for i, j in cell.end_pairs}
    for i in range(n_y):
        n = counts[i]
        idx = starts[i] + np.arange(n)
        prv = np.insert(idx[:-1], 0, starts[prev_of[i]] + counts[prev_of[i]] - 1)
        pimg = np.zeros((n, 2), np.int64)
        pimg[0] = (-1, 0)
        nxt = np.append(idx[1:], starts[pair[i]])
        nimg = np.zeros((n, 2), np.int64)
        nimg[-1] = (1, 0)
        tri.append(np.stack([prv, idx, nxt], axis=1))
        timg.append(np.stack([pimg, np.zeros((n, 2), np.int64), nimg], axis=1))
    E, EI_ = _assemble(edges, eimg)
    T, TI = _assemble(tri, timg)
    P = X[E] + lattice.reference_shift(EI_)
    l0 = np.linalg.norm(P[:, 1] - P[:, 0], axis=1)
    Pt = X[T] + lattice.reference_shift(TI)
    lbar = 0.5 * (np.linalg.norm(Pt[:, 1] - Pt[:, 0], axis=1) + np.linalg.norm(Pt[:, 2] - Pt[:, 1], axis=1))
    # strand bookkeeping: position of each yarn in its strand and arc unrolled along the strand
    st = strands(cell)
    strand_of, pos = np.zeros(n_y, np.int64), np.zeros(n_y, np.int64)
    offset, cycle, length = np.zeros(n_y), np.zeros(len(st), np.int64), np.zeros(len(st))
    seg_y = np.concatenate(yarn)
    for k, cyc in enumerate(st):
        acc = 0.0
        for p_, i in enumerate(cyc):
            strand_of[i], pos[i], offset[i] = k, p_, acc
            acc += l0[seg_y == i].sum()
        cycle[k], length[k] = len(cyc), acc
    arc = np.empty(len(E))
    for i in range(n_y):
        sel = seg_y == i
        li = l0[sel]
        arc[sel] = offset[i] + np.concatenate([[0.0], np.cumsum(li)[:-1]]) + 0.5 * li
    topo = SegmentTopology(strand_of[seg_y], pos[seg_y], arc, cycle, length)
    node_yarn = np.concatenate([np.full(counts[i], i) for i in range(n_y)])
    return RodModel(X, E, EI_, T, TI, l0, lbar, topo, node_yarn, lattice)


def with_directors(model: RodModel) -> RodModel:
    """The same rods made shear-deformable: every edge gets a director, its reference unit tangent.

    The DOFs become ``q = [u (3N), d − d₀ (3E), h (6)]``; see :func:`knitframe_solvers.rod_terms.shear`.
    """
    p0, p1 = model.segments(np.zeros(model.n_dof))
    t = (p1 - p0) / np.linalg.norm(p1 - p0, axis=1)[:, None]
    start = -np.ones(model.n_nodes, np.int64)
    start[model.edges[:, 0]] = np.arange(len(model.edges))
    pairs = np.stack([start[model.triplets[:, 0]], start[model.triplets[:, 1]]], axis=1)
    if np.any(pairs < 0) or np.any(model.edges[pairs[:, 0], 1] != model.triplets[:, 1]):
        raise ValueError("every bending vertex needs the edges into and out of it")
    return attrs.evolve(model, directors=t, director_pairs=pairs)


def write_rod_vtu(
    path: Path, model: RodModel, q: np.ndarray, radius: float, cell_data: dict | None = None
) -> Path:
    """Deformed centerlines as VTU line cells; segments crossing the cell boundary get their own end point.

    A shear-deformable model adds each segment's shear angle (``shear_angle_deg``).
    """
    import meshio

    x = model.positions(q)
    p0, p1 = model.segments(q)
    n = model.n_nodes
    cross = np.any(model.edge_images[:, 1] != 0, axis=1)
    extra = p1[cross]
    pts = np.vstack([x, extra])
    cells = model.edges.copy()
    cells[cross, 1] = n + np.arange(int(cross.sum()))
    yarn = np.concatenate([model.yarn, model.yarn[model.edges[cross, 0]]])
    cell_data = dict(cell_data or {})
    if model.directors is not None:  # the angle between each segment and its section's normal
        cell_data.setdefault("shear_angle_deg", model.shear_angles(q))
    disp = pts - np.vstack([model.X, model.X[model.edges[cross, 1]]])
    meshio.write(
        path,
        meshio.Mesh(
            pts,
            [("line", cells)],
            point_data={
                "yarn": yarn.astype(np.float64),
                "displacement": disp,
                "radius": np.full(len(pts), radius),
            },
            cell_data={k: [np.asarray(v_, dtype=np.float64)] for k, v_ in cell_data.items()},
        ),
    )
    return path
