"""Discrete elastic rod energies per element, with analytic gradients and Hessians (vectorised).

Each function takes element point positions and returns the energy per element (m,), the
gradient with respect to the points (m, k, 3) and the Hessian (m, k, 3, k, 3); the caller scatters
them with :class:`knitframe.numerics.periodic.PointMap`.

Stretching (edge x0–x1, rest length l0, axial stiffness EA in N)::

    E = ½ EA l0 (l/l0 − 1)²,   l = |x1 − x0|

Bending (vertex x1 between edges a = x1 − x0 and b = x2 − x1, bending stiffness EI in N·mm²,
Voronoi length l̄ = (l0_a + l0_b)/2)::

    E = EI/(2 l̄) |κb|²,   κb = 2 a×b / (|a||b| + a·b),   |κb|² = 4 (1 − c)/(1 + c),  c = â·b̂

which is EI φ²/(2 l̄) for a small turning angle φ: the discrete ½∫EI κ² ds of a straight rest
shape (Bergou et al. 2008). Twist is not modelled: a yarn of circular section with a straight,
untwisted rest state has no bending–twist coupling, so the centerline alone carries the
stretching and bending energy.

A rest curvature κ0 (the rod solver's pre-stress starts from the knitted shape and releases it
to straight) enters as E = EI/(2 l̄) (v − v0)², v = √(|κb|² + ε²), v0 = √(κ0² + ε²), ε = 0.05:
≈ (|κb| − κ0)² but smooth through a straight vertex, where |κb| itself has a cone. Without
twist it constrains how much a vertex bends, not in which direction.

Shear-deformable rods (:func:`shear`, :func:`director_bend`, :func:`director_norm`) give every edge a
director d, the normal of its cross-section, as its own unknown. The section then bends between
the directors of consecutive edges and shears where d leaves the edge's tangent ê::

    E_bend = EI/(2 l̄) |κb(d_a, d_b)|²,   E_shear = 2 κGA l0 tan²(γ/2) ≈ ½ κGA l0 γ²,
    E_norm = (κGA l0 + EI/l0) (|d|² − 1)² / 8

γ the shear angle, tan²(γ/2) = (1 − c)/(1 + c) with c = ê·d̂: like the bending measure, it grows
without bound as γ → π, so a director cannot turn over. The first two depend on d only through its
direction; the third fixes its length (it is zero at |d| = 1, and as stiff along d as the other
two are across it). This is a torsion-free Timoshenko–Reissner rod: with d = ê it is the rod
above, and for a small load of wave number k it is as stiff as EI/(1 + EI k²/κGA), whatever k.
"""

from __future__ import annotations

import numpy as np

__all__ = ["stretch", "bend", "director_bend", "shear", "director_norm", "REST_EPS"]

#: smoothing of the rest-curvature energy at a straight vertex (|κb| is 2 tan(φ/2), dimensionless)
REST_EPS = 0.05


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


def bend(
    p: np.ndarray, lbar: np.ndarray, EI: np.ndarray | float, order: int = 2, kappa0: np.ndarray | None = None
):
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
    In c = â·b̂, with f = (1 − c)/(1 + c), K = EI/(2 l̄): E = 4K f (straight rest shape), or with
    v = √(4f + ε²): E = K (v − v0)², E′ = 2K (v − v0) v′, E″ = 2K (v′² + (v − v0) v″),
    v′ = 2f′/v, v″ = 2f″/v − 4f′²/v³; f′ = −2/(1 + c)², f″ = 4/(1 + c)³. ∇_a c = P_a b̂/|a| with
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
    rest = kappa0 is not None
    if rest:
        v = np.sqrt(4.0 * np.maximum(f, 0.0) + REST_EPS**2)
        v0 = np.sqrt(np.asarray(kappa0) ** 2 + REST_EPS**2)
        E = K * (v - v0) ** 2
    else:
        E = 4.0 * K * f
    E = np.where(c > -1.0, E, np.inf)
    if order == 0:
        return E, None, None
    fp = -2.0 / opc**2
    fpp = 4.0 / opc**3
    if rest:
        vp = 2.0 * fp / v
        vpp = 2.0 * fpp / v - 4.0 * fp**2 / v**3
        f1 = 2.0 * K * (v - v0) * vp
        f2 = 2.0 * K * (vp**2 + (v - v0) * vpp)
    else:
        f1, f2 = 4.0 * K * fp, 4.0 * K * fpp
    ga = (bh - c[:, None] * ah) / la[:, None]  # ∇_a c
    gb = (ah - c[:, None] * bh) / lb[:, None]  # ∇_b c
    Ga, Gb = f1[:, None] * ga, f1[:, None] * gb
    g = np.stack([-Ga, Ga - Gb, Gb], axis=1)
    if order == 1:
        return E, g, None
    return E, g, _bend_hessian(ah, bh, c, la, lb, ga, gb, f1, f2)


