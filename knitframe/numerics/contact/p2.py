"""Quadratic (P2) facets: shape functions and the closest-point projection.

A curved quadratic facet is x(ξ) = Σ N_i(ξ) x_i over the reference triangle (corners, then the
edge nodes 01, 12, 20). :func:`project_p2` finds the closest point ξ* of a point p on it by a
projected, globalised Newton method; :class:`P2Projection` holds the result.
"""

from __future__ import annotations

import attrs
import numpy as np

from knitframe.errors import NumericalError
from knitframe.numerics.contact._algebra import dot
from knitframe.numerics.contact.gaps import barycentric

__all__ = ["p2_shape", "p2_coefficients", "P2Projection", "project_p2", "rim_edges"]


def p2_shape(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic triangle shape functions N (m, 6) and derivatives dN/dξ (m, 6, 2) at ξ (m, 2).

    Node order: corners (0, 0), (1, 0), (0, 1), then edge midpoints 01, 12, 20.
    """
    s, t = xi[:, 0], xi[:, 1]
    l0 = 1.0 - s - t
    N = np.empty((len(s), 6))
    N[:, 0] = l0 * (2 * l0 - 1)
    N[:, 1] = s * (2 * s - 1)
    N[:, 2] = t * (2 * t - 1)
    N[:, 3] = 4 * l0 * s
    N[:, 4] = 4 * s * t
    N[:, 5] = 4 * t * l0
    dN = np.zeros((len(s), 6, 2))
    dN[:, 0, 0] = dN[:, 0, 1] = -(4 * l0 - 1)
    dN[:, 1, 0] = 4 * s - 1
    dN[:, 2, 1] = 4 * t - 1
    dN[:, 3, 0] = 4 * (l0 - s)
    dN[:, 3, 1] = -4 * s
    dN[:, 4, 0] = 4 * t
    dN[:, 4, 1] = 4 * s
    dN[:, 5, 0] = -4 * t
    dN[:, 5, 1] = 4 * (l0 - t)
    return N, dN


def p2_coefficients(Xf: np.ndarray) -> tuple[np.ndarray, ...]:
    """Monomial coefficients (a0 … a5), each (m, 3), of x(s, t) = a0 + a1 s + a2 t + a3 s² + a4 st + a5 t².

    From the Lagrange nodes Xf (m, 6, 3): a0 = x0, a1 = −3x0 − x1 + 4x3, a2 = −3x0 − x2 + 4x5,
    a3 = 2x0 + 2x1 − 4x3, a4 = 4(x0 − x3 + x4 − x5), a5 = 2x0 + 2x2 − 4x5.
    """
    x0, x1, x2, x3, x4, x5 = (Xf[:, i] for i in range(6))
    return (
        x0,
        -3 * x0 - x1 + 4 * x3,
        -3 * x0 - x2 + 4 * x5,
        2 * x0 + 2 * x1 - 4 * x3,
        4 * (x0 - x3 + x4 - x5),
        2 * x0 + 2 * x2 - 4 * x5,
    )


@attrs.frozen(eq=False)
class P2Projection:
    """Closest points of points p on quadratic facets (see :func:`project_p2`)."""

    #: (m, 2) parametric point ξ* in the reference triangle
    xi: np.ndarray
    #: (m, 3) facet point x(ξ*), mm
    x: np.ndarray
    #: (m, 3) tangent ∂x/∂ξ1 at ξ*, mm
    xs: np.ndarray
    #: (m, 3) tangent ∂x/∂ξ2 at ξ*, mm
    xt: np.ndarray
    #: (m, 3) unit normal xs × xt / |xs × xt| (orientation of the corner order)
    n: np.ndarray
    #: (m,) gap n·(p − x), mm
    g: np.ndarray
    #: (m,) |p − x|, mm
    dist: np.ndarray
    #: (m,) ξ* is an unclipped stationary point (p − x ⟂ the facet)
    interior: np.ndarray


def project_p2(
    p: np.ndarray,
    Xf: np.ndarray,
    iterations: int = 30,
    tol: float = 1e-13,
    lam: np.ndarray | None = None,
    *,
    extend: bool = False,
    start: np.ndarray | None = None,
) -> P2Projection:
    """Closest points of p (m, 3) on quadratic facets Xf (m, 6, 3), ξ* in the reference triangle.

    Projected Newton's method on f(ξ) = ½|p − x(ξ)|² from the projection onto the corners'
    plane. With r = p − x(ξ), x_α = ∂x/∂ξ_α and the constant second derivatives x_αβ of the
    quadratic map, the step solves (x_α·x_β − r·x_αβ) Δξ_β = r·x_α (the Gauss-Newton matrix
    x_α·x_β where that is not positive definite). On the triangle's rim the constraints that the
    descent direction r·x_α pushes against are held: along an edge the step is the Newton step of
    f restricted to the edge, at a corner there is none; ξ is clipped to the triangle after each
    step; the start is the plane projection or, if closer, the nearest point of a 28-point lattice
    on the triangle. A step that raises f is halved until it does not, each trial clipped to the
    triangle (a full step of the indefinite or Gauss-Newton model can leave the basin of the
    closest point for a far local minimum on the rim, and the gap then jumps with p); a row that
    finds no lower f is not converged. Rows stop once |Δξ| ≤ ``tol`` (the convergence is
    quadratic, inside and along edges), at most ``iterations``. The point is ``interior`` when it
    converged off the rim: there p − x is along n and the gap n·(p − x) is a smooth function of p
    and the nodes. ``lam`` (m, 3): the barycentric coordinates of p on the corners' plane if
    already known (the start).

    With ``extend`` the facet's polynomial map is continued beyond the triangle (as a plane
    continues a flat triangle) and Newton runs unconstrained from ``start`` (m, 2); a row is
    ``interior`` when it converges to a minimum with ξ within 0.5 of the triangle.
    """
    a = p2_coefficients(Xf)
    if start is not None:
        xi = np.array(start, dtype=np.float64)
    else:
        if lam is None:
            lam = barycentric(p, Xf[:, 0], Xf[:, 1], Xf[:, 2])
        xi, _ = _clip_triangle(lam[:, 1:].copy())
        xi = _best_start(p, *a, xi)
    converged, failed = _newton(p, a, xi, iterations, tol, extend)
    if extend:
        inner = ~failed
    else:
        inner = (xi[:, 0] > 0.0) & (xi[:, 1] > 0.0) & (xi[:, 0] + xi[:, 1] < 1.0 - 1e-14)
    return _projection(p, a, xi, converged & inner)


def _newton(
    p: np.ndarray, a: tuple[np.ndarray, ...], xi: np.ndarray, iterations: int, tol: float, extend: bool
) -> tuple[np.ndarray, np.ndarray]:
    """The Newton iteration of :func:`project_p2` from ξ (m, 2), updated in place; ``a`` the facets'
    coefficients (:func:`p2_coefficients`). Returns which rows converged and which (with ``extend``)
    have no minimum near the triangle."""
    m = len(p)
    converged = np.zeros(m, bool)
    failed = np.zeros(m, bool)
    act = np.arange(m)
    for _ in range(iterations):
        if act.size == 0:
            break
        b, pa = tuple(c[act] for c in a), p[act]
        step, new, out, f0 = _newton_step(pa, b, xi[act], extend)
        failed[act[out]] = True
        # globalised: a step must not raise f (the step is halved otherwise, each trial clipped to the
        # triangle); a full step of the indefinite or Gauss-Newton model can leave the basin of the
        # closest point for a far local minimum on the rim, and the gap then jumps with p
        full = np.max(np.abs(new - xi[act]), axis=1)
        new, stuck = _descend(pa, *b, xi[act], step, f0, ~out, clip=not extend)
        # no point along a step longer than tol lowers f: not a minimum, so not converged
        out |= stuck & (full > tol)
        moved = np.max(np.abs(new - xi[act]), axis=1)
        xi[act[~out]] = new[~out]
        done = (moved <= tol) & ~out
        converged[act[done]] = True
        act = act[~(done | out)]
    return converged, failed


def _newton_step(
    pa: np.ndarray, b: tuple[np.ndarray, ...], xi: np.ndarray, extend: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One step of :func:`project_p2` at ξ (k, 2) of points pa (k, 3) on facets of coefficients ``b``.

    Returns the step Δξ (k, 2), the point after the full step (clipped to the triangle unless
    ``extend``), the rows that (with ``extend``) have no minimum near the triangle, and
    f(ξ) = ½|p − x(ξ)|² (k,).
    """
    _, b1, b2, b3, b4, b5 = b
    s, t = xi[:, 0], xi[:, 1]
    sc, tc = s[:, None], t[:, None]
    xs = b1 + 2.0 * b3 * sc + b4 * tc
    xt = b2 + b4 * sc + 2.0 * b5 * tc
    r = pa - _p2_point(b, sc, tc)
    G11, G12, G22 = dot(xs, xs), dot(xs, xt), dot(xt, xt)
    H11, H12, H22 = G11 - 2.0 * dot(r, b3), G12 - dot(r, b4), G22 - 2.0 * dot(r, b5)
    det = H11 * H22 - H12 * H12
    gn = ~((H11 > 0) & (det > 1e-12 * G11 * G22))  # not positive definite: Gauss-Newton step
    H11, H12, H22 = np.where(gn, G11, H11), np.where(gn, G12, H12), np.where(gn, G22, H22)
    det = H11 * H22 - H12 * H12
    f1, f2 = dot(r, xs), dot(r, xt)  # descent direction −∇f
    ds = (H22 * f1 - H12 * f2) / det
    dt = (H11 * f2 - H12 * f1) / det
    if extend:
        new = np.column_stack([s + ds, t + dt])
        out = gn | (new.min(axis=1) < -0.5) | (new.sum(axis=1) > 1.5)  # no minimum near the triangle
    else:
        ds, dt = _rim_step(s, t, f1, f2, (H11, H12, H22), (G11, G12, G22), ds, dt)
        new, _ = _clip_triangle(np.column_stack([s + ds, t + dt]))
        out = np.zeros(len(s), bool)
    return np.column_stack([ds, dt]), new, out, 0.5 * dot(r, r)


