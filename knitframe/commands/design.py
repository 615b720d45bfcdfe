"""``knitframe design LIMB --library LIB --objective pressure_profile --target-mmHg 30 --out DIR``.

Designs a compression sleeve for a limb: the fabric of every region of a knitted tube, chosen from
a fabric library so that the objective (uniform stress, uniform pressure, or a graduated pressure
profile) is met without any fabric over its limit. LIMB is a scan (STL, OBJ, PLY); ``--example``
uses the built-in adult arm. Writes ``design.json``, ``knit-map.csv``, ``knit-map.png``,
``pressure.png`` and ``design.vtu``. The same as a config's ``[design]`` table and
:func:`knitframe.design`.
"""

from __future__ import annotations

from knitframe.outdir import add_overwrite_argument


def add_parser(sub) -> None:
    p = sub.add_parser("design", help="design a compression sleeve for a limb", description=__doc__)
    p.add_argument("limb", nargs="?", help="limb scan (STL, OBJ, PLY)")
    p.add_argument("--example", action="store_true", help="use the built-in example arm")
    p.add_argument(
        "--circumferences",
        default=None,
        metavar="MM,MM,...",
        help="measured circumferences (mm) instead of a scan, with --positions",
    )
    p.add_argument(
        "--positions",
        default=None,
        metavar="MM,MM,...",
        help="distances (mm) of the measured circumferences from the wrist or ankle",
    )
    p.add_argument("--library", default="builtin", help="fabric library: 'builtin' or a library.json")
    p.add_argument(
        "--objective",
        default="pressure_profile",
        help="design objective plugin: pressure_profile, pressure_uniformity or stress_variance",
    )
    p.add_argument(
        "--target-mmHg",
        type=float,
        default=None,
        dest="target_mmHg",
        help="target pressure (at the distal end for pressure_profile), mmHg",
    )
    p.add_argument(
        "--class",
        default=None,
        dest="compression_class",
        metavar="I|II|III|IV",
        help="pressure_profile: RAL-GZ 387 compression class; its middle is the distal target (default II)",
    )
    p.add_argument(
        "--graduation",
        default=None,
        help="pressure_profile: linear (100 %% to 60 %%, default), arm-sleeve (100/70/40 %%) or flat",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=None,
        help="pressure_profile: a station meets the prescription within this fraction of its target (0.2)",
    )
    p.add_argument(
        "--ceiling-mmHg",
        type=float,
        default=60.0,
        dest="ceiling_mmHg",
        help="no station's mean pressure may exceed this, mmHg (default 60)",
    )
    p.add_argument(
        "--limb-tolerance",
        type=float,
        default=0.03,
        dest="limb_tolerance",
        help="fraction the limb's circumference may change by (swelling): bands reported for it (0.03)",
    )
    p.add_argument(
        "--robust",
        action="store_true",
        help="design for the worst case over the limb ± --limb-tolerance and every --also-limb",
    )
    p.add_argument(
        "--also-limb",
        action="append",
        default=[],
        dest="also_limb",
        metavar="SCAN",
        help="another scan of the same limb (flexed, swollen); the design holds for all (repeatable)",
    )
    p.add_argument(
        "--gauge",
        action="append",
        default=[],
        metavar="FABRIC=STITCHES,COURSES",
        help="a library fabric's measured gauge: stitches and courses per 10 cm of a relaxed swatch "
        "(repeatable)",
    )
    p.add_argument(
        "--no-shaping",
        action="store_true",
        dest="no_shaping",
        help="knit one needle count from end to end (default: shaped by increases and decreases)",
    )
    p.add_argument(
        "--ratios",
        default=None,
        metavar="R,R,...",
        help="pressure_profile: target ratios from the distal end to the top (default 1,0.6)",
    )
    p.add_argument(
        "--mode",
        choices=("knitting", "paper"),
        default="knitting",
        help="knitting: needles × courses (default); paper: a wrist cylinder mapped element for element",
    )
    p.add_argument(
        "--method",
        choices=("optimal", "paper"),
        default="optimal",
        help="optimal: exact course bands (default); paper: the paper's per-element procedure",
    )
    p.add_argument(
        "--needles", type=int, default=None, help="knitting mode: stitches per course (default: searched)"
    )
    p.add_argument(
        "--min-courses",
        type=float,
        default=10.0,
        dest="min_courses",
        help="least courses in each region (default 10)",
    )
    p.add_argument(
        "--max-fabrics", type=int, default=None, dest="max_fabrics", help="at most this many distinct fabrics"
    )
    p.add_argument(
        "--pressure",
        choices=("equivalent", "local"),
        default="equivalent",
        help="the Laplace radius the objective uses (both are reported)",
    )
    p.add_argument("--out", default=None, help="output folder, new or empty (default: design-out)")
    add_overwrite_argument(p)
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=main)


def _numbers(text: str, option: str) -> list[float]:
    from knitframe.errors import ConfigError

    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ConfigError(option, f"expected comma-separated numbers, got {text!r}") from None


def _gauges(items: list[str]) -> dict[str, list[float]]:
    """``FABRIC=STITCHES,COURSES`` options as the ``[design.gauge]`` table."""
    from knitframe.errors import ConfigError

    out = {}
    for item in items:
        name, sep, numbers = item.partition("=")
        values = _numbers(numbers, "--gauge") if sep else []
        if not name.strip() or len(values) != 2:
            raise ConfigError("--gauge", f"expected FABRIC=STITCHES,COURSES (per 10 cm), got {item!r}")
        out[name.strip()] = values
    return out


