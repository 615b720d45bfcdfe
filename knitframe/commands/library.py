"""``knitframe library build|show|build-builtin``: fabric libraries for garment design.

``knitframe library build PARAMS.json... --out DIR [--name NAME] [--course-pitch MM ...]
[--wale-pitch MM ...] [--gauge STITCHES,COURSES] [--max-tension N_PER_MM ...] [--max-stretch L ...]
[--pattern P ...] [--yarn Y ...] [--stitch-length S ...] [--arc-length MM ...] [--entry-name NAME ...]
[--scatter S ...] [--overwrite]``
writes ``DIR/library.json`` with one entry per fitted model (a ``params.json`` of ``knitframe
fit``). Each per-fabric option takes one value per params file, or one for all. Pattern, yarn,
stitch length, arc length and entry name come from the params file's metadata where present.
``--gauge 22,30`` (stitches and courses per 10 cm of a relaxed swatch, for every file) gives
measured pitches 100/22 and 100/30 mm; given pitches count as measured too. Pitches not given are
estimated by Munden's relations from the arc length or stitch length; ``--max-tension`` is required.

``knitframe library show [LIB.json|builtin]`` prints a library as a table (default: the built-in one);
estimated pitches are marked ``est``.

``knitframe library build-builtin --out DIR`` refits the built-in library from the Singal et al.
2024 tests shipped with knitframe: ``DIR/library.json`` plus each fit's params.json and fit.png in
``DIR/fits/``.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from knitframe.errors import ConfigError
from knitframe.outdir import OutputDir, add_overwrite_argument, fingerprint

#: per-file options of ``library build``: (flag, keyword of FabricLibrary.from_fits, type, metavar, help)
_PER_FILE = (
    (
        "--course-pitch",
        "course_pitch",
        float,
        "MM",
        "relaxed stitch width along the course, mm per wale column",
    ),
    ("--wale-pitch", "wale_pitch", float, "MM", "relaxed stitch height along the wale, mm per course"),
    (
        "--max-tension",
        "max_tension",
        float,
        "N_PER_MM",
        "largest course tension the fabric may carry, N/mm (required)",
    ),
    ("--max-stretch", "max_stretch", float, "L", "largest course stretch it may take (optional)"),
    (
        "--pattern",
        "pattern",
        str,
        "P",
        "stitch pattern (jersey, garter, rib, seed, ...) if not in the params file",
    ),
    ("--yarn", "yarn", str, "Y", "yarn name if not in the params file"),
    ("--stitch-length", "stitch_length", float, "S", "machine stitch-length setting, if known"),
    ("--arc-length", "arc_length", float, "MM", "mm of yarn per stitch, if known"),
    ("--entry-name", "names", str, "NAME", "entry names (default: each params file's folder name)"),
    (
        "--scatter",
        "tension_scatter",
        float,
        "S",
        "scatter of the course tests' repeats, median relative half-spread of their tension (optional)",
    ),
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "library", help="build and show fabric libraries for garment design", description=__doc__
    )
    actions = p.add_subparsers(dest="library_command", metavar="ACTION", parser_class=type(p))
    actions.required = True

    b = actions.add_parser(
        "build",
        help="a library.json from fitted params.json files",
        description="Write DIR/library.json with one entry per params.json of a fit.",
    )
    b.add_argument("params", nargs="+", type=Path, help="params.json files written by 'knitframe fit'")
    b.add_argument("--name", default=None, help="library name (default: the output folder's name)")
    for flag, key, typ, metavar, text in _PER_FILE:
        b.add_argument(
            flag,
            nargs="+",
            type=typ,
            metavar=metavar,
            default=None,
            dest=key,
            help=f"{text}; one per params file or one for all",
        )
    b.add_argument(
        "--gauge",
        default=None,
        metavar="STITCHES,COURSES",
        help="knitter's gauge of every fabric: stitches and courses per 10 cm of a relaxed swatch, "
        "e.g. 22,30 (course pitch 100/STITCHES mm, wale pitch 100/COURSES mm); "
        "not with --course-pitch/--wale-pitch",
    )
    _output_arguments(b, main_build)

    s = actions.add_parser(
        "show",
        help="print a library as a table",
        description="Print a library.json (or the built-in library) as a table.",
    )
    s.add_argument("library", nargs="?", default="builtin", help="library.json, or 'builtin' (default)")
    s.set_defaults(func=main_show)

    r = actions.add_parser(
        "build-builtin",
        help="refit the built-in library from the shipped Singal et al. 2024 data",
        description="Refit the built-in library: DIR/library.json and DIR/fits/<name>-params.json, "
        "<name>-fit.png. About 40 s on one core.",
    )
    _output_arguments(r, main_build_builtin)


def _output_arguments(parser, func) -> None:
    """--out, --overwrite and --quiet of an action that writes a folder, and the function that runs it."""
    parser.add_argument("--out", required=True, help="output folder (new, or empty; see --overwrite)")
    add_overwrite_argument(parser)
    parser.add_argument("--quiet", action="store_true", help="print nothing on success")
    parser.set_defaults(func=func)


def main_build(args) -> int:
    from knitframe.garment.library import FabricLibrary
    from knitframe.version import __version__

    n = len(args.params)
    kwargs = {}
    for flag, key, _, _, _ in _PER_FILE:
        values = getattr(args, key)
        if values is not None and len(values) not in (1, n):
            raise ConfigError(
                flag, f"got {len(values)} values for {n} params files; give one per file or one for all"
            )
        if values is not None:
            for v in values:
                if isinstance(v, float) and not math.isfinite(v):
                    raise ConfigError(flag, f"must be finite, got {v!r}")
        kwargs[key] = values
    kwargs["gauge"] = _gauge_option(args.gauge)
    if kwargs["gauge"] is not None and (args.course_pitch is not None or args.wale_pitch is not None):
        both = "--course-pitch" if args.course_pitch is not None else "--wale-pitch"
        raise ConfigError("--gauge", f"give either --gauge or {both}, not both")
    if kwargs["max_tension"] is None:
        raise ConfigError(
            "--max-tension", "required: the largest course tension (N/mm) each fabric may carry"
        )
    od = OutputDir(
        args.out,
        command="library build",
        overwrite=args.overwrite,
        fingerprint=fingerprint(
            {"params": [str(p.resolve()) for p in args.params], "name": args.name, **kwargs}
        ),
    )
    od.check()  # before any work
    name = args.name if args.name is not None else od.out.name
    flags = {key: flag for flag, key, *_ in _PER_FILE} | {"gauge": "--gauge"}
    try:
        library = FabricLibrary.from_fits(args.params, name=name, **kwargs)
    except ConfigError as e:  # name the command-line option, not the keyword
        path = flags.get(e.path, e.path)
        raise ConfigError(path, e.problem, source=e.source) from None
    with od:
        library.save(od.staging / "library.json")
        od.commit(
            {
                "knitframe": __version__,
                "command": "library build",
                "params": [str(p) for p in args.params],
                "name": name,
                "entries": library.names,
            }
        )
    if not args.quiet:
        print(f"library '{library.name}': {len(library)} fabrics ({', '.join(library.names)})")
        print(f"wrote {od.out / 'library.json'}")
    return 0


def _gauge_option(text: str | None) -> tuple[float, float] | None:
    """``--gauge STITCHES,COURSES``: two finite numbers > 0, per 10 cm."""
    if text is None:
        return None
    parts = text.split(",")
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 2:
        raise ConfigError("--gauge", f"expected STITCHES,COURSES per 10 cm (e.g. 22,30), got {text!r}")
    for what, v in zip(("stitches", "courses"), values):
        if not (math.isfinite(v) and v > 0):
            raise ConfigError("--gauge", f"{what} per 10 cm must be a finite number > 0, got {v!r}")
    return values


def main_build_builtin(args) -> int:
    from knitframe.garment.library import BUILTIN_FITTER, BUILTIN_MODEL, build_builtin
    from knitframe.version import __version__

    od = OutputDir(
        args.out,
        command="library build-builtin",
        overwrite=args.overwrite,
        fingerprint=fingerprint({"builtin": BUILTIN_MODEL, "fitter": BUILTIN_FITTER}),
    )
    od.check()

    def progress(name, result):
        if not args.quiet:
            print(f"{name}: {result.headline()}", flush=True)

    with od:
        library = build_builtin(od.staging, progress=progress)
        library.save(od.staging / "library.json")
        od.commit(
            {
                "knitframe": __version__,
                "command": "library build-builtin",
                "model": BUILTIN_MODEL,
                "fitter": BUILTIN_FITTER,
                "entries": library.names,
            }
        )
    if not args.quiet:
        print(f"wrote {od.out / 'library.json'} and {od.out / 'fits'}/")
    return 0


def _g(x: float | None, digits: int = 4) -> str:
    return "-" if x is None else f"{x:.{digits}g}"


def _columns(entry) -> tuple[str, str, str, str]:
    """(a, b, θ, other parameters) of an entry's model for the table."""
    params = dict(entry.params)
    a = [k for k in params if k == "a" or (k.startswith("a") and k[1:].isdigit())]
    b = [k for k in params if k == "b" or (k.startswith("b") and k[1:].isdigit())]
    t = [k for k in params if k.startswith("theta")]
    other = [k for k in params if k not in a + b + t]
    theta = "/".join(_g(params[k], 3) for k in t) if t else _FIXED.get(entry.model, "-")
    return (
        "/".join(_g(params[k], 3) for k in a) or "-",
        "/".join(_g(params[k], 3) for k in b) or "-",
        theta,
        " ".join(f"{k}={_g(params[k], 3)}" for k in other),
    )


