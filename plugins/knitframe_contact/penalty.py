"""Contact law ``penalty``: node-to-surface penalty contact between solid (tetrahedral) yarn surfaces.

Each slave node s is paired with the nearest master triangle (a, b, c) — of another yarn, of a
periodic image, or of the same yarn further than the exclusion length along it — and penalised
by its signed plane gap g (see :func:`knitframe.numerics.contact.plane_gap`)::

    W = Σ_s ½ ε A_s ⟨−g_s⟩²,        ⟨x⟩ = max(x, 0)

with A_s the node's tributary reference area (a third of each adjacent surface triangle) and ε
the penalty stiffness in N/mm³ (pressure per mm of penetration; default ``factor``·E/h from the
solver's contact modulus E and element size h); ⟨−g⟩² fades out across the last half of the
search reach (``fade``). On linear meshes the master triangles are by default replaced by
quadratic Nagata patches through the nodal normals (``smoothing``; see ``mortar``), and the gap
is measured to the patch. The gradient and the Hessian are exact for the current pairing,
including the rotation of the master plane. Node pressure ε⟨−g⟩ is reported for output. Pairs
are only kept when the slave node normal is not turned the master normal's way (within 60° of
parallel), and when the penetration is shallower than the search reach (deeper pairs are the
far side of a body).

Friction (only when the solver passes a ``friction_state``): regularised Coulomb friction with
the normal force lagged from the last converged state. :meth:`SolidPenalty.friction_state`
freezes the active nodes with their normal force λ_s = ε A_s ⟨−g_s⟩, the master triangle's
unit normal n and the barycentric point ξ of the node's projection on it;
:meth:`SolidPenalty.evaluate` then adds::

    D = Σ_s μ λ_s ε_s f0(|u_T,s| / ε_s),   u_T = (I − n nᵀ)[(x_s − x_m(ξ)) − (x_s − x_m(ξ))₀]
    f0(y) = y² − y³/3 (y < 1),  y − 1/3 (y ≥ 1)

(the slip of the node against the same material point x_m(ξ) = Σ ξ_i x_i of the master
triangle, with its image shift F̄·S_k; ε_s = ``slip`` × the mean size of the node's slave
facets), whose tangential force rises smoothly to μ λ_s at the slip ε_s
(:func:`knitframe.numerics.contact.friction_terms`).
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.numerics.contact import (
    Candidates,
    FrictionState,
    P2Projection,
    SolidSurface,
    barycentric,
    chain_facet_derivatives,
    facet_size,
    finish_evaluation,
    nagata_facets,
    node_normals,
    p2_gap_derivatives,
    penalty_depth,
    penalty_terms,
    plane_gap,
    select_pairs,
)


@attrs.frozen
class SolidContactLaw:
    """Fields and penalty stiffness shared by the solid contact laws (``penalty``, ``mortar``)."""

    discretisation: ClassVar[str] = "solid"
    #: the largest load strain these laws have finished on a knitted cell: past it the signed gap's
    #: pairing switches where yarns slide and the path stalls (13-23 %, docs/validation.md); a config
    #: asking for more is refused before any work (VolumetricSolver.check_law_reach)
    finishes_strain: ClassVar[float | None] = 0.10
    #: a signed-gap penalty, not a barrier: no collision check bounds the steps
    barrier: ClassVar[bool] = False
    #: evaluate takes the search's ``candidates``, held through a line search
    holds_candidates: ClassVar[bool] = True

    #: ε, N/mm³; default factor·E/h
    stiffness: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: ε = factor · E / h when stiffness is not given, -
    factor: float = attrs.field(default=10.0, validator=v.positive)
    #: Coulomb coefficient μ (used only with a friction state), -
    friction: float = attrs.field(default=0.3, validator=v.in_range(0.0, 10.0))
    #: regularisation slip ε_s / slave facet size (mean corner-edge length), -
    slip: float = attrs.field(default=0.05, validator=v.positive)
    #: penetration / reach from which the penalty fades out, reaching zero force at the reach (1: no fade), -
    fade: float = attrs.field(default=0.5, validator=v.in_range(0.0, 1.0, lo_open=True))
    #: master surface of linear (P1) meshes: "none" (flat facets) or "nagata" (quadratic patches through the
    #: nodal normals), -
    smoothing: str = attrs.field(default="nagata", validator=v.one_of(("none", "nagata")))

    def band(self, reach: float) -> tuple[float, float] | None:
        """The fade band (d1, d2) of the penetration, mm (see
        :func:`~knitframe.numerics.contact.penalty_depth`).

        A pair is only kept up to the search reach; without the fade the energy would jump by
        ½ ε w reach² when a pair crosses it (a point that comes within reach of the far side
        of a curved master, not a true contact). Across the band the force fades to zero, so
        the energy is continuous there. Converged penetrations are a few percent of r, far
        below the band; a run reports its largest.
        """
        return None if self.fade >= 1.0 else (self.fade * reach, reach)

    def normal_pressure(self, g: np.ndarray, stiffness: float, reach: float) -> np.ndarray:
        """Contact pressure ½ ε ψ'(⟨−g⟩) (MPa): ε⟨−g⟩ below the fade band."""
        return 0.5 * stiffness * penalty_depth(g, self.band(reach))[1]

    def smoothed(self, surface: SolidSurface) -> bool:
        """Whether the master surface is made of Nagata patches: linear (P1) facets and
        ``smoothing = "nagata"``."""
        return surface.facets.shape[1] == 3 and self.smoothing == "nagata"

    def master_normals(self, surface: SolidSurface, x: np.ndarray | None = None) -> np.ndarray | None:
        """Angle-weighted unit normals (N, 3) of the master surface at x (default: the reference nodes)
        that shape its patches, or None when the surface is not smoothed. A solver freezes them at the
        start of each increment and passes them to :meth:`evaluate` as ``normals``."""
        if not self.smoothed(surface):
            return None
        return node_normals(
            surface.X if x is None else x, surface.triangles[surface.tri_master], surface.identify
        )

    def _nodal(self, surface: SolidSurface, normals: np.ndarray | None) -> np.ndarray:
        """The frozen nodal normals of an evaluation, or the reference configuration's."""
        return self.master_normals(surface) if normals is None else normals

    def patches(
        self,
        surface: SolidSurface,
        x: np.ndarray,
        triangle: np.ndarray,
        shift: np.ndarray,
        normals: np.ndarray | None,
    ) -> np.ndarray:
        """Nagata patches (m, 6, 3) of master triangles ``triangle`` (m,) moved by ``shift`` (m, 3): each
        distinct triangle is built once (:func:`~knitframe.numerics.contact.nagata_facets`)."""
        nodal = self._nodal(surface, normals)
        used, where = np.unique(triangle, return_inverse=True)
        tri = surface.triangles[used]
        return nagata_facets(x[tri], nodal[tri], blocks=False)[0][where] + shift[:, None, :]

    def corner_normals(
        self, surface: SolidSurface, triangle: np.ndarray, normals: np.ndarray | None
    ) -> np.ndarray | None:
        """Nodal normals (m, 3, 3) at the corners of master triangles ``triangle`` (m,) that shape their
        patches (the edge pseudo-normals of :func:`~knitframe.numerics.contact.select_pairs`), or None
        when the surface is not smoothed."""
        if not self.smoothed(surface):
            return None
        nodal = self._nodal(surface, normals)
        return nodal[surface.triangles[triangle]]

    def patch_gap_derivatives(
        self,
        surface: SolidSurface,
        Xt: np.ndarray,
        triangle: np.ndarray,
        projection,
        weights: np.ndarray | None,
        order: int,
        normals: np.ndarray | None,
    ):
        """Gap gradient and Hessian of pairs on patches, in (slave points, the triangles' corners
        Xt (m, 3, 3))."""
        nodal = self._nodal(surface, normals)
        X6, A6 = nagata_facets(Xt, nodal[surface.triangles[triangle]])
        return chain_facet_derivatives(*p2_gap_derivatives(projection, X6, weights, order), A6)

    def search(
        self,
        surface: SolidSurface,
        points: np.ndarray,
        point_node: np.ndarray,
        x: np.ndarray,
        h: np.ndarray | None,
        reach: float,
        held: Candidates | None,
        **kw,
    ) -> Candidates:
        """Candidate master elements of the query points: the broad-phase search
        (:meth:`SolidSurface.candidates`), or the ``held`` candidates of an earlier evaluation
        (its ``info["candidates"]``), whose image shifts F̄·S_k follow the current macro DOFs h.

        Within a Newton iteration a solver holds the candidates of the iterate while its line
        search tries steps; each point still takes its nearest qualifying element among them, so
        the gap is the same function of the nodes as with a fresh search, without the KD-tree.
        The held set covers the step: a pair out of ``reach`` at the iterate cannot penetrate
        within a step that moves no node more than half the reach, and the penalty fades to zero
        at the reach.
        """
        if held is None:
            return surface.candidates(points, point_node, x, h, reach, **kw)
        shift = (
            np.zeros((len(held.point), 3))
            if surface.lattice is None
            else surface.lattice.shift(held.image, np.zeros(6) if h is None else h)
        )
        return Candidates(held.point, held.triangle, held.image, shift)

    def penalty(self, modulus: float, size: float) -> float:
        """Penalty stiffness ε (N/mm³) for contact modulus E (MPa) and element size h (mm): the given
        ``stiffness``, else ``factor`` · E / h."""
        return float(self.stiffness) if self.stiffness is not None else self.factor * modulus / size

    def step_limit(self, surface, x, h, dx, dh, *, stiffness: float) -> float:
        """1.0: a penalty admits any step (the solver asks only a ``barrier`` law)."""
        return 1.0


