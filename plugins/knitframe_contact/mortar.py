"""Contact law ``mortar``: segment-to-segment penalty contact integrated over the slave surface.

The gap is measured at the quadrature points of every slave triangle, x_q = Σ_i N_i(ξ_q) x_i, to
the nearest opposing master triangle (another yarn, a periodic image, or a distant part of the
same yarn), and the penalty energy is integrated over the slave surface::

    W = ∫_Γs ½ ε ⟨−g(x)⟩² dA ≈ Σ_f Σ_q ½ ε w_q A_f ⟨−g(x_q)⟩²

so the contact traction ε⟨−g⟩ is a field on the slave surface, not a set of nodal forces: a
uniform pressure is transmitted as a uniform pressure (contact patch test), and the force on
the master side is integrated consistently through the master's shape functions at the
projection points. The gradient and Hessian are exact for the current pairing (Gauss-point-to-
segment form of the penalty mortar method; the integration is by quadrature on the slave
triangles rather than by clipping against the master segments, which is exact for flat contact
and converges with ``quadrature`` otherwise).
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np

from knitframe import hookimpl, validators as v
from knitframe.periodic import PointMap
from knitframe_contact.penalty import default_stiffness
from knitframe_contact.solid_geometry import (
    SolidSurface, facet_gap, nearest, p2_shape, penalty_terms, plane_gap, point_triangle_distance, project_p2, scatter,
)


def triangle_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric points (q, 3) and weights (q,) summing to 1 of scikit-fem's triangle rule of ``order``."""
    from skfem.quadrature import get_quadrature
    from skfem.refdom import RefTri

    X, W = get_quadrature(RefTri, order)
    return np.column_stack([1.0 - X[0] - X[1], X[0], X[1]]), W / W.sum()


