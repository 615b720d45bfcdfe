"""Contact law ``rod_penalty``: smooth penalty between yarn centerlines, with a stiffening core.

For two points of yarn centerlines a distance d apart (knitted diameter dk, stiffness k,
penetration δ = dk − d, smoothing length ε = smoothing·dk)::

    e(d) = k ε² h(δ/ε) + k_c dk² B(d/dk)
    h(x) = 0 (x ≤ 0),  x³/6 (0 < x ≤ 1),  x²/2 − x/2 + 1/6 (x > 1)          (C², −e′ = k(δ − ε/2))
    B(y) = −(y − y₁)² ln((y − c)/(y₁ − c))  for c < y < y₁ = (1 + c)/2, else 0; +∞ for y ≤ c

h is a linear penalty with a C² onset; B is a barrier (Li et al. 2020, IPC) that stiffens the law
once the two yarns are squeezed past y₁ and forbids centre distances below c·dk, so soft yarns
cannot pass through each other.

The rod solver uses e as an energy density per unit length of both centerlines (N/mm, k and
k_c in N/mm³), integrated over every pair of yarn segments
(:mod:`knitframe_solvers.rod_contact`). It scales k so that two parallel yarns have the yarn
model's transverse line-contact stiffness at 5 % flattening (or ``stiffness``, N/mm²), and k_c
so that their line stiffness is the yarn's core modulus (``Yarn.core_E``) halfway through the
barrier's band: the core of packed fibres. Unset, c is the yarn's compaction limit
(``Yarn.compaction``), the same number at which the volumetric solver's yarns stop compacting.

Friction (only when the scene asks for it): regularised Coulomb on the slip u_T of the two
material contact points since the last converged step, with the normal force λ lagged from
that step (Li et al. 2020)::

    D(u_T) = μ λ ε_s f0(|u_T|/ε_s),   f0(y) = y² − y³/3 (y < 1),  y − 1/3 (y ≥ 1)

so the tangential force is μ λ once the slip exceeds ε_s.
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.interfaces import RodContactLaw
from knitframe.numerics.contact import friction_potential


@attrs.frozen
class CenterlineLaw(RodContactLaw):
    """What every rod contact law derives from its ``normal(d, dk, k, k_core)``, and its friction.

    The protocol's defaults of ``outer``, ``for_yarn`` and ``rigidity`` are inherited.
    """

    discretisation: ClassVar[str] = "rod"

    #: Coulomb coefficient μ, -
    friction: float = attrs.field(default=0.3, validator=v.in_range(0.0, 10.0))
    #: regularisation slip ε_s / the contact distance, -
    slip: float = attrs.field(default=0.01, validator=v.in_range(0.0, 1.0, lo_open=True))

    def force(self, d: np.ndarray, dk: float, k: float, k_core: float | None = None) -> np.ndarray:
        """Repulsion −de/dd at centre distances d (mm); zero when d ≥ dk."""
        return -self.normal(d, dk, k, k_core)[1]

    def friction_potential(
        self, u: np.ndarray, lam: np.ndarray, dk: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Friction pseudo-potential D, its gradient (m, 3) and Hessian (m, 3, 3) in the slip u (m, 3) mm.

        ``lam`` (m,) is the lagged normal force, N.
        """
        eps = np.full(len(u), self.slip * dk)
        return friction_potential(u, self.friction * np.asarray(lam, dtype=np.float64), eps)


@attrs.frozen
class RodPenalty(CenterlineLaw):
    """Smooth penalty + stiffening barrier between rod centerlines, optional regularised Coulomb friction."""

    name: ClassVar[str] = "rod_penalty"
    description: ClassVar[str] = (
        "smooth centerline penalty with a stiffening core, regularised Coulomb friction (rods)"
    )

    #: line contact stiffness of two parallel yarns at 5 % flattening, N/mm²; default: the yarn model's
    stiffness: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: ε/dk, -
    smoothing: float = attrs.field(default=0.05, validator=v.in_range(1e-3, 1.0))
    #: smallest centre distance / dk (0: no barrier), -; default: the yarn's compaction limit J_min
    core: float | None = attrs.field(default=None, validator=v.optional(v.in_range(0.0, 1.0, hi_open=True)))

    def normal(
        self, d: np.ndarray, dk: float, k: float, k_core: float | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Energy e and its first and second derivatives with respect to the centre distance d.

        Parameters
        ----------
        d : (m,) centre distances, mm
        dk : contact distance (knitted diameter), mm
        k : penalty stiffness (N/mm³ for the rod solver's density, N/mm for a point contact)
        k_core : barrier stiffness k_c, same units as k (default k)

        Returns ``(e, de/dd, d²e/dd²)``, each (m,); e is +inf inside the core.
        """
        d = np.asarray(d, dtype=np.float64)
        eps = self.smoothing * dk
        x = (dk - d) / eps
        xc = np.clip(x, 0.0, 1.0)
        h = np.where(x > 1.0, 0.5 * x * x - 0.5 * x + 1.0 / 6.0, xc**3 / 6.0)
        h1 = np.where(x > 1.0, x - 0.5, 0.5 * xc**2)
        h2 = np.where(x > 1.0, 1.0, xc)
        e, e1, e2 = k * eps**2 * h, -k * eps * h1, k * h2
        if self.core:
            c = self.core
            y1 = 0.5 * (1.0 + c)
            y = d / dk
            band = (y < y1) & (y > c)
            yy = np.where(band, y, y1)
            r = (yy - c) / (y1 - c)
            lg = np.log(r)
            z = yy - y1
            w = yy - c
            B = -(z**2) * lg
            B1 = -2.0 * z * lg - z**2 / w
            B2 = -2.0 * lg - 4.0 * z / w + z**2 / w**2
            kc = k if k_core is None else k_core
            e = e + kc * dk**2 * B
            e1 = e1 + kc * dk * B1
            e2 = e2 + kc * B2
            inside = y <= c
            e = np.where(inside, np.inf, e)
        return e, e1, e2


@hookimpl
def register_contact_laws(register):
    register(RodPenalty)
