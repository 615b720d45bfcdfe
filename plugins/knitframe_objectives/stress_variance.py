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
        raise NumericalError(
            f"values and weights must be non-empty and of one shape, got {x.shape} and {w.shape}"
        )
    x, w = x.ravel(), w.ravel()
    if x.size == 0:
        raise NumericalError(
            f"values and weights must be non-empty and of one shape, got {x.shape} and {w.shape}"
        )
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(w))) or np.any(w < 0) or w.sum() <= 0:
        raise NumericalError("values must be finite and weights finite, non-negative and not all zero")
    W = w.sum()
    mean = (w * x).sum() / W  # elementwise sums, not BLAS dot: this runs inside the optimiser's loops
    if mean == 0:
        raise NumericalError("mean value is zero; the coefficient of variation is undefined")
    return float((w * (x - mean) ** 2).sum() / (W * mean**2))


def level_cost(value: np.ndarray, area: np.ndarray, level: float | None) -> np.ndarray:
    r"""Per-element term of a uniformity objective at level τ: :math:`w_e (x_e/\tau - 1)^2`.

    For one assignment, :math:`\min_\tau \sum_e w_e (x_e/\tau - 1)^2 = W\,\mathrm{CV}^2/(1 + \mathrm{CV}^2)`
    (at :math:`\tau = \sum w x^2 / \sum w x`), a strictly increasing function of CV². Minimising
    this sum over assignments *and* τ therefore minimises the CV exactly; the optimiser searches τ.
    """
    if level is None or not level > 0:
        raise NumericalError(f"a uniformity objective needs a level > 0, got {level}")
    return np.asarray(area, dtype=np.float64) * (np.asarray(value, dtype=np.float64) / level - 1.0) ** 2


@attrs.frozen
class StressVariance:
    """Area-weighted CV² of element tension: 0 when the stress is uniform (paper's objective)."""

    name: ClassVar[str] = "stress_variance"
    description: ClassVar[str] = "area-weighted squared coefficient of variation of fabric tension (paper)"
    quantity: ClassVar[str] = "tension"

    @property
    def relative(self) -> bool:
        return True

    def score(self, tension: np.ndarray, area: np.ndarray, radius: np.ndarray | None = None) -> float:
        return weighted_cv2(tension, area)

    def target(self, position: np.ndarray) -> None:
        """No absolute target: any uniform tension is as good."""
        return None

    def element_cost(self, value, area, position, level=None) -> np.ndarray:
        return level_cost(value, area, level)

    def evaluate(self, value, area, position) -> float:
        return weighted_cv2(value, area)


@hookimpl
def register_design_objectives(register):
    register(StressVariance)
