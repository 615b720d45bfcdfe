"""Pairing: the nearest opposing master element of every query point, with its signed gap.

:func:`select_pairs` narrows the broad phase's candidates
(:meth:`knitframe.numerics.contact.surfaces.SolidSurface.candidates`) to one master element per
point: a linear triangle (plane gap) or a quadratic facet (signed distance to the closest point,
:func:`knitframe.numerics.contact.p2.project_p2`).
"""

from __future__ import annotations

import attrs
import numpy as np

from knitframe.numerics.contact._algebra import dot
from knitframe.numerics.contact.gaps import distance_bound, point_triangle_distance
from knitframe.numerics.contact.p2 import P2Projection, project_p2, rim_edges

__all__ = ["OPPOSING", "Selection", "select_pairs", "nearest"]


#: largest cosine between a master element's normal and a query point's own normal for a pair
#: (60° off parallel)
OPPOSING = 0.5


@attrs.frozen(eq=False)
class Selection:
    """The master element chosen for each query point (see :func:`select_pairs`)."""

    #: (s,) rows of the candidates, one per point that has an opposing element within reach
    rows: np.ndarray
    #: (s,) signed gap, mm
    g: np.ndarray
    #: closest points on quadratic facets (rows), else None
    projection: P2Projection | None


def select_pairs(
    p: np.ndarray,
    point: np.ndarray,
    element: np.ndarray,
    Xe: np.ndarray,
    normal: np.ndarray,
    reach: float,
    *,
    prescreen: float = 0.2,
    open_rim: np.ndarray | None = None,
    facing: float = OPPOSING,
    corner_normals: np.ndarray | None = None,
) -> Selection:
    """For every query point, the nearest opposing master element of its candidates.

    A candidate (point p, element at its image, nodes Xe) qualifies when the element's normal at the
    closest point is not turned the same way as the point's own ``normal`` (the cosine of their
    angle below ``facing``, default :data:`OPPOSING` = 0.5: a pair is refused only when the two
    normals are within 60° of parallel, where the element is the back of the other body; with a
    bound at 0, the flank of a crossing yarn, whose normal stands at right angles to the surface it
    presses into, flipped in and out of contact from one Newton iterate to the next) and the
    distance is below ``reach``. Per point the rank is the distance (for flat triangles plus 2·reach
    when the closest point is on the element's rim rather than a projection into it: their gap is
    the plane's); equal ranks (an edge or corner shared by several elements, or coplanar neighbours;
    equal within 1e-10·reach, so that round-off does not decide) go to the element whose plane faces
    the point most (largest |g|), then to the lower ``element``. The gap is the plane gap of a
    linear triangle (:func:`plane_gap`) or, on quadratic facets, the signed distance
    g = ±|p − x(ξ*)| to the closest point ξ* (:func:`project_p2`), with the sign of n·(p − x*);
    inside the facet (or on its rim with p − x* along n) that is n·(p − x*). Where ξ* is on the rim
    otherwise, the unit vector ±(p − x*)/|p − x*| is returned as the projection's normal n, the
    gap's gradient direction. Ranked by distance alone, the gap is the signed distance to the master
    surface and stays continuous when the nearest facet changes, also between facets that share only
    a corner (a pair switching between such facets made the energy jump when the gap beyond the rim
    was measured to the facet's polynomial continuation). Only beyond an edge on the master
    surface's open boundary (``open_rim`` (n, 3): the candidates' edges 01, 12, 20 that no other
    master facet continues), the gap is measured to the facet's polynomial continuation, as a plane
    continues a flat triangle, where that has a closest point within 0.5 of the triangle whose
    normal stays within 60° of the corners' plane; the signed distance to an open edge would count a
    point beside the surface as inside the body. The sign of a rim point's gap is that of n·(p − x*)
    with the facet's own normal n, or, given ``corner_normals`` (n, 3, 3: the nodal normals at the
    candidates' corners that shape Nagata patches), with the nodal normals interpolated linearly to
    ξ*: on an edge that is the same vector from both facets sharing it (an edge pseudo-normal), so
    the sign does not depend on which of them is chosen; with the facet's own normal, a point in the
    tangent plane of a facet at its edge had n·(p − x*) ≈ 0 and its gap flipped between ±distance
    with round-off. A curved element whose normal at the closest point is turned against its
    corners' plane (a strongly bowed facet folding over near its rim) does not qualify.

    Distances are computed where needed only: first for the candidates into which the point
    projects (barycentric coordinates on the corners' plane ≥ −``prescreen``), then for the rest
    unless their :func:`distance_bound` exceeds reach, or the distance of an element already
    found that the point projects into (such a candidate cannot rank first). The choice is the
    one over all candidates.
    """
    quadratic = Xe.shape[1] == 6
    # a curved facet's normal at the closest point must keep the orientation of its corners' plane: where a
    # strongly bowed facet folds over near its rim the normal flips, and the "gap" there is not a gap
    m_flat = np.cross(Xe[:, 1] - Xe[:, 0], Xe[:, 2] - Xe[:, 0]) if quadratic else None
    rows, res1, res2, ok = _narrow_phase(p, point, Xe, normal, reach, prescreen, facing, m_flat)
    dist, inside, g = (
        np.concatenate([a, b]) for a, b in ((res1[0], res2[0]), (res1[2], res2[2]), (res1[3], res2[3]))
    )
    ok = np.flatnonzero(ok)
    # ranks within rounding of each other are ties: compare them on a grid of 1e-10·reach, so
    # that the choice between coplanar neighbours does not flip with round-off
    q = 1e-10 * reach
    rank = np.floor((dist + (0.0 if quadratic else np.where(inside, 0.0, 2.0 * reach))) / q)
    face = np.floor(-np.abs(g) / q)
    chosen = ok[nearest(point[rows[ok]], rank[ok], face[ok], element[rows[ok]])]
    g = g[chosen]
    if not quadratic:
        return Selection(rows[chosen], g, None)
    fields = [f.name for f in attrs.fields(P2Projection)]
    proj = {f: np.concatenate([getattr(res1[4], f), getattr(res2[4], f)])[chosen] for f in fields}
    _rim_gaps(proj, g, p, Xe, rows[chosen], reach, open_rim, corner_normals, m_flat)
    return Selection(rows[chosen], g, P2Projection(**proj))


