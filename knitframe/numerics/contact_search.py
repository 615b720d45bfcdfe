"""Contact search between yarn segments: closest points and a KD-tree broad phase with periodic images.

Shared by the unit-cell solvers. Segments are straight pieces of yarn centerlines. The broad
phase puts segment midpoints in a :class:`scipy.spatial.cKDTree` and queries it against the
midpoints of every periodic image k1 L1 + k2 L2 (k1, k2 ∈ {−1, 0, 1}) placed under the current
macro deformation F̄; the narrow phase computes exact segment–segment closest points. A
:class:`VerletList` keeps the broad phase's candidates between searches while nothing has moved far
enough to bring a new pair within reach.

Self-contact: two segments on the same strand (one infinite yarn of the fabric, see
:func:`knitframe.geometry.strands`) are neighbours, not contacts, when they lie closer than an
exclusion length along the yarn. Contact between different strands (including the periodic
copies of a yarn along the wale) is always kept.
"""

from __future__ import annotations

from collections.abc import Callable

import attrs
import numpy as np
from scipy.spatial import cKDTree

from knitframe.numerics.periodic import Lattice

__all__ = ["closest_points", "SegmentTopology", "Pairs", "find_pairs", "VerletList", "IMAGES"]

#: periodic images searched: (0, 0) first, then the 8 neighbours
IMAGES = np.array(
    [(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)], dtype=np.int64
)


