r"""Material cards of the paper's one-fibre model (``hgo``) for ABAQUS, CalculiX and FEBio.

The paper's model is a membrane: ``ψ(λ1, λ2) = a/b [exp(b (I4 − 1)²) − 1]`` per unit reference
area, ``I4 = λ1² cos²θ + λ2² sin²θ``. The three hosts are 3-D solids with the Holzapfel–Gasser–
Ogden energy

.. math:: U = C_{10}(\bar I_1 - 3) + U_{vol}(J)
          + \frac{k_1}{2 k_2}\left[e^{k_2 \langle \bar I_4 - 1\rangle^2} - 1\right]

(ABAQUS ``*ANISOTROPIC HYPERELASTIC, HOLZAPFEL`` with κ = 0; CalculiX's ``ELASTIC_FIBER`` user
material; FEBio's ``Holzapfel-Gasser-Ogden``). A block of reference thickness t0 made of it is the
paper's membrane in tension when ``k1 = 2a/t0`` (MPa, a in N/mm), ``k2 = b`` and the block is
nearly incompressible (J ≈ 1, so ``Ī4 = J^{-2/3} I4 ≈ I4`` and the thickness follows
``λ3 = 1/(λ1 λ2)``); the tension per unit width is t0 times the nominal stress. What differs —
the Macaulay bracket, the isochoric invariants, the matrix C10 and the bulk term — is written into
every card's header, with the numbers of that card.

Defaults: ``C10 = matrix_fraction · k1/2`` with 1e-4 (at small strain the matrix adds
3·C10/(k1 cos²θ) = 0.015 %/cos²θ of the fibre's course tension under equibiaxial stretch and
2·C10/(k1 cos⁴θ) = 0.01 %/cos⁴θ under strip-biaxial stretch) and an initial bulk modulus
``2/D = bulk_ratio · k1`` with 1e5 (J − 1 stays near 1e-4 or below over the check's stretches).

:class:`FibreSolid` holds the mapped constants and solves the host energy exactly for a block
under in-plane stretch with a free thickness (:meth:`FibreSolid.membrane`), which the CalculiX
check deck prints next to knitframe's own tensions.
"""

from __future__ import annotations

import math
import re
import textwrap
import xml.etree.ElementTree as ET
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError
from knitframe.export import header_line

__all__ = ["FibreSolid", "write_card", "CCX_EXP_LIMIT"]

#: CalculiX's umat_elastic_fiber stops when k2 (Ī4 − 1)² exceeds this.
CCX_EXP_LIMIT = 227.0
#: Default end of the CalculiX check's tension cases, and the largest k2 (Ī4 − 1)² they reach.
CHECK_STRETCH, CHECK_EXPONENT = 1.2, 3.0
#: End stretch of the check's equibiaxial compression case.
CHECK_COMPRESSION = 0.9
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,59}$")
_WIDTH = 96


def _g(x: float) -> str:
    return f"{x:.10g}"


def _unit_direction(theta_deg: float) -> tuple[float, float]:
    """(cos θ, sin θ), written exactly (:func:`_d`), nudged down by ulps until cx² + cy² <= 1 in
    floating point.

    CalculiX computes the third cosine as sqrt(1 − cx² − cy²) and stops when the argument is
    negative; the nudge keeps that third cosine below about 1e-8, so the fibre stays in the plane.
    """
    t = math.radians(theta_deg)
    c, s = (0.0 if abs(v) < 1e-15 else v for v in (math.cos(t), math.sin(t)))
    for _ in range(64):
        if c * c + s * s <= 1.0:
            return c, s
        c, s = math.nextafter(c, 0.0), math.nextafter(s, 0.0)
    raise AssertionError("unreachable: the pair shrinks below unit norm")  # pragma: no cover


def _d(x: float) -> str:
    """A direction cosine, written so that it reads back as exactly the same float."""
    return repr(float(x) + 0.0)


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0:
        raise ConfigError(name, f"must be a finite number > 0 for a material card, got {value!r}")
    return v


