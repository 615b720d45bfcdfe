"""The built-in yarn library and :func:`resolve_yarn`, which turns a config value into a Yarn.

Diameters are the paper's measurements (du Pasquier et al. 2026). Moduli are representative
estimates to be replaced by fits to the user's own tests (``knitframe.yarn.fit``); docs/yarns.md
gives the source of every number.
"""

from __future__ import annotations

from knitframe import hookimpl
from knitframe.records import Yarn
from knitframe.yarn import resolve_yarn  # noqa: F401  (re-exported for plugin users)

__all__ = ["YARNS", "resolve_yarn"]

_PAPER = "du Pasquier et al. 2026 (EML), yarn section"

YARNS = (
    Yarn(
        name="cotton",
        d0=0.445,
        dk=0.444,
        E_axial=1200.0,
        E_transverse=0.12,
        nu=0.3,
        failure_strain=0.10,
        tex=59.0,
        fibre_density=1.52,
        measured=("d0", "dk", "failure_strain", "tex"),
        model="transverse_isotropic",
        source=f"Cotton 20/2 (Supreme Corp.): d0, dk and strain capacity < 10 % from {_PAPER}; "
        "tex from the count (20/2 Ne = 2 x 29.5 tex); cotton fibre density 1.52 g/cm3 (handbook); "
        "E_axial representative (1-1.5 GPa: ~400 cN/tex x 59 tex over the dk section); "
        "E_transverse = 1e-4 E_axial (paper's ratio)",
    ),
    Yarn(
        name="nylon",
        d0=0.951,
        dk=0.334,
        E_axial=40.0,
        E_transverse=0.004,
        nu=0.3,
        failure_strain=1.2,
        tex=15.56,
        fibre_density=1.14,
        measured=("d0", "dk", "failure_strain", "tex"),
        model="transverse_isotropic",
        source="Nylon 70 den, 24 f, 2-ply textured (Hickory Throwing): "
        f"d0, dk and elongation > 120 % from {_PAPER}; "
        "tex from the count (2 x 70 den = 15.56 tex); nylon 6,6 fibre density 1.14 g/cm3 (handbook); "
        "E_axial representative of the crimp-straightening range (30-50 MPa; ~0.4-0.5 GPa once straight); "
        "E_transverse = 1e-4 E_axial (paper's ratio)",
    ),
    Yarn(
        name="pearl-cotton",
        d0=0.74,
        dk=0.74,
        E_axial=1200.0,
        E_transverse=0.12,
        nu=0.3,
        bending_stiffness=0.0708,
        tex=394.0,
        fibre_density=1.52,
        measured=("bending_stiffness",),
        model="transverse_isotropic",
        source="Pearl cotton 3/2, the cotton of Singal et al. 2024 (Nat Commun 15:2622, Supplement): "
        "bending modulus B = 70.8 mN mm2 measured (bending_stiffness); "
        "their compression law k = 11.49, p = 2.94 has no Yarn field and is not used. "
        "d0 = dk = 0.74 mm estimated from the count (3/2 = Ne 1.5, about 394 tex) with Peirce's "
        "d = 1/(28 sqrt(Ne)) inch; E_axial representative of cotton yarn (as 'cotton'); "
        "E_transverse = 1e-4 E_axial (the paper's ratio for cotton)",
    ),
    Yarn(
        name="acrylic",
        d0=0.95,
        dk=0.95,
        E_axial=79.0,
        E_transverse=0.0079,
        nu=0.3,
        bending_stiffness=0.045,
        tex=502.0,
        fibre_density=1.17,
        shell_diameter=1.48,
        core_diameter=0.65,
        compression_k=0.0006,
        compression_p=2.4,
        measured=("E_axial", "bending_stiffness"),
        model="transverse_isotropic",
        source="Acrylic worsted (Knit Picks Brava Worsted, 100 % acrylic), "
        "the acrylic of Singal et al. 2024 (Nat Commun 15:2622): "
        "E_axial = stretching modulus 79.0 MPa measured (Ding 2023, cited by Singal); "
        "bending_stiffness = B = 0.045 N mm2, the bending modulus of Singal et al.'s own simulations "
        "of this yarn (sabetta/stitch-by-stitch, code/fabric_simulations/*config.dat, 'acrylic params'); "
        "d0 = dk = 0.95 mm estimated from the count (label: 100 g per 218 yd, about 502 tex) "
        "as a round yarn 60 % fibre by volume (Peirce's packing for cotton) of acrylic fibre 1.17 g/cm3; "
        "E_transverse = 1e-4 E_axial (the paper's ratio for cotton and nylon, an estimate); nu assumed; "
        "compression law (contact law rod_shell) = that of Singal et al.'s jersey simulation of this yarn "
        "(stockinetteconfig.dat): shell 2 x 0.74 mm, core 2 x 0.325 mm, k = 0.0006 N/mm3, p = 2.4",
    ),
    Yarn(
        name="pet",
        d0=0.178,
        dk=0.178,
        E_axial=4000.0,
        E_transverse=4000.0,
        nu=0.35,
        measured=("d0", "dk"),
        model="isotropic",
        source=f"PET monofilament 0.178 mm (Thread Exchange), isotropic, from {_PAPER}; "
        "E = 4 GPa and nu = 0.35 representative (3-5 GPa)",
    ),
)


@hookimpl
def register_yarns(register) -> None:
    for yarn in YARNS:
        label = yarn.source.split(" (")[0]
        register(
            yarn, description=f"{label}: d0 {yarn.d0:g} mm, dk {yarn.dk:g} mm, E_axial {yarn.E_axial:g} MPa"
        )
