"""Discrete elastic rod energies per element, with analytic gradients and Hessians (vectorised).

Each function takes element point positions and returns the energy per element (m,), the
gradient with respect to the points (m, k, 3) and the Hessian (m, k, 3, k, 3); the caller scatters
them with :class:`knitframe.periodic.PointMap`.

Stretching (edge x0–x1, rest length l0, axial stiffness EA in N)::

    E = ½ EA l0 (l/l0 − 1)²,   l = |x1 − x0|

Bending (vertex x1 between edges a = x1 − x0 and b = x2 − x1, bending stiffness EI in N·mm²,
Voronoi length l̄ = (l0_a + l0_b)/2)::

    E = EI/(2 l̄) (|κb| − κ0)²,   κb = 2 a×b / (|a||b| + a·b),   |κb| = 2 √((1 − c)/(1 + c)),  c = â·b̂

which is EI φ²/(2 l̄) for a small turning angle φ and a straight rest shape (κ0 = 0), the
discrete ½∫EI κ² ds (Bergou et al. 2008). Twist is not modelled: a yarn of circular section with
a straight, untwisted rest state has no bending–twist coupling, so the centerline alone carries
the stretching and bending energy. A rest curvature magnitude κ0 > 0 is used only on the way
there (the rod solver's pre-stress releases the knitted curvature to straight); without twist
it constrains how much a vertex bends, not in which direction.
"""

from __future__ import annotations

import numpy as np

__all__ = ["stretch", "bend"]


def stretch(p: np.ndarray, l0: np.ndarray, EA: np.ndarray | float, order: int = 2):
    """Axial energy of edges.

    Parameters
    ----------
    p : (m, 2, 3) edge end points, mm
    l0 : (m,) rest lengths, mm
    EA : float or (m,) axial stiffness, N
    order : 0 energy, 1 + gradient, 2 + Hessian

    Returns
    -------
    E (m,) N·mm, g (m, 2, 3) N, H (m, 2, 3, 2, 3) N/mm (None when not asked)
    """
    e = p[:, 1] - p[:, 0]
    l = np.linalg.norm(e, axis=1)
    strain = l / l0 - 1.0
    E = 0.5 * EA * l0 * strain**2
    if order == 0:
        return E, None, None
    t = e / l[:, None]
    f = (EA * strain)[:, None] * t  # dE/de
    g = np.stack([-f, f], axis=1)
    if order == 1:
        return E, g, None
    ka = np.broadcast_to(EA / l0, l.shape)
    tt = t[:, :, None] * t[:, None, :]
    He = ka[:, None, None] * tt + (EA * strain / l)[:, None, None] * (np.eye(3) - tt)
    H = np.empty((len(l), 2, 3, 2, 3))
    H[:, 0, :, 0, :] = He
    H[:, 1, :, 1, :] = He
    H[:, 0, :, 1, :] = -He
    H[:, 1, :, 0, :] = -He
    return E, g, H


