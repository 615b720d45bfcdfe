"""Pattern ``tuck``: 1x1 cross tuck, a single-jersey fabric whose needles knit and tuck in turn.

Course 0 knits on needle 0 and tucks on needle 1, course 1 the other way round. That is a
repeat of two courses by two needles, so it fills knitframe's 2x2 cell with one yarn per course.

A tuck stitch takes the yarn into the needle hook without knocking the old loop over. So:

- a **tuck loop** is not drawn through the loop below it; it lies behind that loop (+z is the
  technical face, so behind means lower z);
- the old loop stays on the needle for one more course: every **knit loop is held**, one wale
  pitch taller than a jersey loop;
- the next knit loop on that needle is drawn, from back to front, through **both** the held loop
  and the tuck loop.

Row r of the cell (yarn ``rowr``), t in [-π, 3π], head of column j at t = 2πj:

    x(t) = p_c/(2π) · (t + a(t) sin 2t + b(t) sin t)
    y(t) = r p_w - H + (H + h(t)) (1 + cos t)/2
    z(t) = c0(t) + c1(t) cos t + c2(t) cos 2t

Each shape value q = (a, b, h, c0, c1, c2) switches smoothly between its knit and tuck value,

    q(t) = q_tuck + (q_knit - q_tuck) k(t),    k(t) = (1 + σ_r S(cos(t/2))) / 2,

with S the smooth sign of :func:`knitframe.geometry.smooth_sign`, σ_0 = +1 (row 0 knits in
column 0) and σ_1 = -1. Knit: a = ``roundness`` (Crane's loop), b = 0, h = H + p_w (the held
loop reaches one course higher) and z = -D at the sinkers, +D on the legs, 0 at the head.
Tuck: a = ``tuck_roundness``, b = ``tuck_spread`` (a wider, open loop), h = H - drop·(2H - p_w)
(the head rests just inside the held loop's head) and z = -D at the sinkers, 0 on the legs,
-``tuck_depth``·D at the head (behind the held loop). D = ``depth``·dk. H is solved so that the
yarn length per stitch matches the fabric's.
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

import knitframe
from knitframe import validators as v
from knitframe.errors import GeometryError
from knitframe.geometry import (
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


def z_profile(sinker: float, leg: float, head: float) -> np.ndarray:
    """(c0, c1, c2) of z = c0 + c1 cos u + c2 cos 2u through z at the sinker, legs and head (u = π, ±π/2, 0), mm."""
    mid = 0.5 * (head + sinker)
    return np.array([0.5 * (mid + leg), 0.5 * (head - sinker), 0.5 * (mid - leg)])


@attrs.frozen
class TuckRow:
    """One course of the cell: a knit and a tuck stitch per 4π of t; evaluates r(t) and dr/dt exactly."""

    course_pitch: float  #: p_c, mm
    y0: float  #: row offset r·p_w, mm
    height: float  #: H, mm
    sigma: float  #: +1 if column 0 knits, -1 if column 0 tucks
    knit: tuple[float, ...]  #: knit values of (a, b, h, c0, c1, c2)
    tuck: tuple[float, ...]  #: tuck values of (a, b, h, c0, c1, c2)
    sharpness: float  #: κ of the smooth switch, -

    def _shape(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """q(t) and dq/dt, both (n, 6)."""
        s, ds = smooth_sign(np.cos(0.5 * t), self.sharpness)
        k = 0.5 * (1.0 + self.sigma * s)
        dk = -0.25 * self.sigma * ds * np.sin(0.5 * t)
        jump = np.subtract(self.knit, self.tuck)
        return np.add(self.tuck, k[:, None] * jump), dk[:, None] * jump

    def position(self, t: np.ndarray) -> np.ndarray:
        """r(t), (n,) -> (n, 3) mm."""
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        a, b, h, c0, c1, c2 = self._shape(t)[0].T
        x = self.course_pitch / (2.0 * np.pi) * (t + a * np.sin(2.0 * t) + b * np.sin(t))
        y = self.y0 - self.height + (self.height + h) * 0.5 * (1.0 + np.cos(t))
        z = c0 + c1 * np.cos(t) + c2 * np.cos(2.0 * t)
        return np.stack([x, y, z], axis=-1)

    def derivative(self, t: np.ndarray) -> np.ndarray:
        """dr/dt, (n,) -> (n, 3) mm."""
        t = np.asarray(t, dtype=np.float64).reshape(-1)
        q, dq = self._shape(t)
        a, b, h, c0, c1, c2 = q.T
        da, db, dh, dc0, dc1, dc2 = dq.T
        s1, c1t, s2, c2t = np.sin(t), np.cos(t), np.sin(2.0 * t), np.cos(2.0 * t)
        dx = self.course_pitch / (2.0 * np.pi) * (1.0 + da * s2 + 2.0 * a * c2t + db * s1 + b * c1t)
        dy = 0.5 * dh * (1.0 + c1t) - 0.5 * (self.height + h) * s1
        dz = dc0 + dc1 * c1t - c1 * s1 + dc2 * c2t - 2.0 * c2 * s2
        return np.stack([dx, dy, dz], axis=-1)

    def centerline(self, name: str) -> Centerline:
        """The course as a Centerline over its two stitches, t in [-π, 3π] (sinker to sinker)."""
        period = (2.0 * self.course_pitch, 0.0, 0.0)
        return Centerline(name, self.position, self.derivative, -np.pi, 3.0 * np.pi, period)


#: Crossing signs (z_upper - z_lower > 0: "+") of a course's stitches with the courses below, in
#: the x-y projection and in order along the upper yarn. A knit loop enters the loops below from
#: behind their legs and leaves in front of their heads; a tuck loop only lies behind the held loop.
LINKS = {
    ("knit", "course below"): "-++-",
    ("knit", "two courses below"): "-++-",
    ("tuck", "course below"): "--",
    ("tuck", "two courses below"): "",
}


def links(cell: UnitCell) -> dict[tuple[int, str, str], str]:
    """Crossing signs of every stitch with the course below and the course two below.

    Returns ``{(row, stitch, lower): signs}``. ``stitch`` is "knit" or "tuck". ``lower`` is
    "course below" (under a knit stitch the tuck loop on its needle, under a tuck stitch the held
    loop) or "two courses below" (under a knit stitch the loop held on its needle). ``signs``
    holds "+" (upper yarn in front) or "-" per crossing, in order along the upper yarn.
    """
    out = {}
    for r in range(2):
        below = ((r - 1) % 2, -cell.L2 if r == 0 else np.zeros(3))
        for lower, (row, shift) in (("course below", below), ("two courses below", (r, -cell.L2))):
            found = crossings(cell, r, row, shift)
            for col in range(2):
                signs = ["+" if dz > 0 else "-" for t, _, dz in found if round(t / (2.0 * np.pi)) % 2 == col]
                out[(r, cell.info["stitches"][r][col], lower)] = "".join(signs)
    return out


@attrs.frozen
class Tuck:
    """1x1 cross tuck unit cell: course 0 knits needle 0 and tucks needle 1, course 1 the reverse.

    The fields are the pattern's options. The defaults are modelling choices, not measurements:
    with them the smallest centerline clearance of cotton at SL10-12 is about half a diameter.
    """

    name: ClassVar[str] = "tuck"
    description: ClassVar[str] = "1x1 cross tuck: knit and tuck alternate by needle and course (example plugin)"

    stitch_lengths: dict[str, float] = attrs.field(
        factory=lambda: dict(STITCH_LENGTHS), validator=check_stitch_lengths
    )  #: machine setting -> yarn length per stitch, mm
    Kc: float = attrs.field(default=8.5, validator=v.positive)  #: courses/cm = Kc/ℓ[cm] (jersey: 5.3), -
    Kw: float = attrs.field(default=3.6, validator=v.positive)  #: wales/cm = Kw/ℓ[cm] (jersey: 4.0), -
    roundness: float = attrs.field(default=1.8, validator=v.in_range(0.0, 10.0))  #: Crane's a of the knit loops, -
    tuck_roundness: float = attrs.field(default=0.35, validator=v.in_range(0.0, 10.0))  #: a of the tuck loops, -
    tuck_spread: float = attrs.field(default=0.7, validator=v.in_range(0.0, 1.0))  #: b: how wide the tuck loops open, -
    depth: float = attrs.field(default=0.7, validator=v.positive)  #: out-of-plane amplitude D / dk, -
    tuck_depth: float = attrs.field(default=0.65, validator=v.positive)  #: tuck head behind the mid-plane / D, -
    tuck_drop: float = attrs.field(
        default=0.15, validator=v.in_range(0.0, 1.0, hi_open=True)
    )  #: tuck head below the held loop's head / (2H - p_w), -
    sharpness: float = attrs.field(
        default=3.0, validator=v.in_range(0.0, 50.0, lo_open=True)
    )  #: κ of the smooth knit/tuck switch, -

    def rows(self, height: float, pc: float, pw: float, dk: float) -> list[TuckRow]:
        """The two courses for loop height H = ``height``, pitches ``pc``, ``pw`` and diameter ``dk``, mm."""
        D = self.depth * dk
        knit = (self.roundness, 0.0, height + pw, *z_profile(-D, D, 0.0))
        tuck_head = height - self.tuck_drop * (2.0 * height - pw)
        tuck = (self.tuck_roundness, self.tuck_spread, tuck_head, *z_profile(-D, 0.0, -self.tuck_depth * D))
        return [TuckRow(pc, r * pw, height, 1.0 - 2.0 * r, knit, tuck, self.sharpness) for r in range(2)]

    def cell(self, fabric: knitframe.Fabric) -> UnitCell:
        """The 2x2 unit cell whose arc length per stitch matches the fabric's to 1e-9 relative."""
        arc = arc_length_for(fabric, self.stitch_lengths)
        pc, pw = munden_pitches(arc, fabric, self.Kc, self.Kw)
        dk = float(fabric.yarn.dk)

        def per_stitch(height: float) -> float:
            return sum(row.centerline("").arc_length() for row in self.rows(height, pc, pw, dk)) / 4.0

        # below H = p_w/2 a knit loop's base cannot reach the loops it must pass through
        context = f"course pitch {pc:.4g} mm, wale pitch {pw:.4g} mm and dk {dk:g} mm"
        height = solve_arc_length(per_stitch, arc, 0.5 * pw, max(pw, arc), context=context)
        yarns = tuple(row.centerline(f"row{r}") for r, row in enumerate(self.rows(height, pc, pw, dk)))
        # every needle works on the face side ("k"); which stitches tuck goes in info["stitches"]
        layout = (("k", "k"), ("k", "k"))
        info = {"stitches": [["knit", "tuck"], ["tuck", "knit"]], "loop_height": height}
        cell = course_cell(self.name, yarns, pc, pw, dk, layout, arc, info)
        for (row, stitch, lower), signs in links(cell).items():
            if signs != LINKS[(stitch, lower)]:
                raise GeometryError(
                    f"tuck: at {arc:g} mm per stitch and pitches {pc:.4g} x {pw:.4g} mm the {stitch} stitch of "
                    f"course {row} crosses the {lower} as '{signs}', not '{LINKS[(stitch, lower)]}'; "
                    "change the pitches or the stitch length"
                )
        return cell


@knitframe.hookimpl
def register_patterns(register):
    register(Tuck)
