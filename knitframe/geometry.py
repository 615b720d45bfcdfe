"""Unit-cell yarn geometry shared by the pattern plugins and the unit-cell solvers.

A pattern plugin's ``cell(fabric)`` returns a :class:`UnitCell`: the yarn centerlines of a 2x2
stitch cell as smooth parametric curves :class:`Centerline` with exact tangents, the lattice
vectors, the pairing of yarn ends across the course boundary and the knit/purl layout.

Axes: x is the course, y the wale, z out of the fabric plane; lengths in mm.

Periodicity. Along the course a yarn is cut at the cell boundary: the end of yarn ``i`` at ``t1``
continues as the start of yarn ``j`` shifted by ``L1`` for every ``(i, j)`` in ``end_pairs``.
Following the pairs from a yarn back to itself gives a *strand*: one infinite yarn of the fabric.
Along the wale the rows hold together only through contact with periodic images (``±L2``,
``±L1 ± L2``); :func:`image_shifts` lists them.

Pattern plugins, built-in or third-party, share the helpers that turn a Fabric into cell
dimensions: the machine stitch-length table (:data:`STITCH_LENGTHS`, :func:`arc_length_for`,
:func:`check_stitch_lengths`), Munden's pitches (:func:`munden_pitches`), a smooth sign for
blending stitch shapes (:func:`smooth_sign`), the arc-length calibration
(:func:`solve_arc_length`) and the cell of one yarn per course row (:func:`course_cell`).

Besides the records this module holds the geometry every consumer needs: arc length,
rotation-minimising frames closed over each strand (:func:`frames`), the minimum
centerline-to-centerline clearance with periodic images and self-contact (:func:`clearance`),
and writers for VTU (:func:`write_vtu`) and a three-view PNG (:func:`plot_views`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from knitframe.errors import FieldError, GeometryError, NumericalError

if TYPE_CHECKING:
    from knitframe.records import Fabric

__all__ = [
    "Centerline",
    "UnitCell",
    "Frames",
    "Contact",
    "Clearance",
    "strands",
    "image_shifts",
    "STITCH_LENGTHS",
    "MUNDEN_KC",
    "MUNDEN_KW",
    "check_stitch_lengths",
    "arc_length_for",
    "munden_pitches",
    "smooth_sign",
    "solve_arc_length",
    "course_cell",
    "arc_length",
    "frames",
    "clearance",
    "crossings",
    "tube_surface",
    "write_vtu",
    "plot_views",
    "summary",
    "ARC_LENGTH_RANGE_DK",
    "MIN_PITCH_DK",
    "checked_cell",
]


def _vec3(value: Any) -> np.ndarray:
    arr = np.array(value, dtype=np.float64, copy=True).reshape(3)
    arr.setflags(write=False)
    return arr


# Composite Gauss-Legendre nodes on [0, 1]: 8 per panel is exact for degree-15 polynomials.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_GL_X, _GL_W = 0.5 * (_GL_X + 1.0), 0.5 * _GL_W


def _integrate_speed(derivative: Callable, a: float, b: float, panels: int) -> float:
    edges = np.linspace(a, b, panels + 1)
    h = np.diff(edges)
    t = (edges[:-1, None] + h[:, None] * _GL_X[None, :]).reshape(-1)
    speed = np.linalg.norm(np.asarray(derivative(t), dtype=np.float64), axis=1)
    return float(np.sum((h[:, None] * _GL_W[None, :]).reshape(-1) * speed))


def arc_length(derivative: Callable, a: float, b: float, *, rtol: float = 1e-12) -> float:
    """Arc length ∫_a^b |r'(t)| dt by composite Gauss-Legendre quadrature, doubling the panels.

    Parameters
    ----------
    derivative : callable
        ``t (n,) -> (n, 3)`` exact derivative dr/dt, mm per unit t.
    a, b : float
        Parameter interval.
    rtol : float
        Relative change between two successive doublings at which the result is accepted.

    Returns
    -------
    float
        Length in mm. Raises NumericalError when the quadrature does not settle (a cusp).
    """
    prev = _integrate_speed(derivative, a, b, 32)
    for panels in (64, 128, 256, 512, 1024, 2048, 4096):
        cur = _integrate_speed(derivative, a, b, panels)
        if not np.isfinite(cur):
            raise NumericalError(f"arc length is not finite on [{a}, {b}]")
        if abs(cur - prev) <= rtol * abs(cur):
            return cur
        prev = cur
    raise NumericalError(f"arc length on [{a}, {b}] did not converge (last change {abs(cur - prev):.3g} mm)")


@attrs.frozen(eq=False)
class Centerline:
    """One yarn of the cell as a smooth parametric curve r(t), t in [t0, t1].

    ``position`` and ``derivative`` accept any real t (not only [t0, t1]) and are vectorised:
    ``t (n,) -> (n, 3)`` in mm and mm per unit t. ``period`` is r(t1) - r(t0).
    """

    #: e.g. "row0"
    name: str
    #: t (n,) -> (n, 3), mm
    position: Callable[[np.ndarray], np.ndarray]
    #: t (n,) -> (n, 3) exact dr/dt, mm
    derivative: Callable[[np.ndarray], np.ndarray]
    t0: float
    t1: float
    #: (3,) r(t1) - r(t0), mm
    period: np.ndarray = attrs.field(converter=_vec3)

    def sample(self, n: int, *, endpoint: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``n`` uniformly spaced parameters with positions and unit tangents.

        Returns ``t`` (n,), ``x`` (n, 3) mm and unit tangents (n, 3). ``endpoint=False`` drops t1
        (whose point is the paired yarn's start shifted by L1), for periodic discretisations.
        """
        t = np.linspace(self.t0, self.t1, n, endpoint=endpoint)
        x = np.asarray(self.position(t), dtype=np.float64)
        d = np.asarray(self.derivative(t), dtype=np.float64)
        speed = np.linalg.norm(d, axis=1)
        ok = np.isfinite(speed) & np.all(np.isfinite(x), axis=1)
        ok[ok] = speed[ok] > 1e-12 * (1.0 + speed[ok].max(initial=0.0))
        if not np.all(ok):
            bad = int(np.flatnonzero(~ok)[0])
            raise NumericalError(
                f"yarn '{self.name}': no tangent at t = {t[bad]:.6g} (speed {speed[bad]:.3g})"
            )
        return t, x, d / speed[:, None]

    def arc_length(self) -> float:
        """Length of the curve between t0 and t1, mm (relative accuracy about 1e-12)."""
        return arc_length(self.derivative, self.t0, self.t1)

    def arc_table(self, n: int = 2048) -> tuple[np.ndarray, np.ndarray]:
        """``n + 1`` parameters from t0 to t1 and the arc length s(t) from t0 at each, mm (4-point Gauss per interval)."""
        grid = np.linspace(self.t0, self.t1, n + 1)
        gx, gw = np.polynomial.legendre.leggauss(4)
        h = grid[1] - grid[0]
        tq = (grid[:-1, None] + 0.5 * h * (gx[None, :] + 1.0)).reshape(-1)
        seg = (0.5 * h * gw[None, :] * np.linalg.norm(self.derivative(tq), axis=1).reshape(n, 4)).sum(axis=1)
        return grid, np.concatenate([[0.0], np.cumsum(seg)])

    def arc_coordinate(self, t: np.ndarray, *, n: int = 2048) -> np.ndarray:
        """Arc length s(t) from t0, mm, for t in [t0, t1] (interpolated in :meth:`arc_table`)."""
        return np.interp(t, *self.arc_table(n))