def bend(p: np.ndarray, lbar: np.ndarray, EI: np.ndarray | float, order: int = 2, kappa0: np.ndarray | None = None):
    """Bending energy of vertex triplets.

    Parameters
    ----------
    p : (m, 3, 3) points x0, x1, x2, mm
    lbar : (m,) Voronoi length (l0_a + l0_b)/2, mm
    EI : float or (m,) bending stiffness, N·mm²
    kappa0 : (m,) rest curvature magnitude |κb|, - (None: straight rest shape)

    Returns
    -------
    E (m,) N·mm, g (m, 3, 3) N, H (m, 3, 3, 3, 3) N/mm (None when not asked)

    Notes
    -----
    In c = â·b̂, with f = (1 − c)/(1 + c) and u = |κb| = 2√f: E = K (u − κ0)², K = EI/(2 l̄);
    E′ = 2K (u − κ0) u′, E″ = 2K (u′² + (u − κ0) u″), u′ = f′/√f, u″ = f″/√f − f′²/(2 f^{3/2}),
    f′ = −2/(1 + c)², f″ = 4/(1 + c)³ (for κ0 = 0: E = 4K f). ∇_a c = P_a b̂/|a| with
    P_a = I − â âᵀ, ∇²_aa c = (3c ââᵀ − âb̂ᵀ − b̂âᵀ − c I)/|a|², ∇²_ab c = P_a P_b/(|a||b|). A
    fold-back (c → −1) has infinite energy.
    """
    a = p[:, 1] - p[:, 0]
    b = p[:, 2] - p[:, 1]
    la = np.linalg.norm(a, axis=1)
    lb = np.linalg.norm(b, axis=1)
    ah = a / la[:, None]
    bh = b / lb[:, None]
    c = np.einsum("ij,ij->i", ah, bh)
    K = 0.5 * EI / lbar
    opc = 1.0 + c
    with np.errstate(divide="ignore", invalid="ignore"):
        f = (1.0 - c) / opc
    rest = kappa0 is not None and np.any(kappa0 != 0)
    if rest:
        sf = np.sqrt(np.maximum(f, 1e-30))
        u = 2.0 * sf
        E = K * (u - kappa0) ** 2
    else:
        E = 4.0 * K * f
    E = np.where(c > -1.0, E, np.inf)
    if order == 0:
        return E, None, None
    fp = -2.0 / opc**2
    fpp = 4.0 / opc**3
    if rest:
        up = fp / sf
        upp = fpp / sf - fp**2 / (2.0 * sf**3)
        f1 = 2.0 * K * (u - kappa0) * up
        f2 = 2.0 * K * (up**2 + (u - kappa0) * upp)
    else:
        f1, f2 = 4.0 * K * fp, 4.0 * K * fpp
    ga = (bh - c[:, None] * ah) / la[:, None]  # ∇_a c
    gb = (ah - c[:, None] * bh) / lb[:, None]  # ∇_b c
    Ga, Gb = f1[:, None] * ga, f1[:, None] * gb
    g = np.stack([-Ga, Ga - Gb, Gb], axis=1)
    if order == 1:
        return E, g, None
    eye = np.eye(3)
    aa = ah[:, :, None] * ah[:, None, :]
    bb = bh[:, :, None] * bh[:, None, :]
    ab = ah[:, :, None] * bh[:, None, :]
    ba = np.swapaxes(ab, 1, 2)
    cc = c[:, None, None]
    Haa = (3 * cc * aa - ab - ba - cc * eye) / (la**2)[:, None, None]
    Hbb = (3 * cc * bb - ba - ab - cc * eye) / (lb**2)[:, None, None]
    Hab = np.einsum("mij,mjk->mik", eye - aa, eye - bb) / (la * lb)[:, None, None]
    f1_ = f1[:, None, None]
    f2_ = f2[:, None, None]
    Eaa = f2_ * ga[:, :, None] * ga[:, None, :] + f1_ * Haa
    Ebb = f2_ * gb[:, :, None] * gb[:, None, :] + f1_ * Hbb
    Eab = f2_ * ga[:, :, None] * gb[:, None, :] + f1_ * Hab
    Eba = np.swapaxes(Eab, 1, 2)
    # a = x1 − x0, b = x2 − x1: d(a, b)/d(x0, x1, x2) = [[−I, I, 0], [0, −I, I]]
    H = np.empty((len(c), 3, 3, 3, 3))
    H[:, 0, :, 0, :] = Eaa
    H[:, 0, :, 1, :] = -Eaa + Eab
    H[:, 0, :, 2, :] = -Eab
    H[:, 1, :, 0, :] = -Eaa + Eba
    H[:, 1, :, 1, :] = Eaa - Eab - Eba + Ebb
    H[:, 1, :, 2, :] = Eab - Ebb
    H[:, 2, :, 0, :] = -Eba
    H[:, 2, :, 1, :] = Eba - Ebb
    H[:, 2, :, 2, :] = Ebb
    return E, g, H
