"""Contact law ``penalty``: node-to-surface penalty contact between solid (tetrahedral) yarn surfaces.

Each slave node s is paired with the nearest master triangle (a, b, c) — of another yarn, of a
periodic image, or of the same yarn further than the exclusion length along it — and penalised
by its signed plane gap g (see :func:`knitframe_contact.solid_geometry.plane_gap`)::

    W = Σ_s ½ ε A_s ⟨−g_s⟩²,        ⟨x⟩ = max(x, 0)

with A_s the node's tributary reference area (a third of each adjacent surface triangle) and ε
the penalty stiffness in N/mm³ (pressure per mm of penetration; default ``factor``·E/h from the
solver's contact modulus E and element size h). The gradient and the Hessian are exact for the
current pairing, including the rotation of the master plane. Node pressure ε⟨−g⟩ is reported for
output. Pairs are only kept when the slave node normal opposes the master normal, and when the
penetration is shallower than the search reach (deeper pairs are the far side of a body).
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np

from knitframe import hookimpl, validators as v
from knitframe.periodic import PointMap
from knitframe_contact.solid_geometry import (
    SolidSurface, nearest, node_normals, penalty_terms, plane_gap, point_triangle_distance, scatter,
)


def default_stiffness(stiffness: float | None, factor: float, modulus: float, size: float) -> float:
    """ε in N/mm³: the given stiffness, else factor · E / h."""
    return float(stiffness) if stiffness is not None else factor * modulus / size


@attrs.frozen
class SolidPenalty:
    """Node-to-surface penalty contact for solid meshes, with periodic images and self-contact."""

    name: ClassVar[str] = "penalty"
    description: ClassVar[str] = "node-to-surface penalty contact between tetrahedral yarn surfaces (solid)"
    discretisation: ClassVar[str] = "solid"

    stiffness: float | None = attrs.field(default=None, validator=v.optional(v.positive))  #: ε, N/mm³; default factor·E/h
    factor: float = attrs.field(default=10.0, validator=v.positive)  #: ε = factor · E / h when stiffness is not given, -

    def penalty(self, modulus: float, size: float) -> float:
        """Penalty stiffness ε (N/mm³) for contact modulus E (MPa) and element size h (mm)."""
        return default_stiffness(self.stiffness, self.factor, modulus, size)

    def pairs(self, surface: SolidSurface, x: np.ndarray, h: np.ndarray | None, reach: float) -> dict[str, np.ndarray]:
        """Slave node → nearest opposing master triangle within ``reach`` (mm), with its image."""
        slave = surface.slave_nodes
        cand = surface.candidates(x[slave], slave, x, h, reach)
        tri = surface.triangles[cand.triangle]
        A, B, C = (x[tri[:, k]] + cand.shift for k in range(3))
        p = x[slave[cand.point]]
        dist, inside = point_triangle_distance(p, A, B, C)
        nm = np.cross(B - A, C - A)
        ns = node_normals(x, surface.triangles[surface.tri_slave])[slave[cand.point]]
        ok = (np.einsum("ij,ij->i", nm, ns) < 0) & (dist < reach)
        # prefer a triangle the node projects into: switching between those keeps the gap continuous
        rank = dist + np.where(inside, 0.0, 2.0 * reach)
        rows = np.flatnonzero(ok)[nearest(cand.point[ok], rank[ok])]
        return {"node": slave[cand.point[rows]], "triangle": cand.triangle[rows], "image": cand.image[rows]}

    def evaluate(self, surface: SolidSurface, x: np.ndarray, h: np.ndarray | None, order: int, *,
                 stiffness: float, reach: float) -> tuple[float, Any, Any, dict[str, Any]]:
        """Energy (N·mm), gradient and Hessian in q = [u (3N), h (6)], and diagnostics.

        Parameters
        ----------
        surface : the contact surface (reference areas set).
        x : (N, 3) current node coordinates, mm.  h : (6,) macro DOFs or None.
        order : 0, 1 or 2.  stiffness : ε, N/mm³.  reach : search distance, mm.
        """
        pr = self.pairs(surface, x, h, reach)
        tri = surface.triangles[pr["triangle"]]
        nodes = np.column_stack([pr["node"], tri])
        images = np.zeros((len(nodes), 4, 2), np.int64)
        images[:, 1:] = pr["image"][:, None, :]
        pm = PointMap(surface.n_nodes, nodes, images, surface.lattice)
        pts = pm.points(x, h)
        g, dg, Hg = plane_gap(pts[:, 0], pts[:, 1], pts[:, 2], pts[:, 3], order=order)
        keep = (g < 0) & (g > -reach)
        weight = surface.tributary[pr["node"]]
        sel = np.flatnonzero(keep)
        E, grad, hess = penalty_terms(g[sel], None if dg is None else dg[sel], None if Hg is None else Hg[sel],
                                      weight[sel], stiffness, order)
        pm_act = PointMap(surface.n_nodes, nodes[sel], images[sel], surface.lattice)
        E, G, H = scatter(pm_act, E, grad, hess, order)
        pressure = np.zeros(surface.n_nodes)
        pressure[pr["node"][sel]] = -stiffness * g[sel]
        info = {
            "active": int(sel.size),
            "max_penetration": float(-g[sel].min()) if sel.size else 0.0,
            "pressure": pressure,
            "force": float(np.sum(weight[sel] * pressure[pr["node"][sel]])),
        }
        return E, G, H, info


@hookimpl
def register_contact_laws(register):
    register(SolidPenalty)
