"""Hyperelastic yarn laws, rod stiffnesses and yarn-yarn line contact, shared by the yarn models.

The solid law is the transversely isotropic model of Bonet & Burton (1998, Comput. Methods Appl.
Mech. Engrg. 162:151-164): a compressible neo-Hookean matrix plus fibre terms in the invariants of
C = FᵀF and the fibre (yarn tangent) direction a,

    W = μ/2 (I1 - 3) - μ ln J + λ/2 (ln J)²
        + [α + β ln J + γ (I4 - 1)] (I4 - 1) - α/2 (I5 - 1),
    I1 = tr C,  J = det F,  I4 = a·C a,  I5 = a·C² a.

α = β = γ = 0 gives the isotropic neo-Hookean law. The five constants are chosen so the law
linearises exactly to transversely isotropic elasticity with axial modulus E_A, transverse
modulus E_T, axial shear modulus G_A and Poisson ratio ν (used for ν_T and ν_AT):

    μ = E_T / (2(1 + ν)),  λ = C_2233,  β = (C_1122 - λ)/2,  α = μ - G_A,
    γ = (C_1111 - λ - 2μ - 4β + 4α) / 8,

with C the linear stiffness (fibre along 1) from inverting the compliance matrix.
"""

from __future__ import annotations

from typing import ClassVar

import attrs
import numpy as np

from knitframe import validators as v
from knitframe.errors import NumericalError
from knitframe.records import Yarn
from knitframe.yarn import line_contact_approach, line_contact_load, line_contact_stiffness

__all__ = ["linear_stiffness", "constants", "invariant_law", "YarnModelBase"]


def linear_stiffness(E_A: float, E_T: float, G_A: float, nu: float) -> np.ndarray:
    """6x6 Voigt stiffness (order 11, 22, 33, 23, 13, 12; engineering shear) with the fibre along 1, MPa."""
    s = np.array(
        [
            [1.0 / E_A, -nu / E_A, -nu / E_A],
            [-nu / E_A, 1.0 / E_T, -nu / E_T],
            [-nu / E_A, -nu / E_T, 1.0 / E_T],
        ]
    )
    c = np.zeros((6, 6))
    c[:3, :3] = np.linalg.inv(s)
    c[3, 3] = E_T / (2.0 * (1.0 + nu))
    c[4, 4] = c[5, 5] = G_A
    return c


def constants(E_A: float, E_T: float, G_A: float, nu: float) -> dict[str, float]:
    """Bonet-Burton constants (μ, λ, α, β, γ), MPa, matching the linear transversely isotropic law."""
    c = linear_stiffness(E_A, E_T, G_A, nu)
    mu = E_T / (2.0 * (1.0 + nu))
    lam = c[1, 2]
    beta = 0.5 * (c[0, 1] - lam)
    alpha = mu - G_A
    gamma = (c[0, 0] - lam - 2.0 * mu - 4.0 * beta + 4.0 * alpha) / 8.0
    return {"mu": mu, "lam": lam, "alpha": alpha, "beta": beta, "gamma": gamma}