@attrs.frozen
class FibreSolid:
    """The paper's membrane as a Holzapfel solid of reference thickness ``thickness`` (mm)."""

    #: N/mm
    a: float
    #: -
    b: float
    #: degrees from the course towards the wale, as stored in params.json
    theta_deg: float
    #: t0, mm
    thickness: float = 1.0
    #: C10 = matrix_fraction · k1/2
    matrix_fraction: float = 1e-4
    #: initial bulk modulus 2/D = bulk_ratio · k1
    bulk_ratio: float = 1e5

    def __attrs_post_init__(self):
        _positive("a", self.a)
        _positive("b", self.b)
        _positive("thickness", self.thickness)
        _positive("matrix_fraction", self.matrix_fraction)
        _positive("bulk_ratio", self.bulk_ratio)
        if not math.isfinite(self.theta_deg):
            raise ConfigError("theta_deg", f"must be a finite angle in degrees, got {self.theta_deg!r}")

    @property
    def k1(self) -> float:
        """MPa: 2a/t0."""
        return 2.0 * self.a / self.thickness

    @property
    def k2(self) -> float:
        return self.b

    @property
    def c10(self) -> float:
        """MPa."""
        return self.matrix_fraction * self.k1 / 2.0

    @property
    def d(self) -> float:
        """1/MPa: 2 / (bulk_ratio · k1)."""
        return 2.0 / (self.bulk_ratio * self.k1)

    @property
    def direction(self) -> tuple[float, float]:
        """Fibre direction cosines (x = course, y = wale) as written in every card."""
        return _unit_direction(self.theta_deg)

    # ------------------------------------------------------------------ the host energy, exactly
    def _nominal(self, l1: float, l2: float, l3: float) -> tuple[float, float, float]:
        """Nominal stresses P1, P2, P3 (MPa) of the CalculiX energy at F = diag(l1, l2, l3)."""
        cx, cy = self.direction
        cz2 = max(0.0, 1.0 - cx * cx - cy * cy)
        lam, a2 = (l1, l2, l3), (cx * cx, cy * cy, cz2)
        J = l1 * l2 * l3
        r = J ** (-2.0 / 3.0)
        S = l1 * l1 + l2 * l2 + l3 * l3
        Q = sum(li * li * ai for li, ai in zip(lam, a2, strict=True))
        x = r * Q - 1.0
        g = self.k1 * x * math.exp(min(self.k2 * x * x, 700.0)) if x > 0 else 0.0
        out = []
        for li, ai in zip(lam, a2, strict=True):
            dI1 = r * (2.0 * li - 2.0 * S / (3.0 * li))
            dI4 = r * (2.0 * li * ai - 2.0 * Q / (3.0 * li))
            out.append(self.c10 * dI1 + 2.0 * (J - 1.0) / self.d * J / li + g * dI4)
        return out[0], out[1], out[2]

    def membrane(self, lam1: float, lam2: float) -> tuple[float, float, float]:
        """``(T1, T2, λ3)`` of a block of this card under F = diag(λ1, λ2, λ3), λ3 free (σ33 = 0).

        T = t0 · P, N/mm: the tension per unit width the CalculiX check should print. Uses the
        CalculiX bulk term (J − 1)²/D; the root λ3 is bracketed and found by bisection-safe Brent.
        """
        from scipy.optimize import brentq

        l1, l2 = float(lam1), float(lam2)
        p3 = lambda l3: self._nominal(l1, l2, l3)[2]  # noqa: E731
        lo, hi = 0.99 / (l1 * l2), 1.01 / (l1 * l2)  # J near 1: the root is close to 1/(λ1 λ2)
        while p3(lo) > 0 and lo > 1e-6:
            lo /= 1.1
        while p3(hi) < 0 and hi < 1e6:
            hi *= 1.1
        l3 = brentq(p3, lo, hi, xtol=1e-15, rtol=1e-14, maxiter=500)
        P1, P2, _ = self._nominal(l1, l2, l3)
        return self.thickness * P1, self.thickness * P2, l3


