"""Shells of a scan: surface moments, connected shells, and the choice of the limb's shell."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from knitframe.errors import DataError
from knitframe.garment.limb.sections import _perpendicular
from knitframe.garment.limb.slicing import _Slicer

#: disconnected pieces with less than this fraction of the largest shell's area are scan debris
FRAGMENT_AREA_FRACTION = 0.01


def _surface_moments(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Area, area centroid (3,) and covariance (3, 3) of a triangulated surface (exact).

    For a triangle (a, b, c) of area A: ∫x dA = A s/3 and ∫xxᵀ dA = A/12 (ssᵀ + aaᵀ + bbᵀ + ccᵀ),
    s = a + b + c. Coordinates are taken relative to the vertex mean for conditioning.
    """
    shift = vertices.mean(axis=0)
    tri = vertices[faces] - shift
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    total = float(area.sum())
    s = tri.sum(axis=1)
    centroid = (area @ s) / (3.0 * total)
    second = (np.einsum("f,fi,fj->ij", area, s, s) + np.einsum("f,fvi,fvj->ij", area, tri, tri)) / (
        12.0 * total
    )
    cov = second - np.outer(centroid, centroid)
    return total, centroid + shift, cov


def _canonical_sign(v: np.ndarray) -> np.ndarray:
    """v or -v, whichever has its largest-magnitude component positive."""
    return v if v[int(np.argmax(np.abs(v)))] >= 0.0 else -v


def _components(faces: np.ndarray, n_vertices: int) -> tuple[int, np.ndarray]:
    """Connected shells: (count, shell label of each face), via the vertex graph of the edges."""
    e = np.concatenate((faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]))
    g = sparse.coo_matrix(
        (np.ones(len(e), dtype=np.int8), (e[:, 0], e[:, 1])), shape=(n_vertices, n_vertices)
    )
    count, labels = csgraph.connected_components(g, directed=False)
    used, face_label = np.unique(labels[faces[:, 0]], return_inverse=True)
    return len(used), face_label.reshape(-1)


def _submesh(vertices: np.ndarray, faces: np.ndarray) -> Any:
    """A trimesh.Trimesh of only the vertices these faces use."""
    import trimesh

    used, inverse = np.unique(faces, return_inverse=True)
    return trimesh.Trimesh(vertices[used], inverse.reshape(faces.shape), process=False)


def _choose_shell(vertices: np.ndarray, faces: np.ndarray, label: str) -> tuple[np.ndarray, list[str]]:
    """Faces of the limb's shell, and notices. See :meth:`Limb.from_scan` step 2."""
    count, face_label = _components(faces, len(vertices))
    if count == 1:
        return faces, []
    tri = vertices[faces]
    areas = np.bincount(
        face_label,
        weights=0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1),
        minlength=count,
    )
    order = np.argsort(-areas)
    main = int(order[0])
    fragments = [int(s) for s in order[1:] if areas[s] < FRAGMENT_AREA_FRACTION * areas[main]]
    others = [int(s) for s in order[1:] if areas[s] >= FRAGMENT_AREA_FRACTION * areas[main]]
    main_faces = faces[face_label == main]
    notes = []
    if others:
        outer = _submesh(vertices, main_faces)
        _, center, cov = _surface_moments(vertices, main_faces)
        d = np.linalg.eigh(cov)[1][:, 2]
        slicer = _Slicer(outer, center, d)
        f1 = _perpendicular(d)
        f2 = np.cross(f1, d)
        outside = 0
        for s in others:
            idx = np.unique(faces[face_label == s])
            sample = vertices[idx[np.unique(np.linspace(0, len(idx) - 1, 24).astype(np.int64))]]
            h = (vertices[idx] - center) @ d
            sample = np.vstack((sample, vertices[idx[[np.argmin(h), np.argmax(h)]]]))
            if not all(_inside_section(slicer, f1, f2, p) for p in sample):
                outside += 1
        if outside:
            raise DataError(
                label,
                f"{len(others) + 1} separate shells side by side ({outside} not inside the "
                "largest): ambiguous which is the limb (two limbs?); crop the scan to one limb",
            )
        inner = len(others)
        notes.append(
            f"outer shell of {inner + 1} chosen; {inner} inner shell{'s' if inner > 1 else ''} ignored"
        )
    if fragments:
        k = len(fragments)
        notes.append(
            f"{k} small disconnected fragment{'s' if k > 1 else ''} (each under "
            f"{FRAGMENT_AREA_FRACTION:.0%} of the limb's area) ignored"
        )
    return main_faces, notes


def _inside_section(slicer: _Slicer, f1: np.ndarray, f2: np.ndarray, p: np.ndarray) -> bool:
    """Whether point p lies inside the shell's cross-section through it (even–odd ray test)."""
    z = float((p - slicer.origin) @ slicer.d)
    if not slicer.hsorted[0] < z < slicer.hsorted[-1]:
        return False
    seg = slicer.segments(float(slicer.off_vertices(np.array([z]))[0])) - slicer.origin
    a = np.stack((seg[:, 0] @ f1, seg[:, 0] @ f2), axis=1)
    b = np.stack((seg[:, 1] @ f1, seg[:, 1] @ f2), axis=1)
    q = np.array([(p - slicer.origin) @ f1, (p - slicer.origin) @ f2])
    cross = (a[:, 1] > q[1]) != (b[:, 1] > q[1])
    dy = np.where(cross, b[:, 1] - a[:, 1], 1.0)
    xi = a[:, 0] + (q[1] - a[:, 1]) / dy * (b[:, 0] - a[:, 0])
    return bool(np.count_nonzero(cross & (xi > q[0])) % 2 == 1)
