r"""Homogenizer ``hgo2m``: two fibre families (course, wale) plus a membrane; it predicts uniaxial tests.

.. math::

    \psi = \sum_{\alpha=1,2} \frac{\mu_\alpha}{2}\left(\lambda_\alpha^2 - 1 - 2\ln\lambda_\alpha\right)
         + \frac{K}{4}\left(J^2 - 1 - 2\ln J\right)
         + \sum_{\alpha=1,2} \frac{a_\alpha}{b_\alpha}
           \left[e^{b_\alpha \langle \lambda_\alpha^2 - 1\rangle^2} - 1\right],
    \qquad J = \lambda_1 \lambda_2

Parameters ``(mu1, mu2, K, a1, b1, a2, b2)``: μ, K, a in N/mm (energy per unit reference area),
b dimensionless. The first two terms are a compressible neo-Hookean-type membrane; with
μ1 = μ2 = μ it is the isotropic one, ``μ/2 (λ1² + λ2² − 2 − 2 ln J) + K/4 (J² − 1 − 2 ln J)``.
The fibres are the paper's exponential law along the course (θ = 0) and the wale (θ = 90°); by
default they carry no compression (⟨·⟩), as in ABAQUS and FEBio.

Small strain: ``C11 = 2μ1 + K + 8a1``, ``C22 = 2μ2 + K + 8a2``, ``C12 = K``; the lateral
contraction of a uniaxial course test is ν12 = K/(2μ2 + K) (wale fibre slack), of a wale test
ν21 = K/(2μ1 + K).

Why this form. With free sides the paper's model must keep I4 = 1 and carries no tension below
λ = 1/cos θ. Here every term is convex in each stretch separately and the membrane makes
P_free → −∞ as λ_free → 0, so P_free = 0 has exactly one root: tension *and* contraction are
predicted. Fitting Singal et al.'s tests showed that knits contract very differently when pulled
along the course and along the wale (garter: −31 % at 58 % course strain, −13 % at 79 % wale
strain), which an isotropic membrane (one ν) cannot follow; hence μ1 ≠ μ2. Two families at ±θ
would not help: under stretch without shear they share one I4.
"""

from __future__ import annotations

import math
from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe.errors import KnitframeError
from knitframe.fitting import solve_free_side
from knitframe_homogenizers.hgo import _fmt, as_stretch, febio_block, fibre_gh, fibre_terms

__all__ = ["HGO2M"]


def _fibre(a: float, b: float, lam: np.ndarray, compression: bool) -> dict[str, np.ndarray]:
    """Fibre along one axis: I4 = λ², so P = 2λ g and ∂P/∂λ = 4λ² h + 2g."""
    return fibre_terms(a, b, lam * lam, compression)


def _log_term(lam: np.ndarray) -> np.ndarray:
    """λ² − 1 − 2 ln λ ≥ 0, zero at λ = 1."""
    return lam * lam - 1.0 - 2.0 * np.log(lam)


