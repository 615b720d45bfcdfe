"""Friction of the solid contact laws: the lagged, regularised Coulomb law.

The pairs in contact at the last converged state are frozen (:class:`FrictionState`) with
their normal force, normal and the master's material point, and the slip of each slave point
against that material point is resisted by a smooth potential whose force reaches μ·λ
(:func:`friction_potential`, :func:`friction_terms`). The rod contact law uses the same
potential.
"""

from __future__ import annotations

import attrs
import numpy as np

from knitframe.errors import NumericalError
from knitframe.numerics.contact._algebra import dot
from knitframe.numerics.periodic import Lattice

__all__ = ["FrictionState", "friction_potential", "friction_terms"]


@attrs.frozen(eq=False)
class FrictionState:
    """Contact pairs of the last converged state, frozen for the lagged friction of the next increment.

    A pair is a slave point (a node for ``penalty``, a quadrature point of a slave facet for
    ``mortar``) pressed with normal force λ against a master element at an image. The slave
    point's position and the master's material point under it are both linear in the nodes,
    c = Σ_a w_a p_a over the pair's points p_a = x_a (+ the image shift F̄·S_k on the master
    side), with weights ``weights``: the slave shape functions, then minus the master's at the
    frozen parametric point ``xi``. ``offset`` is c at the frozen state.
    """

    #: (m,) slave node (penalty) or slave facet (mortar)
    slave: np.ndarray
    #: (m,) quadrature point on the slave facet (mortar), −1 for a node
    point: np.ndarray
    #: (m,) master element: linear triangle, or facet on quadratic mortar surfaces
    master: np.ndarray
    #: (m, 2) integer image of the master element
    image: np.ndarray
    #: (m, 2) parametric point of the projection on the master element, -
    xi: np.ndarray
    #: (m,) normal force λ = ε·w·⟨−g⟩ of the pair at the frozen state, N
    force: np.ndarray
    #: (m, 3) unit master normal at the projection
    normal: np.ndarray
    #: (m,) reference size of the slave element, mm
    size: np.ndarray
    #: (m, k) nodes of the pair: slave side, then master side
    nodes: np.ndarray
    #: (m, k, 2) images of those nodes
    images: np.ndarray
    #: (m, k) c = Σ_a w_a p_a, slave point minus master material point
    weights: np.ndarray
    #: (m, 3) c at the frozen state, mm
    offset: np.ndarray

    def __len__(self) -> int:
        return int(self.force.shape[0])


def friction_potential(
    u: np.ndarray, mu_lam: np.ndarray, eps: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Regularised Coulomb potential D (m,), its gradient (m, 3) and Hessian (m, 3, 3) in the slip u (m, 3).

    With y = |u|/ε_s::

        D = μλ ε_s f0(y),   f0(y) = y² − y³/3 (y < 1),  y − 1/3 (y ≥ 1)
        ∇D = μλ φ(y) û,     φ(y) = 2y − y² (y < 1),  1 (y ≥ 1)

    so the friction force rises smoothly (C¹) from 0 with the stick stiffness 2μλ/ε_s and reaches
    the Coulomb force μλ at the slip ε_s. ``mu_lam`` (m,) is μλ (N) and ``eps`` (m,) ε_s (mm).
    D is convex in u; no division by |u| happens at zero slip.
    """
    n = np.linalg.norm(u, axis=1)
    y = n / eps
    stick = y < 1.0
    D = mu_lam * eps * np.where(stick, y**2 - y**3 / 3.0, y - 1.0 / 3.0)
    safe = np.where(n > 0, n, 1.0)
    uh = u / safe[:, None]
    coef = np.where(stick, mu_lam * (2.0 - y) / eps, mu_lam / safe)
    g = coef[:, None] * u
    eye = np.eye(3)
    uu = uh[:, :, None] * uh[:, None, :]
    H_stick = (mu_lam / eps)[:, None, None] * ((2.0 - y)[:, None, None] * eye - y[:, None, None] * uu)
    H_slip = (mu_lam / safe)[:, None, None] * (eye - uu)
    return D, g, np.where(stick[:, None, None], H_stick, H_slip)


def friction_terms(
    state: FrictionState,
    x: np.ndarray,
    h: np.ndarray | None,
    lattice: Lattice | None,
    mu: float,
    slip: float,
    order: int,
) -> tuple[float, np.ndarray | None, np.ndarray | None, dict]:
    """Lagged regularised Coulomb friction of frozen pairs: energy, element gradients and Hessians.

    For each pair the relative position c = Σ_a w_a p_a of the slave point and the master's
    material point (at the frozen parametric point, with the current image shift F̄·S_k) has
    slipped by c − c₀ since the frozen state; its tangential part with respect to the frozen
    normal n is u_T = (I − n nᵀ)(c − c₀), and::

        D = Σ_pairs μ λ ε_s f0(|u_T| / ε_s),       ε_s = slip · ℓ

    (:func:`friction_potential`, ℓ the pair's element ``size``). c is linear in the nodes, so
    ∂D/∂p_a = w_a P ∇D and ∂²D/∂p_a∂p_b = w_a w_b P ∇²D P, exactly. Returns E (N·mm), grad
    (m, k, 3), hess (m, k, 3, k, 3) and {"slipping": pairs past ε_s, "force": Σ|∇D| N}.
    """
    p = x[state.nodes]
    if lattice is not None:
        p = p + lattice.shift(state.images, np.zeros(6) if h is None else h)
    c = np.einsum("mk,mki->mi", state.weights, p)
    nrm = state.normal
    d = c - state.offset
    u = d - dot(d, nrm)[:, None] * nrm
    eps = slip * state.size
    D, gu, Hu = friction_potential(u, mu * state.force, eps)
    E = float(np.sum(D))
    if not np.isfinite(E):
        raise NumericalError("solid contact: non-finite friction energy")
    gc = gu - dot(gu, nrm)[:, None] * nrm  # P ∇D
    info = {
        "slipping": int(np.count_nonzero(np.linalg.norm(u, axis=1) >= eps)),
        "friction_force": float(np.sum(np.linalg.norm(gc, axis=1))),
    }
    if order == 0:
        return E, None, None, info
    w = state.weights
    grad = w[:, :, None] * gc[:, None, :]
    if order == 1:
        return E, grad, None, info
    P = np.eye(3)[None] - nrm[:, :, None] * nrm[:, None, :]
    Hc = P @ Hu @ P
    ww = w[:, :, None] * w[:, None, :]
    hess = ww[:, :, None, :, None] * Hc[:, None, :, None, :]
    return E, grad, hess, info
