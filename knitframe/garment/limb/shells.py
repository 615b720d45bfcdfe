"""Shells of a scan: surface moments, connected shells, and the choice of the limb's shell."""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from knitframe.errors import DataError
from knitframe.garment.limb.sections import perpendicular
from knitframe.garment.limb.slicing import Slicer

__all__ = [
    "FRAGMENT_AREA_FRACTION",
    "FEW_TRIANGLES",
    "FEW_TRIANGLES_FRACTION",
    "SMALL_SIZE_FRACTION",
    "surface_moments",
    "canonical_sign",
    "submesh",
    "Debris",
    "choose_shell",
]

# A disconnected shell tiny next to the limb (the largest shell by area) in any one of three ways is scan
# debris, dropped with one notice; _debris says why each way is needed.
#: 1. its area is under this fraction of the limb's
FRAGMENT_AREA_FRACTION = 0.01
#: 2. it has fewer triangles than this and than FEW_TRIANGLES_FRACTION of the limb's
FEW_TRIANGLES = 50
#: 2. (with FEW_TRIANGLES) the fraction of the limb's triangles
FEW_TRIANGLES_FRACTION = 0.005
#: 3. it is under this fraction of the limb's size across (the limb's length)
SMALL_SIZE_FRACTION = 0.05


def surface_moments(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
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


def canonical_sign(v: np.ndarray) -> np.ndarray:
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


def submesh(vertices: np.ndarray, faces: np.ndarray) -> Any:
    """A trimesh.Trimesh of only the vertices these faces use."""
    import trimesh

    used, inverse = np.unique(faces, return_inverse=True)
    return trimesh.Trimesh(vertices[used], inverse.reshape(faces.shape), process=False)


@attrs.frozen
class Debris:
    """Shells dropped as scan debris: how many, their fewest and most triangles, the largest share of the
    limb's area among them and the largest size across (in the scan's units)."""

    count: int
    triangles: tuple[int, int]
    area_fraction: float
    across: float

    def note(self, scale: float) -> str:
        """The one-line notice, sizes in mm (``scale``: the factor from the scan's units to mm)."""
        few, most = self.triangles
        tri = f"{few} triangle{'s' if most > 1 else ''}" if few == most else f"{few}–{most} triangles"
        percent = 100.0 * self.area_fraction
        share = shares = "under 0.01 %"
        if percent >= 0.01:
            share = f"{percent:.2g} %"
            shares = f"at most {share}"
        mm = self.across * scale
        size = f"{mm:.0f} mm" if mm >= 10.0 else f"{mm:.2g} mm"
        if self.count == 1:
            detail = f"{tri}, {share} of the limb's area, {size} across"
        else:
            detail = f"{tri} each, {shares} of the limb's area, the largest {size} across"
        plural = "s" if self.count > 1 else ""
        return f"{self.count} small disconnected fragment{plural} dropped as scan debris ({detail})"


def _sizes(vertices: np.ndarray, faces: np.ndarray, face_label: np.ndarray, count: int) -> np.ndarray:
    """Each shell's size across: the longest side of its vertices' box along their own principal axes.

    Whatever the shell's orientation this is within a factor √3 of its largest vertex-to-vertex
    distance (the side is spanned by two vertices; the box, whose diagonal is at most √3 sides, holds
    them all): a tube's length, a sphere's diameter, a sliver triangle's length.
    """
    shell = np.full(len(vertices), -1, dtype=np.int64)
    shell[faces] = face_label[:, None]
    used = np.flatnonzero(shell >= 0)
    used = used[np.argsort(shell[used], kind="stable")]
    shell = shell[used]
    x = vertices[used] - vertices[used].mean(axis=0)
    n = np.bincount(shell, minlength=count)
    x -= (np.stack([np.bincount(shell, x[:, i], count) for i in range(3)], axis=1) / n[:, None])[shell]
    cov = np.empty((count, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            cov[:, i, j] = cov[:, j, i] = np.bincount(shell, x[:, i] * x[:, j], count)
    along = np.einsum("vi,vij->vj", x, np.linalg.eigh(cov)[1][shell])
    starts = np.searchsorted(shell, np.arange(count))
    return (np.maximum.reduceat(along, starts) - np.minimum.reduceat(along, starts)).max(axis=1)


def _debris(areas: np.ndarray, triangles: np.ndarray, sizes: np.ndarray, main: int) -> np.ndarray:
    """Whether each shell is scan debris next to the limb's shell ``main`` (never ``main`` itself).

    Tiny next to the limb in any one of three ways. Area alone (under 1 % of the limb's) misses the
    debris a scanner leaves that is not small in area. A long sliver triangle, or a few, spanning a gap
    can exceed 1 % of the limb's area: it is caught by its triangle count, since a scanner meshes a
    limb or a bone as finely as the limb, so a shell with under 50 triangles and under 0.5 % of the
    limb's is neither (the relative bound keeps a coarse mesh's second limb a shell, to be refused). A
    crumpled or doubled clump of noise can have much area in a small space: it is caught by its size,
    since no limb or bone is under a twentieth of the limb's length across (20 mm on a 400 mm arm).
    What remains is a shell: inside the limb it is ignored (bones), beside it the scan is refused.
    """
    tiny = (
        (areas < FRAGMENT_AREA_FRACTION * areas[main])
        | ((triangles < FEW_TRIANGLES) & (triangles < FEW_TRIANGLES_FRACTION * triangles[main]))
        | (sizes < SMALL_SIZE_FRACTION * sizes[main])
    )
    tiny[main] = False
    return tiny


def choose_shell(
    vertices: np.ndarray, faces: np.ndarray, label: str
) -> tuple[np.ndarray, list[str], Debris | None]:
    """Faces of the limb's shell, notices, and the shells dropped as debris (None if none).

    See :meth:`Limb.from_scan` step 2: the limb is the largest shell by area; :func:`_debris` drops the
    tiny ones; any other must lie inside it (bones, ignored with a notice), else the scan is refused.
    The debris notice is :meth:`Debris.note`, given once the scan's units are known.
    """
    count, face_label = _components(faces, len(vertices))
    if count == 1:
        return faces, [], None
    tri = vertices[faces]
    areas = np.bincount(
        face_label,
        weights=0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1),
        minlength=count,
    )
    triangles = np.bincount(face_label, minlength=count)
    sizes = _sizes(vertices, faces, face_label, count)
    main = int(np.argmax(areas))
    debris = _debris(areas, triangles, sizes, main)
    others = [int(s) for s in np.argsort(-areas) if s != main and not debris[s]]
    main_faces = faces[face_label == main]
    notes = []
    if others:
        outer = submesh(vertices, main_faces)
        _, center, cov = surface_moments(vertices, main_faces)
        d = np.linalg.eigh(cov)[1][:, 2]
        slicer = Slicer(outer, center, d)
        f1 = perpendicular(d)
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
    dropped = None
    if debris.any():
        dropped = Debris(
            count=int(debris.sum()),
            triangles=(int(triangles[debris].min()), int(triangles[debris].max())),
            area_fraction=float(areas[debris].max() / areas[main]),
            across=float(sizes[debris].max()),
        )
    return main_faces, notes, dropped


def _inside_section(slicer: Slicer, f1: np.ndarray, f2: np.ndarray, p: np.ndarray) -> bool:
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
