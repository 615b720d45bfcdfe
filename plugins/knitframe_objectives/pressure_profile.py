"""Objective ``pressure_profile``: graduated compression, highest at the wrist or ankle.

Clinical sleeves and stockings are graduated: the pressure is highest distally and falls along
the limb (a typical graded arm sleeve gives about 22 / 15 / 9 mmHg from forearm to shoulder). The
target is ``target_mmHg`` at the distal end, or the middle of a RAL-GZ 387 ``compression_class``
(class II's 27.5 mmHg when neither is given), times a ratio that is interpolated linearly between
the given positions (0 = distal end, 1 = top), or a named ``graduation``
(:mod:`knitframe.garment.prescription`). A station meets the prescription within ``tolerance``::

    [design]
    objective = { kind = "pressure_profile", compression_class = "II", graduation = "arm-sleeve" }
    objective = { kind = "pressure_profile", target_mmHg = 30, at = [0.0, 1.0], ratios = [1.0, 0.6] }
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe.errors import FieldError
from knitframe_objectives.pressure_uniformity import mean_relative_error, relative_error_cost


@attrs.frozen
class PressureProfile:
    """Area-weighted mean squared relative error of the pressure to a graduated target profile."""

    name: ClassVar[str] = "pressure_profile"
    description: ClassVar[str] = (
        "graduated compression: a target at the wrist/ankle falling along the limb by ratios"
    )
    quantity: ClassVar[str] = "pressure"

    #: target pressure at the distal end (wrist or ankle), mmHg (default: the class's middle)
    target_mmHg: float | None = None
    #: RAL-GZ 387 class I, II, III or IV (default II when no target_mmHg is given)
    compression_class: str | None = None
    #: a named graduation ("linear", "arm-sleeve", "flat") instead of at and ratios
    graduation: str | None = None
    #: positions along the limb, 0 distal to 1 top
    at: list[float] = attrs.Factory(lambda: [0.0, 1.0])
    #: target / target_mmHg at those positions
    ratios: list[float] = attrs.Factory(lambda: [1.0, 0.6])
    #: a station meets the prescription within this relative error of its target
    tolerance: float = 0.2

    def __attrs_post_init__(self) -> None:
        from knitframe.garment import class_target, graduation

        if self.target_mmHg is None:
            object.__setattr__(self, "target_mmHg", class_target(self.compression_class or "II"))
        elif self.compression_class is not None:
            class_target(self.compression_class)  # checked; the explicit target wins
        if self.graduation is not None:
            at, ratios = graduation(self.graduation)
            object.__setattr__(self, "at", at)
            object.__setattr__(self, "ratios", ratios)
        if not (isinstance(self.tolerance, (int, float)) and 0 < self.tolerance < 1):
            raise FieldError(
                "tolerance", f"must be a fraction in (0, 1) (0.2 = ±20 %), got {self.tolerance!r}"
            )
        if not (np.isfinite(self.target_mmHg) and self.target_mmHg > 0):
            raise FieldError("target_mmHg", f"must be a finite number > 0, got {self.target_mmHg}")
        if len(self.at) != len(self.ratios) or len(self.at) < 1:
            raise FieldError(
                "ratios", f"needs one ratio per position in 'at' ({len(self.at)}), got {len(self.ratios)}"
            )
        at = np.asarray(self.at, dtype=np.float64)
        if not np.all(np.isfinite(at)) or np.any(at < 0) or np.any(at > 1) or np.any(np.diff(at) <= 0):
            raise FieldError("at", f"must be increasing positions in [0, 1], got {self.at}")
        r = np.asarray(self.ratios, dtype=np.float64)
        if not np.all(np.isfinite(r)) or np.any(r <= 0):
            raise FieldError("ratios", f"must be finite and > 0, got {self.ratios}")

    @property
    def relative(self) -> bool:
        return False

    def target(self, position: np.ndarray) -> np.ndarray:
        """Target pressure (mmHg) at positions along the limb (0 distal, 1 top)."""
        return self.target_mmHg * np.interp(np.asarray(position, dtype=np.float64), self.at, self.ratios)

    def score(self, tension: np.ndarray, area: np.ndarray, radius: np.ndarray | None = None) -> float:
        from knitframe_objectives.pressure_uniformity import laplace_pressure

        p = laplace_pressure(tension, radius if radius is not None else np.ones_like(np.asarray(tension)))
        return self.evaluate(p, area, np.linspace(0.0, 1.0, np.size(p)))

    def element_cost(self, value, area, position, level=None) -> np.ndarray:
        return relative_error_cost(value, area, self.target(position))

    def evaluate(self, value, area, position) -> float:
        return mean_relative_error(value, area, self.target(position))


@hookimpl
def register_design_objectives(register):
    register(PressureProfile)
