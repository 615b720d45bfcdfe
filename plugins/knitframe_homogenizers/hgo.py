r"""Homogenizer ``hgo``: the paper's one-fibre reduced fabric model (du Pasquier et al., Eq. 1–3).

.. math::

    \psi = \frac{a}{b}\left[e^{b (I_4 - 1)^2} - 1\right], \qquad
    I_4 = \lambda_1^2 \cos^2\theta + \lambda_2^2 \sin^2\theta, \qquad
    P_\alpha = \frac{\partial \psi}{\partial \lambda_\alpha}
             = 2a (I_4 - 1) e^{b (I_4 - 1)^2} \frac{\partial I_4}{\partial \lambda_\alpha}

with ``a`` in N/mm (energy per unit reference area), ``b`` dimensionless and the fibre angle θ in
radians from the course. P1, P2 are tensions per unit reference width (N/mm).

Overflow. ``exp(z)`` with ``z = b (I4 − 1)²`` overflows float64 at z ≈ 709 (b = 100 at 100 %
stretch gives z = 900), and squared residuals overflow long before that. Above ``Z_CAP = 200`` the
exponential is continued by its second-order Taylor polynomial,
``E(z) = e^{Zc} (1 + d + d²/2)`` with ``d = z − Zc``. E is C², increasing and convex, so energy,
stresses, tangents and parameter derivatives stay finite, consistent with each other (the stress is
still exactly ∂ψ/∂λ of the capped energy) and monotone: a parameter set that far out simply gets
a huge but finite stress, which a fitter sees as a steep penalty. No fabric reaches z = 200 with
a meaningful ``a`` (e^200 ≈ 7e86), so the cap never changes a physically relevant value.

The b → 0 limit is evaluated without cancellation through ``Φ(z) = (E(z) − 1)/z`` (series near 0):
``ψ = a x² Φ(b x²)`` with ``x = I4 − 1``, which tends to ``a (I4 − 1)²``.

Exports: :meth:`HGO.card` writes the cards of ``knitframe export`` and of the ``[fit]`` option
``export`` (ABAQUS, CalculiX, a CalculiX check deck, FEBio; see
:mod:`knitframe_homogenizers.cards`) from the parameters as stored in params.json (θ in degrees).
The older :meth:`HGO.abaqus` (an ABAQUS ``*ANISOTROPIC HYPERELASTIC, HOLZAPFEL`` card, k1 = 2a,
k2 = b, κ = 0, D = 0) and :meth:`HGO.febio` (an FEBio ``solid mixture`` with a ``fiber-exp-pow``
fibre, ξ = 2a, α = b, β = 2) take θ in radians, like every other method here; both state where the
host model differs.
"""

from __future__ import annotations

import math
import warnings
from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe.errors import KnitframeWarning
from knitframe.fitting import direction_index, free_side_zero_message, solve_free_side

__all__ = ["HGO", "Z_CAP", "capped_exp", "fibre_terms", "fibre_gh", "abaqus_card", "febio_block"]

#: Exponent above which exp(z) is continued by its second-order Taylor polynomial (see module doc).
Z_CAP = 200.0
_E_CAP = math.exp(Z_CAP)