def _bend_hessian(
    ah: np.ndarray,
    bh: np.ndarray,
    c: np.ndarray,
    la: np.ndarray,
    lb: np.ndarray,
    ga: np.ndarray,
    gb: np.ndarray,
    f1: np.ndarray,
    f2: np.ndarray,
) -> np.ndarray:
    """Hessian (m, 3, 3, 3, 3) of the bending energy E(c) with respect to x0, x1, x2.

    ``ah``, ``bh`` (m, 3) are the unit edges, ``la``, ``lb`` (m,) their lengths, ``ga``, ``gb``
    (m, 3) the gradients ∇_a c, ∇_b c, and ``f1``, ``f2`` (m,) E′ and E″ in c (see :func:`bend`):
    ∇²_aa E = E″ ∇_a c ∇_a cᵀ + E′ ∇²_aa c, likewise for bb and ab, then mapped to the points.
    """
    Eaa, Ebb, Eab = _chain_in_c(ah, bh, c, la, lb, ga, gb, f1, f2)
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
    return H


def _cos_hessian(ah: np.ndarray, bh: np.ndarray, c: np.ndarray, la: np.ndarray, lb: np.ndarray):
    """Second derivatives ∇²_aa c, ∇²_bb c, ∇²_ab c (m, 3, 3) of c = â·b̂ (see :func:`bend`)."""
    eye = np.eye(3)
    aa = ah[:, :, None] * ah[:, None, :]
    bb = bh[:, :, None] * bh[:, None, :]
    ab = ah[:, :, None] * bh[:, None, :]
    ba = np.swapaxes(ab, 1, 2)
    cc = c[:, None, None]
    Haa = (3 * cc * aa - ab - ba - cc * eye) / (la**2)[:, None, None]
    Hbb = (3 * cc * bb - ba - ab - cc * eye) / (lb**2)[:, None, None]
    Hab = np.einsum("mij,mjk->mik", eye - aa, eye - bb) / (la * lb)[:, None, None]
    return Haa, Hbb, Hab


