"""``knitframe export PARAMS.json --format abaqus|calculix|calculix-deck|febio --out FILE``.

Writes the material card of a fitted reduced model (a params.json of ``knitframe fit`` or of a
``[fit]`` stage) for ABAQUS (``*ANISOTROPIC HYPERELASTIC, HOLZAPFEL``), CalculiX (the
``ELASTIC_FIBER`` user material), FEBio (``Holzapfel-Gasser-Ogden``), or a runnable CalculiX deck
that checks the card against knitframe's own model (``calculix-deck``; run it with ``ccx``).
Units mm, N, MPa; θ is read in degrees as stored. Each card's header states how the target
software differs from the paper's model. See docs/export.md.

FILE must be new; ``--overwrite`` replaces only a card knitframe wrote. The file is written
atomically: it is either complete or not there.
"""

from __future__ import annotations

import math
from pathlib import Path

from knitframe.errors import ConfigError

#: card keyword → command-line option, for error messages
_OPTIONS = {
    "thickness": "--thickness",
    "name": "--name",
    "matrix_fraction": "--matrix-fraction",
    "bulk_ratio": "--bulk-ratio",
    "max_stretch": "--max-stretch",
    "format": "--format",
}


def add_parser(sub) -> None:
    from knitframe.export import FORMATS

    p = sub.add_parser(
        "export",
        help="write a fitted model's material card for ABAQUS, CalculiX or FEBio",
        description=__doc__,
    )
    p.add_argument("params", type=Path, help="params.json of a fit")
    p.add_argument("--format", required=True, choices=list(FORMATS), help="card format")
    p.add_argument("--out", required=True, help="card file to write (new; see --overwrite)")
    p.add_argument(
        "--thickness",
        type=float,
        default=1.0,
        metavar="MM",
        help="reference thickness t0 of the solid or shell the card is for, mm; k1 = 2a/t0 (default 1)",
    )
    p.add_argument(
        "--name", default="KNIT", help="material name (CalculiX prefixes ELASTIC_FIBER_; default KNIT)"
    )
    p.add_argument(
        "--matrix-fraction",
        type=float,
        default=1e-4,
        metavar="F",
        help="matrix C10 = F * k1/2 (default 1e-4)",
    )
    p.add_argument(
        "--bulk-ratio",
        type=float,
        default=1e5,
        metavar="R",
        help="initial bulk modulus 2/D = R * k1 (default 1e5: nearly incompressible)",
    )
    p.add_argument(
        "--max-stretch",
        type=float,
        default=None,
        metavar="L",
        help="calculix-deck: end stretch of the tension cases (default 1.2, less for stiff fits)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace FILE if it is a card knitframe wrote")
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=main)


def main(args) -> int:
    from knitframe.export import check_out_file, export_card, load_params, write_card

    check_out_file(args.out, overwrite=args.overwrite)  # before any work
    for flag, value in (
        ("--thickness", args.thickness),
        ("--matrix-fraction", args.matrix_fraction),
        ("--bulk-ratio", args.bulk_ratio),
    ):
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(flag, f"must be a finite number > 0, got {value:g}")
    if args.max_stretch is not None and args.format != "calculix-deck":
        raise ConfigError("--max-stretch", "only applies to --format calculix-deck")
    data = load_params(args.params)
    options = {
        "thickness": args.thickness,
        "name": args.name,
        "matrix_fraction": args.matrix_fraction,
        "bulk_ratio": args.bulk_ratio,
    }
    if args.format == "calculix-deck":
        options["max_stretch"] = args.max_stretch
    text = export_card(data, args.format, path=args.params.name, options=_OPTIONS, **options)
    out = write_card(args.out, text, overwrite=args.overwrite)
    if not args.quiet:
        print(f"wrote {out} ({data['model']} -> {args.format})")
    return 0
