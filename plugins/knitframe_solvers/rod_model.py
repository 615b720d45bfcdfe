"""The rod model of yarn centerlines: the total energy with its gradient and sparse Hessian.

The discretisation (:class:`RodModel`, :func:`from_cell`, :func:`open_rods`,
:func:`with_directors`, :func:`write_rod_vtu`) is :mod:`knitframe_solvers.rod_geometry`'s, and
exported here with the energy. DOFs: ``q = [u (3 N), h (6)]`` — node displacements (mm) and the
macro DOFs of :mod:`knitframe.numerics.periodic` (H = F̄ − I), with a shear-deformable model's
directors before the macro DOFs; an element point is a node at a periodic image, so contact with
images is contact between points whose image shifts depend on F̄.

The energy is the sum of the terms of the effects asked for: stretching (always), bending
(``bending``), contact (``contact``; same-strand pairs only with ``self_contact``), lagged
friction (``friction``) and external work −f·q. Terms not asked for are never evaluated:
:attr:`RodEnergy.calls` counts evaluations per term.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import attrs
import numpy as np

from knitframe.numerics.contact_search import VerletList, find_pairs
from knitframe.numerics.pattern import PatternCache
from knitframe.numerics.periodic import PointMap
from knitframe_solvers.rod_contact import friction_energy, gauss_points, pair_weights, quadrature_contact
from knitframe_solvers.rod_geometry import RodModel, from_cell, open_rods, with_directors, write_rod_vtu
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
    #: (m,) the segment pair of each point pair, an index into ``pairs`` (non-decreasing)
    group: np.ndarray | None = None
    #: (n, 4): the distinct segment pairs (i, j, k1, k2) of the point pairs, in order
    pairs: np.ndarray | None = None

    def __attrs_post_init__(self) -> None:
        if self.group is None:  # point pairs of one segment pair share its DOFs: grouped once per lag
            key = np.column_stack([self.i, self.j, self.k]).astype(np.int64)
            new = np.ones(len(key), dtype=bool)
            new[1:] = np.any(key[1:] != key[:-1], axis=1)
            self.group = np.cumsum(new) - 1
            self.pairs = key[new]


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
        self._pair_maps: dict[bytes, PointMap] = {}
        self._verlet = VerletList()  # the contact search's broad phase, kept while nothing moved far
        # the Hessian's CSR structure per set of terms: rebuilt only when the contact pairs change
        self._assembly = PatternCache(m.n_dof)

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
            verlet=self._verlet,
        )

    def _pair_map(self, i: np.ndarray, j: np.ndarray, k: np.ndarray) -> PointMap:
        """The point map of these segment pairs; the same object while the same pairs come back (its
        DOF map and Hessian positions are then reused)."""
        # i, j (n,) and k (n, 2): the byte length gives n, so the key is unambiguous
        key = b"".join(np.ascontiguousarray(a, dtype=np.int64).tobytes() for a in (i, j, k))
        pm = self._pair_maps.get(key)
        if pm is None:
            m = self.model
            nodes = np.concatenate([m.edges[i], m.edges[j]], axis=1)
            images = np.concatenate([m.edge_images[i], m.edge_images[j] + k[:, None, :]], axis=1)
            pm = PointMap(m.n_points, nodes, images, m.lattice)
            self._pair_maps[key] = pm
            while len(self._pair_maps) > 8:
                del self._pair_maps[next(iter(self._pair_maps))]
        return pm

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
        parts: list[PointMap] = []
        values: list[np.ndarray] = []
        info: dict[str, Any] = {"active_contacts": 0, "strands_in_contact": 0, "min_distance": np.inf}

        def add(pm: PointMap, e, ge, He):
            nonlocal E
            E += float(np.sum(e))
            if order >= 1:
                g[:] += pm.gradient(ge)
            if order >= 2:
                parts.append(pm)
                values.append(pm.hessian_values(He))

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
                # one map per segment pair; its point pairs' gradients and Hessians are summed onto it
                pm = self._pair_map(L.pairs[:, 0], L.pairs[:, 1], L.pairs[:, 2:])
                p = pm.points(x, h)[L.group]
                add(
                    pm, *friction_energy(p, L.s, L.t, L.c, L.normal, L.lam, self.law, self.dk, order, L.group)
                )
        if self.external is not None:
            E -= float(self.external @ q)
            if order >= 1:
                g -= self.external
        H = None
        if order >= 2:
            H = self._assembly.matrix(parts, values)
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
