"""Helpers that turn a Fabric into the dimensions of a knitted cell, shared by the pattern plugins.

Pattern plugins, built-in or third-party, share the helpers that turn a Fabric into cell
dimensions: the machine stitch-length table (:data:`STITCH_LENGTHS`, :func:`arc_length_for`,
:func:`check_stitch_lengths`), Munden's pitches (:func:`munden_pitches`), a smooth sign for
blending stitch shapes (:func:`smooth_sign`), the arc-length calibration
(:func:`solve_arc_length`), the cell of one yarn per course row (:func:`course_cell`) and the
crossings of two yarns in the x-y projection (:func:`crossings`), with which a pattern checks
that its loops interlock.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from knitframe.errors import FieldError, GeometryError, NumericalError
from knitframe.geometry.cell import Centerline, UnitCell, table_arc_length

if TYPE_CHECKING:
    from knitframe.records import Fabric

__all__ = [
    "STITCH_LENGTHS",
    "MUNDEN_KC",
    "MUNDEN_KW",
    "check_stitch_lengths",
    "arc_length_for",
    "munden_pitches",
    "smooth_sign",
    "solve_arc_length",
    "course_cell",
    "crossings",
]


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
    """Yarn length per stitch, mm: ``fabric.arc_length`` if given, else the machine setting looked
    up in ``table`` (:func:`~knitframe.geometry.cell.table_arc_length`)."""
    if fabric.arc_length is not None:
        return float(fabric.arc_length)
    length = table_arc_length(table, fabric.stitch_length)
    if length is not None:
        return length
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
    """The shape parameter h >= ``lower`` at which ``per_stitch(h)`` (mm of yarn per stitch) equals
    ``target``.

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
        for i, j in zip(*np.nonzero(hit), strict=True):
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
