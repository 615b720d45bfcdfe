"""Garment design (level 5): from a limb and a fabric library to a pressure-graded, knittable sleeve.

- :mod:`~knitframe.garment.limb`: the limb, from a scan, from measurements, or the example arm;
- :mod:`~knitframe.garment.library`: candidate fabrics with fitted models, relaxed pitches and limits;
- :mod:`~knitframe.garment.tube`: the knitted tube on the limb (stretches, tensions, pressures);
- :mod:`~knitframe.garment.optimise`: the exact course-band assignment;
- :mod:`~knitframe.garment.core`: :func:`design` and the :class:`Design` it returns;
- :mod:`~knitframe.garment.outputs`: design.json, knit-map.csv/.png, pressure.png, design.vtu.

``knitframe.design(...)`` (:mod:`~knitframe.garment.api`) runs it as the ``[design]`` stage does.
"""
