r"""The knitted tube on the limb: element geometry, stretches, tensions and pressures.

The limb surface is a structured quad grid: element (i, j) lies between stations i and i+1 and
between points j and j+1 of their section loops (R = stations − 1 rows along the limb, A columns
around it). The tube is given the same grid, so elements map one to one (the paper's method).

Stretches (course = around the limb, wale = along it), for element (i, j) in fabric f:

- **paper** mode: the tube is a cylinder of circumference :math:`C_t` (the wrist's by default) and
  length :math:`L_t`; :math:`\lambda_1 = e^{(1)}_{ij} / (C_t/A)`,
  :math:`\lambda_2 = e^{(2)}_{ij} / (L_t/R)`, the same for every fabric;
- **knitting** mode: the tube has N needles (stitches per course); an element spans N/A stitches of
  relaxed width :math:`c_f` (the fabric's course pitch), so :math:`\lambda_1 = e^{(1)}_{ij}/((N/A)\,c_f)`.
  Row i is knitted with :math:`n_{if} = \max(1, \mathrm{round}(\bar e^{(2)}_i / (\lambda_2^* w_f)))`
  courses of height :math:`w_f` (the wale pitch) for a target axial stretch :math:`\lambda_2^*`,
  so :math:`\lambda_2 = e^{(2)}_{ij}/(n_{if} w_f)`. A looser stitch knits a wider tube on the same
  needles: the stretch depends on the fabric, and the optimiser sees it that way.

Here :math:`e^{(1)} = C/A` (the section loops are sampled at equal arc length) and :math:`e^{(2)}` is the
element's mean edge length along the limb.
The tensions are the fabric's reduced model at (λ1, λ2), never negative (a slack fabric carries no
compression). The pressure follows Laplace's law :math:`p = T_1/r`, reported two ways: with the
section's equivalent radius :math:`C/2\pi`, and with the local radius of curvature (higher over a
bony ridge; zero where the section is concave, since the fabric bridges it).
"""

from __future__ import annotations

from typing import Literal

import attrs
import numpy as np

from knitframe.garment.laplace import MMHG_PER_MPA

__all__ = ["ElementGeometry", "Tube", "element_geometry", "MMHG_PER_MPA"]


@attrs.frozen(eq=False)
class ElementGeometry:
    """Per-element geometry of the limb's quad grid (R rows along the limb, A columns around)."""

    #: (R, A) element length around the limb (C/A of its stations), mm
    e1: np.ndarray
    #: (R, A) mean edge length along the limb, mm
    e2: np.ndarray
    #: (R, A) element area, mm²
    area: np.ndarray
    #: (R, A) mean curvature of the section (1/mm; > 0 convex)
    curvature: np.ndarray
    #: (R,) circumference / 2π of the row (mean of its two stations), mm
    equivalent_radius: np.ndarray
    #: (R,) row centre along the limb as a fraction, 0 distal to 1 top
    position: np.ndarray
    #: (R,) row centre along the axis, mm
    z: np.ndarray
    #: (R,) mean of the two stations' circumferences, mm
    circumference: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        return self.e1.shape

    @property
    def row_length(self) -> np.ndarray:
        """(R,) mean element length along the limb of each row, mm."""
        return self.e2.mean(axis=1)


def element_geometry(limb) -> ElementGeometry:
    """The quad grid of a :class:`~knitframe.garment.limb.Limb`'s section loops, vectorised."""
    P = np.asarray(limb.sections, dtype=np.float64)  # (S, A, 3)
    Q = np.roll(P, -1, axis=1)  # point j+1 of each loop
    circ = np.asarray(limb.circumference, dtype=np.float64)
    A = P.shape[1]
    # the loop points are equally spaced by arc length, so each element spans C/A of the section
    # (the chord would be shorter by a factor sinc(π/A))
    around = np.broadcast_to(circ[:, None] / A, P.shape[:2])
    along = np.linalg.norm(P[1:] - P[:-1], axis=2)  # (R, A)
    e1 = 0.5 * (around[:-1] + around[1:])
    e2 = 0.5 * (along + np.roll(along, -1, axis=1))
    # two triangles per quad: (i,j), (i,j+1), (i+1,j+1) and (i,j), (i+1,j+1), (i+1,j)
    a, b, c, d = P[:-1], Q[:-1], Q[1:], P[1:]
    area = 0.5 * (
        np.linalg.norm(np.cross(b - a, c - a), axis=2) + np.linalg.norm(np.cross(c - a, d - a), axis=2)
    )
    kappa = 1.0 / np.asarray(limb.curvature_radius, dtype=np.float64)  # (S, A); 1/inf = 0 where straight
    k_pts = 0.5 * (kappa + np.roll(kappa, -1, axis=1))
    curvature = 0.5 * (k_pts[:-1] + k_pts[1:])
    pos = np.asarray(limb.positions, dtype=np.float64)
    z = 0.5 * (pos[:-1] + pos[1:])
    length = pos[-1] - pos[0]
    return ElementGeometry(
        e1,
        e2,
        area,
        curvature,
        0.25 * (circ[:-1] + circ[1:]) / np.pi,
        (z - pos[0]) / length,
        z,
        0.5 * (circ[:-1] + circ[1:]),
    )


@attrs.frozen
class Tube:
    """How the tube is made: the paper's wrist cylinder, or a knitting machine's needles and courses.

    Attributes
    ----------
    mode : "paper" or "knitting"
    circumference : float, optional
        Paper mode: the tube's circumference, mm (default: the limb's at its distal station).
    length : float, optional
        Paper mode: the tube's length, mm (default: the limb's length).
    needles : int, optional
        Knitting mode: stitches of every course of an unshaped tube (default: chosen with the
        assignment, course band by course band on a shaped tube).
    axial_stretch : float
        Knitting mode: the target wale stretch λ2* the courses per row are chosen for.
    shaping : bool
        Knitting mode: let the needle count change along the tube by increases and decreases
        (:mod:`knitframe.garment.shaping`); False keeps one count from end to end.
    """

    mode: Literal["paper", "knitting"] = "knitting"
    circumference: float | None = None
    length: float | None = None
    needles: int | None = None
    axial_stretch: float = 1.0
    shaping: bool = True

    def stretches(
        self,
        geo: ElementGeometry,
        course_pitch: np.ndarray,
        wale_pitch: np.ndarray,
        limb_distal_circumference: float,
        needles: int | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """λ1, λ2 of shape (F, R, A) and the courses per row (R, F) for fabrics of the given pitches."""
        c = np.asarray(course_pitch, dtype=np.float64)
        w = np.asarray(wale_pitch, dtype=np.float64)
        R, A = geo.shape
        if self.mode == "paper":
            Ct = self.circumference or limb_distal_circumference
            Lt = self.length or float(geo.row_length.sum())
            lam1 = np.broadcast_to(geo.e1 / (Ct / A), (len(c), R, A))
            lam2 = np.broadcast_to(geo.e2 / (Lt / R), (len(c), R, A))
            courses = np.broadcast_to((Lt / R) / w[None, :], (R, len(c)))
            return lam1, lam2, np.array(courses)
        n = needles if needles is not None else self.needles
        if n is None:
            raise ValueError("knitting mode needs a number of needles")
        lam1 = geo.e1[None] / ((n / A) * c[:, None, None])
        courses = np.maximum(1.0, np.round(geo.row_length[:, None] / (self.axial_stretch * w[None, :])))
        lam2 = geo.e2[None] / (courses.T[:, :, None] * w[:, None, None])
        return lam1, lam2, courses