# ---------------------------------------------------------------------------------------------
# headers
# ---------------------------------------------------------------------------------------------
_HOST = {
    "abaqus": "ABAQUS",
    "calculix": "CalculiX",
    "calculix-deck": "CalculiX",
    "febio": "FEBio",
}
_BULK = {
    "abaqus": "(1/D) ((J^2 - 1)/2 - ln J)",
    "calculix": "(1/D1) (J - 1)^2",
    "calculix-deck": "(1/D1) (J - 1)^2",
    "febio": "FEBio's U(J) of uncoupled materials, bulk modulus k = 2/D,",
}
_KEYWORDS = {
    "abaqus": [
        "Keywords: Abaqus Keywords Guide, *ANISOTROPIC HYPERELASTIC with HOLZAPFEL and LOCAL DIRECTIONS=1 "
        "(data line C10, D, k1, k2, kappa), and *ORIENTATION with LOCAL DIRECTIONS=1 (its last data line is "
        "the fibre direction in the local axes).",
        "Use: *SOLID SECTION (or *SHELL SECTION), ELSET=<your set>, MATERIAL={name}, ORIENTATION=ORI-{name}; "
        "local axis 1 = course, 2 = wale, 3 = thickness. D > 0: hybrid elements (C3D8H) or membrane/shell "
        "elements avoid volumetric locking.",
    ],
    "calculix": [
        "Keywords: CalculiX CrunchiX User's Manual, 'Fiber reinforced materials' (a *MATERIAL whose NAME "
        "starts with ELASTIC_FIBER) and *USER MATERIAL with CONSTANTS = 2 + 4n: C10, D1, then per fibre the "
        "x and y direction cosines (z follows from unit length), k1, k2.",
        "Use: *SOLID SECTION, ELSET=<your set>, MATERIAL={ccx_name} with x = course, y = wale, z = "
        "thickness (or an *ORIENTATION on the section: the cosines are then in its local axes). CalculiX "
        "has no hybrid elements: C3D8I or C3D20R avoid volumetric locking.",
    ],
    "febio": [
        "Keywords: FEBio User's Manual, material 'Holzapfel-Gasser-Ogden' (uncoupled: c, k1, k2, kappa, "
        "gamma in degrees, k, with a mat_axis); paste the <material> element into the <Material> section of "
        "an FEBio 4 model.",
        "FEBio's HGO has two fibre families at +-gamma about mat_axis a. Here a is the fibre and gamma = 0, "
        "so both families lie on it and each takes half: k1 (FEBio) = a/t0 = k1/2; c = 2 C10 (FEBio's "
        "matrix is c/2 (I1bar - 3)); k = 2/D.",
    ],
}
_KEYWORDS["calculix-deck"] = _KEYWORDS["calculix"]


def _wrap(text: str, mark: str) -> list[str]:
    return [f"{mark} {line}" for line in textwrap.wrap(text, _WIDTH - len(mark) - 1, break_on_hyphens=False)]


def _header(
    fmt: str, fs: FibreSolid, model: str, source: str, compression_fibre: bool, name: str
) -> list[str]:
    """Header text (without comment marks): units, angle convention, mapping, the four differences."""
    from knitframe import __version__

    host = _HOST[fmt]
    cx, cy = fs.direction
    shares = []
    for axis, fn in (("course", math.cos), ("wale", math.sin)):
        q = fn(math.radians(fs.theta_deg)) ** 2
        if q < 1e-12:
            shares.append(f"{axis}: no fibre tension, the matrix alone")
        else:  # small strain: 3 C10/(k1 q) equibiaxial, 2 C10/(k1 q^2) strip-biaxial (this axis loaded)
            shares.append(
                f"{axis}: {100 * 3 * fs.c10 / (fs.k1 * q):.2g} % (equibiaxial), "
                f"{100 * 2 * fs.c10 / (fs.k1 * q * q):.2g} % (strip-biaxial)"
            )
    top = check_stretch(fs.b)
    _, _, l3 = fs.membrane(top, top)
    jm1 = top * top * l3 - 1.0
    keep = (
        "this fit kept it (compression_fibre = true), so under compression the card is much softer than the "
        "fit"
        if compression_fibre
        else "this fit dropped it too (compression_fibre = false)"
    )
    src = f" ({source})" if source else ""
    return [
        f"Written by knitframe {__version__} from a '{model}' fit{src}.",
        "Paper's model, per unit reference area of the fabric: psi = a/b [exp(b (I4 - 1)^2) - 1], "
        "I4 = lam1^2 cos^2(theta) + lam2^2 sin^2(theta).",
        f"Fit: a = {_g(fs.a)} N/mm, b = {_g(fs.b)}, theta = {_g(fs.theta_deg)} deg (theta_deg as stored in "
        "params.json, from the course towards the wale).",
        "Units: mm, N, MPa (k1, C10 in MPa; D in 1/MPa); angles in degrees; axes x/1 = course, y/2 = wale, "
        "z/3 = thickness.",
        f"Mapping: a solid of reference thickness t0 = {_g(fs.thickness)} mm; k1 = 2a/t0 = {_g(fs.k1)} MPa, "
        f"k2 = b = {_g(fs.k2)}, kappa = 0, fibre direction (cos theta, sin theta, 0) = "
        f"({_d(cx)}, {_d(cy)}, 0). Tension per unit width (N/mm) = t0 x nominal stress (MPa).",
        f"How {host} differs from the paper's model:",
        f"(1) Macaulay bracket: {host} gives the fibre no stress while it is shorter than at rest "
        f"(I4bar < 1); the paper's model keeps the fibre's compressive stress and {keep}. Under compression "
        "only the matrix and the bulk term carry load.",
        "(2) Isochoric invariants: I4bar = J^(-2/3) I4 and I1bar = J^(-2/3) I1 replace I4 and I1. They "
        f"equal the paper's I4 only at J = 1; the bulk term below keeps |J - 1| near {abs(jm1):.1e} at "
        f"equibiaxial stretch {_g(top)}, and the thickness then follows lam3 = 1/(lam1 lam2).",
        f"(3) Matrix: C10 (I1bar - 3) with C10 = {_g(fs.c10)} MPa ({_g(fs.matrix_fraction)} x k1/2), absent "
        "from the paper's model. It gives the fabric some shear and compression stiffness and adds 2 C10 t0 "
        "(lam1 - lam1^-3 lam2^-2) N/mm to the course tension (likewise the wale). At small strain that is, "
        f"of the fibre's tension along the {'; '.join(shares)}; a smaller matrix_fraction lowers it.",
        f"(4) Bulk: {_BULK[fmt]} with D = {_g(fs.d)} 1/MPa (initial bulk modulus 2/D = {_g(2 / fs.d)} MPa = "
        f"{_g(fs.bulk_ratio)} x k1). The paper's membrane has no thickness; this term only holds J near 1.",
        *(line.format(name=name, ccx_name=_ccx_name(name)) for line in _KEYWORDS[fmt]),
    ]