@attrs.frozen
class SolidMortar:
    """Segment-to-segment penalty contact integrated over the slave surface (solid meshes)."""

    name: ClassVar[str] = "mortar"
    description: ClassVar[str] = "segment-to-segment penalty contact integrated over the slave surface (solid)"
    discretisation: ClassVar[str] = "solid"

    stiffness: float | None = attrs.field(default=None, validator=v.optional(v.positive))  #: ε, N/mm³; default factor·E/h
    factor: float = attrs.field(default=10.0, validator=v.positive)  #: ε = factor · E / h when stiffness is not given, -
    quadrature: int = attrs.field(default=4, validator=v.in_range(1, 19))  #: polynomial order of the slave-triangle rule, -

    def penalty(self, modulus: float, size: float) -> float:
        """Penalty stiffness ε (N/mm³) for contact modulus E (MPa) and element size h (mm)."""
        return default_stiffness(self.stiffness, self.factor, modulus, size)

    def evaluate(self, surface: SolidSurface, x: np.ndarray, h: np.ndarray | None, order: int, *,
                 stiffness: float, reach: float) -> tuple[float, Any, Any, dict[str, Any]]:
        """Energy (N·mm), gradient and Hessian in q = [u (3N), h (6)], and diagnostics (see ``penalty``)."""
        quadratic = surface.facets.shape[1] == 6
        lam, w = triangle_rule(self.quadrature)
        if quadratic:
            N_q, dN_q = p2_shape(lam[:, 1:])
        else:
            N_q = lam
        nq = w.size
        sf = surface.facets[surface.slave]  # (F, 3 or 6)
        xs = x[sf]
        xq = np.einsum("qi,fik->fqk", N_q, xs).reshape(-1, 3)
        if quadratic:
            # area element |X_ξ × X_η| of the reference facet at each point (curved facets)
            Jr = np.einsum("qia,fik->fqka", dN_q, surface.X[sf])
            Jc = np.einsum("qia,fik->fqka", dN_q, xs)
            dA = 0.5 * np.linalg.norm(np.cross(Jr[..., 0], Jr[..., 1]), axis=-1).reshape(-1)
            ns_q = np.cross(Jc[..., 0], Jc[..., 1]).reshape(-1, 3)
        else:
            dA = np.repeat(surface.area[surface.slave], nq)
            ns_q = np.repeat(np.cross(xs[:, 1] - xs[:, 0], xs[:, 2] - xs[:, 0]), nq, axis=0)
        face = np.repeat(np.arange(len(sf)), nq)
        qidx = np.tile(np.arange(nq), len(sf))
        cand = surface.candidates(xq, sf[face, 0], x, h, reach, quadratic=quadratic)
        mel = surface.facets[cand.triangle]
        Xm = x[mel] + cand.shift[:, None, :]
        p = xq[cand.point]
        if quadratic:
            g_c, _, dist = facet_gap(p, Xm, order=0)
            nm = project_p2(p, Xm)[2]
            inside = np.abs(dist - np.abs(g_c)) <= 1e-9 * reach  # the closest point is not on the facet's rim
        else:
            dist, inside = point_triangle_distance(p, Xm[:, 0], Xm[:, 1], Xm[:, 2])
            nm = np.cross(Xm[:, 1] - Xm[:, 0], Xm[:, 2] - Xm[:, 0])
        ok = (np.einsum("ij,ij->i", nm, ns_q[cand.point]) < 0) & (dist < reach)
        # prefer a facet the point projects into: switching between those keeps the gap continuous
        rank = dist + np.where(inside, 0.0, 2.0 * reach)
        rows = np.flatnonzero(ok)[nearest(cand.point[ok], rank[ok])]
        point, tri_m, img, Xm = cand.point[rows], cand.triangle[rows], cand.image[rows], Xm[rows]
        if quadratic:
            g, dgm, _ = facet_gap(xq[point], Xm, order=min(order, 1))
            Hg = None
        else:
            g, dgm, Hg = plane_gap(xq[point], Xm[:, 0], Xm[:, 1], Xm[:, 2], order=order)
        sel = np.flatnonzero((g < 0) & (g > -reach))
        f, q, g = face[point[sel]], qidx[point[sel]], g[sel]
        N = N_q[q]  # (m, k) slave shape functions at the points
        weight = w[q] * dA[point[sel]]
        k = N.shape[1]
        dg = None
        if order >= 1:
            dgp = dgm[sel]
            # chain rule: the slave point moves with its facet's nodes, x_q = Σ N_i x_i
            dg = np.concatenate([N[:, :, None] * dgp[:, None, 0, :], dgp[:, 1:]], axis=1)
        Hfull = None
        if order == 2 and Hg is not None:
            H = Hg[sel]
            Hfull = np.zeros((len(sel), 2 * k, 3, 2 * k, 3))
            Hfull[:, :k, :, :k, :] = np.einsum("mi,mj,mkl->mikjl", N, N, H[:, 0, :, 0, :])
            Hfull[:, :k, :, k:, :] = np.einsum("mi,mkbl->mikbl", N, H[:, 0, :, 1:, :])
            Hfull[:, k:, :, :k, :] = np.einsum("mj,makl->makjl", N, H[:, 1:, :, 0, :])
            Hfull[:, k:, :, k:, :] = H[:, 1:, :, 1:, :]
        E, grad, hess = penalty_terms(g, dg, Hfull, weight, stiffness, order)
        nodes = np.column_stack([sf[f], surface.facets[tri_m[sel]]])
        images = np.zeros((len(nodes), 2 * k, 2), np.int64)
        images[:, k:] = img[sel][:, None, :]
        E, G, Hm = scatter(PointMap(surface.n_nodes, nodes, images, surface.lattice), E, grad, hess, order)
        # nodal pressure for output: area-weighted mean of ε⟨−g⟩ over the points of the node's facets
        num, den = np.zeros(surface.n_nodes), np.zeros(surface.n_nodes)
        wq = w[qidx] * dA
        np.add.at(den, np.repeat(sf, nq, axis=0).ravel(), np.repeat(wq, k))
        np.add.at(num, sf[f].ravel(), np.repeat(weight * stiffness * (-g), k))
        pressure = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
        info = {
            "active": int(sel.size),
            "max_penetration": float(-g.min()) if sel.size else 0.0,
            "pressure": pressure,
            "force": float(np.sum(weight * stiffness * (-g))),
        }
        return E, G, Hm, info


@hookimpl
def register_contact_laws(register):
    register(SolidMortar)
