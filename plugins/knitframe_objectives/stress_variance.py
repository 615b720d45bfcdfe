"""Objective ``stress_variance``: the paper's design goal, uniform fabric stress over the garment."""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe.errors import NumericalError


def weighted_cv2(x: np.ndarray, w: np.ndarray) -> float:
    r"""Squared area-weighted coefficient of variation.

    .. math:: \bar x = \frac{\sum_e w_e x_e}{\sum_e w_e}, \qquad
              \mathrm{CV}^2 = \frac{\sum_e w_e (x_e - \bar x)^2}{\bar x^2 \sum_e w_e}

    Zero when every element carries the same value; dimensionless.
    """
    x = np.asarray(x, dtype=np.float64)
    w = np.asarray(w, dtype=np.float64)
    if x.shape != w.shape or x.size == 0:
        raise NumericalError(f"values and weights must be non-empty and of one shape, got {x.shape} and {w.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(w))) or np.any(w < 0) or w.sum() <= 0:
        raise NumericalError("values must be finite and weights finite, non-negative and not all zero")
    mean = np.dot(w, x) / w.sum()
    if mean == 0:
        raise NumericalError("mean value is zero; the coefficient of variation is undefined")
    return float(np.dot(w, (x - mean) ** 2) / (w.sum() * mean**2))


@attrs.frozen
class StressVariance:
    """Area-weighted CV² of element tension: 0 when the stress is uniform (paper's objective)."""

    name: ClassVar[str] = "stress_variance"
    description: ClassVar[str] = "area-weighted squared coefficient of variation of fabric tension (paper)"

    def score(self, tension: np.ndarray, area: np.ndarray, radius: np.ndarray | None = None) -> float:
        return weighted_cv2(tension, area)


@hookimpl
def register_design_objectives(register):
    register(StressVariance)
