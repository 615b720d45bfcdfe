"""The swept cross-section (a unit disc triangulated by gmsh) and arc-length sampling of centerlines."""

from __future__ import annotations

import functools
from typing import Any

import attrs
import numpy as np

from knitframe.errors import GeometryError

__all__ = ["Section", "section_mesh", "arc_length_samples"]


@attrs.frozen(eq=False)
class Section:
    """Triangulated unit disc: the cross-section swept along every yarn."""

    #: (n, 2) coordinates in the unit disc, -
    points: np.ndarray
    #: (m, 3) vertex indices, counter-clockwise
    triangles: np.ndarray
    #: (n,) bool, vertex on the unit circle
    boundary: np.ndarray
    #: (k, 2) sorted vertex pairs of the circle's edges
    boundary_edges: np.ndarray


@functools.lru_cache(maxsize=16)
def section_mesh(h: float) -> Section:
    """Unit disc meshed by gmsh with target element size ``h`` (fraction of the radius).

    Boundary vertices are projected exactly onto the unit circle, triangles are oriented
    counter-clockwise and vertices are renumbered in reverse Cuthill-McKee order so that the
    swept mesh has a small bandwidth.
    """
    try:
        import gmsh
    except ImportError:  # the volumetric extra
        raise GeometryError('meshing needs gmsh: pip install "knitframe[volumetric]"') from None
    if not 0.02 <= h <= 1.5:
        raise GeometryError(f"mesh seed must be in [0.02, 1.5] radii, got {h}")
    started = gmsh.isInitialized()
    if not started:
        gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("knitframe-section")
        gmsh.model.occ.addDisk(0.0, 0.0, 0.0, 1.0, 1.0)
        gmsh.model.occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.Algorithm", 6)  # Frontal-Delaunay: near-equilateral triangles
        gmsh.model.mesh.generate(2)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, _, enodes = gmsh.model.mesh.getElements(2)
        gmsh.model.remove()
    finally:
        if not started:
            gmsh.finalize()
    pts_all = xyz.reshape(-1, 3)[:, :2]
    lookup = np.zeros(int(tags.max()) + 1, dtype=np.int64)
    lookup[tags.astype(np.int64)] = np.arange(tags.size)
    tri = lookup[np.asarray(enodes[0], dtype=np.int64).reshape(-1, 3)]
    used = np.unique(tri)
    remap = np.full(pts_all.shape[0], -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    pts, tri = pts_all[used], remap[tri]
    # Reverse Cuthill-McKee keeps the swept system's bandwidth small for the direct solvers.
    import scipy.sparse as sp
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    n = pts.shape[0]
    e = tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    adj = sp.coo_matrix((np.ones(e.shape[0]), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    perm = np.asarray(reverse_cuthill_mckee(adj + adj.T, symmetric_mode=True))
    inv = np.empty(n, dtype=np.int64)
    inv[perm] = np.arange(n)
    pts, tri = pts[perm], inv[tri]
    d1, d2 = pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]]
    area2 = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    tri[area2 < 0] = tri[area2 < 0][:, [0, 2, 1]]
    edges = np.sort(tri[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    bedges = uniq[count == 1]
    boundary = np.zeros(n, dtype=bool)
    boundary[bedges.ravel()] = True
    pts[boundary] /= np.linalg.norm(pts[boundary], axis=1, keepdims=True)
    for a in (pts, tri, boundary, bedges):
        a.setflags(write=False)
    return Section(pts, tri, boundary, bedges)


def arc_length_samples(centerline: Any, n: int, *, resolution: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Parameters t_k of n + 1 points equally spaced in arc length, and their arc lengths s_k.

    The arc length s(t) = ∫ |r'(τ)| dτ is integrated with Simpson's rule on ``resolution`` · n
    sub-intervals and inverted by monotone interpolation; points are then exact on the curve.

    Returns
    -------
    t, s : (n + 1,) arrays; t[0] = t0, t[-1] = t1, s in mm.
    """
    m = 2 * max(resolution * n, 256)
    tf = np.linspace(centerline.t0, centerline.t1, m + 1)
    speed = np.linalg.norm(np.asarray(centerline.derivative(tf), dtype=np.float64), axis=1)
    dt = tf[2] - tf[0]
    pieces = dt / 6.0 * (speed[:-2:2] + 4.0 * speed[1:-1:2] + speed[2::2])
    s_even = np.concatenate([[0.0], np.cumsum(pieces)])
    t_even = tf[::2]
    total = s_even[-1]
    if not np.isfinite(total) or total <= 0:
        raise GeometryError(
            f"yarn '{getattr(centerline, 'name', '?')}': centerline has no finite positive length"
        )
    s = np.linspace(0.0, total, n + 1)
    t = np.interp(s, s_even, t_even)
    t[0], t[-1] = centerline.t0, centerline.t1
    return t, s
