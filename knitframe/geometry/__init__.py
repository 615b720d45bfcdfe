"""Unit-cell yarn geometry shared by the pattern plugins and the unit-cell solvers.

A pattern plugin's ``cell(fabric)`` returns a :class:`UnitCell`: the yarn centerlines of a 2x2
stitch cell as smooth parametric curves :class:`Centerline` with exact tangents, the lattice
vectors, the pairing of yarn ends across the course boundary and the knit/purl layout. Axes: x is
the course, y the wale, z out of the fabric plane; lengths in mm.

The package holds one concern per module; every public name is importable from here:

- :mod:`knitframe.geometry.cell`: the records :class:`Centerline` and :class:`UnitCell`, arc
  length, strands and periodic image shifts, and the lookup of a Fabric's cell through its
  pattern plugin (:func:`unit_cell`, :func:`checked_cell` with its limits
  :data:`ARC_LENGTH_RANGE_DK` and :data:`MIN_PITCH_DK`);
- :mod:`knitframe.geometry.knit`: the helpers pattern plugins build a cell with: the machine
  stitch-length table (:data:`STITCH_LENGTHS`, :func:`arc_length_for`,
  :func:`check_stitch_lengths`), Munden's pitches (:func:`munden_pitches`), a smooth sign for
  blending stitch shapes (:func:`smooth_sign`), the arc-length calibration
  (:func:`solve_arc_length`), the cell of one yarn per course row (:func:`course_cell`) and the
  crossings of two yarns in the x-y projection (:func:`crossings`);
- :mod:`knitframe.geometry.framing`: rotation-minimising frames closed over each strand
  (:func:`frames`, :class:`Frames`);
- :mod:`knitframe.geometry.bending`: the length scale on which the yarns bend, the Rayleigh
  wavenumber of their curvature (:func:`bending_wavenumber`);
- :mod:`knitframe.geometry.proximity`: the minimum centerline-to-centerline clearance with
  periodic images and self-contact (:func:`clearance`, :class:`Clearance`, :class:`Contact`);
- :mod:`knitframe.geometry.views`: writers for VTU (:func:`write_vtu`, :func:`tube_surface`) and a
  three-view PNG (:func:`plot_views`), and the plain data of ``geometry.json`` (:func:`summary`).

The modules of frames and clearance are named ``framing`` and ``proximity`` so that their names
differ from the functions :func:`frames` and :func:`clearance` exported here.
"""

from knitframe.geometry.bending import bending_wavenumber
from knitframe.geometry.cell import (
    ARC_LENGTH_RANGE_DK,
    MIN_PITCH_DK,
    Centerline,
    UnitCell,
    arc_length,
    checked_cell,
    image_shifts,
    strands,
    unit_cell,
)
from knitframe.geometry.framing import Frames, frames
from knitframe.geometry.knit import (
    MUNDEN_KC,
    MUNDEN_KW,
    STITCH_LENGTHS,
    arc_length_for,
    check_stitch_lengths,
    course_cell,
    crossings,
    munden_pitches,
    smooth_sign,
    solve_arc_length,
)
from knitframe.geometry.proximity import Clearance, Contact, clearance
from knitframe.geometry.views import plot_views, summary, tube_surface, write_vtu

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
    "bending_wavenumber",
    "crossings",
    "tube_surface",
    "write_vtu",
    "plot_views",
    "summary",
    "ARC_LENGTH_RANGE_DK",
    "MIN_PITCH_DK",
    "checked_cell",
    "unit_cell",
]
