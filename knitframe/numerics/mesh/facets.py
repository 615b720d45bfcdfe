"""Boundary facets of a tetrahedral mesh as node arrays (P1 or P2), and their linear sub-triangles."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["surface_facets", "split_facets"]


def surface_facets(mesh: Any, facets: np.ndarray) -> np.ndarray:
    """Boundary ``facets`` as node arrays, normals outward: (M, 3) for P1, (M, 6) for P2.

    Node numbering as in :class:`CellMesh` (P2: vertices, then one node per edge). A quadratic
    facet lists its corners v0, v1, v2 and then its edge nodes e01, e12, e20.
    """
    facets = np.asarray(facets, dtype=np.int64)
    tri = mesh.facets[:, facets].T.copy()
    x = mesh.p.T
    # outward: away from the centroid of the facet's (only) tetrahedron
    tet = mesh.f2t[0, facets]
    inward = x[mesh.t[:, tet]].mean(axis=0) - x[tri].mean(axis=1)
    nrm = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
    flip = np.einsum("ij,ij->i", nrm, inward) > 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    if not isinstance(mesh, _mesh_tet2()):
        return tri
    nv = mesh.nvertices
    ekey = np.sort(mesh.edges, axis=0)
    ekey = ekey[0] * nv + ekey[1]
    order_e = np.argsort(ekey)

    def edge_node(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        k = np.minimum(a, b) * nv + np.maximum(a, b)
        return nv + order_e[np.searchsorted(ekey, k, sorter=order_e)]

    v0, v1, v2 = tri.T
    return np.column_stack([v0, v1, v2, edge_node(v0, v1), edge_node(v1, v2), edge_node(v2, v0)])


def split_facets(facets: np.ndarray) -> np.ndarray:
    """Linear triangles of facets (M, 3) → themselves, (M, 6) → their 4 sub-triangles (4M, 3), block-wise.

    Sub-triangle k of facet f is row k·M + f: the three corner triangles, then the middle one.
    """
    if facets.shape[1] == 3:
        return facets
    v0, v1, v2, e01, e12, e20 = facets.T
    return np.concatenate(
        [np.stack(s, axis=1) for s in ((v0, e01, e20), (e01, v1, e12), (e20, e12, v2), (e01, e12, e20))]
    )


def _mesh_tet2() -> type:
    import skfem

    return skfem.MeshTet2
