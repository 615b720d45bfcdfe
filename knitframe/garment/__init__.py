"""Garment design (level 5): from a limb and a fabric library to a pressure-graded, knittable sleeve.

- :mod:`~knitframe.garment.limb`: the limb, from a scan, from measurements, or the example arm
  (a package: loop geometry, the record, measured limbs, and a scan's reading, shells, slicing and
  checks);
- :mod:`~knitframe.garment.library`: candidate fabrics with fitted models, relaxed pitches and limits
  (a package: field checks, the entry, the library record, entries from fits, the built-in library);
- :mod:`~knitframe.garment.tube`: the knitted tube on the limb (stretches, tensions, pressures);
- :mod:`~knitframe.garment.optimise`: the exact course-band assignment;
- :mod:`~knitframe.garment.assign`: every fabric's fields on the tube, the band solve, the needle
  search; :mod:`~knitframe.garment.paper`: the paper's per-element method;
- :mod:`~knitframe.garment.core`: :func:`design` and the :class:`Design` it returns;
- :mod:`~knitframe.garment.outputs`: design.json, knit-map.csv/.png, pressure.png, design.vtu;
- :mod:`~knitframe.garment.knitout`: machine output (a package: the knit map, machine settings, the
  program writer, the knitout-interpreter checks and DAT, the stitch chart, the files).

``knitframe.design(...)`` (:mod:`~knitframe.garment.api`) runs it as the ``[design]`` stage does.
The subpackages are not imported here, so that ``import knitframe`` stays light. What a design
objective plugin builds on is exported here: :func:`laplace_mmhg` (:mod:`~knitframe.garment.laplace`,
the pressure of a tension on a curved limb) and :func:`class_target`, :func:`graduation`
(:mod:`~knitframe.garment.prescription`, the compression classes and graduations).
"""

from knitframe.garment.laplace import laplace_mmhg
from knitframe.garment.prescription import class_target, graduation

__all__ = ["laplace_mmhg", "class_target", "graduation"]