@attrs.frozen
class SolidPenalty(SolidContactLaw):
    """Node-to-surface penalty contact for solid meshes, with periodic images and self-contact."""

    name: ClassVar[str] = "penalty"
    description: ClassVar[str] = "node-to-surface penalty contact between tetrahedral yarn surfaces (solid)"

    def pairs(
        self,
        surface: SolidSurface,
        x: np.ndarray,
        h: np.ndarray | None,
        reach: float,
        normals: np.ndarray | None = None,
        held: Candidates | None = None,
    ) -> dict[str, Any]:
        """Slave node → nearest opposing master triangle within ``reach`` (mm), with its image (see
        :func:`knitframe.numerics.contact.select_pairs`); on a smoothed surface also the
        patch projection and gap. ``held``: candidates to choose from instead of a search (:meth:`search`)."""
        slave = surface.slave_nodes
        cand = self.search(surface, x[slave], slave, x, h, reach, held)
        Xm = x[surface.triangles[cand.triangle]] + cand.shift[:, None, :]
        smooth = self.smoothed(surface)
        if smooth:
            Xm = self.patches(surface, x, cand.triangle, cand.shift, normals)
        ns = node_normals(x, surface.triangles[surface.tri_slave])[slave]
        chosen = select_pairs(
            x[slave[cand.point]],
            cand.point,
            cand.triangle,
            Xm,
            ns[cand.point],
            reach,
            open_rim=surface.open_rim(cand.triangle, False),
            corner_normals=self.corner_normals(surface, cand.triangle, normals),
        )
        rows = chosen.rows
        return {
            "node": slave[cand.point[rows]],
            "triangle": cand.triangle[rows],
            "image": cand.image[rows],
            "g": chosen.g,
            "projection": chosen.projection if smooth else None,
            "candidates": cand,
        }

    def _active(
        self,
        surface: SolidSurface,
        x: np.ndarray,
        h: np.ndarray | None,
        reach: float,
        order: int,
        normals: np.ndarray | None = None,
        held: Candidates | None = None,
    ):
        """Active pairs: nodes (m, 4) and images (m, 4, 2) of (s, a, b, c), their points, gaps and
        derivatives."""
        pr = self.pairs(surface, x, h, reach, normals, held)
        tri = surface.triangles[pr["triangle"]]
        nodes = np.column_stack([pr["node"], tri])
        images = np.zeros((len(nodes), 4, 2), np.int64)
        images[:, 1:] = pr["image"][:, None, :]
        p = x[nodes]
        if surface.lattice is not None:
            p = p + surface.lattice.shift(images, np.zeros(6) if h is None else h)
        smooth = pr["projection"] is not None
        g = pr["g"] if smooth else plane_gap(p[:, 0], p[:, 1], p[:, 2], p[:, 3], order=0)[0]
        sel = np.flatnonzero((g < 0) & (g > -reach))
        p = p[sel]
        if smooth:
            proj = P2Projection(*(getattr(pr["projection"], f.name)[sel] for f in attrs.fields(P2Projection)))
            g, dg, Hg = g[sel], None, None
            if order >= 1:
                dg, Hg = self.patch_gap_derivatives(
                    surface, p[:, 1:], pr["triangle"][sel], proj, None, order, normals
                )
        else:
            g, dg, Hg = plane_gap(p[:, 0], p[:, 1], p[:, 2], p[:, 3], order=order)
        return {
            "node": pr["node"][sel],
            "triangle": pr["triangle"][sel],
            "image": pr["image"][sel],
            "nodes": nodes[sel],
            "images": images[sel],
            "p": p,
            "g": g,
            "dg": dg,
            "Hg": Hg,
            "candidates": pr["candidates"],
        }

    def friction_state(
        self,
        surface: SolidSurface,
        x: np.ndarray,
        h: np.ndarray | None,
        *,
        stiffness: float,
        reach: float,
        normals: np.ndarray | None = None,
    ) -> FrictionState:
        """Freeze the active node pairs of the converged state x for the next increment's friction.

        Each pair keeps its slave node, master triangle and image, the barycentric point ξ of the
        node's projection on the master's plane, the normal force λ = ε A_s ⟨−g⟩ (N), the unit
        master normal, and the relative position c₀ = x_s − x_m(ξ) (see the module docstring).
        """
        a = self._active(surface, x, h, reach, 0, normals)
        p = a["p"]
        lam = barycentric(p[:, 0], p[:, 1], p[:, 2], p[:, 3])
        weights = np.column_stack([np.ones(len(lam)), -lam])
        nrm = np.cross(p[:, 2] - p[:, 1], p[:, 3] - p[:, 1])
        # element size of a node: the mean size of the slave facets around it
        sf = surface.facets[surface.slave]
        num, den = np.zeros(surface.n_nodes), np.zeros(surface.n_nodes)
        np.add.at(num, sf.ravel(), np.repeat(facet_size(surface)[surface.slave], sf.shape[1]))
        np.add.at(den, sf.ravel(), 1.0)
        size = num[a["node"]] / den[a["node"]]
        force = surface.tributary[a["node"]] * self.normal_pressure(a["g"], stiffness, reach)
        return FrictionState(
            a["node"],
            np.full(len(lam), -1),
            a["triangle"],
            a["image"],
            lam[:, 1:],
            force,
            nrm / np.linalg.norm(nrm, axis=1, keepdims=True),
            size,
            a["nodes"],
            a["images"],
            weights,
            np.einsum("mk,mki->mi", weights, p),
        )

    def evaluate(
        self,
        surface: SolidSurface,
        x: np.ndarray,
        h: np.ndarray | None,
        order: int,
        *,
        stiffness: float,
        reach: float,
        friction_state: FrictionState | None = None,
        normals: np.ndarray | None = None,
        candidates: Candidates | None = None,
    ) -> tuple[float, Any, Any, dict[str, Any]]:
        """Energy (N·mm), gradient and Hessian in q = [u (3N), h (6)], and diagnostics.

        Parameters
        ----------
        surface : the contact surface (reference areas set).
        x : (N, 3) current node coordinates, mm.  h : (6,) macro DOFs or None.
        order : 0, 1 or 2.  stiffness : ε, N/mm³.  reach : search distance, mm.
        friction_state : pairs frozen by :meth:`friction_state` at the last converged state;
            their lagged regularised Coulomb friction is added (module docstring).
        normals : (N, 3) nodal normals that shape the smoothed master surface of linear meshes
            (``smoothing = "nagata"``), fixed in this evaluation; default the reference
            configuration's. Solvers freeze them at the start of each increment.
        candidates : the candidate master elements of an earlier evaluation (its
            ``info["candidates"]``) to choose pairs from instead of a broad-phase search
            (:meth:`search`). Every evaluation reports the candidates it used.
        """
        a = self._active(surface, x, h, reach, order, normals, candidates)
        g = a["g"]
        weight = surface.tributary[a["node"]]
        E, grad, hess = penalty_terms(g, a["dg"], a["Hg"], weight, stiffness, order, self.band(reach))
        pressure = np.zeros(surface.n_nodes)
        pressure[a["node"]] = self.normal_pressure(g, stiffness, reach)
        return finish_evaluation(
            surface,
            x,
            h,
            order,
            E,
            (a["nodes"], a["images"], grad, hess),
            friction=self.friction,
            slip=self.slip,
            friction_state=friction_state,
            g=g,
            pressure=pressure,
            force=float(np.sum(weight * pressure[a["node"]])),
            candidates=a["candidates"],
        )


@hookimpl
def register_contact_laws(register):
    register(SolidPenalty)