def _outer(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """(..., 3, 3) ⊗ (..., 3, 3) -> (..., 3, 3, 3, 3): X_iJ Y_kL."""
    return X[..., :, :, None, None] * Y[..., None, None, :, :]


def invariant_law(
    F: np.ndarray,
    a: np.ndarray | None,
    mu: float,
    lam: float,
    alpha: float = 0.0,
    beta: float = 0.0,
    gamma: float = 0.0,
    order: int = 2,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Energy density, first Piola stress and tangent of the Bonet-Burton law (see module docstring).

    Parameters
    ----------
    F : (..., 3, 3) deformation gradients.
    a : (..., 3) unit fibre directions in the reference configuration (None for isotropic).
    mu, lam, alpha, beta, gamma : float
        Constants, MPa.
    order : 0 returns W only, 1 adds P, 2 adds A (the others are None).

    Returns
    -------
    W : (...,) MPa;  P : (..., 3, 3) MPa, P = F S;
    A : (..., 3, 3, 3, 3) MPa, A_iJkL = ∂P_iJ/∂F_kL = δ_ik S_LJ + F_iI F_kK ℂ_IJKL,
        with S = 2∂W/∂C and ℂ = 4∂²W/∂C². ℂ is a sum of dyads X ⊗ Y of symmetric tensors built
        from C⁻¹, A = a ⊗ a and I, so its push-forward is assembled from the dyads of F·X
        directly, F_iI F_kK X_IJ Y_KL = (FX)_iJ (FY)_kL, without forming ℂ:

        ℂ = λ C⁻¹⊗C⁻¹ + 2c₁ C⁻¹⊙C⁻¹ + 2β (C⁻¹⊗A + A⊗C⁻¹) + 8γ A⊗A
            − α (A_IL δ_JK + A_IK δ_JL + A_JL δ_IK + A_JK δ_IL),
        c₁ = μ − λ ln J − β (I4 − 1),  (C⁻¹⊙C⁻¹)_IJKL = ½ (C⁻¹_IK C⁻¹_JL + C⁻¹_IL C⁻¹_JK).
    """
    F = np.asarray(F, dtype=np.float64)
    J = np.linalg.det(F)
    if np.any(~np.isfinite(J)) or np.any(J <= 0):
        bad = np.unravel_index(int(np.argmin(np.where(np.isfinite(J), J, -np.inf))), J.shape)
        raise NumericalError(f"yarn law: det F = {J[bad]:.3g} <= 0 at index {tuple(int(i) for i in bad)}")
    C = np.einsum("...ki,...kj->...ij", F, F)
    lnJ = np.log(J)
    I1 = np.trace(C, axis1=-2, axis2=-1)
    W = 0.5 * mu * (I1 - 3.0) - mu * lnJ + 0.5 * lam * lnJ**2
    fibre = a is not None and bool(alpha or beta or gamma)
    if fibre:
        a = np.broadcast_to(np.asarray(a, dtype=np.float64), C.shape[:-1])
        Ca = np.einsum("...ij,...j->...i", C, a)
        I4 = np.einsum("...i,...i->...", a, Ca)
        I5 = np.einsum("...i,...i->...", Ca, Ca)
        e4 = I4 - 1.0
        W = W + (alpha + beta * lnJ + gamma * e4) * e4 - 0.5 * alpha * (I5 - 1.0)
    if not np.all(np.isfinite(W)):
        raise NumericalError("yarn law: non-finite energy")
    if order == 0:
        return W, None, None
    Ci = np.linalg.inv(C)
    eye = np.broadcast_to(np.eye(3), C.shape)
    S = mu * (eye - Ci) + lam * lnJ[..., None, None] * Ci
    c1 = mu - lam * lnJ
    if fibre:
        A_ = a[..., :, None] * a[..., None, :]
        aCa = a[..., :, None] * Ca[..., None, :]
        S = (
            S
            + (beta * e4)[..., None, None] * Ci
            + 2.0 * (alpha + beta * lnJ + 2.0 * gamma * e4)[..., None, None] * A_
        )
        S = S - alpha * (aCa + np.swapaxes(aCa, -1, -2))
        c1 = c1 - beta * e4
    P = F @ S
    if not np.all(np.isfinite(P)):
        raise NumericalError("yarn law: non-finite stress")
    if order == 1:
        return W, P, None
    return W, P, _tangent(F, a if fibre else None, Ci, S, c1, lam, alpha, beta, gamma)


def _tangent(
    F: np.ndarray,
    a: np.ndarray | None,
    Ci: np.ndarray,
    S: np.ndarray,
    c1: np.ndarray,
    lam: float,
    alpha: float,
    beta: float,
    gamma: float,
) -> np.ndarray:
    """The tangent A_iJkL = δ_ik S_LJ + F_iI F_kK ℂ_IJKL of :func:`invariant_law` (..., 3, 3, 3, 3), MPa.

    ``Ci`` is C⁻¹, ``S`` the second Piola stress and ``c1`` = μ − λ ln J − β (I4 − 1) as
    computed there; ``a`` the fibre directions (..., 3), or None when the law has no fibre
    terms. ℂ's dyads are pushed forward term by term, (FX)_iJ (FY)_kL, as in
    :func:`invariant_law`'s docstring.
    """
    eye = np.broadcast_to(np.eye(3), S.shape)
    FC = F @ Ci  # (F C⁻¹)_iJ
    b = FC @ np.swapaxes(F, -1, -2)  # F C⁻¹ Fᵀ = I, kept general for round-off consistency
    A = lam * _outer(FC, FC)
    # 2c₁ C⁻¹⊙C⁻¹ pushed forward: c₁ (b_ik C⁻¹_JL + (FC⁻¹)_iL (FC⁻¹)_kJ)
    A = A + c1[..., None, None, None, None] * (
        b[..., :, None, :, None] * Ci[..., None, :, None, :]
        + FC[..., :, None, None, :] * np.swapaxes(FC, -1, -2)[..., None, :, :, None]
    )
    # geometric term δ_ik S_LJ
    A = A + eye[..., :, None, :, None] * S[..., None, :, None, :]
    if a is not None:
        A_ = a[..., :, None] * a[..., None, :]
        Fa = np.einsum("...iI,...I->...i", F, a)
        FA = Fa[..., :, None] * a[..., None, :]  # (F A)_iJ = (Fa)_i a_J
        A = A + 2.0 * beta * (_outer(FC, FA) + _outer(FA, FC)) + 8.0 * gamma * _outer(FA, FA)
        # −α pushed forward: (Fa)_i a_L F_kJ + (Fa)_i (Fa)_k δ_JL + (FFᵀ)_ik a_J a_L + F_iL a_J (Fa)_k
        FFt = F @ np.swapaxes(F, -1, -2)
        t1 = FA[..., :, None, None, :] * np.swapaxes(F, -1, -2)[..., None, :, :, None]
        t2 = (Fa[..., :, None] * Fa[..., None, :])[..., :, None, :, None] * eye[..., None, :, None, :]
        t3 = FFt[..., :, None, :, None] * A_[..., None, :, None, :]
        t4 = F[..., :, None, None, :] * (a[..., :, None] * Fa[..., None, :])[..., None, :, :, None]
        A = A - alpha * (t1 + t2 + t3 + t4)
    return A


@attrs.frozen
class YarnModelBase:
    """Fields and rod/contact quantities shared by the yarn models.

    Subclasses add ``evaluate(F, fibre) -> (W, P, A)``, the solid law, and ``from_yarn``.
    """

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""

    #: axial Young's modulus, MPa
    E_axial: float = attrs.field(validator=v.positive)
    #: knitted radius dk/2, mm
    radius: float = attrs.field(validator=v.positive)
    #: Poisson ratio, -
    nu: float = attrs.field(default=0.3, validator=v.in_range(-1.0, 0.5, lo_open=True, hi_open=True))
    #: fitted EI, N·mm²
    bending_modulus: float | None = attrs.field(default=None, validator=v.optional(v.positive))

    @property
    def transverse_modulus(self) -> float:
        """Modulus governing transverse contact, MPa."""
        return self.E_axial

    @property
    def shear_modulus(self) -> float:
        """Axial shear modulus, MPa."""
        return self.E_axial / (2.0 * (1.0 + self.nu))

    @property
    def area(self) -> float:
        """Cross-section π r², mm²."""
        return np.pi * self.radius**2

    @property
    def EA(self) -> float:
        """Axial stiffness E_A π r², N."""
        return self.E_axial * self.area

    @property
    def EI(self) -> float:
        """Bending stiffness, N·mm²: the fitted ``bending_modulus`` if given, else E_A π r⁴/4."""
        return (
            self.bending_modulus
            if self.bending_modulus is not None
            else self.E_axial * np.pi * self.radius**4 / 4.0
        )

    @property
    def GJ(self) -> float:
        """Torsional stiffness G_A π r⁴/2, N·mm²."""
        return self.shear_modulus * np.pi * self.radius**4 / 2.0

    def contact_approach(self, f: np.ndarray) -> np.ndarray:
        """Approach (mm) of two touching parallel yarns under line load ``f`` (N/mm).

        Hertz line contact of two cylinders of radius dk/2 with the transverse modulus and ν
        (:func:`knitframe.yarn.fit.line_contact_approach`).
        """
        return line_contact_approach(f, self.radius, self.transverse_modulus, self.nu)

    def contact_load(self, delta: np.ndarray) -> np.ndarray:
        """Line load (N/mm) between two parallel yarns whose axes approach by ``delta`` (mm)."""
        return line_contact_load(delta, self.radius, self.transverse_modulus, self.nu)

    def contact_stiffness(self, f: np.ndarray) -> np.ndarray:
        """Tangent transverse contact stiffness per unit length df/dδ at line load ``f``, N/mm².

        From δ(f) = (4f/π)(1 - ν²)/E_T (ln(4R/b) - 1/2) with b ∝ √f:
        dδ/df = (4/π)(1 - ν²)/E_T (ln(4R/b) - 1).
        """
        return line_contact_stiffness(f, self.radius, self.transverse_modulus, self.nu)

    def energy(self, F: np.ndarray, fibre: np.ndarray | None = None) -> np.ndarray:
        """Strain energy density (...,), MPa."""
        return self.evaluate(F, fibre)[0]

    def stress(self, F: np.ndarray, fibre: np.ndarray | None = None) -> np.ndarray:
        """First Piola-Kirchhoff stress (..., 3, 3), MPa."""
        return self.evaluate(F, fibre)[1]

    def tangent(self, F: np.ndarray, fibre: np.ndarray | None = None) -> np.ndarray:
        """Tangent ∂P/∂F (..., 3, 3, 3, 3), MPa."""
        return self.evaluate(F, fibre)[2]

    def rod(self) -> dict[str, float]:
        """Rod stiffnesses EA (N), EI and GJ (N·mm²) and the yarn radius (mm)."""
        return {"EA": self.EA, "EI": self.EI, "GJ": self.GJ, "radius": self.radius}

    @classmethod
    def _common(cls, yarn: Yarn) -> dict[str, float]:
        return {
            "E_axial": yarn.E_axial,
            "radius": yarn.rk,
            "nu": yarn.nu,
            "bending_modulus": yarn.bending_stiffness,
        }


def compaction_barrier(
    F: np.ndarray, a: np.ndarray, c: float, E_core: float, order: int = 2
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Energy density, first Piola stress and tangent of the compaction barrier, MPa.

    The fibres of a yarn cannot pack denser than solid: its cross-section area ratio
    x = J/√I4 = det F / |F a| (area of the section across the fibre a over its natural area) stays
    above the compaction limit c. Below x₁ = (1 + c)/2 a barrier (the one of the rod's contact
    core, Li et al. 2020) stiffens the yarn::

        W_c = K B(x),  B(x) = −(x − x₁)² ln((x − c)/(x₁ − c))  for x_s ≤ x < x₁,  0 for x ≥ x₁
        B(x) = B(x_s) + B′(x_s)(x − x_s) + ½ B″(x_s)(x − x_s)²   for x < x_s = c + (x₁ − c)/20
        K = E_core / B″(x_m),  x_m = (c + x₁)/2            (the tangent d²W_c/dx² is E_core mid-band)
        ∂x/∂F = x M,  M = F⁻ᵀ − (F a ⊗ a)/I4
        P = K B′ x M
        A = K [(B″ x² + B′ x) M ⊗ M + B′ x ∂M/∂F],
        ∂M_iJ/∂F_kL = −F⁻¹_Jk F⁻¹_Li − δ_ik a_J a_L / I4 + 2 (F a)_i a_J (F a)_k a_L / I4²

    The quadratic below x_s (C², 69 E_core stiff) keeps every state admissible: a pre-stress step
    that grows the yarn's natural section around a section already at the limit starts from a
    finite energy and is pushed back, where a log barrier would make it inadmissible.

    Parameters
    ----------
    F : (..., 3, 3) deformation gradients; a : (..., 3) unit fibre directions.
    c : compaction limit in (0, 1); E_core : modulus of the packed core, MPa.
    """
    x1 = 0.5 * (1.0 + c)
    xs_ = c + 0.05 * (x1 - c)

    def B(x, k):
        r = (x - c) / (x1 - c)
        z, w = x - x1, x - c
        if k == 0:
            return -(z**2) * np.log(r)
        if k == 1:
            return -2.0 * z * np.log(r) - z**2 / w
        return -2.0 * np.log(r) - 4.0 * z / w + z**2 / w**2

    Bs = [B(xs_, k) for k in range(3)]

    def g(x, k):
        """B and its derivatives with the quadratic continuation below x_s (x < x₁)."""
        inner = x >= xs_
        xi = np.where(inner, x, xs_)
        d = x - xs_
        if k == 0:
            ext = Bs[0] + Bs[1] * d + 0.5 * Bs[2] * d * d
        elif k == 1:
            ext = Bs[1] + Bs[2] * d
        else:
            ext = np.full_like(x, Bs[2])
        return np.where(inner, B(xi, k), ext)

    K = E_core / B(0.5 * (c + x1), 2)
    Fa = np.einsum("...iJ,...J->...i", F, a)
    I4 = np.einsum("...i,...i->...", Fa, Fa)
    J = np.linalg.det(F)
    x = J / np.sqrt(I4)
    band = x < x1
    W = np.zeros(x.shape)
    W[band] = K * g(x[band], 0)
    if order < 1:
        return W, None, None
    P = np.zeros_like(F)
    A = np.zeros(F.shape + (3, 3)) if order >= 2 else None
    if not np.any(band):
        return W, P, A
    # only the points in the band carry the term: compute there and scatter
    Fb, ab, Fab, I4b, xb = F[band], a[band], Fa[band], I4[band], x[band]
    Finv = np.linalg.inv(Fb)
    M = np.swapaxes(Finv, -1, -2) - Fab[:, :, None] * ab[:, None, :] / I4b[:, None, None]
    b1 = K * g(xb, 1)
    P[band] = (b1 * xb)[:, None, None] * M
    if order < 2:
        return W, P, None
    b2 = K * g(xb, 2)
    dM = -np.einsum("pJk,pLi->piJkL", Finv, Finv)
    dM -= np.einsum("ik,pJ,pL->piJkL", np.eye(3), ab, ab) / I4b[:, None, None, None, None]
    aa = Fab[:, :, None] * ab[:, None, :]
    dM += 2.0 * aa[:, :, :, None, None] * aa[:, None, None, :, :] / (I4b**2)[:, None, None, None, None]
    A[band] = (b2 * xb**2 + b1 * xb)[:, None, None, None, None] * M[:, :, :, None, None] * M[
        :, None, None, :, :
    ] + (b1 * xb)[:, None, None, None, None] * dM
    return W, P, A