def config_from_args(args) -> dict:
    """The ``[design]`` config table the command line stands for."""
    from pathlib import Path

    from knitframe.errors import ConfigError

    given = [bool(args.limb), bool(args.example), args.circumferences is not None]
    if sum(given) != 1:
        raise ConfigError(
            "LIMB", "give a limb scan, --example, or --circumferences with --positions (one of them)"
        )
    if args.circumferences is not None:
        if args.positions is None:
            raise ConfigError("--positions", "required with --circumferences")
        limb = {
            "circumferences_mm": _numbers(args.circumferences, "--circumferences"),
            "positions_mm": _numbers(args.positions, "--positions"),
        }
    else:
        limb = "example" if args.example else str(Path(args.limb).resolve())
    objective: dict = {"kind": args.objective}
    if args.target_mmHg is not None:
        objective["target_mmHg"] = args.target_mmHg
    if args.compression_class is not None and args.objective == "pressure_uniformity":
        from knitframe.errors import FieldError
        from knitframe.garment.prescription import class_target

        try:
            objective.setdefault("target_mmHg", class_target(args.compression_class))
        except FieldError as e:
            raise ConfigError("--class", e.problem) from None
    elif args.compression_class is not None and args.objective != "pressure_profile":
        raise ConfigError("--class", f"applies to a pressure objective, not {args.objective}")
    for key in ("compression_class", "graduation", "tolerance"):
        if getattr(args, key) is not None and args.objective == "pressure_profile":
            objective[key] = getattr(args, key)
        elif getattr(args, key) is not None and key != "compression_class":
            raise ConfigError("--" + key, f"applies to --objective pressure_profile, not {args.objective}")
    if args.ratios is not None:
        ratios = _numbers(args.ratios, "--ratios")
        objective["ratios"] = ratios
        objective["at"] = (
            [k / max(len(ratios) - 1, 1) for k in range(len(ratios))] if len(ratios) > 1 else [0.0]
        )
    library = args.library if args.library == "builtin" else str(Path(args.library).resolve())
    table = {
        "limb": limb,
        "library": library,
        "objective": objective,
        "method": args.method,
        "pressure": args.pressure,
        "min_courses": args.min_courses,
        "tube": {"mode": args.mode, "shaping": not args.no_shaping},
        "ceiling_mmHg": args.ceiling_mmHg,
        "limb_tolerance": args.limb_tolerance,
        "robust": args.robust,
        "limbs": [str(Path(x).resolve()) for x in args.also_limb],
        "gauge": _gauges(args.gauge),
    }
    if args.needles is not None:
        table["tube"]["needles"] = args.needles
    if args.max_fabrics is not None:
        table["max_fabrics"] = args.max_fabrics
    return {"pipeline": {"name": "design"}, "design": table}


_OPTION = {
    "design.limb": "LIMB",
    "design.library": "--library",
    "design.objective": "--objective",
    "design.objective.kind": "--objective",
    "design.objective.target_mmHg": "--target-mmHg",
    "design.objective.ratios": "--ratios",
    "design.objective.compression_class": "--class",
    "design.objective.graduation": "--graduation",
    "design.objective.tolerance": "--tolerance",
    "design.ceiling_mmHg": "--ceiling-mmHg",
    "design.limb_tolerance": "--limb-tolerance",
    "design.limbs": "--also-limb",
    "design.gauge": "--gauge",
    "design.tube.needles": "--needles",
    "design.min_courses": "--min-courses",
    "design.max_fabrics": "--max-fabrics",
}


def main(args) -> int:
    from pathlib import Path

    from knitframe.errors import ConfigError
    from knitframe.pipeline import Pipeline

    config = config_from_args(args)
    try:
        pipeline = Pipeline(config, base_dir=Path.cwd())
        result = pipeline.run(
            args.out if args.out is not None else "design-out", overwrite=args.overwrite, quiet=args.quiet
        )
    except ConfigError as e:  # name the command-line option rather than the config key it became
        option = next(
            (
                _OPTION[k]
                for k in sorted(_OPTION, key=len, reverse=True)
                if e.path == k or e.path.startswith(k + ".")
            ),
            None,
        )
        if option is None:
            raise
        raise ConfigError(option, e.problem) from None
    if not args.quiet:
        from knitframe.garment.outputs import station_table

        d = result.objects["design"]
        print(station_table(d))
        for note in d.limb.notes:
            print(f"limb: {note}")
        est = [name for name, v in d.to_json()["pitches"].items() if v["estimate"]]
        if est:
            e = 100 * d.safety.get("pitch_error", 0.05)
            print(
                f"pitches: {', '.join(est)} use estimated relaxed pitches; design.json gives each station's "
                f"pressure band for a ±{e:g} % pitch error (give measured gauges with --gauge)"
            )
        for note in result.results["design"].get("machine", {}).get("notes", []):
            print(f"note: {note}")
        print(result.results["design"]["headline"])
        print(f"wrote {', '.join(result.summary['outputs'])} and summary.json to {result.out}")
    return 0
