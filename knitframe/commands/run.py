"""``knitframe run CONFIG [--out DIR] [--resume | --overwrite] [--no-cache]``: run a config-selected pipeline.

The outputs appear in DIR only when the whole run succeeded. An existing DIR that holds anything is
refused unless ``--resume`` continues the same config's run there, or ``--overwrite`` replaces the
files an earlier knitframe run wrote there (nothing else is touched).
"""

from __future__ import annotations

from pathlib import Path

from knitframe.errors import ConfigError
from knitframe.outdir import add_overwrite_argument


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="run a pipeline config", description=__doc__)
    p.add_argument("config", nargs="?", help="TOML config file")
    p.add_argument("--example", action="store_true", help="run the built-in example config")
    p.add_argument("--out", default=None, help="output directory (default: <config name>-out)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument(
        "--resume", action="store_true", help="continue the same config's killed run from its checkpoints"
    )
    add_overwrite_argument(mode)
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.add_argument(
        "--no-cache",
        action="store_true",
        help="compute every executor job afresh (a sweep's points): cached results are neither read nor kept",
    )
    p.set_defaults(func=main)


def main(args) -> int:
    from knitframe.examples import example_config
    from knitframe.pipeline import run

    if args.example == bool(args.config):
        raise ConfigError("", "give a CONFIG file or --example (not both)")
    config = example_config() if args.example else Path(args.config)
    out = args.out if args.out is not None else f"{Path(config).stem}-out"
    result = run(
        config, out, resume=args.resume, overwrite=args.overwrite, quiet=args.quiet, no_cache=args.no_cache
    )
    if not args.quiet:
        for stage in result.summary["stages"]:
            print(f"  {stage['stage']:<12s} {stage['seconds']:9.3f} s")
        print(f"wrote {len(result.summary['outputs']) + 1} files to {result.out}")
        for name, res in result.results.items():
            if isinstance(res, dict) and res.get("headline"):
                print(f"  {name}: {res['headline']}")
    return 0
