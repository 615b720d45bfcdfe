"""Isotropic hyperelastic yarn (monofilament such as PET): compressible neo-Hookean with E and ν."""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe.records import Yarn
from knitframe_yarns.law import YarnModelBase, invariant_law


@attrs.frozen
class Isotropic(YarnModelBase):
    """Isotropic yarn: W = μ/2 (I1 - 3) - μ ln J + λ/2 (ln J)² with μ, λ from E_axial and ν."""

    name: ClassVar[str] = "isotropic"
    description: ClassVar[str] = "isotropic compressible neo-Hookean yarn (monofilament)"

    @property
    def lame(self) -> tuple[float, float]:
        """(μ, λ), MPa."""
        E, nu = self.E_axial, self.nu
        return E / (2.0 * (1.0 + nu)), E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))

    def evaluate(
        self, F: np.ndarray, fibre: np.ndarray | None = None, order: int = 2
    ) -> tuple[np.ndarray, Any, Any]:
        """(W, P, A) at F (..., 3, 3), MPa; ``fibre`` is accepted and ignored; ``order`` as in
        invariant_law."""
        mu, lam = self.lame
        return invariant_law(F, None, mu, lam, order=order)

    @classmethod
    def from_yarn(cls, yarn: Yarn) -> Isotropic:
        """Model with the yarn's axial modulus, Poisson ratio and knitted radius."""
        return cls(**cls._common(yarn))


@hookimpl
def register_yarn_models(register) -> None:
    register(Isotropic)
