"""``knitframe knitout DESIGN_DIR --out DIR [--machine SWG091N2] [--gauge 15] [--width N]
[--carriers YARN=C,...] [--stitch-numbers SL=N,...|FILE] [--dat] [--no-check]``.

Turns a design folder (``design.json`` and ``knit-map.csv`` of ``knitframe design`` in knitting
mode) into a knitout program for a V-bed machine: ``sleeve.k``, checked by knitout-interpreter (a
simulated Shima SWG091N2) before it is written, its stitch chart ``sleeve-chart.png`` and, with
``--dat``, a Shima DAT file ``sleeve.dat``. A shaped tube (``tube.needles_per_course`` in
``design.json``) is knitted with increases and decreases at its edges. The same as a
``[design.machine]`` table in a config.
See docs/machine-output.md.
"""

from __future__ import annotations

import json
from pathlib import Path

from knitframe.outdir import OutputDir, add_overwrite_argument, fingerprint

#: MachineSpec and plan fields -> the option that sets them
_OPTION = {
    "machine": "--machine",
    "gauge": "--gauge",
    "width": "--width",
    "carriers": "--carriers",
    "stitch_numbers": "--stitch-numbers",
    "pattern": "DESIGN_DIR",
    "tube": "DESIGN_DIR",
}


def add_parser(sub) -> None:
    p = sub.add_parser(
        "knitout",
        help="knitout program (and DAT file) of a designed sleeve for a V-bed machine",
        description=__doc__,
    )
    p.add_argument("design", type=Path, metavar="DESIGN_DIR", help="output folder of knitframe design")
    p.add_argument("--out", required=True, help="output folder (new, or empty; see --overwrite)")
    p.add_argument("--machine", default="SWG091N2", help="knitout ;;Machine: (default SWG091N2)")
    p.add_argument(
        "--gauge",
        type=int,
        default=15,
        help="needles per inch (default 15); the tube is knitted at half gauge",
    )
    p.add_argument(
        "--width",
        type=int,
        default=None,
        help="needles per bed the program may use (default: the machine's, 540)",
    )
    p.add_argument(
        "--carriers",
        default=None,
        metavar="YARN=C,...",
        help="carrier of each yarn (default: 1, 2, ... in the order the tube uses the yarns)",
    )
    p.add_argument(
        "--stitch-numbers",
        default=None,
        dest="stitch_numbers",
        metavar="SL=N,...|FILE",
        help="stitch length (machine setting) or 'default' -> x-stitch-number, over the built-in table "
        "10=4,11=5,12=6,default=5; or a .toml/.json file holding that table",
    )
    p.add_argument(
        "--dat", action="store_true", help="also write sleeve.dat (Shima DAT) with knitout-to-dat-python"
    )
    p.add_argument(
        "--no-check",
        action="store_false",
        dest="check",
        help="do not run the program through knitout-interpreter before writing it",
    )
    add_overwrite_argument(p)
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=main)


def _pairs(text: str, option: str) -> dict[str, int]:
    """``KEY=N,KEY=N`` as a dict of integers."""
    from knitframe.errors import ConfigError

    out: dict[str, int] = {}
    for item in (x.strip() for x in text.split(",")):
        if not item:
            continue
        key, sep, value = item.partition("=")
        key = key.strip()
        try:
            number = int(value.strip())
        except ValueError:
            number = None
        if not sep or not key or number is None:
            raise ConfigError(
                option, f"expected KEY=N pairs separated by commas (N an integer), got {item!r}"
            )
        if key in out:
            raise ConfigError(option, f"{key!r} is given twice")
        out[key] = number
    return out


def _stitch_numbers(text: str) -> dict:
    """The ``--stitch-numbers`` table: inline pairs, or a .toml/.json file holding the table."""
    from knitframe.errors import ConfigError

    path = Path(text).expanduser()
    if path.suffix.lower() not in (".toml", ".json"):
        return _pairs(text, "--stitch-numbers")
    if not path.is_file():
        raise ConfigError("--stitch-numbers", f"file not found: {text}")
    try:
        raw = path.read_text(encoding="utf-8")
        if path.suffix.lower() == ".json":
            table = json.loads(raw)
        else:
            import tomllib

            table = tomllib.loads(raw)
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise ConfigError(
            "--stitch-numbers", f"{text}: not a readable table ({' '.join(str(e).split())})"
        ) from None
    table = table.get("stitch_numbers", table) if isinstance(table, dict) else table
    if not isinstance(table, dict):
        raise ConfigError("--stitch-numbers", f"{text}: expected a table of stitch length -> stitch number")
    return {str(k): v for k, v in table.items()}


def main(args) -> int:
    from knitframe.errors import ConfigError, FieldError
    from knitframe.garment.knitout import KnitMap, MachineSpec, missing, plan, program, write_machine_outputs
    from knitframe.version import __version__

    def field_error(e: FieldError) -> ConfigError:
        head, _, key = e.field.partition(".")
        return ConfigError(_OPTION.get(head, "DESIGN_DIR"), f"{key}: {e.problem}" if key else e.problem)

    carriers = _pairs(args.carriers, "--carriers") if args.carriers is not None else {}
    numbers = _stitch_numbers(args.stitch_numbers) if args.stitch_numbers is not None else {}
    try:
        spec = MachineSpec(args.machine, args.gauge, args.width, carriers, numbers, args.dat)
    except FieldError as e:
        raise field_error(e) from None
    od = OutputDir(
        args.out,
        command="knitout",
        overwrite=args.overwrite,
        fingerprint=fingerprint(
            {
                "design": str(args.design.resolve()),
                "machine": args.machine,
                "gauge": args.gauge,
                "width": args.width,
                "carriers": carriers,
                "stitch_numbers": numbers,
                "dat": args.dat,
                "check": args.check,
            }
        ),
    )
    od.check()  # before any work
    for option, problem in (
        ("--no-check", missing(check=args.check)),
        ("--dat", missing(check=False, dat=args.dat)),
    ):
        if problem:
            raise ConfigError(option, problem)
    try:
        kmap = KnitMap.read(args.design)
        p = plan(kmap, spec)
    except FieldError as e:
        raise field_error(e) from None
    lines, report = program(p, check=args.check)
    with od:
        names, info = write_machine_outputs(p, lines, od.staging, dat=args.dat)
        od.commit(
            {
                "knitframe": __version__,
                "command": "knitout",
                "design": str(args.design),
                **info,
                "check": report,
            }
        )
    if not args.quiet:
        carriers_text = ", ".join(f"{y} on carrier {c}" for y, c in p.carriers.items())
        checked = (
            f"checked by {report['interpreter']}: {report['loops']} loops, no error or warning"
            if report
            else "not checked (--no-check)"
        )
        print(f"{kmap.description} in {len(kmap.bands)} bands ({carriers_text}); {checked}")
        for note in p.notes:
            print(f"note: {note}")
        print(f"wrote {', '.join(names)} and summary.json to {od.out}")
    return 0
