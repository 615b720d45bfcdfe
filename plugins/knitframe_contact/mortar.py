"""Contact law ``mortar``: segment-to-segment penalty contact integrated over the slave surface.

The gap is measured at the quadrature points of every slave facet, x_q = Σ_i N_i(ξ_q) x_i, to
the nearest opposing master facet (another yarn, a periodic image, or a distant part of the
same yarn), and the penalty energy is integrated over the slave surface::

    W = ∫_Γs ½ ε ⟨−g(x)⟩² dA ≈ Σ_f Σ_q ½ ε w_q A_f ⟨−g(x_q)⟩²

(faded out across the last half of the search reach, so that a pair entering the search does
not make the energy jump; :meth:`SolidContactLaw.band`), so the contact traction ε⟨−g⟩ is a
field on the slave surface, not a set of nodal forces: a uniform pressure is transmitted as a
uniform pressure (contact patch test), and the force on the master side is integrated
consistently through the master's shape functions at the projection points. On linear facets g
is the distance to the master triangle's plane; on quadratic facets it is the signed distance to
the closest point x(ξ*) of the curved master facet, n·(x_q − x(ξ*)) inside it, so that it stays
continuous where the nearest facet changes (beyond an open edge of the master surface, the
facet's polynomial continuation; :func:`knitframe.numerics.contact.select_pairs`). On
linear meshes the master surface is by default smoothed (``smoothing = "nagata"``): each master
triangle becomes the quadratic patch through its corners' nodal normals
(:func:`knitframe.numerics.contact.nagata_facets`), with the normals frozen for the
increment, so that the gap does not kink at facet edges. The gradient
and Hessian are exact for the current pairing, including the second derivative of the
closest-point projection on curved facets
(:func:`knitframe.numerics.contact.p2_gap_derivatives`; Gauss-Newton only where the
continuation has no closest point near the facet). This is the Gauss-point-to-segment form of
the penalty mortar method; the integration is by quadrature on the slave facets rather than by
clipping against the master segments, which is exact for flat contact and converges with
``quadrature`` otherwise.

Friction (only when the solver passes a ``friction_state``): regularised Coulomb friction with
the normal force lagged from the last converged state. :meth:`SolidMortar.friction_state`
freezes the active quadrature points with their normal force λ_q = ε w_q A_f ⟨−g_q⟩, the master
normal n and the master's material point ξ* under them; :meth:`SolidMortar.evaluate` then adds::

    D = Σ_q μ λ_q ε_s f0(|u_T,q| / ε_s),   u_T = (I − n nᵀ)[(x_q − x_m(ξ*)) − (x_q − x_m(ξ*))₀]
    f0(y) = y² − y³/3 (y < 1),  y − 1/3 (y ≥ 1)

(the slip of the slave point against the same material point of the master, x_m including the
image shift F̄·S_k; ε_s = ``slip`` × the slave facet's size), whose tangential force rises
smoothly to μ λ_q at the slip ε_s (:func:`knitframe.numerics.contact.friction_terms`).
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
    combine,
    facet_size,
    finish_evaluation,
    p2_gap_derivatives,
    p2_shape,
    penalty_terms,
    plane_gap,
    select_pairs,
)
from knitframe_contact.penalty import SolidContactLaw


def triangle_rule(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Barycentric points (q, 3) and weights (q,) summing to 1 of scikit-fem's triangle rule of ``order``."""
    from skfem.quadrature import get_quadrature
    from skfem.refdom import RefTri

    X, W = get_quadrature(RefTri, order)
    return np.column_stack([1.0 - X[0] - X[1], X[0], X[1]]), W / W.sum()


def _take(pr: P2Projection, rows: np.ndarray) -> P2Projection:
    return P2Projection(*(getattr(pr, f.name)[rows] for f in attrs.fields(P2Projection)))