@attrs.frozen
class HGO2M:
    """Course and wale exponential fibres (a1, b1, a2, b2) plus an orthotropic neo-Hookean membrane (mu1, mu2,
    K)."""

    name: ClassVar[str] = "hgo2m"
    description: ClassVar[str] = (
        "course + wale fibres and a membrane (mu1, mu2, K, a1, b1, a2, b2); predicts lateral strain"
    )
    param_names: ClassVar[tuple[str, ...]] = ("mu1", "mu2", "K", "a1", "b1", "a2", "b2")
    units: ClassVar[tuple[str, ...]] = ("N/mm", "N/mm", "N/mm", "N/mm", "-", "N/mm", "-")
    log_scale: ClassVar[tuple[bool, ...]] = (True,) * 7
    predicts_lateral: ClassVar[bool] = True
    #: no bound is a symmetry plane of the model
    symmetric_bounds: ClassVar[tuple[bool, ...]] = (False,) * 7

    #: no format of :mod:`knitframe.export` can hold this model (:attr:`card_refusal` says why)
    card_formats: ClassVar[tuple[str, ...]] = ()
    card_refusal: ClassVar[str] = (
        "its membrane is orthotropic (mu1 != mu2) and compressible in the plane (Poisson ratio K/(2 mu + K), "
        "which can exceed the 0.5 a 3-D solid allows), while the matrix of ABAQUS HOLZAPFEL, CalculiX "
        "ELASTIC_FIBER and FEBio Holzapfel-Gasser-Ogden is an isotropic solid; fit 'hgo' for a card"
    )

    def card(self, fmt: str, params, **options) -> str:
        """No card: ``card_formats`` is empty (:attr:`card_refusal` says why)."""
        raise ValueError(f"hgo2m has no {fmt} card: {self.card_refusal}")

    #: keep the fibre stress in compression (false: tension-only fibres)
    compression_fibre: bool = False

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """μ1, μ2, K, a1, a2 in [1e-6, 1e2] N/mm; b1, b2 in [1e-4, 1e3]."""
        return (
            np.array([1e-6, 1e-6, 1e-6, 1e-6, 1e-4, 1e-6, 1e-4]),
            np.array([1e2, 1e2, 1e2, 1e2, 1e3, 1e2, 1e3]),
        )

    def x0(self) -> np.ndarray:
        """Default parameters: μ1 = μ2 = K = 0.02 N/mm, a1 = a2 = 0.05 N/mm, b1 = b2 = 1."""
        return np.array([0.02, 0.02, 0.02, 0.05, 1.0, 0.05, 1.0])

    def energy(self, params, lam1, lam2) -> np.ndarray:
        """ψ(λ1, λ2), N/mm."""
        mu1, mu2, K, a1, b1, a2, b2 = params
        l1, l2 = as_stretch(lam1, lam2)
        J = l1 * l2
        c = self.compression_fibre
        return (
            0.5 * mu1 * _log_term(l1)
            + 0.5 * mu2 * _log_term(l2)
            + 0.25 * K * (J * J - 1.0 - 2.0 * np.log(J))
            + _fibre(a1, b1, l1, c)["psi"]
            + _fibre(a2, b2, l2, c)["psi"]
        )

    def stress(self, params, lam1, lam2):
        """Nominal tensions ``P1 = μ1(λ1 − 1/λ1) + K/2 (J² − 1)/λ1 + 2λ1 g1`` and likewise P2, N/mm."""
        mu1, mu2, K, a1, b1, a2, b2 = params
        l1, l2 = as_stretch(lam1, lam2)
        q = 0.5 * K * (l1 * l1 * l2 * l2 - 1.0)
        c = self.compression_fibre
        g1, g2 = fibre_gh(a1, b1, l1 * l1, c, second=False)[0], fibre_gh(a2, b2, l2 * l2, c, second=False)[0]
        return mu1 * (l1 - 1.0 / l1) + q / l1 + 2.0 * l1 * g1, mu2 * (l2 - 1.0 / l2) + q / l2 + 2.0 * l2 * g2

    def stress_grad(self, params, lam1, lam2):
        """``(P1, P2, ∂P1/∂p, ∂P2/∂p)``, derivative arrays (n, 7) ordered as ``param_names``."""
        mu1, mu2, K, a1, b1, a2, b2 = params
        l1, l2 = as_stretch(lam1, lam2)
        c = self.compression_fibre
        f1, f2 = _fibre(a1, b1, l1, c), _fibre(a2, b2, l2, c)
        j1 = 0.5 * (l1 * l1 * l2 * l2 - 1.0)
        z = np.zeros_like(l1)
        s1, s2 = l1 - 1.0 / l1, l2 - 1.0 / l2
        P1 = mu1 * s1 + K * j1 / l1 + 2.0 * l1 * f1["g"]
        P2 = mu2 * s2 + K * j1 / l2 + 2.0 * l2 * f2["g"]
        dP1 = np.stack([s1, z, j1 / l1, 2 * l1 * f1["g_a"], 2 * l1 * f1["g_b"], z, z], axis=-1)
        dP2 = np.stack([z, s2, j1 / l2, z, z, 2 * l2 * f2["g_a"], 2 * l2 * f2["g_b"]], axis=-1)
        return P1, P2, dP1, dP2

    def tangent(self, params, lam1, lam2):
        """``(∂P1/∂λ1, ∂P1/∂λ2, ∂P2/∂λ2)``, N/mm; the diagonal terms are > 0 for tension-only fibres."""
        return self.stress_tangent(params, lam1, lam2)[2:]

    def stress_tangent(self, params, lam1, lam2):
        """``(P1, P2, ∂P1/∂λ1, ∂P1/∂λ2, ∂P2/∂λ2)`` sharing one evaluation of each fibre (the free-side solve's
        path)."""
        mu1, mu2, K, a1, b1, a2, b2 = params
        l1, l2 = as_stretch(lam1, lam2)
        c = self.compression_fibre
        g1, h1 = fibre_gh(a1, b1, l1 * l1, c)
        g2, h2 = fibre_gh(a2, b2, l2 * l2, c)
        q = 0.5 * K * (l1 * l1 * l2 * l2 - 1.0)
        i1, i2 = 1.0 / (l1 * l1), 1.0 / (l2 * l2)
        P1 = mu1 * (l1 - 1.0 / l1) + q / l1 + 2.0 * l1 * g1
        P2 = mu2 * (l2 - 1.0 / l2) + q / l2 + 2.0 * l2 * g2
        k11 = mu1 * (1.0 + i1) + 0.5 * K * (l2 * l2 + i1) + 4.0 * l1 * l1 * h1 + 2.0 * g1
        k22 = mu2 * (1.0 + i2) + 0.5 * K * (l1 * l1 + i2) + 4.0 * l2 * l2 * h2 + 2.0 * g2
        return P1, P2, k11, K * l1 * l2, k22

    def free_side_slack(self, params, direction="course") -> float:
        """1.0: the membrane carries tension from the start, so a free side never goes slack."""
        return 1.0

    def solve_uniaxial(self, params, lam, direction="course"):
        """Free-side stretch (the unique root of P_free = 0) and loaded tension: ``(lam_free, P_loaded)``."""
        return solve_free_side(self, params, lam, direction)

    def abaqus(self, params, *, thickness: float = 1.0, name: str = "KNIT") -> str:
        """Not available: no built-in ABAQUS form holds this model (use ``febio`` or the ``hgo`` model)."""
        raise KnitframeError(
            "homogenizer 'hgo2m' has no exact ABAQUS *ANISOTROPIC HYPERELASTIC, HOLZAPFEL card: ABAQUS "
            "shares k1, k2 between fibre families and its matrix is isotropic; export 'hgo' or use the FEBio "
            "block"
        )

    def febio(self, params, *, thickness: float = 1.0, name: str = "knit") -> str:
        """FEBio solid mixture: neo-Hookean matrix plus ``fiber-exp-pow`` fibres at 0° (ξ = 2a1/t, α = b1) and
        90°.

        The fibres map exactly (both are tension-only there). The matrix is the isotropic part of
        the membrane: shear modulus min(μ1, μ2)/t and the Poisson ratio of the areal term; the
        orthotropic excess |μ1 − μ2| has no FEBio counterpart and is left out (stated in the block).
        """
        mu1, mu2, K, a1, b1, a2, b2 = (float(p) for p in params)
        mu = min(mu1, mu2)
        nu = min(K / (2.0 * mu + K), 0.49)  # small-strain Poisson ratio of the isotropic part
        G = mu / thickness
        notes = [
            f"knitframe hgo2m: mu1 = {_fmt(mu1)}, mu2 = {_fmt(mu2)}, K = {_fmt(K)}, a1 = {_fmt(a1)}, "
            f"a2 = {_fmt(a2)} N/mm, b1 = {_fmt(b1)}, b2 = {_fmt(b2)}, thickness = {_fmt(thickness)} mm.",
            "Matrix = isotropic part of the membrane (agrees at small strain only); the orthotropic excess "
            f"|mu1 - mu2| = {_fmt(abs(mu1 - mu2))} N/mm is not represented.",
            "FEBio uses per-volume energies: values are divided by the thickness.",
        ]
        if self.compression_fibre:
            notes.append(
                "FEBio fibres carry no compression; this model's fibres do (compression_fibre = true)."
            )
        return febio_block(
            name,
            2.0 * G * (1.0 + nu),
            nu,
            [(2.0 * a1 / thickness, b1, 0.0), (2.0 * a2 / thickness, b2, 0.5 * math.pi)],
            notes,
        )


@hookimpl
def register_homogenizers(register):
    register(HGO2M)
