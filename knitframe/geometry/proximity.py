"""The minimum centerline-to-centerline clearance of a cell, with periodic images and self-contact.

:func:`clearance` samples every yarn, finds candidate pairs with a KD-tree against the yarns and
their periodic images, drops pairs that are neighbours along one strand, keeps the discrete local
minima of the distance and refines them by a bounded Newton iteration on the curve parameters.
The result is a :class:`Clearance`: the minimum, the closest :class:`Contact` and every contact
closer than the threshold (default the knitted diameter dk).
"""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np

from knitframe.errors import NumericalError
from knitframe.geometry.cell import UnitCell, image_shifts, strands

__all__ = ["Contact", "Clearance", "clearance"]


@attrs.frozen
class Contact:
    """A local minimum of the distance between two centerlines (a yarn and an image of one)."""

    #: yarn indices (a, b)
    yarns: tuple[int, int]
    #: (k1, k2): b is shifted by k1 L1 + k2 L2
    image: tuple[int, int]
    #: parameters on a and b
    t: tuple[float, float]
    #: midpoint of the closest pair, mm
    point: tuple[float, float, float]
    #: centerline-to-centerline distance, mm
    distance: float

    def to_dict(self) -> dict[str, Any]:
        """Plain-data dict for JSON."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in attrs.asdict(self).items()}


@attrs.frozen
class Clearance:
    """Minimum centerline-to-centerline distance of a cell and the places closer than dk."""

    #: mm
    minimum: float
    closest: Contact
    #: local minima with distance < dk, closest first
    overlaps: tuple[Contact, ...]
    #: knitted diameter used as the overlap threshold, mm
    dk: float
    #: pairs on one strand closer than this along it are ignored, mm
    self_exclusion: float
    #: sampling spacing along the yarn before refinement, mm
    spacing: float

    def to_dict(self) -> dict[str, Any]:
        """Plain-data dict for JSON."""
        return {
            "minimum": self.minimum,
            "minimum_over_dk": self.minimum / self.dk,
            "closest": self.closest.to_dict(),
            "overlaps": [c.to_dict() for c in self.overlaps],
            "dk": self.dk,
            "self_exclusion": self.self_exclusion,
            "spacing": self.spacing,
        }


@attrs.frozen(eq=False)
class _Samples:
    """Dense samples of every yarn with strand bookkeeping for the exclusion rule."""

    #: (m,) yarn index
    yarn: np.ndarray
    #: (m,) sample index within the yarn
    index: np.ndarray
    #: (m,)
    t: np.ndarray
    #: (m, 3)
    x: np.ndarray
    #: (m,) strand number
    strand: np.ndarray
    #: (m,) arc coordinate unrolled along the strand, mm
    S: np.ndarray
    #: (n_strands,) strand length Λ per cell crossing, mm
    length: np.ndarray
    #: (n_strands,) yarns per strand
    cycle: np.ndarray
    #: (n_yarns,) position of each yarn in its strand
    pos: np.ndarray
    #: per yarn (t grid, s) arc tables
    tables: list = attrs.Factory(list)


def _samples(cell: UnitCell, spacing: float) -> _Samples:
    st = strands(cell)
    n_y = len(cell.yarns)
    strand_of, pos, offset = np.zeros(n_y, int), np.zeros(n_y, int), np.zeros(n_y)
    length, cycle = np.zeros(len(st)), np.zeros(len(st), int)
    yl = [c.arc_length() for c in cell.yarns]
    for k, cyc in enumerate(st):
        acc = 0.0
        for p, i in enumerate(cyc):
            strand_of[i], pos[i], offset[i] = k, p, acc
            acc += yl[i]
        length[k], cycle[k] = acc, len(cyc)
    parts, tables = [], []
    for i, c in enumerate(cell.yarns):
        n = max(16, int(np.ceil(yl[i] / spacing)))
        t, x, _ = c.sample(n, endpoint=False)
        tables.append(c.arc_table())
        parts.append((np.full(n, i), np.arange(n), t, x, offset[i] + np.interp(t, *tables[-1])))
    yarn, index, t, x, S = (np.concatenate(a) for a in zip(*parts, strict=True))
    return _Samples(yarn, index, t, x, strand_of[yarn], S, length, cycle, pos, tables)


def _unrolled(sm: _Samples, rows: np.ndarray, k1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(strand key, unrolled arc coordinate) of samples ``rows`` on the image shifted by k1 L1.

    Yarn i_p of a strand with m yarns, shifted by k1 L1, lies on the copy of the strand that
    starts with i_0 at image (k1 - p) mod m, one strand-length Λ further for every m images.
    """
    st = sm.strand[rows]
    m = sm.cycle[st]
    rel = k1 - sm.pos[sm.yarn[rows]]
    base = np.mod(rel, m)
    return base, (rel - base) // m * sm.length[st] + sm.S[rows]