@attrs.frozen
class SolidMortar(SolidContactLaw):
    """Segment-to-segment penalty contact integrated over the slave surface (solid meshes)."""

    name: ClassVar[str] = "mortar"
    description: ClassVar[str] = (
        "segment-to-segment penalty contact integrated over the slave surface (solid)"
    )

    #: polynomial order of the slave-triangle rule, -
    quadrature: int = attrs.field(default=4, validator=v.in_range(1, 19))

    def _pairs(
        self,
        surface: SolidSurface,
        x: np.ndarray,
        h: np.ndarray | None,
        reach: float,
        order: int,
        normals: np.ndarray | None = None,
        held: Candidates | None = None,
    ) -> dict[str, Any]:
        """Active quadrature-point pairs of state x: gaps (and their derivatives up to ``order``);
        with ``held`` the pairs are chosen from those candidates (:meth:`search`)."""
        quadratic = surface.facets.shape[1] == 6
        smooth = self.smoothed(surface)
        N_q, w, sf, xq, dA, ns_q = self._slave_points(surface, x, quadratic)
        nq = w.size
        face = np.repeat(np.arange(len(sf)), nq)
        qidx = np.tile(np.arange(nq), len(sf))
        cand = self.search(surface, xq, sf[face, 0], x, h, reach, held, quadratic=quadratic, group=nq)
        elements = surface.facets if quadratic else surface.triangles
        Xm = x[elements[cand.triangle]] + cand.shift[:, None, :]
        Xp = self.patches(surface, x, cand.triangle, cand.shift, normals) if smooth else Xm
        chosen = select_pairs(
            xq[cand.point],
            cand.point,
            cand.triangle,
            Xp,
            ns_q[cand.point],
            reach,
            open_rim=surface.open_rim(cand.triangle, quadratic),
            corner_normals=self.corner_normals(surface, cand.triangle, normals),
        )
        rows, g = chosen.rows, chosen.g
        point, Xm = cand.point[rows], Xm[rows]
        sel = np.flatnonzero((g < 0) & (g > -reach))
        point, Xm, g = point[sel], Xm[sel], g[sel]
        f, q = face[point], qidx[point]
        N = N_q[q]  # (m, k) slave shape functions at the points
        out = {
            "quadratic": quadratic,
            "f": f,
            "q": q,
            "N": N,
            "g": g,
            "Xm": Xm,
            "p": xq[point],
            "master": cand.triangle[rows[sel]],
            "image": cand.image[rows[sel]],
            "weight": w[q] * dA[point],
            "sf": sf,
            "nq": nq,
            "dA": dA,
            "w": w,
            "qidx": qidx,
            "candidates": cand,
        }
        self._gap_derivatives(out, surface, chosen.projection, sel, order, normals)
        return out

    def _slave_points(
        self, surface: SolidSurface, x: np.ndarray, quadratic: bool
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The quadrature points of the slave facets at state x.

        Returns the shape functions at the rule's points N_q (nq, k) and its weights w (nq,), the
        slave facets sf (F, k), the points xq (F·nq, 3), their reference area elements dA (F·nq,) and
        the slave surface's normals there ns_q (F·nq, 3).
        """
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
        return N_q, w, sf, xq, dA, ns_q

    def _gap_derivatives(
        self,
        out: dict[str, Any],
        surface: SolidSurface,
        projection: P2Projection | None,
        sel: np.ndarray,
        order: int,
        normals: np.ndarray | None,
    ) -> None:
        """Add to the pairs ``out`` of :meth:`_pairs` the master's parametric points ``xi``, unit normals
        ``normal`` and, for ``order`` ≥ 1, the gap derivatives ``dg``, ``Hg`` in (slave facet nodes,
        master element nodes); ``projection`` and ``sel``: the chosen pairs' closest points on curved
        masters and the rows of them kept."""
        N, Xm = out["N"], out["Xm"]
        if out["quadratic"]:
            pr = _take(projection, sel)
            out["xi"], out["normal"] = pr.xi, pr.n
            if order >= 1:
                out["dg"], out["Hg"] = p2_gap_derivatives(pr, Xm, N, order)
        elif self.smoothed(surface):
            pr = _take(projection, sel)
            out["xi"], out["normal"] = pr.xi, pr.n
            if order >= 1:
                out["dg"], out["Hg"] = self.patch_gap_derivatives(
                    surface, Xm, out["master"], pr, N, order, normals
                )
        else:
            A, B, C = Xm[:, 0], Xm[:, 1], Xm[:, 2]
            out["xi"] = barycentric(out["p"], A, B, C)[:, 1:]
            nrm = np.cross(B - A, C - A)
            out["normal"] = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
            if order >= 1:
                out["dg"], out["Hg"] = _flat_gap_derivatives(out["p"], N, A, B, C, order)

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
        """Freeze the active quadrature-point pairs of the converged state x for the next increment's
        friction.

        Each pair keeps its slave facet and quadrature point, master facet (linear triangle on
        P1 surfaces) and image, the master's parametric point ξ* of the projection, the normal
        force λ = ε w_q A_f ⟨−g⟩ (N), the unit master normal, and the relative position
        c₀ = x_q − x_m(ξ*) of the two material points (see the module docstring).
        """
        pr = self._pairs(surface, x, h, reach, 0, normals)
        quadratic = pr["quadratic"]
        Nm = p2_shape(pr["xi"])[0] if quadratic else np.column_stack([1.0 - pr["xi"].sum(axis=1), pr["xi"]])
        elements = surface.facets if quadratic else surface.triangles
        nodes = np.column_stack([pr["sf"][pr["f"]], elements[pr["master"]]])
        k = pr["N"].shape[1]
        images = np.zeros((len(nodes), nodes.shape[1], 2), np.int64)
        images[:, k:] = pr["image"][:, None, :]
        weights = np.column_stack([pr["N"], -Nm])
        c0 = pr["p"] - np.einsum("mk,mki->mi", Nm, pr["Xm"])
        slave = surface.slave[pr["f"]]
        return FrictionState(
            slave,
            pr["q"],
            pr["master"],
            pr["image"],
            pr["xi"],
            pr["weight"] * self.normal_pressure(pr["g"], stiffness, reach),
            pr["normal"],
            facet_size(surface)[slave],
            nodes,
            images,
            weights,
            c0,
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
        """Energy (N·mm), gradient and Hessian in q = [u (3N), h (6)], and diagnostics (see ``penalty``).

        ``normals`` (N, 3): the nodal normals that shape the smoothed master surface of linear
        meshes (``smoothing = "nagata"``), held fixed in this evaluation; default the reference
        configuration's (:meth:`master_normals`). A solver freezes them at the start of each
        increment (``node_normals`` of that state), so that the energy, gradient and Hessian of
        the increment are exactly consistent.

        With ``friction_state`` (from :meth:`friction_state` at the last converged state) the
        lagged regularised Coulomb friction of those pairs is added (module docstring).

        ``candidates``: the candidate master elements of an earlier evaluation (its
        ``info["candidates"]``) to choose pairs from instead of a broad-phase search
        (:meth:`search`); every evaluation reports the candidates it used.
        """
        pr = self._pairs(surface, x, h, reach, order, normals, candidates)
        quadratic = pr["quadratic"]
        g, f, weight, sf = pr["g"], pr["f"], pr["weight"], pr["sf"]
        E, grad, hess = penalty_terms(
            g, pr.get("dg"), pr.get("Hg"), weight, stiffness, order, self.band(reach)
        )
        pn = self.normal_pressure(g, stiffness, reach)
        elements = surface.facets if quadratic else surface.triangles
        nodes = np.column_stack([sf[f], elements[pr["master"]]])
        k = pr["N"].shape[1]
        images = np.zeros((len(nodes), 2 * k, 2), np.int64)
        images[:, k:] = pr["image"][:, None, :]
        key = _element_key(surface.slave[f], pr["master"], pr["image"], len(elements))

        def merge(terms: list) -> list:
            """The quadrature points of one slave facet on one master element (and image), with or
            without friction, summed into one element before the assembly."""
            if order < 1:
                return []
            keys = [key]
            if len(terms) > 1:  # the friction's pairs
                fs = friction_state
                keys.append(_element_key(fs.slave, fs.master, fs.image, len(elements)))
            first, grad, hess = combine(
                np.concatenate(keys), [t[2] for t in terms], [t[3] for t in terms] if order == 2 else None
            )
            nodes, images = (np.concatenate([t[i] for t in terms]) for i in (0, 1))
            return [(nodes[first], images[first], grad, hess)]

        return finish_evaluation(
            surface,
            x,
            h,
            order,
            E,
            (nodes, images, grad, hess),
            friction=self.friction,
            slip=self.slip,
            friction_state=friction_state,
            g=g,
            pressure=_nodal_pressure(surface.n_nodes, pr, weight * pn),
            force=float(np.sum(weight * pn)),
            candidates=pr["candidates"],
            merge=merge,
        )


def _element_key(slave: np.ndarray, master: np.ndarray, image: np.ndarray, n_elements: int) -> np.ndarray:
    """One integer per (slave facet, master element, image (m, 2) in −1 … 1) pair."""
    return (slave * n_elements + master) * 9 + 3 * (image[:, 0] + 1) + image[:, 1] + 1


def _nodal_pressure(n_nodes: int, pr: dict[str, Any], force: np.ndarray) -> np.ndarray:
    """Nodal pressure for output (n_nodes,), MPa: the area-weighted mean of ε⟨−g⟩ over the points of the
    node's facets; ``pr`` the pairs of :meth:`SolidMortar._pairs` and ``force`` their w ε⟨−g⟩ (N)."""
    nq, dA, w, sf = pr["nq"], pr["dA"], pr["w"], pr["sf"]
    k = pr["N"].shape[1]
    num, den = np.zeros(n_nodes), np.zeros(n_nodes)
    wq = w[pr["qidx"]] * dA
    np.add.at(den, np.repeat(sf, nq, axis=0).ravel(), np.repeat(wq, k))
    np.add.at(num, sf[pr["f"]].ravel(), np.repeat(force, k))
    return np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)