def check_stretch(b: float) -> float:
    """End stretch of the check's tension cases: 1.2, or less where k2 (λ² − 1)² would pass 3 (e³ ≈ 20)."""
    return min(CHECK_STRETCH, math.sqrt(1.0 + math.sqrt(CHECK_EXPONENT / b)))


# ---------------------------------------------------------------------------------------------
# the four formats
# ---------------------------------------------------------------------------------------------
def _comments(lines: list[str], mark: str = "**") -> list[str]:
    out = []
    for line in lines:
        out += _wrap(line, mark)
    return out


def _abaqus(fs: FibreSolid, name: str, head: list[str]) -> str:
    cx, cy = fs.direction
    lines = [
        header_line("hgo", "abaqus"),
        *_comments(head),
        f"*MATERIAL, NAME={name}",
        "*ANISOTROPIC HYPERELASTIC, HOLZAPFEL, LOCAL DIRECTIONS=1",
        ", ".join(_g(v) for v in (fs.c10, fs.d, fs.k1, fs.k2, 0.0)),
        f"*ORIENTATION, NAME=ORI-{name}, LOCAL DIRECTIONS=1",
        "1., 0., 0., 0., 1., 0.",
        "3, 0.",
        ", ".join(_d(v) for v in (cx, cy, 0.0)),
    ]
    return "\n".join(lines) + "\n"


def _ccx_name(name: str) -> str:
    return name if name.upper().startswith("ELASTIC_FIBER") else f"ELASTIC_FIBER_{name}"


def _calculix_material(fs: FibreSolid, name: str) -> list[str]:
    cx, cy = fs.direction
    values = [_g(fs.c10), _g(fs.d), _d(cx), _d(cy), _g(fs.k1), _g(fs.k2)]
    rows = [values[i : i + 8] for i in range(0, len(values), 8)]  # CalculiX: at most 8 entries per line
    return [
        f"*MATERIAL, NAME={_ccx_name(name)}",
        f"*USER MATERIAL, CONSTANTS={len(values)}",
        *(", ".join(row) for row in rows),
    ]


def _calculix(fs: FibreSolid, name: str, head: list[str]) -> str:
    top = math.sqrt(1.0 + math.sqrt(CCX_EXP_LIMIT / fs.k2))
    limit = (
        f"CalculiX stops when k2 (I4bar - 1)^2 > {CCX_EXP_LIMIT:g}: here when the fibre stretch passes "
        f"{_g(top)}."
    )
    lines = [header_line("hgo", "calculix"), *_comments(head + [limit]), *_calculix_material(fs, name)]
    return "\n".join(lines) + "\n"


