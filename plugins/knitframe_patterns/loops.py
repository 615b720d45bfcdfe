"""Knit and purl loops on Crane's plain-knit curve, shared by the weft-knit pattern plugins.

Crane (2023, "A Simple Parametric Model of Plain-Knit Yarns") draws a row of jersey loops as

    γ(t) = (t + a sin 2t,  h cos t,  d cos 2t),   one loop per 2π of t.

Here it is made dimensional and generalised to purl loops. For row r of the cell (yarn ``rowr``)

    x(t) = p_c/(2π) · (t + a sin 2t)
    y(t) = r·p_w + H cos t
    z(t) = g(t) · (F - D cos 2t)

with course pitch p_c, wale pitch p_w, roundness a, loop-height amplitude H, depth D = depth·dk and
fold F = fold·dk (0 unless asked: knit stitches sit F in front, purl stitches F behind, as in a
relaxed, folded rib).
The head of column j sits at t = 2πj, its legs near t = 2πj ± π/2 and the sinker loops near
t = 2πj ± π. ``g`` carries the knit/purl signs σ = +1 (knit) / -1 (purl):

    g(t) = σ_up(t) w(t) + σ_own(t) (1 - w(t)),   w(t) = (1 + S(cos t)) / 2,
    σ(t) = (σ_0 + σ_1)/2 + (σ_0 - σ_1)/2 · S(cos(t/2)),   S(c) = tanh(κc) / tanh κ.

σ_own are the row's own stitches (they set the legs and sinkers, which pass through the heads of
the row below), σ_up the stitches of the row above (they set the heads, through which that row
passes). For jersey g = 1 and z = -D cos 2t is Crane's curve mirrored so that the technical face
(the side showing the legs' Vs) is +z. A purl loop is a knit loop mirrored z -> -z; where knit and
purl meet, S blends the two smoothly (sharpness κ), so every curve is analytic with an exact
tangent.

The pitches default to Munden's relations for relaxed plain knit, p_c = ℓ/Kw and p_w = ℓ/Kc
(ℓ the yarn length per stitch). Given ℓ, H is solved with :func:`scipy.optimize.brentq` so that
the arc length per stitch equals ℓ: the arc length grows strictly with H, and H must exceed
p_w/2 for the loops of successive rows to interlock.
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from knitframe import validators as v
from knitframe.errors import GeometryError
from knitframe.geometry import (
    MUNDEN_KC,
    MUNDEN_KW,
    STITCH_LENGTHS,
    Centerline,
    UnitCell,
    arc_length_for,
    check_stitch_lengths,
    course_cell,
    crossings,
    munden_pitches,
    smooth_sign,
    solve_arc_length,
)
from knitframe.records import Fabric

__all__ = ["LoopRow", "KnitLoopPattern"]

# The stitch-length table, Munden's pitches, the smooth sign, the arc-length solve and the cell
# assembly live in knitframe.geometry so that third-party patterns can use them.

SIGN = {"k": 1.0, "p": -1.0}


@attrs.frozen
class LoopRow:
    """One row of loops (two stitches per 4π of t); evaluates r(t) and dr/dt exactly."""

    #: p_c, mm
    course_pitch: float
    #: row offset r·p_w, mm
    y0: float
    #: H, mm
    height: float
    #: a, -
    roundness: float
    #: D, mm
    depth: float
    #: σ of this row's two stitches
    own: tuple[float, float]
    #: σ of the two stitches of the row above
    up: tuple[float, float]
    #: κ, -
    sharpness: float
    #: F, mm: knit stitches sit F in front (+z), purl stitches F behind
    fold: float = 0.0

    def _g(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s1, ds1 = smooth_sign(np.cos(t), self.sharpness)
        w, dw = 0.5 * (1.0 + s1), -0.5 * ds1 * np.sin(t)
        s2, ds2 = smooth_sign(np.cos(0.5 * t), self.sharpness)
        half = -0.5 * ds2 * np.sin(0.5 * t)

        def blend(sig):
            mean, diff = 0.5 * (sig[0] + sig[1]), 0.5 * (sig[0] - sig[1])
            return mean + diff * s2, diff * half

        up, dup = blend(self.up)
        own, down = blend(self.own)
        return up * w + own * (1.0 - w), dup * w + (up - own) * dw + down * (1.0 - w)

    def position(self, t: np.ndarray) -> np.ndarray:
        """r(t), (n,) -> (n, 3) mm."""
        t = np.asarray(t, dtype=np.float64)
        g, _ = self._g(t)
        sx = self.course_pitch / (2.0 * np.pi)
        return np.stack(
            [
                sx * (t + self.roundness * np.sin(2.0 * t)),
                self.y0 + self.height * np.cos(t),
                g * (self.fold - self.depth * np.cos(2.0 * t)),
            ],
            axis=-1,
        )

    def derivative(self, t: np.ndarray) -> np.ndarray:
        """dr/dt, (n,) -> (n, 3) mm."""
        t = np.asarray(t, dtype=np.float64)
        g, dg = self._g(t)
        sx = self.course_pitch / (2.0 * np.pi)
        return np.stack(
            [
                sx * (1.0 + 2.0 * self.roundness * np.cos(2.0 * t)),
                -self.height * np.sin(t),
                dg * (self.fold - self.depth * np.cos(2.0 * t)) + 2.0 * self.depth * np.sin(2.0 * t) * g,
            ],
            axis=-1,
        )

    def centerline(self, name: str) -> Centerline:
        """The row as a Centerline over its two stitches, t in [-π, 3π] (sinker to sinker)."""
        return Centerline(
            name, self.position, self.derivative, -np.pi, 3.0 * np.pi, (2.0 * self.course_pitch, 0.0, 0.0)
        )


#: Munden's constants of real knits lie near 4 to 9; outside [1, 20] the pitches are no knit's
_MUNDEN = attrs.validators.and_(v.positive, v.in_range(1.0, 20.0))
#: loops flatter than a tenth of dk pass through the yarns they hold, deeper than 10 dk they are no loops
_DEPTH = attrs.validators.and_(v.positive, v.in_range(0.1, 10.0))


@attrs.frozen
class KnitLoopPattern:
    """Base of the weft-knit patterns: a 2x2 cell of knit/purl loops given by ``layout``.

    Subclasses set ``name``, ``description`` and ``layout`` (rows x columns of "k"/"p"). The
    fields are the pattern options of a config's ``[pattern]`` table.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    layout: ClassVar[tuple[tuple[str, str], tuple[str, str]]] = (("k", "k"), ("k", "k"))

    #: machine setting -> yarn length per stitch, mm
    stitch_lengths: dict[str, float] = attrs.field(
        factory=lambda: dict(STITCH_LENGTHS), validator=check_stitch_lengths
    )
    #: Munden course constant (courses/cm = Kc/ℓ[cm]), -
    Kc: float = attrs.field(default=MUNDEN_KC, validator=_MUNDEN)
    #: Munden wale constant (wales/cm = Kw/ℓ[cm]), -
    Kw: float = attrs.field(default=MUNDEN_KW, validator=_MUNDEN)
    #: Crane's a, -
    roundness: float = attrs.field(default=1.5, validator=v.in_range(0.0, 10.0))
    #: out-of-plane amplitude D / dk (Crane: 1/1.6), -
    depth: float = attrs.field(default=0.625, validator=_DEPTH)
    #: knit/purl blend κ, -
    sharpness: float = attrs.field(default=3.0, validator=v.in_range(0.0, 50.0, lo_open=True))
    #: knit stitches F = fold·dk in front, purl stitches F behind (a folded rib or garter), -
    fold: float = attrs.field(default=0.0, validator=v.in_range(0.0, 5.0))

    def pitches(self, arc: float, fabric: Fabric) -> tuple[float, float]:
        """(course, wale) pitch in mm: the fabric's if given, else Munden's ℓ/Kw and ℓ/Kc."""
        return munden_pitches(arc, fabric, self.Kc, self.Kw)

    def rows(self, height: float, pc: float, pw: float, dk: float) -> list[LoopRow]:
        """The two LoopRows for loop-height amplitude ``height`` (mm)."""
        sig = [[SIGN[s] for s in row] for row in self.layout]
        return [
            LoopRow(
                pc,
                r * pw,
                height,
                self.roundness,
                self.depth * dk,
                tuple(sig[r]),
                tuple(sig[(r + 1) % 2]),
                self.sharpness,
                self.fold * dk,
            )
            for r in range(2)
        ]

    def _per_stitch(self, height: float, pc: float, pw: float, dk: float) -> float:
        return sum(row.centerline("").arc_length() for row in self.rows(height, pc, pw, dk)) / 4.0

    def cell(self, fabric: Fabric) -> UnitCell:
        """The 2x2 unit cell whose arc length per stitch matches the fabric's to 1e-9 relative."""
        if set(s for row in self.layout for s in row) - set(SIGN) or np.shape(self.layout) != (2, 2):
            raise GeometryError(f"pattern '{self.name}': layout must be 2x2 of 'k'/'p', got {self.layout}")
        arc = arc_length_for(fabric, self.stitch_lengths)
        pc, pw = self.pitches(arc, fabric)
        dk = float(fabric.yarn.dk)
        # below H = p_w/2 the heads of one row do not reach the legs of the next
        height = solve_arc_length(
            lambda h: self._per_stitch(h, pc, pw, dk),
            arc,
            0.5 * pw,
            max(pw, arc),
            context=f"course pitch {pc:.4g} mm, wale pitch {pw:.4g} mm and dk {dk:g} mm",
        )
        rows = self.rows(height, pc, pw, dk)
        yarns = tuple(row.centerline(f"row{r}") for r, row in enumerate(rows))
        cell = course_cell(
            self.name,
            yarns,
            pc,
            pw,
            dk,
            self.layout,
            arc,
            info={
                "curve": "crane2023",
                "loop_height": height,
                "roundness": self.roundness,
                "depth": self.depth * dk,
                "sharpness": self.sharpness,
                "fold": self.fold * dk,
                "Kc": self.Kc,
                "Kw": self.Kw,
            },
        )
        _check_interlock(cell, arc)
        return cell


def _check_interlock(cell: UnitCell, arc: float) -> None:
    """Every half-loop must cross the row below (leg over head, sinker over leg) in the x-y projection."""
    for r in range(len(cell.yarns)):
        cr = crossings(cell, r, (r - 1) % len(cell.yarns), -cell.L2 if r == 0 else np.zeros(3), n=400)
        c = cell.yarns[r]
        edges = np.arange(c.t0, c.t1 + 1e-9, np.pi)
        counts = np.histogram([x[0] for x in cr], bins=edges)[0]
        if np.any(counts < 2):
            raise GeometryError(
                f"{cell.pattern}: with arc length {arc:g} mm per stitch the loops do not reach through "
                f"the row below at wale pitch {cell.wale_pitch:.4g} mm; give a smaller wale_pitch "
                "(or larger Kc) or a longer stitch"
            )
