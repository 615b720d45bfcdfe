"""The example arm and :func:`load_limb`, which turns every kind of limb input into a :class:`Limb`."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError
from knitframe.garment.limb.record import Limb

__all__ = ["EXAMPLE_ARM_MEASUREMENTS", "example_arm", "load_limb"]

#: (distance from the wrist mm, circumference mm, minor/major ratio) of the built-in arm
EXAMPLE_ARM_MEASUREMENTS = (
    (0.0, 160.0, 0.70),  # wrist
    (90.0, 205.0, 0.78),  # lower forearm
    (190.0, 250.0, 0.85),  # largest forearm
    (270.0, 245.0, 0.90),  # elbow
    (420.0, 315.0, 0.95),  # upper arm
)


def example_arm(n_stations: int = 41, n_around: int = 64) -> Limb:
    """A built-in parametric adult arm, wrist (station 0) to upper arm, from typical circumferences.

    ============================  ===========  ===============  ===================
    position                      from wrist   circumference    minor/major ratio
    ============================  ===========  ===============  ===================
    wrist                         0 mm         160 mm           0.70
    lower forearm                 90 mm        205 mm           0.78
    largest forearm               190 mm       250 mm           0.85
    elbow                         270 mm       245 mm           0.90
    upper arm                     420 mm       315 mm           0.95
    ============================  ===========  ===============  ===================

    Source: typical adult values and the standard measuring positions of compression-garment
    fitting: the wrist about 15–17 cm around, the upper arm 26–34 cm and about twice the wrist
    (here 315/160 = 1.97), measured at the wrist, the largest forearm, the elbow and the upper arm.
    The positions, the lower-forearm value and the ratios (a flattened wrist rounding towards the
    upper arm; slightly elliptical forearm) are illustrative round numbers for an adult arm, not
    one measured person. Built by :meth:`Limb.from_measurements` (exact elliptic perimeters,
    PCHIP between the measurements), straight axis along +z.
    """
    pos, circ, ratio = (np.array(col) for col in zip(*EXAMPLE_ARM_MEASUREMENTS, strict=False))
    limb = Limb.from_measurements(
        pos, circ, ellipticity=ratio, n_stations=n_stations, n_around=n_around, name="example arm"
    )
    return attrs.evolve(limb, source="example")


def load_limb(path_or_spec: Any, **kwargs: Any) -> Limb:
    """A limb from a scan file path, ``"example"``, a measurement mapping or a :class:`Limb`.

    A mapping needs ``positions_mm`` and ``circumferences_mm`` and may hold ``ellipticity``,
    ``n_stations``, ``n_around`` and ``name`` (passed to :meth:`Limb.from_measurements`); keyword
    arguments go to the chosen constructor.
    """
    if isinstance(path_or_spec, Limb):
        return path_or_spec
    if isinstance(path_or_spec, str) and path_or_spec == "example":
        return example_arm(**kwargs)
    if isinstance(path_or_spec, Mapping):
        spec = dict(path_or_spec)
        missing = [k for k in ("positions_mm", "circumferences_mm") if k not in spec]
        if missing:
            raise ConfigError("limb", f"a measurement table needs {', '.join(missing)}")
        allowed = {"positions_mm", "circumferences_mm", "ellipticity", "n_stations", "n_around", "name"}
        unknown = sorted(set(spec) - allowed)
        if unknown:
            raise ConfigError(f"limb.{unknown[0]}", f"unknown key; allowed: {', '.join(sorted(allowed))}")
        pos = spec.pop("positions_mm")
        circ = spec.pop("circumferences_mm")
        return Limb.from_measurements(pos, circ, **{**spec, **kwargs})
    if isinstance(path_or_spec, (str, Path)):
        return Limb.from_scan(path_or_spec, **kwargs)
    raise ConfigError(
        "limb", f"expected a scan file, 'example' or a measurement table, got {type(path_or_spec).__name__}"
    )