def _chain_in_c(ah, bh, c, la, lb, ga, gb, f1, f2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """∇²_aa E, ∇²_bb E, ∇²_ab E (m, 3, 3) of an energy E(c), c = â·b̂, with E′ = f1 and E″ = f2 (m,):
    ∇²_aa E = E″ ∇_a c ∇_a cᵀ + E′ ∇²_aa c, likewise for bb and ab (``ga``, ``gb`` = ∇_a c, ∇_b c)."""
    Caa, Cbb, Cab = _cos_hessian(ah, bh, c, la, lb)
    f1_, f2_ = f1[:, None, None], f2[:, None, None]
    return (
        f2_ * ga[:, :, None] * ga[:, None, :] + f1_ * Caa,
        f2_ * gb[:, :, None] * gb[:, None, :] + f1_ * Cbb,
        f2_ * ga[:, :, None] * gb[:, None, :] + f1_ * Cab,
    )


def director_bend(
    d: np.ndarray, lbar: np.ndarray, EI: np.ndarray | float, order: int = 2, kappa0: np.ndarray | None = None
):
    """Bending energy between the directors d_a, d_b (m, 2, 3) of consecutive edges.

    The energy of :func:`bend` with the edges a, b replaced by the directors (it depends on their
    directions only). Returns E (m,), g (m, 2, 3), H (m, 2, 3, 2, 3).
    """
    m = len(d)
    p = np.stack([np.zeros((m, 3)), d[:, 0], d[:, 0] + d[:, 1]], axis=1)
    E, gp, Hp = bend(p, lbar, EI, order, kappa0)
    if order == 0:
        return E, None, None
    # a = p1 − p0 = d_a, b = p2 − p1 = d_b: ∂E/∂a = −∂E/∂p0, ∂E/∂b = ∂E/∂p2
    g = np.stack([-gp[:, 0], gp[:, 2]], axis=1)
    if order == 1:
        return E, g, None
    H = np.empty((m, 2, 3, 2, 3))
    H[:, 0, :, 0, :] = Hp[:, 0, :, 0, :]
    H[:, 0, :, 1, :] = -Hp[:, 0, :, 2, :]
    H[:, 1, :, 0, :] = -Hp[:, 2, :, 0, :]
    H[:, 1, :, 1, :] = Hp[:, 2, :, 2, :]
    return E, g, H


def shear(p: np.ndarray, l0: np.ndarray, GA: np.ndarray | float, order: int = 2):
    """Shear energy of edges x0–x1 with director d: E = 2 κGA l0 (1 − c)/(1 + c), c = ê·d̂.

    Parameters
    ----------
    p : (m, 3, 3) points x0, x1 and the director d
    l0 : (m,) rest lengths, mm
    GA : float or (m,) shear stiffness κ G_A A, N

    Returns
    -------
    E (m,) N·mm, g (m, 3, 3) N, H (m, 3, 3, 3, 3) N/mm (None when not asked)
    """
    a = p[:, 1] - p[:, 0]
    b = p[:, 2]
    la = np.linalg.norm(a, axis=1)
    lb = np.linalg.norm(b, axis=1)
    ah, bh = a / la[:, None], b / lb[:, None]
    c = np.einsum("ij,ij->i", ah, bh)
    K = 2.0 * np.broadcast_to(GA * l0, c.shape)
    opc = 1.0 + c
    with np.errstate(divide="ignore", invalid="ignore"):
        E = np.where(c > -1.0, K * (1.0 - c) / opc, np.inf)
    if order == 0:
        return E, None, None
    f1, f2 = -2.0 * K / opc**2, 4.0 * K / opc**3  # dE/dc, d²E/dc²
    ga = (bh - c[:, None] * ah) / la[:, None]
    gb = (ah - c[:, None] * bh) / lb[:, None]
    Ga, Gb = f1[:, None] * ga, f1[:, None] * gb
    g = np.stack([-Ga, Ga, Gb], axis=1)
    if order == 1:
        return E, g, None
    Haa, Hbb, Hab = _chain_in_c(ah, bh, c, la, lb, ga, gb, f1, f2)
    Hba = np.swapaxes(Hab, 1, 2)
    # a = x1 − x0, b = d
    H = np.empty((len(c), 3, 3, 3, 3))
    H[:, 0, :, 0, :] = Haa
    H[:, 0, :, 1, :] = -Haa
    H[:, 1, :, 0, :] = -Haa
    H[:, 1, :, 1, :] = Haa
    H[:, 0, :, 2, :] = -Hab
    H[:, 1, :, 2, :] = Hab
    H[:, 2, :, 0, :] = -Hba
    H[:, 2, :, 1, :] = Hba
    H[:, 2, :, 2, :] = Hbb
    return E, g, H


def director_norm(d: np.ndarray, K: np.ndarray | float, order: int = 2):
    """Energy K (|d|² − 1)²/8 fixing the length of directors d (m, 1, 3); K in N·mm.

    Returns E (m,), g (m, 1, 3), H (m, 1, 3, 1, 3).
    """
    v = d[:, 0]
    s = np.einsum("ij,ij->i", v, v) - 1.0
    K = np.broadcast_to(K, s.shape)
    E = K * s**2 / 8.0
    if order == 0:
        return E, None, None
    g = (0.5 * K * s)[:, None] * v
    if order == 1:
        return E, g[:, None, :], None
    H = 0.5 * K[:, None, None] * (s[:, None, None] * np.eye(3) + 2.0 * v[:, :, None] * v[:, None, :])
    return E, g[:, None, :], H[:, None, :, None, :]