def _narrow(p: np.ndarray, Xe: np.ndarray, lam: np.ndarray, rows: np.ndarray) -> tuple:
    """Distance, element normal, whether the closest point is a projection into the element, gap, and
    (on quadratic facets, else None) the :class:`P2Projection` of the candidate ``rows``."""
    if Xe.shape[1] == 6:
        pr = project_p2(p[rows], Xe[rows], lam=lam[rows])
        return pr.dist, pr.n, pr.interior, pr.g, pr
    x = Xe[rows]
    dist, inside, g = point_triangle_distance(p[rows], x[:, 0], x[:, 1], x[:, 2], gap=True)
    return dist, np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), inside, g, None


def _unfolded(n: np.ndarray, m_flat: np.ndarray, limit: float = 0.0) -> np.ndarray:
    """Whether the normals n (m, 3) keep the orientation of the corners' planes m_flat (m, 3): the cosine
    of their angle above ``limit``."""
    return dot(n, m_flat) > limit * np.linalg.norm(n, axis=1) * np.linalg.norm(m_flat, axis=1)


def _qualifies(
    res: tuple,
    rows: np.ndarray,
    normal: np.ndarray,
    reach: float,
    facing: float,
    m_flat: np.ndarray | None,
) -> np.ndarray:
    """Which candidate ``rows`` qualify (see :func:`select_pairs`): the element normal not within the
    ``facing`` cosine of the point's own ``normal``, the distance below ``reach``, and on curved facets
    the normal not folded over against the corners' plane."""
    n = res[1]
    ok = (
        dot(n, normal[rows]) < facing * np.linalg.norm(n, axis=1) * np.linalg.norm(normal[rows], axis=1)
    ) & (res[0] < reach)
    if m_flat is not None:
        ok &= _unfolded(n, m_flat[rows])
    return ok


def _narrow_phase(
    p: np.ndarray,
    point: np.ndarray,
    Xe: np.ndarray,
    normal: np.ndarray,
    reach: float,
    prescreen: float,
    facing: float,
    m_flat: np.ndarray | None,
) -> tuple[np.ndarray, tuple, tuple, np.ndarray]:
    """Distances of the candidates in two passes (see :func:`select_pairs`): first those the point
    projects into, then the rest whose :func:`distance_bound` is within reach and below the distance of
    an element already found that the point projects into.

    Returns the candidate rows of both passes, the two passes' results of :func:`_narrow` and whether
    each row qualifies (:func:`_qualifies`).
    """
    bound, lam = distance_bound(p, Xe)
    near = bound < reach
    first = np.flatnonzero(near & (lam.min(axis=1) >= -prescreen))
    res1 = _narrow(p, Xe, lam, first)
    ok1 = _qualifies(res1, first, normal, reach, facing, m_flat)
    best = np.full(int(point.max(initial=-1)) + 1, np.inf)
    good = np.flatnonzero(ok1 & res1[2])
    win = good[nearest(point[first[good]], res1[0][good])]
    best[point[first[win]]] = res1[0][win]
    rest = near.copy()
    rest[first] = False
    rest = np.flatnonzero(rest & (bound <= best[point]))
    res2 = _narrow(p, Xe, lam, rest)
    ok2 = _qualifies(res2, rest, normal, reach, facing, m_flat)
    return np.concatenate([first, rest]), res1, res2, np.concatenate([ok1, ok2])


