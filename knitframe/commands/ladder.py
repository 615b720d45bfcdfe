"""``knitframe ladder CONFIG --out DIR [--rungs NAMES] [--max-time SECONDS] [--overwrite]``: what
accuracy costs.

Runs the config's pipeline with the ``[ladder]`` stage: its ``[fabric]`` and ``[scene]`` through a
list of rungs of fidelity (the fitted reduced model, the rod solver at three resolutions, the
volumetric solver at several meshes), each with its wall time, peak memory and the NRMSE of its
course and wale tension against the best rung and, with a ``[data]`` table, against the
measurement. Before a rung starts its estimated time and memory are printed; ``--max-time`` skips
the rungs estimated over it. Writes ``ladder.csv``, ``ladder.md``, ``ladder.png`` (time against
error), ``curves.png`` and ``ladder-curves.csv``. ``--rungs`` and ``--max-time`` replace the
config's ``[ladder]`` rungs and max_time. The same as :func:`knitframe.ladder`.
"""

from __future__ import annotations

from knitframe.outdir import add_overwrite_argument


def add_parser(sub) -> None:
    from knitframe.ladder import DEFAULT_RUNGS, RUNGS

    p = sub.add_parser(
        "ladder",
        help="run one fabric and scene through rungs of fidelity: time, memory, error",
        description=__doc__,
    )
    p.add_argument("config", help="TOML config with [fabric] and [scene] (and [data] for measured curves)")
    p.add_argument("--out", default=None, help="output folder, new or empty (default: <config name>-ladder)")
    p.add_argument(
        "--rungs",
        default=None,
        metavar="NAMES",
        help=f"comma-separated rungs of {', '.join(RUNGS)}, or rod:N, volumetric:p1:r/X, "
        "volumetric:p2:r/X at any resolution; three seeds of one order add a mesh-convergence table "
        f"(default: {','.join(DEFAULT_RUNGS)})",
    )
    p.add_argument(
        "--max-time",
        type=float,
        default=None,
        dest="max_time",
        metavar="SECONDS",
        help="skip the rungs whose estimated wall time is over this many seconds",
    )
    add_overwrite_argument(p)
    p.add_argument("--quiet", action="store_true", help="print only the table")
    p.set_defaults(func=main)


def _options(args) -> tuple[list[str] | None, float | None]:
    from knitframe.errors import ConfigError

    rungs = None
    if args.rungs is not None:
        rungs = [r.strip() for r in args.rungs.split(",")]
        if not all(rungs):
            raise ConfigError("--rungs", f"expected comma-separated rung names, got {args.rungs!r}")
    if args.max_time is not None and not args.max_time > 0:
        raise ConfigError("--max-time", f"must be > 0 seconds, got {args.max_time:g}")
    return rungs, args.max_time


_OPTION = {"ladder.rungs": "--rungs", "ladder.max_time": "--max-time"}


def main(args) -> int:
    from pathlib import Path

    from knitframe.errors import ConfigError
    from knitframe.ladder import ladder_config
    from knitframe.pipeline import Pipeline

    rungs, max_time = _options(args)
    config, base, source = ladder_config(Path(args.config), rungs=rungs, max_time=max_time)
    try:
        pipeline = Pipeline(config, base_dir=base, source=source)
    except ConfigError as e:  # name the command-line option rather than the config key it became
        option = next(
            (
                o
                for k, o in _OPTION.items()
                if (e.path == k or e.path.startswith(k + "["))
                and ((o == "--rungs" and rungs is not None) or (o == "--max-time" and max_time is not None))
            ),
            None,
        )
        if option is None:
            raise
        raise ConfigError(option, e.problem) from None
    out = args.out if args.out is not None else f"{Path(args.config).stem}-ladder"
    result = pipeline.run(out, overwrite=args.overwrite, quiet=args.quiet)
    print(result.objects["ladder"].table, end="")
    if not args.quiet:
        print(f"wrote {', '.join(result.summary['outputs'])} and summary.json to {result.out}")
    return 0
