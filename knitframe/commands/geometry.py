"""``knitframe geometry PATTERN``: the unit cell of a pattern as VTU, a three-view PNG and geometry.json.

Example: ``knitframe geometry jersey --stitch-length 11 --yarn cotton --out jersey-geo`` writes
``centerlines.vtu`` and ``tubes.vtu`` (open in ParaView), ``preview.png`` and ``geometry.json``
(arc length, pitches, minimum clearance, the places closer than the yarn diameter and the
bending wavenumber). Pattern options go in as ``--option KEY=VALUE``, e.g. a folded rib:
``knitframe geometry rib --stitch-length 11 --course-pitch 0.8 --option fold=1.5``.
"""

from __future__ import annotations

import json
import re
import tomllib

from knitframe.outdir import OutputDir, add_overwrite_argument, fingerprint

#: most polyline segments per yarn in the VTU files (each tube has 16 sides per segment)
MAX_SEGMENTS = 100_000
#: a ``fabric.<key>`` path in an error, named as the command's option instead
_FABRIC_KEY = re.compile(r"\bfabric\.[a-z_]+")
#: a ``fabric.pattern_options.<key>[.<sub>…]`` path, named as ``--option <key>[.<sub>…]``
_OPTION_KEY = re.compile(r"\bfabric\.pattern_options\.([A-Za-z_]\w*(?:\.\w+)*)")


def _option(path: str) -> str:
    """The command-line name of a ``fabric.*`` config path: ``fabric.arc_length`` -> ``--arc-length``,
    ``fabric.pattern_options.fold`` -> ``--option fold`` (nested keys keep their dots)."""
    m = _OPTION_KEY.fullmatch(path)
    if m:
        return f"--option {m.group(1)}"
    key = path.removeprefix("fabric.")
    return "PATTERN" if key == "pattern" else "--" + key.replace("_", "-")


def pattern_options(pairs: list[str]) -> dict:
    """``["fold=1.5", "Kc=6"]`` -> ``{"fold": 1.5, "Kc": 6}``; each value is read as a TOML value
    (a bare word as a string). ConfigError at ``--option`` on a malformed pair."""
    from knitframe.errors import ConfigError

    options: dict = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        key = key.strip()
        if not sep or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", key) or not value.strip():
            raise ConfigError("--option", f"expects KEY=VALUE, e.g. fold=1.5, got {pair!r}")
        try:
            options[key] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            options[key] = value.strip()
    return options


def add_parser(sub) -> None:
    p = sub.add_parser(
        "geometry", help="build and export a pattern's unit-cell geometry", description=__doc__
    )
    p.add_argument("pattern", help="pattern name (see `knitframe plugins`)")
    p.add_argument("--stitch-length", type=float, default=None, help="machine setting, e.g. 10, 11, 12")
    p.add_argument(
        "--arc-length", type=float, default=None, help="yarn length per stitch, mm (overrides the setting)"
    )
    p.add_argument("--yarn", default="cotton", help="yarn name from the library (default cotton)")
    p.add_argument("--course-pitch", type=float, default=None, help="stitch width, mm (default: Munden)")
    p.add_argument("--wale-pitch", type=float, default=None, help="stitch height, mm (default: Munden)")
    p.add_argument("--out", default=None, help="output folder, new or empty (default: <pattern>-geometry)")
    add_overwrite_argument(p)
    p.add_argument("--segments", type=int, default=256, help="polyline segments per yarn in the VTU files")
    p.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a pattern option (see docs/configuration.md), e.g. fold=1.5; repeatable",
    )
    p.set_defaults(func=main)


def main(args) -> int:
    from knitframe.errors import ConfigError
    from knitframe.geometry import checked_cell, clearance
    from knitframe.plugins import get_registry
    from knitframe.records import Fabric
    from knitframe.yarn import resolve_yarn

    out = args.out if args.out is not None else f"{args.pattern}-geometry"
    od = OutputDir(out, command="geometry", overwrite=args.overwrite, fingerprint=fingerprint(vars(args)))
    od.check()  # before any work
    reg = get_registry()
    yarn = resolve_yarn(reg, args.yarn, "--yarn")
    if not 8 <= args.segments <= MAX_SEGMENTS:
        raise ConfigError("--segments", f"must be in [8, {MAX_SEGMENTS}], got {args.segments}")
    table = {"pattern": reg["pattern"].canonical(args.pattern), "yarn": yarn}  # stockinette: jersey
    for key in ("stitch_length", "arc_length", "course_pitch", "wale_pitch"):
        if getattr(args, key) is not None:
            table[key] = getattr(args, key)
    options = pattern_options(args.option)
    if options:
        table["pattern_options"] = options
    try:
        cell = checked_cell(Fabric.from_dict(table, "fabric"), reg)  # every refusal before any output
    except ConfigError as e:
        rename = lambda m: _option(m.group(0))  # noqa: E731
        raise ConfigError(
            _option(e.path), _FABRIC_KEY.sub(rename, _OPTION_KEY.sub(rename, e.problem))
        ) from None
    clr = clearance(cell)
    with od:
        info = _write(od, cell, clr, args, yarn, options)
    print(
        f"{cell.pattern}: {cell.arc_length_per_stitch:.6g} mm/stitch, pitches {cell.course_pitch:.4g} x "
        f"{cell.wale_pitch:.4g} mm, min clearance {clr.minimum:.4g} mm ({clr.minimum / cell.dk:.3g} dk), "
        f"{len(clr.overlaps)} places closer than dk, bending wavenumber {info['bending_wavenumber']:.4g}/mm "
        f"({info['bending_waves_per_stitch']:.3g} waves per stitch)"
    )
    print(f"wrote {', '.join(str(od.out / f) for f in od.committed)}")
    return 0


def _write(od: OutputDir, cell, clr, args, yarn, options: dict) -> dict:
    """The geometry files, staged and then committed to the output folder; the geometry.json data."""
    from knitframe.geometry import plot_views, summary, write_vtu
    from knitframe.version import __version__

    out = od.staging
    write_vtu(cell, out, n=args.segments)
    plot_views(cell, out / "preview.png", clearance=clr)
    info = summary(cell, clr)
    info.update(
        {
            "yarn": {"name": yarn.name, "d0": yarn.d0, "dk": yarn.dk, "source": yarn.source},
            "stitch_length": args.stitch_length,
            "arc_length_target": args.arc_length,
            "pattern_options": options,
            "knitframe": __version__,
        }
    )
    (out / "geometry.json").write_text(json.dumps(info, indent=2) + "\n", encoding="utf-8")
    od.commit({"knitframe": __version__, "command": "geometry", "pattern": cell.pattern})
    return info