def _febio(fs: FibreSolid, name: str, head: list[str]) -> str:
    cx, cy = fs.direction
    mat = ET.Element("material", id="1", name=name, type="Holzapfel-Gasser-Ogden")
    for tag, val in (
        ("c", 2.0 * fs.c10),
        ("k1", fs.k1 / 2.0),
        ("k2", fs.k2),
        ("gamma", 0.0),
        ("kappa", 0.0),
        ("k", 2.0 / fs.d),
    ):
        ET.SubElement(mat, tag).text = _g(val)
    axis = ET.SubElement(mat, "mat_axis", type="vector")
    ET.SubElement(axis, "a").text = ",".join(_d(v) for v in (cx, cy, 0.0))
    ET.SubElement(axis, "d").text = ",".join(_d(v) for v in (-cy, cx, 0.0))
    ET.indent(mat)
    comment = (
        "<!--\n"
        + "\n".join(textwrap.fill(line.replace("--", "-"), _WIDTH, break_on_hyphens=False) for line in head)
        + "\n-->"
    )
    return "\n".join([header_line("hgo", "febio"), comment, ET.tostring(mat, encoding="unicode")]) + "\n"


def _deck(
    fs: FibreSolid,
    name: str,
    head: list[str],
    model: Any,
    params_rad: np.ndarray,
    max_stretch: float | None,
    increments: int = 5,
) -> str:
    """A CalculiX input: three separate 1 × 1 × t0 mm C3D8 blocks, each with F = diag(λ1, λ2, λ3), λ3 free."""
    top = check_stretch(fs.b) if max_stretch is None else float(max_stretch)
    if not (math.isfinite(top) and 1.0 < top <= 3.0):
        raise ConfigError("max_stretch", f"must be in (1, 3], got {max_stretch!r}")
    cases = [
        ("EQB", "equibiaxial", top, top),
        ("STRIP", "strip-biaxial", top, 1.0),
        ("COMP", "equibiaxial-compression", CHECK_COMPRESSION, CHECK_COMPRESSION),
    ]
    lines = [header_line("hgo", "calculix-deck"), *_comments(head)]
    lines += _deck_comments(fs, model, params_rad, cases, increments)
    lines += ["*HEADING", f"knitframe check of the {_ccx_name(name)} card", "*NODE, NSET=NALL"]
    lines += _deck_blocks(fs, name, cases)
    lines += _deck_step(cases, increments)
    return "\n".join(lines) + "\n"


def _deck_comments(
    fs: FibreSolid, model: Any, params_rad: np.ndarray, cases: list[tuple], increments: int
) -> list[str]:
    """The deck's comment lines: how to run it, its load cases, and the expected tensions per
    increment from knitframe's fitted model and from the card's own energy solved exactly."""
    t0 = fs.thickness
    lines = _comments(
        [
            "Check deck: one 1 mm x 1 mm x t0 C3D8 block per load case, in-plane displacements of every "
            "node prescribed so that F = diag(lam1, lam2, lam3) with lam3 free (bottom face held in z), "
            f"NLGEOM, the stretch ramped over {increments} equal increments. Run: ccx -i <this file without "
            ".inp>. The .dat lists the total reaction of sets <case>_X1 (fx) and <case>_Y1 (fy): the faces "
            "are 1 mm wide, so these are the tensions per unit width T1, T2 in N/mm, and the z displacement "
            "of <case>_TOP gives lam3.",
            "Strip-biaxial: the lateral side is held (lam2 = 1). The compression case tests (1): its fibre "
            "is slack, so CalculiX shows the matrix only, where knitframe's fit shows the fibre's "
            "compressive stress when it kept it.",
        ]
    )
    lines += [
        f"** check case {c}: {kind}, lam1 1 -> {_g(l1)}, lam2 1 -> {_g(l2)}, {increments} increments"
        for c, kind, l1, l2 in cases
    ]
    lines += [
        f"** check block thickness t0 = {_g(t0)} mm",
        "** Expected tension per unit width, N/mm: knitframe's fitted model, and this card's own energy",
        "** solved exactly for the same block (what CalculiX should print).",
        f"** {'case':<6}{'lam1':>9}{'lam2':>9}{'knitframe T1':>15}{'T2':>13}{'card T1':>13}{'T2':>13}"
        f"{'lam3':>11}",
    ]
    for c, _, l1e, l2e in cases:
        for i in range(1, increments + 1):
            t = i / increments
            l1, l2 = 1 + t * (l1e - 1), 1 + t * (l2e - 1)
            P1, P2 = model.stress(params_rad, np.array([l1]), np.array([l2]))
            T1, T2, l3 = fs.membrane(l1, l2)
            lines.append(
                f"** {c:<6}{l1:>9.5f}{l2:>9.5f}{float(P1[0]):>15.6g}{float(P2[0]):>13.6g}{T1:>13.6g}"
                f"{T2:>13.6g}{l3:>11.6f}"
            )
    return lines


