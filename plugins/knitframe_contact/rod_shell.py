"""Contact law ``rod_shell``: a yarn's soft shell squeezed onto its core (Singal et al. 2024).

A staple-fibre yarn is a loose shell of fibres around a denser core. Two yarn centerline points a
distance d apart overlap once d is below the shell's diameter D, and cannot come closer than the
core's diameter D_c. With z = (d − D_c)/(D − D_c) the fraction of the shell left, the energy
density per unit length of both centerlines (N/mm) is the law of Singal et al. (2024, Nat.
Commun. 15:2622, Supplement; the ``floof`` density of their simulation code)::

    φ(d) = 2 k (D − D_c)² / (p (p − 1)) · [z^(1−p) − 1 + (1 − p)(1 − z)]     0 < z < 1
    φ(d) = 0  for d ≥ D,     +∞ for d ≤ D_c

    φ′(d) = −2 k (D − D_c)/p · (z^(−p) − 1),     φ″(d) = 2 k z^(−p−1)

φ and φ′ vanish where the shells first touch, and φ grows without bound as the shell is squeezed
onto the core, so the core is a barrier. The factor 2: their code sums every point pair twice
(from each side), the rod solver once, so with their rigidity k (N/mm³) and exponent p both
give the same energy.

The law reads its four numbers from the yarn record (``shell_diameter``, ``core_diameter``,
``compression_k``, ``compression_p``); the rod solver then takes D as its contact distance, and
the pattern's cell, built around dk, is where the pre-stress starts. A yarn without them cannot
use this law (a config error before any work). Friction is that of ``rod_penalty``: regularised
Coulomb on the slip of the two contact points, with the normal force lagged from the last step.
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe.errors import ConfigError
from knitframe_contact.rod_penalty import CenterlineLaw


@attrs.frozen
class RodShell(CenterlineLaw):
    """Singal et al.'s compressible-shell law between rod centerlines, optional regularised friction."""

    name: ClassVar[str] = "rod_shell"
    description: ClassVar[str] = (
        "a yarn's soft shell squeezed onto its core, the yarn's compression law (rods; Singal et al. 2024)"
    )

    #: core diameter / shell diameter, -; set from the yarn (:meth:`for_yarn`); until then acrylic's
    core: float = attrs.field(default=0.65 / 1.48, init=False)
    #: exponent p, -; set from the yarn; until then acrylic's
    exponent: float = attrs.field(default=2.4, init=False)
    #: shell diameter D, mm: the rod's contact distance; set from the yarn (None until then)
    outer: float | None = attrs.field(default=None, init=False)
    #: the law's stiffness comes from the yarn's compression law (:meth:`rigidity`), never from here
    stiffness: None = attrs.field(default=None, init=False)

    def for_yarn(self, yarn, path: str = "solver.contact_law") -> RodShell:
        """This law with the yarn's shell, core and exponent; ConfigError if the yarn has no such law."""
        if not yarn.has_compression_law:
            raise ConfigError(
                path,
                f"'rod_shell' needs the yarn's compression law (shell_diameter, core_diameter, "
                f"compression_k, compression_p); yarn '{yarn.name}' has none",
            )
        new = attrs.evolve(self)
        object.__setattr__(new, "core", yarn.core_diameter / yarn.shell_diameter)
        object.__setattr__(new, "exponent", float(yarn.compression_p))
        object.__setattr__(new, "outer", float(yarn.shell_diameter))
        return new

    def rigidity(self, yarn) -> float:
        """The density's stiffness 2k (N/mm³) that the rod solver passes as ``k`` (see the module)."""
        return 2.0 * float(yarn.compression_k)

    def normal(
        self, d: np.ndarray, dk: float, k: float, k_core: float | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Energy φ and its first and second derivatives with respect to the centre distance d.

        Parameters
        ----------
        d : (m,) centre distances, mm
        dk : the shell diameter D (contact distance), mm; the core is ``core``·D
        k : 2k of the law (:meth:`rigidity`), N/mm³
        k_core : unused (the core is the law's own barrier)

        Returns ``(φ, dφ/dd, d²φ/dd²)``, each (m,); φ is +inf at or inside the core.
        """
        d = np.asarray(d, dtype=np.float64)
        p = self.exponent
        dd = (1.0 - self.core) * dk
        z = (d - self.core * dk) / dd
        act = z < 1.0
        inside = z <= 0.0
        zz = np.where(act & ~inside, z, 1.0)
        e = k * dd * dd / (p * (p - 1.0)) * (zz ** (1.0 - p) - 1.0 + (1.0 - p) * (1.0 - zz))
        e1 = -k * dd / p * (zz ** (-p) - 1.0)
        e2 = np.where(act, k * zz ** (-p - 1.0), 0.0)
        return np.where(inside, np.inf, e), e1, e2


@hookimpl
def register_contact_laws(register):
    register(RodShell)
