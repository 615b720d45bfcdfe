"""What a solver reads from a yarn: the property table (measured, estimate or derived) and the
stiffnesses derived from the record (shear, effective bending)."""

from __future__ import annotations

import attrs
import numpy as np

from knitframe.records import MAX_PACKING, Yarn
from knitframe.yarn.fit import line_contact_load, line_contact_stiffness

__all__ = [
    "yarn_properties",
    "YarnProperty",
    "SHEAR_COEFFICIENT",
    "effective_bending",
    "shear_stiffness",
    "shear_length",
]


@attrs.frozen
class YarnProperty:
    """One quantity a solver reads from a yarn: its value and where it comes from."""

    #: what it is, e.g. "axial shear modulus"
    name: str
    #: symbol, e.g. "G_A"
    symbol: str
    value: float | None
    unit: str
    #: "measured", "estimate" (given, not measured) or "derived" (computed from other rows)
    status: str
    #: how it was derived, or the field it comes from
    how: str
    #: which solvers read it and how
    used_by: str


def _source(yarn: Yarn, field: str, derived: str, status: str = "derived") -> tuple[str, str]:
    """(status, how) of a quantity that is the Yarn ``field`` when given, else ``(status, derived)``:
    "derived" when computed from other rows, "estimate" when that is an assumption."""
    if getattr(yarn, field) is None:
        return status, derived
    return ("measured" if field in yarn.measured else "estimate"), field


def yarn_properties(yarn: Yarn) -> list[YarnProperty]:
    """The quantities both solvers read from ``yarn``, marked measured, estimate or derived.

    The derivations (docs/yarns.md, "One yarn for every solver"):

    * G_A = ``G_axial``, else E_T / (2(1 + ν));
    * EI = ``bending_stiffness``, else E_A π dk⁴ / 64;
    * ℓ_s = √(EI/(κ G_A A)) with the solid section's EI (:func:`shear_stiffness`);
    * k_line = df/dδ of the Hertz line contact of two parallel yarns (E_T, ν, radius dk/2) at the
      load that flattens them by 5 % of dk;
    * φk = (tex/ρ)/(π dk²/4), J_min = φk/φmax (φmax = π/(2√3)), else ``compaction_limit``, else 0.5;
    * E_core = ``core_modulus``, else E_A.
    """

    def given(name, symbol, field, unit, used_by):
        return YarnProperty(name, symbol, getattr(yarn, field), unit, *_source(yarn, field, ""), used_by)

    r = 0.5 * yarn.dk
    f5 = line_contact_load(np.array([0.05 * yarn.dk]), r, yarn.E_transverse, yarn.nu)
    k_line = float(line_contact_stiffness(f5, r, yarn.E_transverse, yarn.nu)[0])
    phi = yarn.packing
    if yarn.compaction_limit is None and phi is None:
        j_source = ("estimate", "default 0.5 (no tex or fibre density)")
    else:
        j_source = _source(
            yarn, "compaction_limit", f"φk / φmax, φmax = {MAX_PACKING:.3f} (hexagonal packing)"
        )
    return [
        given("free diameter", "d0", "d0", "mm", "both: the pre-stress"),
        given("knitted diameter", "dk", "dk", "mm", "both: contact distance (rod), section (volumetric)"),
        given("axial modulus", "E_A", "E_axial", "MPa", "both: EA (rod), the fibre term (volumetric)"),
        given(
            "transverse modulus",
            "E_T",
            "E_transverse",
            "MPa",
            "both: contact stiffness (rod), transverse law (volumetric)",
        ),
        given("Poisson ratio", "ν", "nu", "-", "both"),
        YarnProperty(
            "axial shear modulus",
            "G_A",
            yarn.G_A,
            "MPa",
            *_source(yarn, "G_axial", "E_T / (2(1 + ν)): fibres slide along the yarn as easily as across it"),
            "both: axial shear (volumetric), the bending stiffness EI_eff (rod)",
        ),
        YarnProperty(
            "bending stiffness",
            "EI",
            yarn.EI,
            "N·mm²",
            *_source(
                yarn,
                "bending_stiffness",
                "E_A π dk⁴ / 64 (solid section); the rod bends with EI / (1 + EI k²/(κ G_A A)), k = 2π/ℓ",
            ),
            "rod (the volumetric yarn bends with E_A and G_A)",
        ),
        YarnProperty(
            "shear length",
            "ℓ_s",
            shear_length(yarn),
            "mm",
            "derived",
            "√(EI/(κ G_A A)) of the solid section: bent over a shorter length, the yarn bends in shear",
            'rod: shear = "resolved" suits a yarn whose ℓ_s is short against a stitch',
        ),
        YarnProperty(
            "line contact stiffness at 5 % flattening",
            "k_line",
            k_line,
            "N/mm²",
            "derived",
            "Hertz line contact of two yarns with E_T and ν",
            "rod: the contact penalty",
        ),
        YarnProperty(
            "fibre volume fraction, knitted",
            "φk",
            phi,
            "-",
            "derived" if phi is not None else "unknown",
            "(tex/ρ) / (π dk²/4)" if phi is not None else "needs tex and fibre_density",
            "J_min",
        ),
        YarnProperty(
            "compaction limit (smallest section / knitted)",
            "J_min",
            yarn.compaction,
            "-",
            *j_source,
            "rod: the contact core at J_min·dk (an isotropic solid yarn has no compaction barrier)"
            if yarn.isotropic
            else "both: the contact core at J_min·dk (rod), the compaction barrier (volumetric)",
        ),
        YarnProperty(
            "modulus of the packed core",
            "E_core",
            yarn.core_E,
            "MPa",
            *_source(yarn, "core_modulus", "E_A: packed fibres as stiff as the yarn along it", "estimate"),
            "both: stiffness halfway through the compaction barrier",
        ),
        *(
            YarnProperty(
                name,
                symbol,
                getattr(yarn, field),
                unit,
                *(_source(yarn, field, "") if yarn.has_compression_law else ("unknown", "not in the record")),
                "rod: contact law rod_shell (the shell's compression law)",
            )
            for name, symbol, field, unit in (
                ("compression law: shell diameter", "D", "shell_diameter", "mm"),
                ("compression law: core diameter", "D_c", "core_diameter", "mm"),
                ("compression law: rigidity", "k", "compression_k", "N/mm³"),
                ("compression law: exponent", "p", "compression_p", "-"),
            )
        ),
    ]


