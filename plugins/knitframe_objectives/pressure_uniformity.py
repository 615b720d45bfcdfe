"""Objective ``pressure_uniformity``: uniform (or target) interface pressure by Laplace's law."""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl, validators as v
from knitframe.errors import NumericalError
from knitframe_objectives.stress_variance import weighted_cv2

#: 1 MPa in mmHg (1 mmHg = 133.322 Pa)
MPA_TO_MMHG = 1e6 / 133.322


def laplace_pressure(tension: np.ndarray, radius: np.ndarray) -> np.ndarray:
    r"""Interface pressure of a tensioned sleeve on a limb, in mmHg.

    .. math:: p = \frac{T}{r}

    with ``T`` the circumferential tension per unit length (N/mm) and ``r`` the local radius (mm),
    so ``p`` is in MPa before conversion. 20 mmHg on a 16.5 cm wrist needs about 0.07 N/mm.
    """
    r = np.asarray(radius, dtype=np.float64)
    if np.any(~np.isfinite(r)) or np.any(r <= 0):
        raise NumericalError("radius must be finite and > 0 everywhere")
    return np.asarray(tension, dtype=np.float64) / r * MPA_TO_MMHG


@attrs.frozen
class PressureUniformity:
    """Laplace pressure p = T/r: area-weighted CV² of p, or mean squared relative error to a target."""

    name: ClassVar[str] = "pressure_uniformity"
    description: ClassVar[str] = "uniform (or target) interface pressure p = T/r by Laplace's law"

    target_mmHg: float | None = attrs.field(default=None, validator=v.optional(v.positive))  #: target pressure, mmHg

    def score(self, tension: np.ndarray, area: np.ndarray, radius: np.ndarray | None = None) -> float:
        if radius is None:
            raise NumericalError("pressure_uniformity needs the limb radius of every element")
        p = laplace_pressure(tension, radius)
        if self.target_mmHg is None:
            return weighted_cv2(p, area)
        w = np.asarray(area, dtype=np.float64)
        return float(np.dot(w, ((p - self.target_mmHg) / self.target_mmHg) ** 2) / w.sum())


@hookimpl
def register_design_objectives(register):
    register(PressureUniformity)
