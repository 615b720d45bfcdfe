"""Quality of a cell mesh: dihedral angles, aspect ratios, Jacobians and volume."""

from __future__ import annotations

import numpy as np

from knitframe.numerics.mesh.cell import CellMesh

__all__ = ["mesh_quality"]


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