def closest_points(
    p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray, eps: float = 1e-14
) -> tuple[np.ndarray, np.ndarray]:
    """Parameters (s, t) ∈ [0, 1]² of the closest points of segments p0–p1 and q0–q1, vectorised.

    Minimises |p0 + s (p1 − p0) − q0 − t (q1 − q0)|² over the unit square (Ericson, Real-Time
    Collision Detection, 2005, §5.1.9). Parallel segments get s = 0 (the distance is still exact).

    Parameters
    ----------
    p0, p1, q0, q1 : (m, 3) arrays, mm

    Returns
    -------
    s, t : (m,) arrays
    """
    d1 = p1 - p0
    d2 = q1 - q0
    r = p0 - q0
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    f = np.einsum("ij,ij->i", d2, r)
    c = np.einsum("ij,ij->i", d1, r)
    b = np.einsum("ij,ij->i", d1, d2)
    denom = a * e - b * b
    sa = np.where(a > eps, a, 1.0)
    se = np.where(e > eps, e, 1.0)
    general = denom > eps * a * e
    s = np.where(general, np.clip((b * f - c * e) / np.where(general, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / se
    low, high = t < 0.0, t > 1.0
    s = np.where(low, np.clip(-c / sa, 0.0, 1.0), np.where(high, np.clip((b - c) / sa, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # degenerate (point-like) segments
    s = np.where(a <= eps, 0.0, s)
    t = np.where(a <= eps, np.clip(f / se, 0.0, 1.0), t)
    s = np.where(e <= eps, np.clip(-c / sa, 0.0, 1.0), s)
    t = np.where(e <= eps, 0.0, t)
    return s, t


@attrs.frozen(eq=False)
class SegmentTopology:
    """Where each segment sits along its strand, for the self-contact exclusion.

    ``strand`` (n,) strand number of each segment; ``position`` (n,) place of the segment's
    yarn in its strand (0 … cycle−1); ``arc`` (n,) arc coordinate of the segment midpoint
    unrolled along the strand from the strand's first yarn, mm; ``cycle`` (n_strands,) yarns per
    strand (0 for an open rod that does not continue periodically); ``length`` (n_strands,)
    strand arc length per cell crossing, mm.
    """

    strand: np.ndarray
    position: np.ndarray
    arc: np.ndarray
    cycle: np.ndarray
    length: np.ndarray
    #: (n,) previous segment along the yarn, −1 at an open end
    prev: np.ndarray | None = None
    #: (n, 2) image of the previous segment
    prev_image: np.ndarray | None = None

    def unrolled(self, seg: np.ndarray, k1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(copy key, unrolled arc) of segments ``seg`` on the image shifted by k1 L1.

        Yarn p of a strand of m yarns, shifted by k1 L1, lies on the strand copy that starts at
        image (k1 − p) mod m, one strand length further for every m images. Open rods (m = 0)
        have a single copy per image.
        """
        st = self.strand[seg]
        m = self.cycle[st]
        rel = k1 - self.position[seg]
        periodic = m > 0
        mm = np.where(periodic, m, 1)
        base = np.where(periodic, np.mod(rel, mm), k1)
        turns = np.where(periodic, (rel - np.mod(rel, mm)) // mm, 0)
        return base, turns * self.length[st] + self.arc[seg]


@attrs.frozen(eq=False)
class Pairs:
    """Segment pairs closer than the search cutoff: segment ``i`` (image 0) and segment ``j`` at image
    ``k``."""

    #: (m,)
    i: np.ndarray
    #: (m,)
    j: np.ndarray
    #: (m, 2) integer image of j
    k: np.ndarray
    #: (m,) closest-point parameter on i
    s: np.ndarray
    #: (m,) closest-point parameter on j
    t: np.ndarray
    #: (m,) closest distance, mm
    distance: np.ndarray

    def __len__(self) -> int:
        return int(self.i.shape[0])


def _canonical(i: np.ndarray, j: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Keep one of the twins (i, j, k) ~ (j, i, −k); drop a segment against itself."""
    kid = 3 * k[:, 0] + k[:, 1]
    return (i < j) | ((i == j) & (kid > 0))


@attrs.define(eq=False)
class VerletList:
    """Broad-phase candidates kept between contact searches (a Verlet list).

    The broad phase keeps a segment pair (a, b at image k) when their midpoints are closer than
    the reach R = cutoff + 2·max half-length; every pair closer than the cutoff is among them. A list
    built with the reach grown by ``margin``·R, R_ref, at midpoints m_ref and image shifts S_ref, holds
    every pair within the reach R of a later state as long as

        R + 2δ ≤ R_ref,    δ = max_a |m_a − m_a,ref| + max_k |S_k − S_k,ref|,

    since no midpoint distance changed by more than 2δ (the triangle inequality). Then the list
    replaces the KD-tree search, and the exact narrow phase gives the pairs a fresh search gives, in the
    same order (the candidates are sorted). ``builds`` and ``uses`` count the searches and reuses.
    """

    margin: float = 0.25
    builds: int = 0
    uses: int = 0
    _ref: tuple | None = None

    def candidates(
        self, mid: np.ndarray, shifts: np.ndarray, reach: float, build: Callable[[float], tuple]
    ) -> tuple:
        """``build(R)``'s candidates at a reach grown from ``reach``: kept ones while valid, else new.

        ``build`` may filter the broad phase by anything that does not depend on positions (the
        twins, the neighbours along a yarn): a kept list filtered so is still a superset.
        """
        ref = self._ref
        if ref is not None and ref[0].shape == mid.shape and ref[1].shape == shifts.shape:
            move = float(np.max(np.linalg.norm(mid - ref[0], axis=1), initial=0.0))
            move += float(np.max(np.linalg.norm(shifts - ref[1], axis=1), initial=0.0))
            if reach + 2.0 * move <= ref[2]:
                self.uses += 1
                return ref[3]
        grown = reach * (1.0 + self.margin)
        found = build(grown)
        self._ref = (mid.copy(), shifts.copy(), grown, found)
        self.builds += 1
        return found


def _broad_phase(mid: np.ndarray, shifts: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint pairs closer than ``reach``: segment i (image 0) and j_flat = image row · n + j, sorted."""
    img_mid = (mid[None, :, :] + shifts[:, None, :]).reshape(-1, 3)
    found = cKDTree(mid).sparse_distance_matrix(cKDTree(img_mid), reach, output_type="ndarray")
    i = found["i"].astype(np.int64)
    jf = found["j"].astype(np.int64)
    order = np.lexsort((jf, i))
    return i[order], jf[order]


def find_pairs(
    p0: np.ndarray,
    p1: np.ndarray,
    cutoff: float,
    *,
    topology: SegmentTopology,
    lattice: Lattice | None = None,
    h: np.ndarray | None = None,
    self_contact: bool = False,
    exclusion: float = 0.0,
    verlet: VerletList | None = None,
) -> Pairs:
    """Segment pairs whose closest distance is below ``cutoff``, with periodic images and exclusions.

    Parameters
    ----------
    p0, p1 : (n, 3)
        Current segment end points, mm (a segment that crosses the cell boundary has its end
        already shifted into place).
    cutoff : float
        Search distance between centerlines, mm (contact distance dk plus a margin).
    topology : SegmentTopology
        Strand bookkeeping for the self-contact rule.
    lattice, h : optional
        The cell's lattice and the macro DOFs (6,) of the current F̄; without a lattice only
        image (0, 0) is searched.
    self_contact : bool
        Keep pairs on the same strand that are at least ``exclusion`` apart along it; when false,
        every pair on the same strand copy is dropped.
    exclusion : float
        Arc distance along a strand under which pairs are neighbours, mm.
    verlet : VerletList, optional
        Keeps the broad phase's candidates between calls (the result is the same).
    """
    n = len(p0)
    mid = 0.5 * (p0 + p1)
    half = 0.5 * np.linalg.norm(p1 - p0, axis=1)
    reach = cutoff + 2.0 * float(half.max(initial=0.0))
    images = IMAGES if lattice is not None else IMAGES[:1]
    shifts = (
        lattice.shift(images, np.zeros(6) if h is None else h) if lattice is not None else np.zeros((1, 3))
    )

    def build(radius: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The broad phase at ``radius`` without twins and without neighbours along a yarn."""
        i, jf = _broad_phase(mid, shifts, radius)
        j = jf % n
        k = images[jf // n]
        keep = _canonical(i, j, k)
        i, j, k = i[keep], j[keep], k[keep]
        # same strand copy: neighbours along the yarn (or all of it without self-contact)
        base_i, arc_i = topology.unrolled(i, np.zeros(len(i), np.int64))
        base_j, arc_j = topology.unrolled(j, k[:, 0])
        same = (topology.strand[i] == topology.strand[j]) & (k[:, 1] == 0) & (base_i == base_j)
        drop = same if not self_contact else same & (np.abs(arc_i - arc_j) < exclusion)
        return i[~drop], j[~drop], k[~drop]

    i, j, k = build(reach) if verlet is None else verlet.candidates(mid, shifts, reach, build)
    sh = shifts[_image_row(k)] if lattice is not None else np.zeros((len(i), 3))
    q0, q1 = p0[j] + sh, p1[j] + sh
    s, t = closest_points(p0[i], p1[i], q0, q1)
    s, t = _snap(s), _snap(t)
    dvec = p0[i] + s[:, None] * (p1[i] - p0[i]) - q0 - t[:, None] * (q1 - q0)
    d = np.linalg.norm(dvec, axis=1)
    close = d < cutoff
    i, j, k, s, t, d = i[close], j[close], k[close], s[close], t[close], d[close]
    if topology.prev is not None:
        keep = _vertex_once(p0, p1, i, j, k, s, t, topology, shifts if lattice is not None else None)
        i, j, k, s, t, d = i[keep], j[keep], k[keep], s[keep], t[keep], d[keep]
    return Pairs(i, j, k, s, t, d)


def _vertex_once(p0, p1, i, j, k, s, t, topo: SegmentTopology, shifts) -> np.ndarray:
    """Count a closest point at a vertex shared by two segments once, and only where it is a local minimum.

    A pair whose closest point sits at the end (parameter 1) of a segment that continues is
    dropped: the next segment sees the same point at its start. A pair at the start (parameter 0)
    is kept only if the previous segment's closest point is its end, i.e. the vertex is the
    closest point of the polyline; otherwise an interior pair of the previous segment holds it.
    """
    nxt = np.full(len(topo.prev), -1)
    has_prev = topo.prev >= 0
    nxt[topo.prev[has_prev]] = np.flatnonzero(has_prev)
    keep = ~((s == 1.0) & (nxt[i] >= 0)) & ~((t == 1.0) & (nxt[j] >= 0))

    def sh(img):
        return shifts[_image_row(img)] if shifts is not None else 0.0

    for side in ("s", "t"):
        at0 = keep & ((s if side == "s" else t) == 0.0) & (topo.prev[i if side == "s" else j] >= 0)
        if not np.any(at0):
            continue
        ii, jj, kk = i[at0], j[at0], k[at0]
        if side == "s":
            a, ia = topo.prev[ii], topo.prev_image[ii]
            P0, P1 = p0[a] + sh(ia), p1[a] + sh(ia)
            Q0, Q1 = p0[jj] + sh(kk), p1[jj] + sh(kk)
        else:
            b, kb = topo.prev[jj], kk + topo.prev_image[jj]
            P0, P1 = p0[ii], p1[ii]
            Q0, Q1 = p0[b] + sh(kb), p1[b] + sh(kb)
        s2, t2 = (_snap(a) for a in closest_points(P0, P1, Q0, Q1))
        keep[at0] = (s2 if side == "s" else t2) == 1.0
    return keep


def _snap(a: np.ndarray, tol: float = 1e-10) -> np.ndarray:
    """Parameters within ``tol`` of a segment end are at the end (a vertex shared with the next segment)."""
    return np.where(a < tol, 0.0, np.where(a > 1.0 - tol, 1.0, a))


def _image_row(k: np.ndarray) -> np.ndarray:
    """Row of each image k (m, 2) in :data:`IMAGES`."""
    code = (k[:, 0] + 1) * 3 + (k[:, 1] + 1)
    table = np.empty(9, np.int64)
    table[(IMAGES[:, 0] + 1) * 3 + (IMAGES[:, 1] + 1)] = np.arange(9)
    return table[code]