def _deck_blocks(fs: FibreSolid, name: str, cases: list[tuple]) -> list[str]:
    """Nodes, one C3D8 element and its face node sets per load case (blocks 3 mm apart along x),
    the material and the solid sections."""
    t0 = fs.thickness
    lines = []
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    for e, _ in enumerate(cases):
        for k, (x, y, z) in enumerate(corners):
            lines.append(f"{8 * e + k + 1}, {_g(3.0 * e + x)}, {_g(float(y))}, {_g(z * t0)}")
    for e, (c, *_rest) in enumerate(cases):
        n = [8 * e + k + 1 for k in range(8)]
        lines += [f"*ELEMENT, TYPE=C3D8, ELSET={c}", f"{e + 1}, " + ", ".join(map(str, n))]
        sets = {
            "X0": (0, 3, 4, 7),
            "X1": (1, 2, 5, 6),
            "Y0": (0, 1, 4, 5),
            "Y1": (2, 3, 6, 7),
            "Z0": (0, 1, 2, 3),
            "TOP": (4, 5, 6, 7),
        }
        for s, idx in sets.items():
            lines += [f"*NSET, NSET={c}_{s}", ", ".join(str(n[i]) for i in idx)]
    lines += _calculix_material(fs, name)
    for c, *_rest in cases:
        lines.append(f"*SOLID SECTION, ELSET={c}, MATERIAL={_ccx_name(name)}")
    return lines


def _deck_step(cases: list[tuple], increments: int) -> list[str]:
    """The NLGEOM step: prescribed face displacements per case and the printed reactions and
    top-face displacements."""
    lines = ["*STEP, NLGEOM, INC=1000", "*STATIC, DIRECT", f"{_g(1.0 / increments)}, 1.", "*BOUNDARY"]
    for c, _, l1, l2 in cases:
        lines += [
            f"{c}_X0, 1, 1, 0.",
            f"{c}_X1, 1, 1, {_g(l1 - 1.0)}",
            f"{c}_Y0, 2, 2, 0.",
            f"{c}_Y1, 2, 2, {_g(l2 - 1.0)}",
            f"{c}_Z0, 3, 3, 0.",
        ]
    for c, *_rest in cases:
        lines += [
            f"*NODE PRINT, NSET={c}_X1, TOTALS=ONLY",
            "RF",
            f"*NODE PRINT, NSET={c}_Y1, TOTALS=ONLY",
            "RF",
            f"*NODE PRINT, NSET={c}_TOP",
            "U",
        ]
    lines.append("*END STEP")
    return lines


def write_card(
    fmt: str,
    model: Any,
    params: dict[str, float],
    *,
    source: str = "",
    thickness: float = 1.0,
    name: str = "KNIT",
    matrix_fraction: float = 1e-4,
    bulk_ratio: float = 1e5,
    max_stretch: float | None = None,
) -> str:
    """The ``hgo`` card in ``fmt`` from the parameters as stored (``a``, ``b``, ``theta_deg``)."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise ConfigError(
            "name",
            f"must start with a letter and hold only letters, digits, '_' and '-' (at most 60), got {name!r}",
        )
    fs = FibreSolid(params["a"], params["b"], params["theta_deg"], thickness, matrix_fraction, bulk_ratio)
    head = _header(fmt, fs, model.name, source, bool(getattr(model, "compression_fibre", True)), name)
    if fmt == "abaqus":
        return _abaqus(fs, name, head)
    if fmt == "calculix":
        return _calculix(fs, name, head)
    if fmt == "febio":
        return _febio(fs, name, head)
    if fmt == "calculix-deck":
        params_rad = np.array([params["a"], params["b"], math.radians(params["theta_deg"])])
        return _deck(fs, name, head, model, params_rad, max_stretch)
    raise ConfigError("format", f"unknown card format {fmt!r}")