_FIXED = {"hgo2m": "0/90"}


def format_table(library) -> str:
    """The library as a text table, then each entry's full source and pitch source."""
    head = (
        "name",
        "pattern",
        "yarn",
        "model",
        "a N/mm",
        "b",
        "theta deg",
        "pitch c/w mm",
        "max T N/mm",
        "max l1",
        "NRMSE %",
        "scatter %",
        "other params",
        "source",
    )
    rows = []
    for e in library:
        a, b, t, other = _columns(e)
        nrmse = e.fit.get("nrmse", {}).get("overall") if isinstance(e.fit.get("nrmse"), dict) else None
        short = re.split(r" \(|[:;]", e.source, maxsplit=1)[0]  # the full text is listed below the table
        rows.append(
            (
                e.name,
                e.pattern,
                e.yarn,
                e.model,
                a,
                b,
                t,
                f"{e.course_pitch:.3g}/{e.wale_pitch:.3g}" + (" est" if e.pitch_is_estimate else ""),
                _g(e.max_tension),
                _g(e.max_stretch),
                "-" if nrmse is None else f"{100 * nrmse:.2f}",
                "-" if e.tension_scatter is None else f"{100 * e.tension_scatter:.1f}",
                other,
                short[:60] + ("..." if len(short) > 60 else ""),
            )
        )
    widths = [max(len(str(r[i])) for r in [head, *rows]) for i in range(len(head))]
    line = lambda r: "  ".join(str(c).ljust(w) for c, w in zip(r, widths)).rstrip()  # noqa: E731
    out = [
        f"library '{library.name}': {len(library)} fabrics",
        *([library.source] if library.source else []),
        "",
        line(head),
        line(tuple("-" * w for w in widths)),
        *(line(r) for r in rows),
        *(
            [
                "pitch est: estimated, not measured; measure them or give a knitter's gauge "
                "(library build --gauge)"
            ]
            if any(e.pitch_is_estimate for e in library)
            else []
        ),
        "",
        "sources:",
    ]
    for e in library:
        out.append(f"  {e.name}: {e.source}")
        out.append(f"  {' ' * len(e.name)}  pitches: {e.pitch_source}")
    return "\n".join(out)


def main_show(args) -> int:
    from knitframe.garment.library import FabricLibrary, builtin_library

    library = builtin_library() if args.library == "builtin" else FabricLibrary.load(args.library)
    print(format_table(library))
    return 0
