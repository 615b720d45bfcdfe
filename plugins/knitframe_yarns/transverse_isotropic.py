"""Transversely isotropic hyperelastic yarn (cotton, textured nylon): stiff along the yarn, soft across it.

The fibre direction is the yarn tangent in the reference configuration. Energy, stress and tangent
come from the Bonet-Burton law in :mod:`knitframe_yarns.law`, whose linearisation has axial
modulus E_A, transverse modulus E_T, axial shear modulus G_A and Poisson ratio ν. With a
compaction limit the yarn's cross-section stops compacting at J_min of its natural area
(:func:`knitframe_yarns.law.compaction_barrier`, with the core modulus E_core): the fibres are
packed solid there, as in the rod solver's contact core.
"""

from __future__ import annotations

from typing import Any, ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.errors import FieldError
from knitframe.records import Yarn
from knitframe_yarns.law import YarnModelBase, compaction_barrier, constants, invariant_law


@attrs.frozen
class TransverseIsotropic(YarnModelBase):
    """Transversely isotropic yarn: E_A along the fibre (yarn tangent), E_T and G_A across and in shear."""

    name: ClassVar[str] = "transverse_isotropic"
    description: ClassVar[str] = (
        "transversely isotropic hyperelastic yarn (Bonet-Burton), fibre = yarn tangent"
    )

    #: transverse Young's modulus, MPa
    E_transverse: float = attrs.field(kw_only=True, validator=v.positive)
    #: axial shear modulus, MPa
    G_axial: float | None = attrs.field(default=None, kw_only=True, validator=v.optional(v.positive))
    #: smallest cross-section area over the natural one (None: no limit), -
    compaction: float | None = attrs.field(
        default=None, kw_only=True, validator=v.optional(v.in_range(0.0, 1.0, lo_open=True, hi_open=True))
    )
    #: modulus of the packed core, MPa (None: E_axial)
    core_modulus: float | None = attrs.field(default=None, kw_only=True, validator=v.optional(v.positive))

    def __attrs_post_init__(self) -> None:
        if self.E_transverse > self.E_axial:
            raise FieldError("E_transverse", f"must be <= E_axial = {self.E_axial}, got {self.E_transverse}")
        nu_ta = self.nu * self.E_transverse / self.E_axial
        if 1.0 - self.nu - 2.0 * self.nu * nu_ta <= 0.0:
            raise FieldError("nu", f"{self.nu} makes the transversely isotropic stiffness indefinite")

    @property
    def transverse_modulus(self) -> float:
        return self.E_transverse

    @property
    def shear_modulus(self) -> float:
        """G_A if given, else the transverse shear modulus E_T / (2(1 + ν)) (fibres slide past each other)."""
        return self.G_axial if self.G_axial is not None else self.E_transverse / (2.0 * (1.0 + self.nu))

    @property
    def constants(self) -> dict[str, float]:
        """Bonet-Burton constants μ, λ, α, β, γ (MPa)."""
        return constants(self.E_axial, self.E_transverse, self.shear_modulus, self.nu)

    def evaluate(
        self, F: np.ndarray, fibre: np.ndarray | None = None, order: int = 2
    ) -> tuple[np.ndarray, Any, Any]:
        """(W, P, A) at F (..., 3, 3) with unit reference fibre directions ``fibre`` (..., 3), MPa.

        ``order`` 0 computes W only, 1 adds P (the others are None).
        """
        if fibre is None:
            raise FieldError(
                "fibre", "the transversely isotropic law needs the fibre (yarn tangent) direction"
            )
        c = self.constants
        W, P, A = invariant_law(F, fibre, c["mu"], c["lam"], c["alpha"], c["beta"], c["gamma"], order=order)
        if self.compaction is None:
            return W, P, A
        E_core = self.core_modulus if self.core_modulus is not None else self.E_axial
        Wc, Pc, Ac = compaction_barrier(F, fibre, self.compaction, E_core, order=order)
        return (
            W + Wc,
            None if P is None else P + Pc,
            None if A is None else A + Ac,
        )

    @classmethod
    def from_yarn(cls, yarn: Yarn) -> TransverseIsotropic:
        """Model with the yarn's moduli, knitted radius, compaction limit and core modulus."""
        return cls(
            **cls._common(yarn),
            E_transverse=yarn.E_transverse,
            G_axial=yarn.G_axial,
            compaction=yarn.compaction if yarn.compaction < 1.0 else None,
            core_modulus=yarn.core_E,
        )


@hookimpl
def register_yarn_models(register) -> None:
    register(TransverseIsotropic)
