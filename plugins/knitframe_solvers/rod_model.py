"""Rod discretisation of yarn centerlines and the total energy with its gradient and sparse Hessian.

DOFs: ``q = [u (3 N), h (6)]`` — node displacements (mm) and the macro DOFs of
:mod:`knitframe.numerics.periodic` (H = F̄ − I); a shear-deformable model (:func:`with_directors`)
has ``q = [u (3 N), d − d₀ (3 E), h (6)]``, its edges' directors before the macro DOFs. An
element point is a node at a periodic image, so an edge that crosses the cell boundary joins the
last node of yarn i to the first node of its paired yarn j at image (1, 0), and contact with
images is contact between points whose image shifts depend on F̄.

The energy is the sum of the terms of the effects asked for: stretching (always), bending
(``bending``), contact (``contact``; same-strand pairs only with ``self_contact``), lagged
friction (``friction``) and external work −f·q. Terms not asked for are never evaluated:
:attr:`RodEnergy.calls` counts evaluations per term.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import attrs
import numpy as np
import scipy.sparse as sp

from knitframe.numerics.contact_search import SegmentTopology, find_pairs
from knitframe.numerics.periodic import N_MACRO, Lattice, PointMap
from knitframe_solvers.rod_contact import friction_energy, gauss_points, pair_weights, quadrature_contact
from knitframe_solvers.rod_terms import bend, director_bend, director_norm, shear, stretch

__all__ = [
    "RodModel",
    "RodEnergy",
    "from_cell",
    "open_rods",
    "with_directors",
    "knitted_overlap",
    "write_rod_vtu",
]


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


@attrs.define(eq=False)
class FrictionLag:
    """Contacting point pairs of the last converged state, whose normal force and normal friction uses."""

    #: (m,) segment
    i: np.ndarray
    #: (m,) segment at image k
    j: np.ndarray
    #: (m, 2)
    k: np.ndarray
    #: (m,) quadrature parameter on i
    s: np.ndarray
    #: (m,) quadrature parameter on j
    t: np.ndarray
    #: (m, 3) c = J x at the lag
    c: np.ndarray
    #: (m, 3)
    normal: np.ndarray
    #: (m,) normal force of the point pair, N
    lam: np.ndarray


@attrs.define(eq=False, slots=False)
class RodEnergy:
    """Total energy of a :class:`RodModel`: ``energy(q, order) -> (E, g, H, info)``.

    For :func:`knitframe.numerics.newton.minimise`.

    ``dk`` (the contact distance) is mutable for the pre-stress step; with ``dk_full`` set, the
    contact stiffnesses are scaled by (dk_full/dk)², which keeps the line load of two yarns at a
    given d/dk the same while dk grows (the density's line load scales as k·dk²), so the
    undersized yarns of the pre-stress push apart as hard as the full-size ones. ``law`` is a rod
    contact-law plugin instance, None when the scene does not ask for contact; its energy is a
    density integrated over both centerlines (:mod:`knitframe_solvers.rod_contact`) with an
    n × n Gauss rule per segment pair, n = max(``quadrature``, ⌈1.6 l_max/(c·dk)⌉) for a law
    whose core (barrier) is c·dk: the largest gap between samples, about π l/(2n), then stays
    below 0.7·√2·c·dk, so two yarns cannot slip through each other's core between samples.
    Then sampled point pairs reach the core (where φ = +∞) before the exact segment distance
    falls below half of it; a state where it does anyway is inadmissible (E = +∞).
    """

    model: RodModel
    #: N
    EA: float
    #: N·mm²
    EI: float
    bending: bool = True
    #: shear stiffness κ G_A A of a model with directors, N
    GA: float = 0.0
    law: Any = None
    #: contact distance, mm
    dk: float = 0.0
    #: penalty stiffness of the contact density, N/mm³
    k_contact: float = 0.0
    #: core (barrier) stiffness of the contact density, N/mm³
    k_core: float | None = None
    self_contact: bool = False
    #: mm
    exclusion: float = 0.0
    friction: bool = False
    #: Gauss points per segment in each direction of the contact integral
    quadrature: int = 4
    #: line contact stiffness the density was scaled to, N/mm² (reported only)
    k_line: float | None = None
    #: contact distance at which k_contact and k_core hold, mm (None: any dk)
    dk_full: float | None = None
    #: (B,) rest curvature magnitude of each vertex, - (None: straight)
    kappa0: np.ndarray | None = None
    #: (n_dof,) generalised forces, N (and N·mm on h)
    external: np.ndarray | None = None
    lag: FrictionLag | None = None
    calls: Counter = attrs.Factory(Counter)

    def __attrs_post_init__(self) -> None:
        m = self.model
        n_p = m.n_points
        self._stretch_map = PointMap(n_p, m.edges, m.edge_images, m.lattice)
        self._bend_map = PointMap(n_p, m.triplets, m.triplet_images, m.lattice)
        if m.directors is not None:
            n, E = m.n_nodes, len(m.edges)
            own = n + np.arange(E)
            self._shear_map = PointMap(
                n_p,
                np.concatenate([m.edges, own[:, None]], axis=1),
                np.concatenate([m.edge_images, np.zeros((E, 1, 2), np.int64)], axis=1),
                m.lattice,
            )
            self._director_bend_map = PointMap(n_p, n + m.director_pairs, None, m.lattice)
            self._norm_map = PointMap(n_p, own[:, None], None, m.lattice)
            # as stiff along the director as across it (shear and bending), so |d| stays near 1
            self._norm_stiffness = self.GA * m.l0 + self.EI / m.l0
        self._rules: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._l_max = float(m.l0.max(initial=0.0))

    def stiffness(self) -> tuple[float, float | None]:
        """(k_contact, k_core) at the current contact distance, N/mm³ (see the class docstring)."""
        f = 1.0 if self.dk_full is None else (self.dk_full / self.dk) ** 2
        return self.k_contact * f, None if self.k_core is None else self.k_core * f

    @property
    def core(self) -> float:
        """Centre distance below which the contact law forbids states, mm (0: no core)."""
        return float(getattr(self.law, "core", 0.0) or 0.0) * self.dk

    def rule(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The Gauss rule of the contact integral at the current contact distance (see the class)."""
        n = self.quadrature
        if self.core > 0:
            n = max(n, int(np.ceil(1.6 * self._l_max / self.core)))
        if n not in self._rules:
            self._rules[n] = gauss_points(n)
        return self._rules[n]

    # -- contact -------------------------------------------------------------------------------
    def pairs(self, q: np.ndarray):
        """Segment pairs closer than dk under the current state (one contact search)."""
        self.calls["contact_search"] += 1
        p0, p1 = self.model.segments(q)
        h = self.model.macro(q)
        return find_pairs(
            p0,
            p1,
            self.dk,
            topology=self.model.topology,
            lattice=self.model.lattice,
            h=h,
            self_contact=self.self_contact,
            exclusion=self.exclusion,
        )

    def _pair_map(self, i: np.ndarray, j: np.ndarray, k: np.ndarray) -> PointMap:
        m = self.model
        nodes = np.concatenate([m.edges[i], m.edges[j]], axis=1)
        images = np.concatenate([m.edge_images[i], m.edge_images[j] + k[:, None, :]], axis=1)
        return PointMap(m.n_points, nodes, images, m.lattice)

    def _lengths(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        return self.model.l0[i] * self.model.l0[j]

    def update_lag(self, q: np.ndarray) -> None:
        """Freeze the contacting point pairs of state q (normal forces, normals, material points)."""
        pr = self.pairs(q)
        pm = self._pair_map(pr.i, pr.j, pr.k)
        p = pm.points(self.model.positions(q), self.model.macro(q))
        xa, xb, wq = self.rule()
        c = np.einsum("qi,mic->mqc", pair_weights(xa, xb), p)
        r = np.linalg.norm(c, axis=2)
        lam = -(self._lengths(pr.i, pr.j)[:, None] * wq) * self.law.normal(r, self.dk, *self.stiffness())[1]
        m_, q_ = np.nonzero(lam > 0)
        self.lag = FrictionLag(
            pr.i[m_], pr.j[m_], pr.k[m_], xa[q_], xb[q_], c[m_, q_], c[m_, q_] / r[m_, q_, None], lam[m_, q_]
        )

    # -- total ---------------------------------------------------------------------------------
    def __call__(self, q: np.ndarray, order: int = 2):
        m = self.model
        x = m.positions(q)
        h = m.macro(q)
        E = 0.0
        g = np.zeros(m.n_dof) if order >= 1 else None
        coo: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        info: dict[str, Any] = {"active_contacts": 0, "strands_in_contact": 0, "min_distance": np.inf}

        def add(pm: PointMap, e, ge, He):
            nonlocal E
            E += float(np.sum(e))
            if order >= 1:
                g[:] += pm.gradient(ge)
            if order >= 2:
                coo.append(pm.hessian_coo(He))

        self.calls["stretch"] += 1
        add(self._stretch_map, *stretch(self._stretch_map.points(x, h), m.l0, self.EA, order))
        if m.directors is not None:
            xd = np.vstack([x, m.director_vectors(q)])
            self.calls["shear"] += 1
            add(self._shear_map, *shear(self._shear_map.points(xd, h), m.l0, self.GA, order))
            add(self._norm_map, *director_norm(self._norm_map.points(xd), self._norm_stiffness, order))
            if self.bending and len(m.triplets):
                self.calls["bending"] += 1
                d = self._director_bend_map.points(xd)
                add(self._director_bend_map, *director_bend(d, m.lbar, self.EI, order, self.kappa0))
        elif self.bending and len(m.triplets):
            self.calls["bending"] += 1
            add(self._bend_map, *bend(self._bend_map.points(x, h), m.lbar, self.EI, order, self.kappa0))
        if self.law is not None:
            pr = self.pairs(q)
            self.calls["contact"] += 1
            if len(pr):
                pm = self._pair_map(pr.i, pr.j, pr.k)
                e, ge, He, r_min = quadrature_contact(
                    pm.points(x, h),
                    self._lengths(pr.i, pr.j),
                    self.law,
                    self.dk,
                    *self.stiffness(),
                    self.rule(),
                    order,
                )
                act = r_min < self.dk
                if order >= 1:  # pairs with no sample inside dk contribute nothing
                    pm = self._pair_map(pr.i[act], pr.j[act], pr.k[act])
                    ge = ge[act]
                    He = He[act] if He is not None else None
                add(pm, e, ge, He)
                info["active_contacts"] = int(np.count_nonzero(act))
                info["min_distance"] = float(pr.distance.min())
                if info["min_distance"] <= 0.5 * self.core:
                    E = np.inf  # the yarns slipped into each other's core between quadrature samples
                touched = np.union1d(m.topology.strand[pr.i[act]], m.topology.strand[pr.j[act]])
                info["strands_in_contact"] = int(len(touched))
            if self.friction and self.lag is not None and len(self.lag.i):
                self.calls["friction"] += 1
                L = self.lag
                pm = self._pair_map(L.i, L.j, L.k)
                add(
                    pm,
                    *friction_energy(
                        pm.points(x, h), L.s, L.t, L.c, L.normal, L.lam, self.law, self.dk, order
                    ),
                )
        if self.external is not None:
            E -= float(self.external @ q)
            if order >= 1:
                g -= self.external
        H = None
        if order >= 2:
            r, c, v = (np.concatenate(a) for a in zip(*coo, strict=False))
            H = sp.csr_matrix((v, (r, c)), shape=(m.n_dof, m.n_dof))
        if not np.isfinite(E):
            info["diagnostic"] = (
                f"contact barrier crossed (closest centre distance {info['min_distance']:.4g} mm, "
                f"contact distance {self.dk:.4g} mm)"
            )
        return E, g, H, info


def knitted_overlap(energy: RodEnergy, q: np.ndarray) -> str | None:
    """Why state ``q`` cannot start a run without the pre-stress (centerlines inside the contact core).

    None if it can.
    """
    with np.errstate(all="ignore"):
        E0 = energy(q, 0)[0]
    if np.isfinite(E0):
        return None
    d_min = float(energy.pairs(q).distance.min(initial=energy.dk))
    return (
        f"rod: the knitted centerlines overlap (closest centre distance {d_min:.4g} mm < "
        f"{energy.core:.4g} mm); add 'prestress' to scene.effects"
    )


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