def _rim_step(
    s: np.ndarray,
    t: np.ndarray,
    f1: np.ndarray,
    f2: np.ndarray,
    H: tuple[np.ndarray, np.ndarray, np.ndarray],
    G: tuple[np.ndarray, np.ndarray, np.ndarray],
    ds: np.ndarray,
    dt: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The step (ds, dt) with the rim constraints that the descent (f1, f2) pushes against held: along
    an edge the Newton step of f restricted to the edge (curvature from H = (H11, H12, H22), or from the
    Gauss-Newton G where that is not positive), at a corner none."""
    H11, H12, H22 = H
    G11, G12, G22 = G
    # rim constraints the descent pushes against: s ≥ 0, t ≥ 0, s + t ≤ 1
    bs, bt, bst = (s <= 0.0) & (f1 < 0), (t <= 0.0) & (f2 < 0), (s + t >= 1.0 - 1e-14) & (f1 + f2 > 0)
    nb = bs.astype(np.int8) + bt + bst
    # one held constraint: Newton along its edge, tangent τ = (0, 1), (1, 0) or (−1, 1)
    ts = np.where(bs, 0.0, np.where(bt, 1.0, -1.0))
    tt = np.where(bt, 0.0, 1.0)
    curv = ts * ts * H11 + 2.0 * ts * tt * H12 + tt * tt * H22
    curv = np.where(curv > 0, curv, ts * ts * G11 + 2.0 * ts * tt * G12 + tt * tt * G22)
    step = (ts * f1 + tt * f2) / np.where(curv > 0, curv, 1.0)
    edge = nb == 1
    ds = np.where(edge, step * ts, np.where(nb > 1, 0.0, ds))
    dt = np.where(edge, step * tt, np.where(nb > 1, 0.0, dt))
    return ds, dt


def _projection(
    p: np.ndarray, a: tuple[np.ndarray, ...], xi: np.ndarray, interior: np.ndarray
) -> P2Projection:
    """The :class:`P2Projection` of points p at the parametric points ξ (m, 2) of facets of
    coefficients ``a``."""
    a0, a1, a2, a3, a4, a5 = a
    s, t = xi[:, 0:1], xi[:, 1:2]
    x = _p2_point(a, s, t)
    xs = a1 + 2.0 * a3 * s + a4 * t
    xt = a2 + a4 * s + 2.0 * a5 * t
    nv = np.cross(xs, xt)
    nn = np.linalg.norm(nv, axis=1)
    if not np.all(nn > 0):
        raise NumericalError("solid contact: a quadratic facet is degenerate (zero area element)")
    n = nv / nn[:, None]
    r = p - x
    return P2Projection(xi, x, xs, xt, n, dot(n, r), np.linalg.norm(r, axis=1), interior)


def _p2_point(a, s, t):
    """x(ξ) = a0 + a1 s + a2 t + a3 s² + a4 s t + a5 t² of a quadratic facet's coefficients a
    (:func:`p2_coefficients`)."""
    a0, a1, a2, a3, a4, a5 = a
    return a0 + (a1 + a3 * s + a4 * t) * s + (a2 + a5 * t) * t


#: barycentric lattice (order 6, 28 points) of the start search on curved facets
_START_GRID = np.array([(i / 6.0, j / 6.0) for i in range(7) for j in range(7 - i)])


def _best_start(p, a0, a1, a2, a3, a4, a5, xi) -> np.ndarray:
    """The start of the closest-point search: ``xi`` or the point of a 28-point lattice on the
    triangle with the smallest distance, whichever is closer. On a strongly bowed facet the
    distance has several local minima and flat indefinite regions; from the plane projection
    alone Newton can take 20 iterations to leave them, or settle on a far minimum."""
    s, t = _START_GRID[None, :, 0:1], _START_GRID[None, :, 1:2]
    x = _p2_point(tuple(a[:, None] for a in (a0, a1, a2, a3, a4, a5)), s, t)
    f = np.einsum("mkc,mkc->mk", p[:, None] - x, p[:, None] - x)
    k = f.argmin(axis=1)
    s0, t0 = xi[:, 0:1], xi[:, 1:2]
    r0 = p - _p2_point((a0, a1, a2, a3, a4, a5), s0, t0)
    use = f[np.arange(len(p)), k] < dot(r0, r0)
    out = xi.copy()
    out[use] = _START_GRID[k[use]]
    return out


def _descend(p, a0, a1, a2, a3, a4, a5, xi, step, f0, rows, *, clip: bool, halvings: int = 30):
    """Points ξ + α·``step`` (clipped to the triangle with ``clip``) of the selected ``rows``, α = 1, ½, ¼, …,
    the first at which f(ξ) = ½|p − x(ξ)|² does not exceed f0 (within round-off); a row that finds none
    keeps ξ and is flagged in the returned mask ``stuck``. The trials are clipped one by one rather than
    halving the way to the clipped full step: near an edge that chord is not a descent direction, and the
    iteration crept along it for 25 iterations (the accepted steps were round-off)."""
    new = xi.copy()
    todo = np.flatnonzero(rows)
    alpha = 1.0
    for _ in range(halvings + 1):
        if todo.size == 0:
            break
        trial = xi[todo] + alpha * step[todo]
        if clip:
            trial, _ = _clip_triangle(trial)
        s, t = trial[:, 0:1], trial[:, 1:2]
        r = p[todo] - _p2_point(tuple(a[todo] for a in (a0, a1, a2, a3, a4, a5)), s, t)
        ok = 0.5 * dot(r, r) <= f0[todo] * (1.0 + 1e-12) + 1e-300
        new[todo[ok]] = trial[ok]
        todo = todo[~ok]
        alpha *= 0.5
    stuck = np.zeros(len(xi), bool)
    stuck[todo] = True
    return new, stuck


def _clip_triangle(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ξ clipped to the reference triangle (in place), and which rows were clipped."""
    neg = xi < 0.0
    xi = np.maximum(xi, 0.0, out=xi)
    s = xi.sum(axis=1)
    over = s > 1.0
    xi[over] /= s[over, None]
    return xi, np.any(neg, axis=1) | over


def rim_edges(xi: np.ndarray) -> np.ndarray:
    """(m, 3) flags: the parametric point ξ (m, 2) lies on the triangle's edge 01 (t = 0),
    12 (s + t = 1), 20 (s = 0)."""
    return np.column_stack([xi[:, 1] <= 0.0, xi.sum(axis=1) >= 1.0 - 1e-14, xi[:, 0] <= 0.0])
