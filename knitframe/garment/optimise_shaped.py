r"""Course bands of a shaped tube: the fabric *and* the needle count of every element row, solved exactly.

Row i (of R, from the distal end) is knitted in fabric :math:`f_i` on :math:`N_i` needles
(stitches per course) and holds :math:`k_{i f_i}` courses. With :math:`c_{ifN}` the additive cost of
giving row i fabric f on N needles (:math:`+\infty` where a fabric would exceed a limit), find

.. math:: \min_{(f_i, N_i)} \sum_i c_{i f_i N_i}

subject to

- every run of one fabric holds at least ``min_courses`` courses (fabric changes between courses);
- :math:`|N_{i+1} - N_i| \le D_{i f_i}`, the change the machine can make over row i's courses
  (:func:`knitframe.garment.shaping.allowed_change`); :math:`D = 0` is an unshaped tube.

**Dynamic programming** (:func:`solve_shaped`) over the state (fabric f, needles N, courses k of the
current run so far, capped at :math:`M = \lceil \texttt{min\_courses} \rceil`) is exact: the global
optimum. With :math:`V_i(f, N, k)` the least cost of rows 0..i ending in that state,

.. math::
    V_{i+1}(f', N', k') = c_{i+1, f' N'} + \min\Big(
        \min_{|N - N'| \le D_{if'},\ \min(M, k + k_{i+1,f'}) = k'} V_i(f', N, k),\
        [k' = \min(M, k_{i+1,f'})] \min_{f \ne f',\ |N - N'| \le D_{if}} V_i(f, N, M) \Big)

and the answer is :math:`\min_{f,N} V_{R-1}(f, N, M)`. Each step is vectorised over (f, N, k): a sliding
minimum over N of half-width D, a shift in k, and the best and second-best fabric for the switch.
The cost is O(R · F · n_N · M · D_max) operations and O(R · F · n_N · M) memory (the tables kept for
the back-track). Among equal optima the back-track keeps the needle count and the fabric.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from knitframe.garment.optimise import NoAssignment

__all__ = ["ShapedSolution", "solve_shaped"]


@attrs.frozen(eq=False)
class ShapedSolution:
    """Fabric index and needle count of every element row, and the cost."""

    #: (R,) fabric index per row
    rows: np.ndarray
    #: (R,) needles (stitches per course) per row
    needles: np.ndarray
    cost: float
    method: str = "dynamic programming (shaped)"
    gap: float = 0.0
    level: float | None = None

    @property
    def guarantee(self) -> str:
        if self.method != "dynamic programming (shaped)":  # one needle count, solved as course bands
            from knitframe.garment.optimise import BandSolution

            return BandSolution(self.rows, self.cost, self.method, self.gap).guarantee
        return (
            "global optimum over course bands and needle counts within the machine's shaping rules "
            "(dynamic programming, exact)"
        )


def _window_min(V: np.ndarray, D: np.ndarray) -> np.ndarray:
    """min over |d| <= D[f] of V[f, n + d, ...] along axis 1 (out-of-range ignored)."""
    W = V.copy()
    n = V.shape[1]
    dmax = int(min(D.max(initial=0), n - 1))
    for d in range(1, dmax + 1):
        use = (D >= d)[:, None, None]
        W[:, d:] = np.where(use, np.minimum(W[:, d:], V[:, :-d]), W[:, d:])
        W[:, :-d] = np.where(use, np.minimum(W[:, :-d], V[:, d:]), W[:, :-d])
    return W


def solve_shaped(
    cost: np.ndarray,
    courses: np.ndarray,
    change: np.ndarray,
    min_courses: float = 0.0,
) -> ShapedSolution:
    """Exact fabric and needle count of every row (see the module docstring).

    Parameters
    ----------
    cost : (R, F, n) array
        Cost of row i in fabric f on the j-th needle count of a contiguous range; ``+inf`` where not
        allowed.
    courses : (R, F) integer array
        Courses of row i in fabric f (>= 1).
    change : (R, F) integer array
        Most needles the count may change by from row i (in fabric f) to row i+1.
    min_courses : float
        Least courses of every run of one fabric.

    Returns the solution with ``needles`` as indices into the range (the caller adds its first count).
    """
    cost = np.asarray(cost, dtype=np.float64)
    if cost.ndim != 3 or cost.size == 0:
        raise ValueError(f"cost must be a non-empty (rows, fabrics, needles) array, got {cost.shape}")
    R, F, n = cost.shape
    kk = np.asarray(courses)
    if kk.shape != (R, F) or np.any(kk < 1) or np.any(kk != np.round(kk)):
        raise ValueError("courses must be an integer (rows, fabrics) array >= 1")
    if np.any(np.isnan(cost)) or np.any(cost == -np.inf):
        raise ValueError("costs must be finite or +inf")
    kk = kk.astype(np.int64)
    D = np.asarray(change, dtype=np.int64)
    M = max(0, math.ceil(float(min_courses) - 1e-9))
    K = M + 1
    fi = np.arange(F)
    a = np.minimum(M, kk)  # (R, F): the capped course count a row alone brings

    tables = []
    V = np.full((F, n, K), np.inf)
    V[fi, :, a[0]] = cost[0]
    tables.append(V)
    for i in range(R - 1):
        W = _window_min(V, D[i])
        S = np.full((F, n, K), np.inf)
        # the same fabric goes on: k -> min(M, k + courses)
        add = kk[i + 1]
        for kp in range(K):
            if kp < M:
                src = kp - add
                ok = src >= 0
                if ok.any():
                    S[ok, :, kp] = W[fi[ok], :, src[ok]]
            else:
                suffix = np.minimum.accumulate(W[:, :, ::-1], axis=2)[:, :, ::-1]
                S[:, :, M] = suffix[fi, :, np.maximum(0, M - add)]
        if F > 1:  # a new run starts: the best other fabric whose run is complete
            X = W[:, :, M]
            order = np.argsort(X, axis=0, kind="stable")[:2]
            m1 = np.take_along_axis(X, order[:1], 0)[0]
            m2 = np.take_along_axis(X, order[1:2], 0)[0]
            other = np.where(order[0][None, :] == fi[:, None], m2[None, :], m1[None, :])  # (F, n)
            cur = S[fi, :, a[i + 1]]
            S[fi, :, a[i + 1]] = np.minimum(cur, other)
        V = S + cost[i + 1][:, :, None]
        tables.append(V)
    end = V[:, :, M]
    f, j = np.unravel_index(int(np.argmin(end)), end.shape)
    total = float(end[f, j])
    if not np.isfinite(total):
        raise NoAssignment("no assignment meets the limits, the minimum region size and the shaping rules")
    rows = np.empty(R, dtype=np.int64)
    needles = np.empty(R, dtype=np.int64)
    k = M
    f, j = int(f), int(j)
    rows[-1], needles[-1] = f, j
    for i in range(R - 1, 0, -1):
        f, j, k = _predecessor(tables[i - 1], f, j, k, kk, D, M, i)
        rows[i - 1], needles[i - 1] = f, j
    return ShapedSolution(rows, needles, total)


def _predecessor(V, f, j, k, kk, D, M, i):
    """The state of row i−1 that row i's state (f, j, k) came from; among equal values the one that keeps
    the needle count, then the fabric."""
    F, n, _ = V.shape
    cand = []  # (value, |needle change|, fabric changed, fabric, needle index, k)
    lo, hi = max(0, j - D[i - 1, f]), min(n - 1, j + D[i - 1, f])
    for kp in range(M + 1):
        if min(M, kp + kk[i, f]) == k:  # the same fabric went on
            cand += [(V[f, jj, kp], abs(jj - j), 0, f, jj, kp) for jj in range(lo, hi + 1)]
    if k == min(M, kk[i, f]):  # or a run of f started at row i
        for g in range(F):
            if g != f:
                lo, hi = max(0, j - D[i - 1, g]), min(n - 1, j + D[i - 1, g])
                cand += [(V[g, jj, M], abs(jj - j), 1, g, jj, M) for jj in range(lo, hi + 1)]
    vmin = min(c[0] for c in cand)
    tol = 1e-12 * max(1.0, abs(vmin))
    _, _, _, g, jj, kp = min((c for c in cand if c[0] <= vmin + tol), key=lambda c: (c[1], c[2]))
    return g, jj, kp
