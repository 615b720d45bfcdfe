"""Objective ``pressure_uniformity``: uniform (or target) interface pressure by Laplace's law."""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.errors import NumericalError
from knitframe.garment import laplace_mmhg
from knitframe_objectives.stress_variance import level_cost, weighted_cv2


def laplace_pressure(tension: np.ndarray, radius: np.ndarray) -> np.ndarray:
    r"""Interface pressure of a tensioned sleeve on a limb, in mmHg.

    .. math:: p = \frac{T}{r}

    with ``T`` the circumferential tension per unit length (N/mm) and ``r`` the local radius (mm),
    so ``p`` is in MPa before conversion. 20 mmHg on a 16.5 cm wrist needs about 0.07 N/mm.
    """
    r = np.asarray(radius, dtype=np.float64)
    if np.any(~np.isfinite(r)) or np.any(r <= 0):
        raise NumericalError("radius must be finite and > 0 everywhere")
    return laplace_mmhg(tension, r)


def relative_error_cost(value: np.ndarray, area: np.ndarray, target: np.ndarray) -> np.ndarray:
    r"""Per-element squared relative error to a target: :math:`w_e\,((x_e - x^*_e)/x^*_e)^2`."""
    t = np.asarray(target, dtype=np.float64)
    return np.asarray(area, dtype=np.float64) * ((np.asarray(value, dtype=np.float64) - t) / t) ** 2


def mean_relative_error(value: np.ndarray, area: np.ndarray, target: np.ndarray) -> float:
    """Area-weighted mean of the squared relative error to the target (0 when met everywhere)."""
    w = np.asarray(area, dtype=np.float64)
    return float(relative_error_cost(value, w, target).sum() / w.sum())


@attrs.frozen
class PressureUniformity:
    """Laplace pressure p = T/r: area-weighted CV² of p, or mean squared relative error to a target."""

    name: ClassVar[str] = "pressure_uniformity"
    description: ClassVar[str] = "uniform (or target) interface pressure p = T/r by Laplace's law"
    quantity: ClassVar[str] = "pressure"

    #: target pressure, mmHg
    target_mmHg: float | None = attrs.field(default=None, validator=v.optional(v.positive))

    @property
    def relative(self) -> bool:
        return self.target_mmHg is None

    def score(self, tension: np.ndarray, area: np.ndarray, radius: np.ndarray | None = None) -> float:
        if radius is None:
            raise NumericalError("pressure_uniformity needs the limb radius of every element")
        return self.evaluate(laplace_pressure(tension, radius), area, None)

    def element_cost(self, value, area, position, level=None) -> np.ndarray:
        if self.target_mmHg is None:
            return level_cost(value, area, level)
        return relative_error_cost(value, area, self.target_mmHg)

    def target(self, position: np.ndarray) -> np.ndarray | None:
        """``target_mmHg`` at every position, or None for a free level."""
        if self.target_mmHg is None:
            return None
        return np.full(np.shape(position), float(self.target_mmHg))

    def evaluate(self, value, area, position) -> float:
        if self.target_mmHg is None:
            return weighted_cv2(value, area)
        return mean_relative_error(value, area, self.target_mmHg)


@hookimpl
def register_design_objectives(register):
    register(PressureUniformity)