@attrs.frozen(eq=False)
class UnitCell:
    """The 2x2 stitch cell of a pattern: centerlines, lattice, end pairing and knit/purl layout."""

    pattern: str
    #: one yarn per course row, each spanning the two stitches of the row
    yarns: tuple[Centerline, ...]
    #: (3,) course lattice vector (2 x course pitch), mm
    L1: np.ndarray = attrs.field(converter=_vec3)
    #: (3,) wale lattice vector (2 x wale pitch), mm
    L2: np.ndarray = attrs.field(converter=_vec3)
    #: knitted yarn radius dk/2, mm
    radius: float
    #: (i, j): end of yarn i at t1 continues as start of yarn j + L1
    end_pairs: tuple[tuple[int, int], ...]
    #: rows x columns of "k" / "p"
    layout: tuple[tuple[str, ...], ...]
    #: mm
    arc_length_per_stitch: float
    #: mm
    course_pitch: float
    #: mm
    wale_pitch: float
    #: pattern-specific shape parameters, for reports
    info: dict[str, Any] = attrs.Factory(dict)

    def __attrs_post_init__(self) -> None:
        n = len(self.yarns)
        targets = sorted(j for _, j in self.end_pairs)
        if sorted(i for i, _ in self.end_pairs) != list(range(n)) or targets != list(range(n)):
            raise GeometryError(
                f"end_pairs {self.end_pairs} must pair each of the {n} yarns' ends exactly once"
            )

    @property
    def dk(self) -> float:
        """Knitted yarn diameter, mm."""
        return 2.0 * self.radius

    def pair_of(self, i: int) -> int:
        """The yarn whose start continues the end of yarn ``i`` (shifted by L1)."""
        return dict(self.end_pairs)[i]


def strands(cell: UnitCell) -> list[list[int]]:
    """Yarn indices grouped into strands (cycles of ``end_pairs``), each in continuation order."""
    nxt = dict(cell.end_pairs)
    seen: set[int] = set()
    out = []
    for i in range(len(cell.yarns)):
        if i in seen:
            continue
        cyc = [i]
        seen.add(i)
        while nxt[cyc[-1]] != i:
            cyc.append(nxt[cyc[-1]])
            seen.add(cyc[-1])
        out.append(cyc)
    return out