def _flat_gap_derivatives(
    p: np.ndarray, N: np.ndarray, A: np.ndarray, B: np.ndarray, C: np.ndarray, order: int
) -> tuple[np.ndarray, np.ndarray | None]:
    """Plane-gap derivatives of slave points p (m, 3) on flat master triangles (A, B, C), in (slave facet
    nodes, the triangle's corners): dg (m, 2k, 3) and, for ``order`` 2, Hg (m, 2k, 3, 2k, 3)."""
    _, dgm, H = plane_gap(p, A, B, C, order=order)
    k = N.shape[1]
    # chain rule: the slave point moves with its facet's nodes, x_q = Σ N_i x_i
    dg = np.concatenate([N[:, :, None] * dgm[:, None, 0, :], dgm[:, 1:]], axis=1)
    Hfull = None
    if order == 2:
        Hfull = np.zeros((len(p), 2 * k, 3, 2 * k, 3))
        Hfull[:, :k, :, :k, :] = np.einsum("mi,mj,mkl->mikjl", N, N, H[:, 0, :, 0, :])
        Hfull[:, :k, :, k:, :] = np.einsum("mi,mkbl->mikbl", N, H[:, 0, :, 1:, :])
        Hfull[:, k:, :, :k, :] = np.einsum("mj,makl->makjl", N, H[:, 1:, :, 0, :])
        Hfull[:, k:, :, k:, :] = H[:, 1:, :, 1:, :]
    return dg, Hfull


@hookimpl
def register_contact_laws(register):
    register(SolidMortar)
