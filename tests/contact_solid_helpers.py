"""Small solid-contact problems shared by the contact tests: stacked blocks and a cylinder on a flat."""

from __future__ import annotations

import numpy as np
import skfem
from knitframe_linsolvers.direct import direct
from knitframe_solvers.volumetric_material import SolidForms, YarnLaw
from knitframe_yarns.isotropic import Isotropic

from knitframe.numerics.contact import SolidSurface
from knitframe.numerics.contact_search import SegmentTopology
from knitframe.numerics.mesh import surface_facets
from knitframe.numerics.newton import NewtonOptions, minimise


def join(meshes: list, order: int):
    """One mesh from separate P1 bodies (body id per node), raised to P2 if asked."""
    p, t, off = [], [], 0
    for m in meshes:
        p.append(m.p)
        t.append(m.t + off)
        off += m.p.shape[1]
    m1 = skfem.MeshTet1(np.hstack(p), np.hstack(t))
    vbody = np.concatenate([np.full(m.p.shape[1], b) for b, m in enumerate(meshes)])
    if order == 1:
        return m1, vbody
    m2 = skfem.MeshTet2.from_mesh(m1)
    ebody = vbody[m1.edges[0]]
    return m2, np.concatenate([vbody, ebody])


def nodes(mesh) -> np.ndarray:
    return mesh.doflocs.T if isinstance(mesh, skfem.MeshTet2) else mesh.p.T


def surface(mesh, body: np.ndarray, slave_facets: np.ndarray, master_facets: np.ndarray) -> SolidSurface:
    """Contact surface with one strand per body (bodies never contact themselves)."""
    fs, fm = surface_facets(mesh, slave_facets), surface_facets(mesh, master_facets)
    n = nodes(mesh).shape[0]
    nb = int(body.max()) + 1
    topo = SegmentTopology(body, np.zeros(n, np.int64), np.zeros(n), np.zeros(nb, np.int64), np.zeros(nb))
    return SolidSurface.build(
        nodes(mesh),
        np.vstack([fs, fm]),
        np.arange(len(fs)),
        np.arange(len(fs), len(fs) + len(fm)),
        topo,
        exclusion=1.0,
    )


def stacked_blocks(order: int):
    """Block z ∈ [0, 0.5] (body 0, 3×3×2 cells) under a block z ∈ [0.5, 1] (body 1, 5×4×2 cells), unit square.

    Returns (mesh, body, surface with the upper block's bottom as slave and the lower's top as
    master, number of lower-block tetrahedra).
    """
    lo = skfem.MeshTet1.init_tensor(np.linspace(0, 1, 4), np.linspace(0, 1, 4), np.linspace(0, 0.5, 3))
    hi = skfem.MeshTet1.init_tensor(np.linspace(0, 1, 6), np.linspace(0, 1, 5), np.linspace(0.5, 1, 3))
    mesh, body = join([lo, hi], order)
    X = nodes(mesh)
    bf = mesh.boundary_facets()
    fz, vb = X[mesh.facets[:, bf], 2], body[mesh.facets[0, bf]]
    at = np.all(np.isclose(fz, 0.5), axis=0)
    return mesh, body, surface(mesh, body, bf[(vb == 1) & at], bf[(vb == 0) & at]), lo.t.shape[1]


def solve(
    forms: SolidForms,
    law,
    surf: SolidSurface,
    u0: np.ndarray,
    free: np.ndarray,
    stiffness: float,
    reach: float,
    friction_state=None,
):
    """Equilibrium of elasticity + contact (+ lagged friction) by the shared Newton driver; returns
    (u, contact info)."""
    X = nodes(forms.mesh)
    n = forms.ndof

    def fun(u, order):
        E = forms.energy(u)
        if not np.isfinite(E):
            return np.inf, None, None, {}
        Ec, gc, Hc, info = law.evaluate(
            surf,
            X + u.reshape(-1, 3),
            None,
            order,
            stiffness=stiffness,
            reach=reach,
            friction_state=friction_state,
        )
        if order == 0:
            return E + Ec, None, None, info
        g = forms.residual(u) + gc[:n]
        if order == 1:
            return E + Ec, g, None, info
        return E + Ec, g, forms.tangent(u) + Hc[:n, :n], info

    res = minimise(
        fun, u0, free, solve=direct(), options=NewtonOptions(atol=1e-10, rtol=1e-8, max_iter=60, xtol=1e-12)
    )
    return res.x, fun(res.x, 1)[3]


def iso(E: float, nu: float) -> YarnLaw:
    return YarnLaw(Isotropic(E_axial=E, radius=1.0, nu=nu))