#: Timoshenko shear coefficient of a circular section, 6(1 + ν)/(7 + 6ν) at ν = 0.3 (Cowper 1966)
SHEAR_COEFFICIENT = 0.886


def effective_bending(yarn: Yarn, wavelength: float) -> float:
    """Bending stiffness of the yarn bent at ``wavelength`` (mm), shear included, N·mm².

    A Timoshenko beam bent by a load of wave number k = 2π/λ deflects by q/(EI k⁴) + q/(κ G_A A k²),
    so it is as stiff as a shear-rigid beam of

        EI_eff = EI / (1 + EI k² / (κ G_A A)),   A = π dk²/4, κ = 0.886

    with EI the solid section's E_A π dk⁴/64 and G_A the record's axial shear modulus. A yarn whose
    ``bending_stiffness`` is given keeps it: a bending test measures the effective stiffness.
    """
    if yarn.bending_stiffness is not None:
        return yarn.bending_stiffness
    k = 2.0 * np.pi / wavelength
    EI = yarn.EI
    return float(EI / (1.0 + EI * k * k / shear_stiffness(yarn)))


def shear_stiffness(yarn: Yarn) -> float:
    """Transverse shear stiffness κ G_A A of the knitted section, N (A = π dk²/4, κ = 0.886)."""
    return float(SHEAR_COEFFICIENT * yarn.G_A * np.pi * yarn.dk**2 / 4.0)


def shear_length(yarn: Yarn) -> float:
    """√(EI/(κ G_A A)) with the solid section's EI = E_A π dk⁴/64, mm: over a shorter length the
    yarn bends mostly in shear (:func:`shear_stiffness`)."""
    return float(np.sqrt(yarn.E_axial * np.pi * yarn.dk**4 / 64.0 / shear_stiffness(yarn)))