def _excluded(sm: _Samples, a: np.ndarray, b: np.ndarray, k: np.ndarray, excl: float) -> np.ndarray:
    """True where samples a (image 0) and b (image k) lie on one strand closer than ``excl`` along it."""
    ka, Sa = _unrolled(sm, a, np.zeros(len(a), int))
    kb, Sb = _unrolled(sm, b, k[:, 0])
    same = (sm.strand[a] == sm.strand[b]) & (k[:, 1] == 0) & (ka == kb)
    return same & (np.abs(Sa - Sb) < excl)


def clearance(
    cell: UnitCell,
    *,
    spacing: float | None = None,
    self_exclusion: float | None = None,
    threshold: float | None = None,
) -> Clearance:
    """Minimum centerline-to-centerline distance, with periodic images and self-contact.

    Candidates come from a KD-tree (:class:`scipy.spatial.cKDTree`) on samples every
    ``spacing`` mm (default dk/10) of every yarn against the yarns and their images shifted by
    k1 L1 + k2 L2, k1, k2 ∈ {-1, 0, 1}. Pairs on the same strand less than ``self_exclusion``
    (default π·dk) apart along it are ignored: they are neighbours, not contacts (their chord
    is at most their arc distance). Discrete local minima of the distance over the remaining
    pairs are refined together by a bounded Newton iteration on (t_a, t_b) with the exact
    derivatives (:func:`_refine`). Pairs that are minima only because their closer neighbours
    are excluded, and refined pairs that slide among excluded neighbours, keep their sampled
    values.

    Parameters
    ----------
    cell : UnitCell
    spacing : float, optional
        Sampling step along the yarn, mm.
    self_exclusion : float, optional
        Arc distance along one strand under which pairs are ignored, mm.
    threshold : float, optional
        Distance under which a contact is listed in ``overlaps``; default dk.

    Returns
    -------
    Clearance
        ``minimum`` (mm), the ``closest`` contact and every local minimum below ``threshold``.
    """
    dk = cell.dk
    h = spacing or dk / 10.0
    excl = np.pi * dk if self_exclusion is None else float(self_exclusion)
    thr = dk if threshold is None else float(threshold)
    sm = _samples(cell, h)
    a, b, k, dist = _candidate_pairs(cell, sm, max(1.5 * thr, 2.0 * h), excl)
    cand = _local_minima(cell, sm, a, b, k, dist, excl)
    contacts = _dedupe(_refined_contacts(cell, sm, cand, excl))
    contacts.sort(key=lambda c: c.distance)
    return Clearance(
        minimum=contacts[0].distance,
        closest=contacts[0],
        overlaps=tuple(c for c in contacts if c.distance < thr),
        dk=dk,
        self_exclusion=excl,
        spacing=h,
    )