def image_shifts(cell: UnitCell, reach: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Periodic image offsets ``k1 L1 + k2 L2`` for k1, k2 in [-reach, reach].

    Returns ``(k, shift)``: integer pairs (m, 2) with (0, 0) first, and shifts (m, 3) in mm.
    """
    r = np.arange(-reach, reach + 1)
    k = np.array([(a, b) for a in r for b in r], dtype=int)
    k = k[np.argsort(np.abs(k).sum(axis=1), kind="stable")]
    return k, k[:, :1] * cell.L1[None, :] + k[:, 1:] * cell.L2[None, :]


# ------------------------------------------------------------------------------- pattern helpers
#: Machine stitch-length setting -> yarn length per stitch, mm (paper's microscopy, 12 stitches).
STITCH_LENGTHS: dict[str, float] = {"10": 3.9, "11": 4.7, "12": 5.9}
#: Munden's constants for relaxed plain knit (courses/cm = Kc/ℓ, wales/cm = Kw/ℓ, ℓ in cm); mid-range values.
MUNDEN_KC, MUNDEN_KW = 5.3, 4.0


def check_stitch_lengths(instance, attribute, value) -> None:
    """attrs validator of a ``stitch_lengths`` table: machine-setting keys ("11") to arc lengths > 0 mm."""
    for key, length in value.items():
        try:
            float(key)
        except ValueError:
            raise FieldError(
                f"{attribute.name}.{key}", 'key must be a machine setting number, e.g. "11"'
            ) from None
        if not (isinstance(length, (int, float)) and np.isfinite(length) and length > 0):
            raise FieldError(f"{attribute.name}.{key}", f"must be an arc length > 0 mm, got {length!r}")


def arc_length_for(fabric: Fabric, table: dict[str, float]) -> float:
    """Yarn length per stitch, mm: ``fabric.arc_length`` if given, else the machine setting looked up in ``table``."""
    if fabric.arc_length is not None:
        return float(fabric.arc_length)
    for key, length in table.items():
        if float(key) == float(fabric.stitch_length):
            return float(length)
    known = ", ".join(f"{k} -> {val} mm" for k, val in sorted(table.items(), key=lambda kv: float(kv[0])))
    raise GeometryError(
        f"stitch_length {fabric.stitch_length:g} is not in the stitch-length table ({known}); "
        "give arc_length in mm or add the setting to the pattern's stitch_lengths"
    )


def munden_pitches(
    arc: float, fabric: Fabric, Kc: float = MUNDEN_KC, Kw: float = MUNDEN_KW
) -> tuple[float, float]:
    """(course, wale) pitch in mm: the fabric's if given, else Munden's p_c = ℓ/Kw and p_w = ℓ/Kc.

    ``arc`` is the yarn length per stitch ℓ in mm; Kc and Kw are the dimensionless constants
    (courses/cm = Kc/ℓ, wales/cm = Kw/ℓ with ℓ in cm).
    """
    return (
        float(fabric.course_pitch) if fabric.course_pitch is not None else arc / Kw,
        float(fabric.wale_pitch) if fabric.wale_pitch is not None else arc / Kc,
    )


def smooth_sign(c: np.ndarray, kappa: float) -> tuple[np.ndarray, np.ndarray]:
    """S(c) = tanh(κc)/tanh κ and dS/dc: a smooth sign, exactly ±1 at c = ±1, sharper for larger κ.

    With c = cos t or cos(t/2) it switches a stitch property analytically between stitches, so
    a curve blended with it keeps an exact derivative. ``c`` (n,) -> two arrays (n,).
    """
    th = np.tanh(kappa * np.asarray(c, dtype=np.float64))
    k = np.tanh(kappa)
    return th / k, kappa * (1.0 - th * th) / k


def solve_arc_length(
    per_stitch: Callable[[float], float], target: float, lower: float, upper: float, *, context: str
) -> float:
    """The shape parameter h >= ``lower`` at which ``per_stitch(h)`` (mm of yarn per stitch) equals ``target``.

    ``per_stitch`` must grow with h. The bracket [lower, upper] is widened by doubling ``upper``,
    then :func:`scipy.optimize.brentq` solves to round-off. When even ``lower`` (the smallest
    shape that still interlocks) needs more yarn than ``target`` the request is impossible:
    GeometryError names the target, ``context`` (e.g. the pitches) and the least yarn needed.
    """
    from scipy.optimize import brentq

    f = lambda h: per_stitch(h) - target  # noqa: E731
    low = f(lower)
    if low >= 0.0:
        raise GeometryError(
            f"arc length {target:g} mm per stitch is too short for {context}: "
            f"interlocking loops need more than {low + target:.4g} mm"
        )
    while f(upper) <= 0.0:
        upper *= 2.0
    return brentq(f, lower, upper, xtol=1e-15 * upper, rtol=4 * np.finfo(float).eps, maxiter=200)


def course_cell(
    pattern: str,
    yarns: tuple[Centerline, ...],
    course_pitch: float,
    wale_pitch: float,
    dk: float,
    layout: tuple[tuple[str, ...], ...],
    target: float,
    info: dict[str, Any] | None = None,
) -> UnitCell:
    """The 2x2 cell of one yarn per course row, each yarn continuing as itself across the course boundary.

    L1 = (2 p_c, 0, 0), L2 = (0, 2 p_w, 0), end_pairs (i, i), radius dk/2 (lengths in mm). The arc
    length per stitch, the yarns' total length over the stitches of ``layout``, must match
    ``target`` to 1e-9 relative; a miss means the calibration failed and raises NumericalError.
    """
    got = sum(y.arc_length() for y in yarns) / sum(len(row) for row in layout)
    if abs(got - target) > 1e-9 * target:
        raise NumericalError(f"pattern '{pattern}': arc length {got!r} mm missed the target {target!r} mm")
    return UnitCell(
        pattern=pattern,
        yarns=tuple(yarns),
        L1=(2.0 * course_pitch, 0.0, 0.0),
        L2=(0.0, 2.0 * wale_pitch, 0.0),
        radius=0.5 * dk,
        end_pairs=tuple((i, i) for i in range(len(yarns))),
        layout=tuple(tuple(row) for row in layout),
        arc_length_per_stitch=got,
        course_pitch=course_pitch,
        wale_pitch=wale_pitch,
        info=dict(info or {}),
    )


# ----------------------------------------------------------------------------------------- frames
@attrs.frozen(eq=False)
class Frames:
    """Rotation-minimising frame along one yarn at ``n + 1`` parameters from t0 to t1 inclusive."""

    #: (n+1,)
    t: np.ndarray
    #: (n+1, 3) positions, mm
    x: np.ndarray
    #: (n+1, 3) unit tangents
    tangent: np.ndarray
    #: (n+1, 3) unit normals, ⟂ tangent
    normal: np.ndarray
    #: (n+1, 3) tangent x normal
    binormal: np.ndarray


def _householder(v: np.ndarray) -> np.ndarray:
    """(m, 3, 3) reflections I - 2 v vᵀ / (v·v); identity where v = 0."""
    c = np.einsum("ij,ij->i", v, v)
    safe = np.where(c > 0, c, 1.0)
    h = np.eye(3)[None] - 2.0 * v[:, :, None] * v[:, None, :] / safe[:, None, None]
    h[c <= 1e-300] = np.eye(3)
    return h


def _prefix_products(m: np.ndarray) -> np.ndarray:
    """Cumulative products P_k = M_k ... M_1 M_0 of (n, 3, 3) matrices by a log-depth scan."""
    p = m.copy()
    k = 1
    while k < len(p):
        p[k:] = p[k:] @ p[:-k]
        k *= 2
    return p


def frames(cell: UnitCell, n: int = 256) -> list[Frames]:
    """Rotation-minimising frames of every yarn, closed periodically over each strand.

    The double-reflection method (Wang, Jüttler, Zheng & Liu 2008, ACM TOG 27(1)) propagates a
    normal from sample to sample: with v1 = x_{i+1} - x_i, reflect r_i and T_i in the plane
    ⟂ v1 to get r_L, T_L; with v2 = T_{i+1} - T_L, reflect r_L in the plane ⟂ v2. After one trip
    round a strand the frame comes back turned by the strand's holonomy angle φ about the
    tangent; the frame is then untwisted by -φ s/Λ (s the arc coordinate along the strand of
    length Λ), so it is continuous across every cell boundary. Each yarn gets ``n`` intervals.

    Returns
    -------
    list of Frames
        One per yarn, in the order of ``cell.yarns``; frame ``[-1]`` of yarn ``i`` equals frame
        ``[0]`` of its paired yarn.
    """
    out: list[Frames | None] = [None] * len(cell.yarns)
    for strand in strands(cell):
        ts, xs, tans = [], [], []
        shift = np.zeros(3)
        for k, i in enumerate(strand):
            t, x, tan = cell.yarns[i].sample(n + 1)
            ts.append(t)
            xs.append(x[:-1] + shift)
            tans.append(tan[:-1])
            shift = shift + cell.L1
        # closing sample: the strand's start one full strand further on
        _, x_first, tan_first = cell.yarns[strand[0]].sample(2)
        x = np.vstack(xs + [x_first[:1] + shift])
        tan = np.vstack(tans + [tan_first[:1]])
        v1 = x[1:] - x[:-1]
        h1 = _householder(v1)
        t_left = np.einsum("mij,mj->mi", h1, tan[:-1])
        h2 = _householder(tan[1:] - t_left)
        step = h2 @ h1  # rotation taking frame i to frame i+1
        r0 = _perpendicular(tan[0])
        rot = _prefix_products(step)
        r = np.vstack([r0, np.einsum("mij,j->mi", rot, r0)])
        # holonomy: angle from the propagated end normal back to r0 about the (common) tangent
        b0 = np.cross(tan[0], r0)
        phi = np.arctan2(r[-1] @ b0, r[-1] @ r0)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(v1, axis=1))])
        ang = -phi * s / s[-1]
        b = np.cross(tan, r)
        normal = np.cos(ang)[:, None] * r + np.sin(ang)[:, None] * b
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        binormal = np.cross(tan, normal)
        if not (np.all(np.isfinite(normal)) and np.all(np.isfinite(binormal))):
            raise NumericalError(f"frame of strand {strand} is not finite (degenerate tangent?)")
        for k, i in enumerate(strand):
            sl = slice(k * n, k * n + n + 1)
            back = k * cell.L1
            out[i] = Frames(ts[k], x[sl] - back, tan[sl], normal[sl], binormal[sl])
    return out  # type: ignore[return-value]


def _perpendicular(t: np.ndarray) -> np.ndarray:
    """A unit vector ⟂ t, chosen from the coordinate axis least aligned with t."""
    e = np.zeros(3)
    e[int(np.argmin(np.abs(t)))] = 1.0
    r = e - (e @ t) * t
    return r / np.linalg.norm(r)


# -------------------------------------------------------------------------------------- clearance
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
    yarn, index, t, x, S = (np.concatenate(a) for a in zip(*parts))
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
    from scipy.spatial import cKDTree

    dk = cell.dk
    h = spacing or dk / 10.0
    excl = np.pi * dk if self_exclusion is None else float(self_exclusion)
    thr = dk if threshold is None else float(threshold)
    sm = _samples(cell, h)
    kk, shifts = image_shifts(cell)
    n = len(sm.t)
    img_x = (sm.x[None, :, :] + shifts[:, None, :]).reshape(-1, 3)
    base_tree = cKDTree(sm.x)
    img_tree = cKDTree(img_x)
    extent = float(np.linalg.norm(cell.L1) + np.linalg.norm(cell.L2))
    radius = max(1.5 * thr, 2.0 * h)
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
    a, b, k, dist = a[keep], b[keep], k[keep], pairs["v"][keep]
    cand = _local_minima(cell, sm, a, b, k, dist, excl)
    ia = np.array([c[0] for c in cand], int)
    ib = np.array([c[1] for c in cand], int)
    kc = np.array([c[2] for c in cand], int).reshape(-1, 2)
    d0 = np.array([c[3] for c in cand])
    # minima only because their closer neighbours are excluded stay as sampled
    free = ~np.array([c[4] for c in cand], bool)
    ta, tb, d = sm.t[ia].copy(), sm.t[ib].copy(), d0.copy()
    if np.any(free):
        ta[free], tb[free], d[free] = _refine(cell, sm, ia[free], ib[free], kc[free], d0[free], excl)
    contacts = [_contact(cell, ia[i], ib[i], tuple(kc[i]), ta[i], tb[i], d[i], sm) for i in range(len(ia))]
    contacts = _dedupe(contacts)
    contacts.sort(key=lambda c: c.distance)
    return Clearance(
        minimum=contacts[0].distance,
        closest=contacts[0],
        overlaps=tuple(c for c in contacts if c.distance < thr),
        dk=dk,
        self_exclusion=excl,
        spacing=h,
    )


def _local_minima(cell, sm, a, b, k, dist, excl):
    """Sampled pairs whose distance is not above any non-excluded neighbour pair (a±1, b) or (a, b±1)."""
    n = len(sm.t)
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
    counts = np.bincount(sm.yarn, minlength=len(cell.yarns))
    t0s, t1s = np.array([c.t0 for c in cell.yarns]), np.array([c.t1 for c in cell.yarns])
    ta0, tb0 = sm.t[ia].copy(), sm.t[ib].copy()
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
    eps = 1e-6 * span

    def fval(t):
        diff = _eval(cell, ya, t[:, 0], "position") - _eval(cell, yb, t[:, 1], "position") - shift
        return 0.5 * np.einsum("ij,ij->i", diff, diff), diff

    t = np.stack([ta0, tb0], 1)
    f, diff = fval(t)
    for _ in range(40):
        da, db = _eval(cell, ya, t[:, 0], "derivative"), _eval(cell, yb, t[:, 1], "derivative")
        dda = (
            _eval(cell, ya, t[:, 0] + eps[ya], "derivative")
            - _eval(cell, ya, t[:, 0] - eps[ya], "derivative")
        ) / (2 * eps[ya])[:, None]
        ddb = (
            _eval(cell, yb, t[:, 1] + eps[yb], "derivative")
            - _eval(cell, yb, t[:, 1] - eps[yb], "derivative")
        ) / (2 * eps[yb])[:, None]
        g = np.stack([np.einsum("ij,ij->i", diff, da), -np.einsum("ij,ij->i", diff, db)], 1)
        h11 = np.einsum("ij,ij->i", da, da) + np.einsum("ij,ij->i", diff, dda)
        h22 = np.einsum("ij,ij->i", db, db) - np.einsum("ij,ij->i", diff, ddb)
        h12 = -np.einsum("ij,ij->i", da, db)
        det = h11 * h22 - h12 * h12
        newton = (det > 1e-14 * (h11 * h22 + 1e-300)) & (h11 > 0)
        safe = np.where(newton, det, 1.0)
        step = np.where(
            newton[:, None],
            -np.stack([h22 * g[:, 0] - h12 * g[:, 1], h11 * g[:, 1] - h12 * g[:, 0]], 1) / safe[:, None],
            -g / (np.einsum("ij,ij->i", da, da) + np.einsum("ij,ij->i", db, db))[:, None],
        )
        before = t.copy()
        moved = np.zeros(len(t), bool)
        for _ in range(30):
            trial = np.clip(t + step, lo, hi)
            ft, dt = fval(trial)
            ok = (ft <= f) & ~moved
            t[ok], f[ok], diff[ok] = trial[ok], ft[ok], dt[ok]
            moved |= ok
            if moved.all():
                break
            step = np.where(moved[:, None], step, 0.5 * step)
        if np.max(np.abs(t - before)) < 1e-13 * span.max():
            break
    d = np.sqrt(2.0 * f)
    bad = ~np.isfinite(d) | (d > d0)
    same = sm.strand[ia] == sm.strand[ib]
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
    t[bad] = np.stack([ta0, tb0], 1)[bad]
    d[bad] = d0[bad]
    return t[:, 0], t[:, 1], d


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


def crossings(
    cell: UnitCell, upper: int, lower: int, shift: np.ndarray, n: int = 800
) -> list[tuple[float, float, float]]:
    """Crossings in the x-y projection of yarn ``upper`` with yarn ``lower`` shifted by ``shift`` (and ±L1).

    Both yarns are sampled as polylines of ``n`` segments. Returns ``(t_upper, x, z_upper -
    z_lower)`` for each crossing, sorted by t_upper: the sign says which yarn passes in front (+z).
    """
    cu, cl = cell.yarns[upper], cell.yarns[lower]
    tu = np.linspace(cu.t0, cu.t1, n + 1)
    xu = cu.position(tu)
    tl = np.linspace(cl.t0, cl.t1, n + 1)
    out = []
    for k1 in (-1, 0, 1):
        xl = cl.position(tl) + shift + k1 * cell.L1
        p, r = xu[:-1, None, :2], (xu[1:] - xu[:-1])[:, None, :2]
        q, s = xl[None, :-1, :2], (xl[1:] - xl[:-1])[None, :, :2]
        den = r[..., 0] * s[..., 1] - r[..., 1] * s[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            qp = q - p
            lam = (qp[..., 0] * s[..., 1] - qp[..., 1] * s[..., 0]) / den
            mu = (qp[..., 0] * r[..., 1] - qp[..., 1] * r[..., 0]) / den
        hit = (den != 0) & (lam >= 0) & (lam < 1) & (mu >= 0) & (mu < 1)
        for i, j in zip(*np.nonzero(hit)):
            zu = xu[i, 2] + lam[i, j] * (xu[i + 1, 2] - xu[i, 2])
            zl = xl[j, 2] + mu[i, j] * (xl[j + 1, 2] - xl[j, 2])
            out.append(
                (
                    float(tu[i] + lam[i, j] * (tu[1] - tu[0])),
                    float(xu[i, 0] + lam[i, j] * r[i, 0, 0]),
                    float(zu - zl),
                )
            )
    return sorted(out)


# ---------------------------------------------------------------------------------------- output
def tube_surface(fr: Frames, radius: float, sides: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Points and quads of the tube of ``radius`` swept along one yarn's frames.

    Returns points ((n+1)·sides, 3) mm and quad cells (n·sides, 4), ring by ring.
    """
    phi = 2.0 * np.pi * np.arange(sides) / sides
    ring = (
        np.cos(phi)[None, :, None] * fr.normal[:, None, :]
        + np.sin(phi)[None, :, None] * fr.binormal[:, None, :]
    )
    pts = (fr.x[:, None, :] + radius * ring).reshape(-1, 3)
    i = np.arange(len(fr.t) - 1)[:, None]
    j = np.arange(sides)[None, :]
    jn = (j + 1) % sides
    quads = np.stack([i * sides + j, i * sides + jn, (i + 1) * sides + jn, (i + 1) * sides + j], axis=-1)
    return pts, quads.reshape(-1, 4)


def write_vtu(cell: UnitCell, out: str | Path, *, n: int = 256, sides: int = 16) -> list[Path]:
    """Write ``centerlines.vtu`` (polylines with tangents) and ``tubes.vtu`` (swept surfaces) to ``out``.

    Each yarn gets ``n`` segments; ``yarn`` point data numbers the yarns. Returns the paths.
    """
    import meshio

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fr = frames(cell, n)
    pts, lines, yid, tan, nrm = [], [], [], [], []
    tpts, tquads, tyid = [], [], []
    off = toff = 0
    for i, f in enumerate(fr):
        m = len(f.t)
        pts.append(f.x)
        lines.append(off + np.stack([np.arange(m - 1), np.arange(1, m)], axis=1))
        yid.append(np.full(m, i))
        tan.append(f.tangent)
        nrm.append(f.normal)
        off += m
        p, q = tube_surface(f, cell.radius, sides)
        tpts.append(p)
        tquads.append(q + toff)
        tyid.append(np.full(len(p), i))
        toff += len(p)
    paths = [out / "centerlines.vtu", out / "tubes.vtu"]
    meshio.write(
        paths[0],
        meshio.Mesh(
            np.vstack(pts),
            [("line", np.vstack(lines))],
            point_data={"yarn": np.concatenate(yid), "tangent": np.vstack(tan), "normal": np.vstack(nrm)},
        ),
    )
    meshio.write(
        paths[1],
        meshio.Mesh(
            np.vstack(tpts), [("quad", np.vstack(tquads))], point_data={"yarn": np.concatenate(tyid)}
        ),
    )
    return paths


def plot_views(cell: UnitCell, path: str | Path, *, tiles: int = 2, n: int = 400) -> Path:
    """Three-view PNG (front x-y, top x-z, side y-z) of ``tiles`` x ``tiles`` copies of the cell.

    Yarns are drawn as segments of the knitted diameter's width, painted back to front and
    darker further back, so each view shows which yarn passes over which. Rows have their own
    colours.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    colors = plt.get_cmap("tab10").colors
    segs, depth, col = {v: [] for v in range(3)}, {v: [] for v in range(3)}, []
    views = ((0, 1, 2), (0, 2, 1), (1, 2, 0))  # (horizontal, vertical, depth axis)
    for i, c in enumerate(cell.yarns):
        _, x, _ = c.sample(n)
        for k1 in range(tiles):
            for k2 in range(tiles):
                xs = x + k1 * cell.L1 + k2 * cell.L2
                for v, (hx, vy, dz) in enumerate(views):
                    p = xs[:, [hx, vy]]
                    segs[v].append(np.stack([p[:-1], p[1:]], axis=1))
                    depth[v].append(0.5 * (xs[:-1, dz] + xs[1:, dz]) * (1 if v != 1 else -1))
                col.append(np.repeat([colors[i % 10]], n - 1, axis=0))
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.2))
    labels = ("x (course), mm", "y (wale), mm", "z (thickness), mm")
    names = ("front (x-y)", "top (x-z)", "side (y-z)")
    allc = np.vstack(col)
    for v, ax in enumerate(axes):
        s = np.vstack(segs[v])
        order = np.argsort(np.concatenate(depth[v]), kind="stable")
        ax.set_aspect("equal")
        lo, hi = s.reshape(-1, 2).min(0) - cell.radius, s.reshape(-1, 2).max(0) + cell.radius
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        fig.canvas.draw()
        bbox = ax.get_window_extent()
        pts_per_mm = min(bbox.width / (hi[0] - lo[0]), bbox.height / (hi[1] - lo[1])) * 72.0 / fig.dpi
        dep = np.concatenate(depth[v])[order]
        shade = (0.55 + 0.45 * (dep - dep.min()) / max(float(np.ptp(dep)), 1e-300))[:, None]
        ax.add_collection(
            LineCollection(
                s[order], colors=allc[order] * shade, linewidths=cell.dk * pts_per_mm, capstyle="round"
            )
        )
        ax.set_xlabel(labels[views[v][0]])
        ax.set_ylabel(labels[views[v][1]])
        ax.set_title(names[v])
    fig.suptitle(
        f"{cell.pattern}: {cell.arc_length_per_stitch:.3g} mm/stitch, pitches {cell.course_pitch:.3g} x "
        f"{cell.wale_pitch:.3g} mm, dk {cell.dk:.3g} mm ({tiles}x{tiles} cells)"
    )
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def summary(cell: UnitCell, clr: Clearance | None = None) -> dict[str, Any]:
    """Plain-data description of a cell (and its clearance) for ``geometry.json``."""
    lengths = [c.arc_length() for c in cell.yarns]
    out: dict[str, Any] = {
        "pattern": cell.pattern,
        "layout": [list(r) for r in cell.layout],
        "arc_length_per_stitch": cell.arc_length_per_stitch,
        "yarn_lengths": lengths,
        "course_pitch": cell.course_pitch,
        "wale_pitch": cell.wale_pitch,
        "L1": cell.L1.tolist(),
        "L2": cell.L2.tolist(),
        "dk": cell.dk,
        "end_pairs": [list(p) for p in cell.end_pairs],
        "shape": dict(cell.info),
    }
    if clr is not None:
        out["clearance"] = clr.to_dict()
    return out


def unit_cell(fabric: Fabric, registry=None) -> UnitCell:
    """The unit cell of ``fabric``: its pattern plugin, built with ``fabric.pattern_options``, asked for the cell.

    Both unit-cell solvers call this, so a pattern option set in a config (``[fabric.pattern_options]``)
    reaches every solver. Errors in the options name the TOML path ``fabric.pattern_options.<key>``.
    """
    return pattern_for(fabric, registry).cell(fabric)


#: Yarn per stitch a pattern can realise, in multiples of the knitted diameter dk: a loop wraps at
#: least half a turn round the yarn it holds (π dk); past 200 dk (five times the loosest knits) a
#: stitch is no longer a stitch, and sampling it every dk/10 would take unbounded memory.
ARC_LENGTH_RANGE_DK = (np.pi, 200.0)
#: Smallest course or wale pitch in multiples of dk: closer stitches pass through each other.
MIN_PITCH_DK = 0.5


def checked_cell(fabric: Fabric, registry=None) -> UnitCell:
    """The unit cell of ``fabric``, its dimensions checked before it is built; errors name the ``fabric.*`` key.

    Refused, each with a ConfigError: a machine setting missing from the pattern's
    ``stitch_lengths`` table (``fabric.stitch_length``); yarn per stitch outside
    :data:`ARC_LENGTH_RANGE_DK` times dk (``fabric.arc_length``, or ``fabric.stitch_length`` when
    the table gave it); a pitch under :data:`MIN_PITCH_DK` dk, or longer than the yarn of a stitch
    can span (the course pitch at most the arc length, the wale pitch half of it, since each
    loop climbs one wale and comes back); and every request the pattern itself cannot meet
    (its GeometryError or NumericalError), named at the pitch the user gave, else the arc length.
    The simulate stage calls this while validating the config and ``knitframe geometry`` before
    it writes, so an impossible request leaves nothing behind.
    """
    from knitframe.errors import ConfigError

    pattern = pattern_for(fabric, registry)
    arc_key = "fabric.arc_length" if fabric.arc_length is not None else "fabric.stitch_length"
    table = getattr(pattern, "stitch_lengths", None)
    arc = None if fabric.arc_length is None else float(fabric.arc_length)
    if arc is None and isinstance(table, dict):
        setting = float(fabric.stitch_length)
        arc = next((float(length) for key, length in table.items() if float(key) == setting), None)
        if arc is None:
            keys = ", ".join(sorted(table, key=float))
            raise ConfigError(
                "fabric.stitch_length",
                f"{setting:g} is not in the stitch-length table ({keys}); give fabric.arc_length in mm",
            )
    dk = float(fabric.yarn.dk)
    given = [k for k in ("course_pitch", "wale_pitch") if getattr(fabric, k) is not None]

    def check_arc(length: float) -> None:
        lo, hi = ARC_LENGTH_RANGE_DK
        if not lo * dk <= length <= hi * dk:
            what = (
                f"{length:g} mm per stitch"
                if arc_key == "fabric.arc_length"
                else f"setting {float(fabric.stitch_length):g} gives {length:g} mm per stitch, which"
            )
            raise ConfigError(
                arc_key,
                f"{what} is outside [{lo * dk:.4g}, {hi * dk:.4g}] mm, the yarn per stitch "
                f"a yarn of dk {dk:g} mm can knit (pi to {hi:g} times dk)",
            )

    if arc is not None:
        check_arc(arc)
    for key in given:
        value, span = float(getattr(fabric, key)), (1.0 if key == "course_pitch" else 0.5)
        if value < MIN_PITCH_DK * dk:
            raise ConfigError(
                f"fabric.{key}",
                f"{value:g} mm is under {MIN_PITCH_DK:g} dk = {MIN_PITCH_DK * dk:.4g} mm: "
                "neighbouring stitches would pass through each other",
            )
        if arc is not None and value > span * arc:
            raise ConfigError(
                f"fabric.{key}",
                f"{value:g} mm is more than the {span * arc:.4g} mm that "
                f"{arc:g} mm of yarn per stitch can span",
            )
    try:
        cell = pattern.cell(fabric)
    except (GeometryError, NumericalError) as e:
        raise ConfigError(f"fabric.{given[0]}" if given else arc_key, str(e)) from None
    if arc is None:
        check_arc(float(cell.arc_length_per_stitch))
    return cell


def pattern_for(fabric: Fabric, registry=None) -> Any:
    """The pattern plugin instance of ``fabric`` with its ``pattern_options``; ConfigError on bad names or options."""
    from knitframe.config import instantiate
    from knitframe.errors import ConfigError, UnknownPluginError
    from knitframe.plugins import get_registry

    registry = registry or get_registry()
    try:
        registry["pattern"].entry(fabric.pattern)
    except UnknownPluginError as e:
        raise ConfigError("fabric.pattern", str(e)) from None
    return instantiate(
        registry, "pattern", {"kind": fabric.pattern, **fabric.pattern_options}, "fabric.pattern_options"
    )