def _rim_gaps(
    proj: dict[str, np.ndarray],
    g: np.ndarray,
    p: np.ndarray,
    Xe: np.ndarray,
    sel: np.ndarray,
    reach: float,
    open_rim: np.ndarray | None,
    corner_normals: np.ndarray | None,
    m_flat: np.ndarray,
) -> None:
    """Gaps of the chosen pairs on quadratic facets whose closest point is on the rim (see
    :func:`select_pairs`); ``proj`` (the fields of the chosen rows' :class:`P2Projection`) and ``g`` are
    updated in place. ``sel``: the chosen candidate rows.

    A closest point on the rim: the gap is the signed distance ±|p − x*| (sign of n·(p − x*)), and the
    unit direction of p − x* takes the normal's place. The gap is then the signed distance to the master
    surface wherever the point is, continuous when the nearest point passes from one curved facet to
    another, including facets that share no edge.
    """
    rim = np.flatnonzero(~proj["interior"])
    r = p[sel] - proj["x"]  # from the closest point to the query point
    # on the rim but along the normal (a point right over an edge or corner): the facet's own gap
    normal_only = np.linalg.norm(
        r[rim] - proj["g"][rim, None] * proj["n"][rim], axis=1
    ) <= 1e-10 * np.maximum(proj["dist"][rim], reach)
    proj["interior"][rim[normal_only]] = True
    rim = rim[~normal_only]
    if open_rim is not None and rim.size:
        rim = _continue_open_rim(proj, g, p, Xe, sel, rim, open_rim, m_flat)
    if rim.size:
        _signed_distance(proj, g, r, rim, sel, reach, corner_normals)


def _continue_open_rim(
    proj: dict[str, np.ndarray],
    g: np.ndarray,
    p: np.ndarray,
    Xe: np.ndarray,
    sel: np.ndarray,
    rim: np.ndarray,
    open_rim: np.ndarray,
    m_flat: np.ndarray,
) -> np.ndarray:
    """Beyond an open edge of the master surface (no facet continues it) the gap is measured to the
    facet's polynomial continuation, as a plane continues a flat triangle, where that has a closest point
    near the facet that is not folded over (normal within 60° of the corners' plane). Updates ``proj``
    and ``g`` in place; returns the ``rim`` rows still on the rim."""
    xi = proj["xi"][rim]
    beyond = np.flatnonzero(np.any(rim_edges(xi) & open_rim[sel[rim]], axis=1))
    if beyond.size:
        rb = sel[rim[beyond]]
        ext = project_p2(p[rb], Xe[rb], extend=True, start=xi[beyond])
        valid = ext.interior & _unfolded(ext.n, m_flat[rb], 0.5)
        use = rim[beyond[valid]]
        for f in proj:
            proj[f][use] = getattr(ext, f)[valid]
        g[use] = ext.g[valid]
        rim = np.setdiff1d(rim, use)
    return rim


def _signed_distance(
    proj: dict[str, np.ndarray],
    g: np.ndarray,
    r: np.ndarray,
    rim: np.ndarray,
    sel: np.ndarray,
    reach: float,
    corner_normals: np.ndarray | None,
) -> None:
    """The gap ±|r| of the ``rim`` rows, r = p − x*, and the unit ±r/|r| as their normal (in place).

    The sign is that of n·r with the facet's own normal n, or with the nodal normals
    ``corner_normals`` interpolated linearly to ξ*: on an edge that is the same vector from both facets
    sharing it (an edge pseudo-normal), so the sign does not depend on which of them is chosen.
    """
    d = proj["dist"][rim]
    r = r[rim]
    side = g[rim]
    if corner_normals is not None:
        xi = proj["xi"][rim]
        bary = np.column_stack([1.0 - xi.sum(axis=1), xi])
        side = dot(r, np.einsum("mk,mkc->mc", bary, corner_normals[sel[rim]]))
    sign = np.where(side < 0.0, -1.0, 1.0)
    ok_d = d > 1e-12 * reach
    unit = np.where(ok_d[:, None], r / np.where(ok_d, d, 1.0)[:, None], proj["n"][rim] * sign[:, None])
    proj["n"][rim] = sign[:, None] * unit
    g[rim] = proj["g"][rim] = sign * d


def nearest(point: np.ndarray, dist: np.ndarray, *ties: np.ndarray) -> np.ndarray:
    """Row of the smallest ``dist`` for every distinct value of ``point`` (vectorised arg-min per group).

    Equal distances (a point nearest to an edge or corner shared by several elements) are
    decided by the smallest of ``ties[0]``, then ``ties[1]`` …, then by the row order.
    """
    if point.size == 0:
        return np.zeros(0, np.int64)
    order = np.lexsort((*reversed(ties), dist, point))
    _, first = np.unique(point[order], return_index=True)
    return order[first]