def hertz_supports(mesh, body: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Supports of the cylinder-on-flat Hertz problem: nodes X, fixed DOFs (N, 3) and the cylinder's
    axis-plane nodes ``sym`` (y = 0, loaded by their prescribed y-displacement): plane strain (z
    fixed), the flat rigid (all fixed), symmetry at x = 0."""
    X = nodes(mesh)
    fixed = np.zeros((len(X), 3), bool)
    fixed[:, 2] = True
    fixed[body == 1] = True
    fixed[(body == 0) & np.isclose(X[:, 0], 0), 0] = True
    sym = (body == 0) & np.isclose(X[:, 1], 0)
    fixed[sym, 1] = True
    return X, fixed, sym


def quarter_cylinder_on_flat(R: float, h_contact: float, h_far: float, thickness: float, order: int):
    """Quarter disc x ≥ 0, y ≤ 0 of radius R (one element thick in z) above a flat block touching at (0, −R).

    Returns (mesh, body, slave facets (arc), master facets (block top)).
    """
    import gmsh

    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        geo = gmsh.model.geo
        c = geo.addPoint(0, 0, 0, h_far)
        p1 = geo.addPoint(R, 0, 0, h_far)
        p2 = geo.addPoint(0, -R, 0, h_contact)
        arc = geo.addCircleArc(p1, c, p2)
        l1 = geo.addLine(p2, c)
        l2 = geo.addLine(c, p1)
        s = geo.addPlaneSurface([geo.addCurveLoop([arc, l1, l2])])
        geo.extrude([(2, s)], 0, 0, thickness, numElements=[1])
        geo.synchronize()
        # grade the size away from the contact point
        f = gmsh.model.mesh.field.add("Distance")
        gmsh.model.mesh.field.setNumbers(f, "PointsList", [p2])
        th = gmsh.model.mesh.field.add("MathEval")
        gmsh.model.mesh.field.setString(th, "F", f"min({h_contact} + 0.35*F{f}, {h_far})")
        gmsh.model.mesh.field.setAsBackgroundMesh(th)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.model.mesh.generate(3)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, _, en = gmsh.model.mesh.getElements(3)
    finally:
        gmsh.finalize()
    lookup = np.zeros(int(tags.max()) + 1, np.int64)
    lookup[tags.astype(np.int64)] = np.arange(tags.size)
    tet = lookup[np.asarray(en[0], np.int64).reshape(-1, 4)]
    used = np.unique(tet)
    remap = np.full(tags.size, -1)
    remap[used] = np.arange(used.size)
    cyl = skfem.MeshTet1(xyz.reshape(-1, 3)[used].T.copy(), remap[tet].T.copy())
    nb = max(int(round(0.5 * R / h_contact / 4)), 4)
    block = skfem.MeshTet1.init_tensor(
        np.linspace(0, 0.5 * R, nb + 1), np.linspace(-1.2 * R, -R, 3), np.linspace(0, thickness, 2)
    )
    mesh, body = join([cyl, block], order)
    if order == 2:
        # curved isoparametric arc: push the arc's mid-edge nodes onto the circle
        X = mesh.doflocs.copy()
        r = np.hypot(X[0], X[1])
        on_arc = (body == 0) & (np.abs(r - R) < 0.02 * h_far) & (X[1] < -1e-12) & (X[0] > 1e-12)
        X[:2, on_arc] *= R / r[on_arc]
        mesh = skfem.MeshTet2(X, mesh.t)
    Xn = nodes(mesh)
    bf = mesh.boundary_facets()
    fx = Xn[mesh.facets[:, bf]]  # (3, nbf, 3)
    vb = body[mesh.facets[0, bf]]
    rr = np.hypot(fx[..., 0], fx[..., 1])
    arc_f = bf[
        (vb == 0)
        & np.all(np.abs(rr - R) < 1e-6 * R + 0.01 * h_contact, axis=0)
        & ~np.all(np.isclose(fx[..., 2], fx[0:1, :, 2]), axis=0)
    ]
    top_f = bf[(vb == 1) & np.all(np.isclose(fx[..., 1], -R), axis=0)]
    return mesh, body, arc_f, top_f


def image_blocks():
    """A slave block's right face (x = 1) meets the left face (master) of the periodic image of a
    second block.

    Block A = [0.5, 1] x [0.2, 0.8] x [0.1, 0.4] (slave: its right face) and block B =
    [0, 0.4] x [0, 1] x [0, 0.5] (master: its left face), whose image one lattice vector
    L1 = (0.98, 0.0731) on overlaps A by 0.02. The master face is larger than the slave one and
    meshed differently, so that no slave node lies over a master edge or beyond the master's rim
    (the gap has kinks there). Returns (X, surface, n_nodes).
    """
    import skfem

    from knitframe.numerics.contact import SolidSurface
    from knitframe.numerics.contact_search import SegmentTopology
    from knitframe.numerics.mesh import surface_facets
    from knitframe.numerics.periodic import Lattice

    a = skfem.MeshTet1.init_tensor(np.linspace(0.5, 1, 3), np.linspace(0.2, 0.8, 4), np.linspace(0.1, 0.4, 3))
    b = skfem.MeshTet1.init_tensor(np.linspace(0, 0.4, 3), np.linspace(0, 1, 5), np.linspace(0, 0.5, 4))
    m, body = join([a, b], 1)
    X = m.p.T
    bf = m.boundary_facets()
    fx = X[m.facets[:, bf], 0]
    right, left = bf[np.all(np.isclose(fx, 1), axis=0)], bf[np.all(np.isclose(fx, 0), axis=0)]
    facets = np.vstack([surface_facets(m, right), surface_facets(m, left)])
    n = len(X)
    topo = SegmentTopology(body, np.zeros(n, np.int64), np.zeros(n), np.zeros(2, np.int64), np.zeros(2))
    lattice = Lattice([0.98, 0.0731, 0], [0, 3.0, 0])
    surf = SolidSurface.build(
        X, facets, np.arange(len(right)), np.arange(len(right), len(facets)), topo, 1.0, lattice
    )
    return X, surf, n


def assert_derivatives(f, u, du, n):
    """Central differences of ``f(v, order) -> (E, g, H, info)`` along du match g·du and H·du on the
    n node DOFs."""
    E, g, H, info = f(u, 2)
    h = 1e-7
    fd_g = (f(u + h * du, 0)[0] - f(u - h * du, 0)[0]) / (2 * h)
    fd_H = (f(u + h * du, 1)[1] - f(u - h * du, 1)[1])[:n] / (2 * h)
    assert abs(g[:n] @ du - fd_g) < 1e-6 * abs(fd_g)
    assert np.linalg.norm(H[:n, :n] @ du - fd_H) < 1e-6 * np.linalg.norm(fd_H)
    return info