def capped_exp(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r"""Capped exponential E(z) and the functions the fibre term needs, for z >= 0.

    Returns ``(E − 1, E', E'', Φ, Φ')`` with ``Φ(z) = (E(z) − 1)/z`` (Φ(0) = 1), all of the shape of
    ``z``. Below :data:`Z_CAP`, E = exp; above, E = e^{Zc}(1 + d + d²/2), d = z − Zc.
    """
    z = np.asarray(z, dtype=np.float64)
    zl = np.minimum(z, Z_CAP)
    d = z - zl
    ez = np.exp(zl)
    em1 = np.where(d > 0, ez * (1.0 + d + 0.5 * d * d) - 1.0, np.expm1(zl))
    e1 = ez * (1.0 + d)
    e2 = ez
    small = z < 1e-3
    zs = np.where(small, 1.0, z)  # dummy value where the series is used: no 0/0
    phi = np.where(small, 1.0 + z / 2 + z * z / 6 + z**3 / 24, em1 / zs)
    dphi = np.where(small, 0.5 + z / 3 + z * z / 8 + z**3 / 30, (zs * e1 - em1) / (zs * zs))
    return em1, e1, e2, phi, dphi


def fibre_terms(a: float, b: float, i4: np.ndarray, compression: bool) -> dict[str, np.ndarray]:
    r"""Energy of one exponential fibre family and its derivatives with respect to I4, a and b.

    ``ψ = a x² Φ(b x²)`` with ``x = I4 − 1`` (or ``max(x, 0)`` when the fibre carries no
    compression). Keys: ``psi`` (N/mm), ``g = ∂ψ/∂I4``, ``h = ∂²ψ/∂I4²``, ``psi_a``, ``psi_b``,
    ``g_a``, ``g_b`` (derivatives of ψ and g by a and b). Arrays have the shape of ``i4``.
    """
    x = np.asarray(i4, dtype=np.float64) - 1.0
    active = np.ones(x.shape, dtype=bool) if compression else x > 0
    x = np.where(active, x, 0.0)
    x2 = x * x
    z = b * x2
    em1, e1, e2, phi, dphi = capped_exp(z)
    return {
        "psi": a * x2 * phi,
        "g": 2.0 * a * x * e1,
        "h": np.where(active, 2.0 * a * (e1 + 2.0 * z * e2), 0.0),
        "psi_a": x2 * phi,
        "psi_b": a * x2 * x2 * dphi,
        "g_a": 2.0 * x * e1,
        "g_b": 2.0 * a * x * x2 * e2,
    }


def fibre_gh(a: float, b: float, i4: np.ndarray, compression: bool, second: bool = True):
    """``g = ∂ψ/∂I4`` and (if ``second``) ``h = ∂²ψ/∂I4²`` only: the cheap path of :func:`fibre_terms`."""
    x = i4 - 1.0
    if not compression:
        x = np.maximum(x, 0.0)
    z = b * x * x
    zl = np.minimum(z, Z_CAP)
    ez = np.exp(zl)
    e1 = ez * (1.0 + (z - zl))
    g = 2.0 * a * x * e1
    if not second:
        return g, None
    return g, 2.0 * a * (e1 + 2.0 * z * ez) * (True if compression else i4 > 1.0)


def fibre_stress(a: float, b: float, theta: float, lam1: np.ndarray, lam2: np.ndarray, compression: bool):
    """Fibre tensions only (the path used for throughput): ``P = g ∂I4/∂λ``, N/mm."""
    c2, s2 = math.cos(theta) ** 2, math.sin(theta) ** 2
    g, _ = fibre_gh(a, b, lam1 * lam1 * c2 + lam2 * lam2 * s2, compression, second=False)
    return 2.0 * g * lam1 * c2, 2.0 * g * lam2 * s2


def fibre_kinematics(theta: float, lam1: np.ndarray, lam2: np.ndarray) -> dict[str, np.ndarray | float]:
    """I4 and its derivatives by λ1, λ2 and θ for a fibre at angle θ from the course."""
    c, s = math.cos(theta), math.sin(theta)
    s2t = math.sin(2.0 * theta)
    return {
        "i4": lam1 * lam1 * c * c + lam2 * lam2 * s * s,
        "d1": 2.0 * lam1 * c * c,  # ∂I4/∂λ1
        "d2": 2.0 * lam2 * s * s,  # ∂I4/∂λ2
        "dt": (lam2 * lam2 - lam1 * lam1) * s2t,  # ∂I4/∂θ
        "d1t": -2.0 * lam1 * s2t,  # ∂²I4/∂λ1∂θ
        "d2t": 2.0 * lam2 * s2t,  # ∂²I4/∂λ2∂θ
        "c2": c * c,
        "s2": s * s,
    }


def fibre_stress_grad(a, b, theta, lam1, lam2, compression):
    """Fibre P1, P2 and their derivatives by (a, b, θ): ``(P1, P2, dP1 (n, 3), dP2 (n, 3))``."""
    k = fibre_kinematics(theta, lam1, lam2)
    f = fibre_terms(a, b, k["i4"], compression)
    g, h = f["g"], f["h"]
    dP1 = np.stack([f["g_a"] * k["d1"], f["g_b"] * k["d1"], h * k["dt"] * k["d1"] + g * k["d1t"]], axis=-1)
    dP2 = np.stack([f["g_a"] * k["d2"], f["g_b"] * k["d2"], h * k["dt"] * k["d2"] + g * k["d2t"]], axis=-1)
    return g * k["d1"], g * k["d2"], dP1, dP2


def as_stretch(lam1, lam2) -> tuple[np.ndarray, np.ndarray]:
    """Broadcast stretches to float64 arrays; non-finite or non-positive values raise ValueError."""
    l1, l2 = np.broadcast_arrays(np.asarray(lam1, dtype=np.float64), np.asarray(lam2, dtype=np.float64))
    if not (np.isfinite(l1).all() and np.isfinite(l2).all()) or (l1 <= 0).any() or (l2 <= 0).any():
        raise ValueError("stretches must be finite and > 0")
    return l1, l2


def _fmt(x: float) -> str:
    return f"{x:.10g}"


def abaqus_card(name: str, c10: float, d: float, k1: float, k2: float, theta: float, notes: list[str]) -> str:
    """ABAQUS material + orientation with one Holzapfel fibre family at θ (radians) in local axes 1-2.

    Data line ``C10, D, k1, k2, kappa`` with κ = 0; the orientation's local direction 1 is the
    course, the extra data line gives the fibre direction ``cos θ, sin θ, 0``. ``notes`` become
    ``**`` comment lines at the top.
    """
    lines = [f"** {n}" for n in notes]
    lines += [
        f"*MATERIAL, NAME={name}",
        "*ANISOTROPIC HYPERELASTIC, HOLZAPFEL, LOCAL DIRECTIONS=1",
        ", ".join(_fmt(v) for v in (c10, d, k1, k2, 0.0)),
        f"*ORIENTATION, NAME=ORI-{name}, LOCAL DIRECTIONS=1",
        "1., 0., 0., 0., 1., 0.",
        "3, 0.",
        ", ".join(_fmt(v) for v in (math.cos(theta), math.sin(theta), 0.0)),
    ]
    return "\n".join(lines) + "\n"


def febio_block(
    name: str, matrix_E: float, matrix_v: float, fibres: list[tuple[float, float, float]], notes: list[str]
) -> str:
    """FEBio ``<material type="solid mixture">``: neo-Hookean matrix plus ``fiber-exp-pow`` fibres.

    ``fibres`` holds ``(ξ, α, θ)`` per family: ``Ψ = ξ/(α β)(exp[α (I_n − 1)^β] − 1)`` with β = 2,
    the fibre in the 1-2 plane at θ (radians; written in degrees, ``phi = 90``) from axis 1.
    ``notes`` become an XML comment.
    """
    import xml.etree.ElementTree as ET

    mat = ET.Element("material", id="1", name=name, type="solid mixture")
    mat.append(ET.Comment(" " + " ".join(notes).replace("--", "-") + " "))
    ET.SubElement(mat, "mat_axis", type="vector")
    mat[-1].append(_el("a", "1,0,0"))
    mat[-1].append(_el("d", "0,1,0"))
    solid = ET.SubElement(mat, "solid", type="neo-Hookean")
    solid.append(_el("E", _fmt(matrix_E)))
    solid.append(_el("v", _fmt(matrix_v)))
    for ksi, alpha, theta in fibres:
        fibre = ET.SubElement(mat, "solid", type="fiber-exp-pow")
        for tag, val in (("ksi", ksi), ("alpha", alpha), ("beta", 2.0)):
            fibre.append(_el(tag, _fmt(val)))
        axis = ET.SubElement(fibre, "fiber", type="angles")
        axis.append(_el("theta", _fmt(math.degrees(theta))))
        axis.append(_el("phi", "90"))
    ET.indent(mat)
    return ET.tostring(mat, encoding="unicode") + "\n"


def _el(tag: str, text: str):
    import xml.etree.ElementTree as ET

    e = ET.Element(tag)
    e.text = text
    return e


#: Differences between this model and the hosts' Holzapfel/fibre laws, written into every export.
HOST_NOTES = (
    "ABAQUS and FEBio drop the fibre stress in compression (I4 < 1); knitframe's hgo keeps it unless "
    "compression_fibre = false.",
    "The hosts use isochoric invariants (I4bar = J^(-2/3) I4) and need an isotropic matrix term (C10, D "
    "/ neo-Hookean E, v); the fabric model has none, so a small matrix is added that barely changes the "
    "tension-stretch curve.",
    "knitframe energies are per unit reference area (N/mm); the card holds them per unit volume for a shell "
    "of the given thickness (k1 = 2a/t, so k1 = 2a at t = 1 mm).",
)


@attrs.frozen
class HGO:
    """Paper model: one exponential fibre family at θ, parameters (a N/mm, b -, θ rad)."""

    name: ClassVar[str] = "hgo"
    description: ClassVar[str] = "paper's reduced model: one exponential fibre at angle theta (a, b, theta)"
    param_names: ClassVar[tuple[str, ...]] = ("a", "b", "theta")
    units: ClassVar[tuple[str, ...]] = ("N/mm", "-", "rad")
    #: optimise these parameters on a log scale
    log_scale: ClassVar[tuple[bool, ...]] = (True, True, False)
    #: a free side's stretch is taken from the data, not predicted (P2 = 0 forces I4 = 1)
    predicts_lateral: ClassVar[bool] = False
    #: bounds that are symmetry planes (I4 is even about θ = 0 and θ = π/2): a fit ending there is not cut off
    symmetric_bounds: ClassVar[tuple[bool, ...]] = (False, False, True)

    #: formats :meth:`card` writes (see :mod:`knitframe.export`)
    card_formats: ClassVar[tuple[str, ...]] = ("abaqus", "calculix", "calculix-deck", "febio")
    #: every format of :mod:`knitframe.export` can hold the model: nothing to refuse
    card_refusal: ClassVar[str] = ""

    #: keep the fibre stress for I4 < 1 (paper); false drops it
    compression_fibre: bool = True

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Parameter box used by the fitters: a in [1e-6, 1e2] N/mm, b in [1e-4, 1e3], θ in [0, π/2]."""
        return np.array([1e-6, 1e-4, 0.0]), np.array([1e2, 1e3, 0.5 * math.pi])

    def x0(self) -> np.ndarray:
        """Default parameters: a = 0.1 N/mm, b = 1, θ = 45°."""
        return np.array([0.1, 1.0, 0.25 * math.pi])

    def energy(self, params, lam1, lam2) -> np.ndarray:
        """ψ(λ1, λ2), N/mm; arrays of any broadcastable shape."""
        a, b, theta = params
        l1, l2 = as_stretch(lam1, lam2)
        return fibre_terms(a, b, fibre_kinematics(theta, l1, l2)["i4"], self.compression_fibre)["psi"]

    def stress(self, params, lam1, lam2) -> tuple[np.ndarray, np.ndarray]:
        """Nominal tensions ``P1 = ∂ψ/∂λ1``, ``P2 = ∂ψ/∂λ2`` per unit reference width, N/mm."""
        a, b, theta = params
        l1, l2 = as_stretch(lam1, lam2)
        return fibre_stress(a, b, theta, l1, l2, self.compression_fibre)

    def stress_grad(self, params, lam1, lam2):
        """``(P1, P2, ∂P1/∂p, ∂P2/∂p)``; the derivative arrays have shape (n, 3) for (a, b, θ)."""
        a, b, theta = params
        l1, l2 = as_stretch(lam1, lam2)
        return fibre_stress_grad(a, b, theta, l1, l2, self.compression_fibre)

    def tangent(self, params, lam1, lam2):
        """``(∂P1/∂λ1, ∂P1/∂λ2, ∂P2/∂λ2)``, N/mm (∂P2/∂λ1 = ∂P1/∂λ2)."""
        return self.stress_tangent(params, lam1, lam2)[2:]

    def stress_tangent(self, params, lam1, lam2):
        """``(P1, P2, ∂P1/∂λ1, ∂P1/∂λ2, ∂P2/∂λ2)`` from one evaluation of the fibre law."""
        a, b, theta = params
        l1, l2 = as_stretch(lam1, lam2)
        c2, s2 = math.cos(theta) ** 2, math.sin(theta) ** 2
        d1, d2 = 2.0 * l1 * c2, 2.0 * l2 * s2
        g, h = fibre_gh(a, b, l1 * l1 * c2 + l2 * l2 * s2, self.compression_fibre)
        return g * d1, g * d2, h * d1 * d1 + 2.0 * g * c2, h * d1 * d2, h * d2 * d2 + 2.0 * g * s2

    def free_side_slack(self, params, direction="course") -> float:
        """Loaded stretch up to which a free side keeps the tension at zero: 1/cos θ (course), 1/sin θ
        (wale)."""
        theta = float(params[2])
        c = math.cos(theta) if direction_index(direction) == 0 else math.sin(theta)
        return 1.0 / c if c > 1e-12 else math.inf

    def solve_uniaxial(self, params, lam, direction="course"):
        """Free-side stretch and loaded tension under uniaxial load: ``(lam_free, P_loaded)``.

        P_free = 0 forces I4 = 1 while the loaded stretch is below 1/cos θ (course) or 1/sin θ
        (wale): the tension stays zero there. Beyond it no positive root exists and the free side
        collapses to the solver's lower bound (see :func:`knitframe.fitting.solve_free_side`).
        A curve that stretches (some λ > 1) but never passes that point is zero everywhere: it
        gets a :class:`~knitframe.errors.KnitframeWarning`.
        """
        lf, P = solve_free_side(self, params, lam, direction)
        top = float(np.max(lam))
        slack = self.free_side_slack(params, direction)
        if 1.0 < top <= slack:
            warnings.warn(
                free_side_zero_message(self.name, top, slack, direction), KnitframeWarning, stacklevel=2
            )
        return lf, P

    def card(self, fmt: str, params, **options) -> str:
        """Material card in ``fmt`` (one of :attr:`card_formats`) from the parameters as stored in
        params.json.

        ``params`` maps ``a`` (N/mm), ``b`` and ``theta_deg`` (degrees, as stored: no radians);
        ``options``: ``thickness`` (mm), ``name``, ``matrix_fraction``, ``bulk_ratio``,
        ``max_stretch`` (check deck) and ``source`` (a phrase about the fit for the header).
        """
        from knitframe_homogenizers.cards import write_card

        return write_card(fmt, self, dict(params), **options)

    def abaqus(
        self, params, *, thickness: float = 1.0, name: str = "KNIT", matrix_fraction: float = 1e-3
    ) -> str:
        """ABAQUS card: k1 = 2a/t, k2 = b, κ = 0, fibre at θ; a small matrix C10 = matrix_fraction·k1/2."""
        a, b, theta = (float(p) for p in params)
        k1 = 2.0 * a / thickness
        notes = [
            f"knitframe hgo: a = {_fmt(a)} N/mm, b = {_fmt(b)}, theta = {_fmt(math.degrees(theta))} deg, "
            f"thickness = {_fmt(thickness)} mm",
            *HOST_NOTES,
            "D = 0 makes the matrix incompressible (Abaqus/Standard: use hybrid or plane-stress elements).",
        ]
        return abaqus_card(name, matrix_fraction * k1 / 2.0, 0.0, k1, b, theta, notes)

    def febio(
        self, params, *, thickness: float = 1.0, name: str = "knit", matrix_fraction: float = 1e-3
    ) -> str:
        """FEBio block: ξ = 2a/t, α = b, β = 2, fibre at θ, neo-Hookean matrix E = 3·matrix_fraction·ξ."""
        a, b, theta = (float(p) for p in params)
        ksi = 2.0 * a / thickness
        notes = [
            f"knitframe hgo: a = {_fmt(a)} N/mm, b = {_fmt(b)}, theta = {_fmt(math.degrees(theta))} deg, "
            f"thickness = {_fmt(thickness)} mm.",
            *HOST_NOTES,
        ]
        # the same matrix as the ABAQUS card (E = 6 C10); ν just below 0.5 keeps FEBio's matrix stable
        return febio_block(name, 3.0 * matrix_fraction * ksi, 0.49, [(ksi, b, theta)], notes)


@hookimpl
def register_homogenizers(register):
    register(HGO)
