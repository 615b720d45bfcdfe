"""The unit-cell records, their periodicity, and the lookup that asks a pattern plugin for a cell.

A pattern plugin's ``cell(fabric)`` returns a :class:`UnitCell`: the yarn centerlines of a 2x2
stitch cell as smooth parametric curves :class:`Centerline` with exact tangents, the lattice
vectors, the pairing of yarn ends across the course boundary and the knit/purl layout.

Axes: x is the course, y the wale, z out of the fabric plane; lengths in mm.

Periodicity. Along the course a yarn is cut at the cell boundary: the end of yarn ``i`` at ``t1``
continues as the start of yarn ``j`` shifted by ``L1`` for every ``(i, j)`` in ``end_pairs``.
Following the pairs from a yarn back to itself gives a *strand*: one infinite yarn of the fabric.
Along the wale the rows hold together only through contact with periodic images (``±L2``,
``±L1 ± L2``); :func:`image_shifts` lists them.

The lookup: :func:`pattern_for` builds the pattern plugin of a Fabric from the registry with its
``pattern_options``, :func:`unit_cell` asks it for the cell, and :func:`checked_cell` first checks
the requested dimensions against :data:`ARC_LENGTH_RANGE_DK` and :data:`MIN_PITCH_DK`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from knitframe.errors import GeometryError, NumericalError
from knitframe.interfaces import Pattern, declared

if TYPE_CHECKING:
    from knitframe.records import Fabric

__all__ = [
    "Centerline",
    "UnitCell",
    "arc_length",
    "strands",
    "image_shifts",
    "unit_cell",
    "pattern_for",
    "checked_cell",
    "table_arc_length",
    "ARC_LENGTH_RANGE_DK",
    "MIN_PITCH_DK",
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
        """``n + 1`` parameters from t0 to t1 and the arc length s(t) from t0 at each, mm.

        The arc length is integrated by 4-point Gauss quadrature per interval.
        """
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


def unit_cell(fabric: Fabric, registry=None) -> UnitCell:
    """The unit cell of ``fabric``: its pattern plugin, built with ``fabric.pattern_options``, asked
    for the cell.

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


def table_arc_length(table: dict[str, float], setting: float) -> float | None:
    """Yarn per stitch, mm, that a ``stitch_lengths`` table gives for the machine ``setting``
    (keys compared as numbers, "11" == 11.0), or None when the setting is not in the table."""
    return next((float(length) for key, length in table.items() if float(key) == float(setting)), None)


def checked_cell(fabric: Fabric, registry=None) -> UnitCell:
    """The unit cell of ``fabric``, its dimensions checked before it is built; errors name the
    ``fabric.*`` key.

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
    table = declared(pattern, Pattern, "stitch_lengths")
    arc = None if fabric.arc_length is None else float(fabric.arc_length)
    if arc is None and isinstance(table, dict):
        setting = float(fabric.stitch_length)
        arc = table_arc_length(table, setting)
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
    """The pattern plugin instance of ``fabric`` with its ``pattern_options``.

    ConfigError on bad names or options.
    """
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