def _candidate_pairs(
    cell: UnitCell, sm: _Samples, radius: float, excl: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sample pairs (a, b + image k) closer than ``radius`` mm that are not strand neighbours.

    A KD-tree of the samples is searched against one of the samples of every image
    k1 L1 + k2 L2, k1, k2 ∈ {-1, 0, 1}; while every pair found is excluded the radius doubles,
    up to twice the cell's extent |L1| + |L2|. Returns ``a`` (p,), ``b`` (p,) sample indices,
    ``k`` (p, 2) image indices and the distances (p,) in mm; NumericalError if none is left.
    """
    from scipy.spatial import cKDTree

    kk, shifts = image_shifts(cell)
    n = len(sm.t)
    img_x = (sm.x[None, :, :] + shifts[:, None, :]).reshape(-1, 3)
    base_tree = cKDTree(sm.x)
    img_tree = cKDTree(img_x)
    extent = float(np.linalg.norm(cell.L1) + np.linalg.norm(cell.L2))
    while True:
        pairs = base_tree.sparse_distance_matrix(img_tree, radius, output_type="ndarray")
        a = pairs["i"].astype(int)
        b = pairs["j"].astype(int) % n
        k = kk[pairs["j"].astype(int) // n]
        keep = ~_excluded(sm, a, b, k, excl)
        if np.any(keep) or radius > 2 * extent:
            break
        radius *= 2.0
    if not np.any(keep):
        raise NumericalError("clearance: found no pair of yarn points within the cell's reach")
    return a[keep], b[keep], k[keep], pairs["v"][keep]


def _refined_contacts(cell: UnitCell, sm: _Samples, cand: list, excl: float) -> list[Contact]:
    """The candidate local minima of :func:`_local_minima` as Contacts, refined by :func:`_refine`."""
    ia = np.array([c[0] for c in cand], int)
    ib = np.array([c[1] for c in cand], int)
    kc = np.array([c[2] for c in cand], int).reshape(-1, 2)
    d0 = np.array([c[3] for c in cand])
    # minima only because their closer neighbours are excluded stay as sampled
    free = ~np.array([c[4] for c in cand], bool)
    ta, tb, d = sm.t[ia].copy(), sm.t[ib].copy(), d0.copy()
    if np.any(free):
        ta[free], tb[free], d[free] = _refine(cell, sm, ia[free], ib[free], kc[free], d0[free], excl)
    return [_contact(cell, ia[i], ib[i], tuple(kc[i]), ta[i], tb[i], d[i], sm) for i in range(len(ia))]


def _local_minima(cell, sm, a, b, k, dist, excl):
    """Sampled pairs whose distance is not above any non-excluded neighbour pair (a±1, b) or (a, b±1)."""
    # one of the twin pairs (a, b, k) ~ (b, a, -k) only
    kid = k[:, 0] * 3 + k[:, 1]
    canon = (sm.yarn[a] < sm.yarn[b]) | ((sm.yarn[a] == sm.yarn[b]) & ((kid > 0) | ((kid == 0) & (a < b))))
    a, b, k, dist = a[canon], b[canon], k[canon], dist[canon]
    shift = k[:, :1] * cell.L1 + k[:, 1:] * cell.L2
    is_min = np.ones(len(a), bool)
    boundary = np.zeros(len(a), bool)
    starts = np.searchsorted(sm.yarn, np.arange(len(cell.yarns)))
    counts = np.bincount(sm.yarn, minlength=len(cell.yarns))
    for which in (0, 1):
        for step in (-1, 1):
            idx = a if which == 0 else b
            y = sm.yarn[idx]
            loc = sm.index[idx] + step
            inside = (loc >= 0) & (loc < counts[y])
            nb = np.where(inside, starts[y] + np.clip(loc, 0, counts[y] - 1), idx)
            na, nb_ = (nb, b) if which == 0 else (a, nb)
            dn = np.linalg.norm(sm.x[na] - sm.x[nb_] - shift, axis=1)
            ex = _excluded(sm, na, nb_, k, excl)
            is_min &= ~inside | ex | (dist <= dn)
            boundary |= inside & ex
    sel = np.flatnonzero(is_min)
    return [
        (int(a[i]), int(b[i]), (int(k[i, 0]), int(k[i, 1])), float(dist[i]), bool(boundary[i])) for i in sel
    ]


def _eval(cell: UnitCell, yarn: np.ndarray, t: np.ndarray, which: str) -> np.ndarray:
    """``position`` or ``derivative`` of yarn[i] at t[i] for mixed yarns, (m, 3)."""
    out = np.empty((len(t), 3))
    for y in np.unique(yarn):
        sel = yarn == y
        out[sel] = getattr(cell.yarns[y], which)(t[sel])
    return out


def _refine(
    cell: UnitCell, sm: _Samples, ia: np.ndarray, ib: np.ndarray, k: np.ndarray, d0: np.ndarray, excl: float
):
    """Closest pairs near the sampled pairs (ia, ib + image k): vectorised bounded Newton on (t_a, t_b).

    f = |r_a(t_a) - r_b(t_b) - s|² / 2 has the exact gradient (diff·r_a', -diff·r_b') and the
    Hessian [[r_a'·r_a' + diff·r_a'', -r_a'·r_b'], [., r_b'·r_b' - diff·r_b'']] with r'' from
    central differences of the exact r'. Each parameter stays within 3 sample steps of its start;
    steps that do not lower f are halved. Returns (t_a, t_b, distance), falling back to the
    sampled pair where refinement fails or lands among excluded neighbours.
    """
    ya, yb = sm.yarn[ia], sm.yarn[ib]
    shift = k[:, :1] * cell.L1 + k[:, 1:] * cell.L2
    span = np.array([c.t1 - c.t0 for c in cell.yarns])
    ta0, tb0 = sm.t[ia].copy(), sm.t[ib].copy()
    lo, hi = _bounds(cell, sm, ya, yb, ta0, tb0, span)
    t, f = _bounded_newton(cell, ya, yb, shift, np.stack([ta0, tb0], 1), lo, hi, span)
    d = np.sqrt(2.0 * f)
    bad = ~np.isfinite(d) | (d > d0)
    bad |= _slid_among_excluded(sm, ia, ib, k, t, ta0, tb0, excl)
    t[bad] = np.stack([ta0, tb0], 1)[bad]
    d[bad] = d0[bad]
    return t[:, 0], t[:, 1], d


def _bounds(
    cell: UnitCell,
    sm: _Samples,
    ya: np.ndarray,
    yb: np.ndarray,
    ta0: np.ndarray,
    tb0: np.ndarray,
    span: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (m, 2) on (t_a, t_b): 3 sample steps either side of the start, within [t0, t1]."""
    counts = np.bincount(sm.yarn, minlength=len(cell.yarns))
    t0s, t1s = np.array([c.t0 for c in cell.yarns]), np.array([c.t1 for c in cell.yarns])
    lo = np.stack(
        [
            np.maximum(t0s[ya], ta0 - 3 * span[ya] / counts[ya]),
            np.maximum(t0s[yb], tb0 - 3 * span[yb] / counts[yb]),
        ],
        1,
    )
    hi = np.stack(
        [
            np.minimum(t1s[ya], ta0 + 3 * span[ya] / counts[ya]),
            np.minimum(t1s[yb], tb0 + 3 * span[yb] / counts[yb]),
        ],
        1,
    )
    return lo, hi


def _half_sq_distance(
    cell: UnitCell, ya: np.ndarray, yb: np.ndarray, shift: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """f = |r_a(t_a) - r_b(t_b) - s|² / 2 (m,) and the difference r_a - r_b - s (m, 3), mm² and mm."""
    diff = _eval(cell, ya, t[:, 0], "position") - _eval(cell, yb, t[:, 1], "position") - shift
    return 0.5 * np.einsum("ij,ij->i", diff, diff), diff


def _bounded_newton(
    cell: UnitCell,
    ya: np.ndarray,
    yb: np.ndarray,
    shift: np.ndarray,
    t: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    span: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Minimise f over t (m, 2) within [lo, hi], in place: Newton steps halved until f does not rise.

    At most 40 steps, each with at most 30 halvings; stops when no parameter moved by more than
    1e-13 of the longest yarn's parameter span. Returns t (m, 2) and f (m,).
    """
    eps = 1e-6 * span
    f, diff = _half_sq_distance(cell, ya, yb, shift, t)
    for _ in range(40):
        step = _newton_step(cell, ya, yb, t, diff, eps)
        before = t.copy()
        moved = np.zeros(len(t), bool)
        for _ in range(30):
            trial = np.clip(t + step, lo, hi)
            ft, dt = _half_sq_distance(cell, ya, yb, shift, trial)
            ok = (ft <= f) & ~moved
            t[ok], f[ok], diff[ok] = trial[ok], ft[ok], dt[ok]
            moved |= ok
            if moved.all():
                break
            step = np.where(moved[:, None], step, 0.5 * step)
        if np.max(np.abs(t - before)) < 1e-13 * span.max():
            break
    return t, f


def _newton_step(
    cell: UnitCell, ya: np.ndarray, yb: np.ndarray, t: np.ndarray, diff: np.ndarray, eps: np.ndarray
) -> np.ndarray:
    """The Newton step (m, 2) on (t_a, t_b) of f, or a scaled gradient step where H is not positive.

    Gradient (diff·r_a', -diff·r_b'), Hessian [[r_a'·r_a' + diff·r_a'', -r_a'·r_b'],
    [., r_b'·r_b' - diff·r_b'']] with r'' from central differences (step ``eps`` per yarn) of
    the exact r'.
    """
    da, db = _eval(cell, ya, t[:, 0], "derivative"), _eval(cell, yb, t[:, 1], "derivative")
    dda = (
        _eval(cell, ya, t[:, 0] + eps[ya], "derivative") - _eval(cell, ya, t[:, 0] - eps[ya], "derivative")
    ) / (2 * eps[ya])[:, None]
    ddb = (
        _eval(cell, yb, t[:, 1] + eps[yb], "derivative") - _eval(cell, yb, t[:, 1] - eps[yb], "derivative")
    ) / (2 * eps[yb])[:, None]
    g = np.stack([np.einsum("ij,ij->i", diff, da), -np.einsum("ij,ij->i", diff, db)], 1)
    h11 = np.einsum("ij,ij->i", da, da) + np.einsum("ij,ij->i", diff, dda)
    h22 = np.einsum("ij,ij->i", db, db) - np.einsum("ij,ij->i", diff, ddb)
    h12 = -np.einsum("ij,ij->i", da, db)
    det = h11 * h22 - h12 * h12
    newton = (det > 1e-14 * (h11 * h22 + 1e-300)) & (h11 > 0)
    safe = np.where(newton, det, 1.0)
    return np.where(
        newton[:, None],
        -np.stack([h22 * g[:, 0] - h12 * g[:, 1], h11 * g[:, 1] - h12 * g[:, 0]], 1) / safe[:, None],
        -g / (np.einsum("ij,ij->i", da, da) + np.einsum("ij,ij->i", db, db))[:, None],
    )


def _slid_among_excluded(
    sm: _Samples,
    ia: np.ndarray,
    ib: np.ndarray,
    k: np.ndarray,
    t: np.ndarray,
    ta0: np.ndarray,
    tb0: np.ndarray,
    excl: float,
) -> np.ndarray:
    """True (m,) where a refined pair on one strand has moved to within ``excl`` along it.

    The arc coordinates of the refined parameters ``t`` (m, 2) are the sampled ones moved by
    the arc length between the sampled parameters (ta0, tb0) and t, from the yarns' arc tables.
    """
    ya, yb = sm.yarn[ia], sm.yarn[ib]
    same = sm.strand[ia] == sm.strand[ib]
    bad = np.zeros(len(ia), bool)
    if np.any(same):
        Sa = sm.S[ia] + _interp_yarn(sm, ya, t[:, 0]) - _interp_yarn(sm, ya, ta0)
        Sb = sm.S[ib] + _interp_yarn(sm, yb, t[:, 1]) - _interp_yarn(sm, yb, tb0)
        sm2 = attrs.evolve(
            sm,
            S=np.concatenate([Sa, Sb]),
            yarn=np.concatenate([ya, yb]),
            strand=np.concatenate([sm.strand[ia], sm.strand[ib]]),
        )
        m = len(ia)
        bad |= same & _excluded(sm2, np.arange(m), np.arange(m, 2 * m), k, excl)
    return bad


def _interp_yarn(sm: _Samples, yarn: np.ndarray, t: np.ndarray) -> np.ndarray:
    out = np.empty(len(t))
    for y in np.unique(yarn):
        sel = yarn == y
        out[sel] = np.interp(t[sel], *sm.tables[y])
    return out


def _contact(cell, ia, ib, kb, ta, tb, d, sm) -> Contact:
    ya, yb = int(sm.yarn[ia]), int(sm.yarn[ib])
    pa = cell.yarns[ya].position(np.array([ta]))[0]
    pb = cell.yarns[yb].position(np.array([tb]))[0] + kb[0] * cell.L1 + kb[1] * cell.L2
    mid = 0.5 * (pa + pb)
    return Contact(
        (ya, yb),
        (int(kb[0]), int(kb[1])),
        (float(ta), float(tb)),
        (float(mid[0]), float(mid[1]), float(mid[2])),
        float(d),
    )


def _dedupe(contacts: list[Contact]) -> list[Contact]:
    """Drop local minima that refined onto the same pair of points."""
    out: dict[tuple, Contact] = {}
    for c in contacts:
        key = (c.yarns, c.image, round(c.t[0], 6), round(c.t[1], 6))
        if key not in out or c.distance < out[key].distance:
            out[key] = c
    return list(out.values())
