"""The ``knitframe`` command. Each subcommand lives in :mod:`knitframe.commands`.

Errors caused by input print one line, ``knitframe: error: <what>``, and exit with code 2
(3 for a numerical failure); there is never a traceback for them. The file system refusing a write
(a full disk, a quota, a read-only or removed folder, no permission) is one line too, naming the
path and the way on, and exit code 1.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import logging
import os
import sys
import warnings

from knitframe.errors import KnitframeError, KnitframeWarning, WriteError
from knitframe.version import __version__

__all__ = ["main", "COMMANDS"]

#: Subcommand modules; each defines ``add_parser(subparsers)`` which sets ``func`` on its parser.
COMMANDS = (
    "run",
    "plugins",
    "yarn",
    "geometry",
    "fit",
    "design",
    "library",
    "export",
    "ladder",
    "knitout",
    "cache",
)


class _Parser(argparse.ArgumentParser):
    """argparse with the house error format: one line, ``knitframe: error: …``, exit code 2."""

    def error(self, message: str):
        print(f"knitframe: error: {message} (see '{self.prog} --help')", file=sys.stderr)
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="knitframe", description="Mechanics of weft-knitted fabrics: simulate, fit and design."
    )
    parser.add_argument("--version", action="version", version=f"knitframe {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMANDS:
        importlib.import_module(f"knitframe.commands.{name}").add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    _log_to_stderr(quiet=bool(getattr(args, "quiet", False)))
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        # numpy's floating-point warnings never reach the terminal: a non-finite intermediate is an
        # error (the code that can name the field raises a ConfigError or NumericalError first)
        warnings.simplefilter("error", RuntimeWarning)
        warnings.showwarning = _show_warning
        try:
            return int(args.func(args) or 0)
        except (KnitframeError, OSError) as e:
            if isinstance(e, OSError):
                e = _write_error(e)
            # --resume is named only by a command that has it
            text = e.line(resume=hasattr(args, "resume")) if isinstance(e, WriteError) else str(e)
            print(f"knitframe: error: {text}", file=sys.stderr)
            return e.exit_code
        except RuntimeWarning as e:
            print(f"knitframe: error: numerical failure (non-finite value): {e}", file=sys.stderr)
            return 3
        except KeyboardInterrupt:
            print("knitframe: interrupted", file=sys.stderr)
            return 130


def _write_error(error: OSError) -> WriteError:
    """An OS error outside an output folder (which names its own files): the file it names or was
    writing, or standard output when that is a file on a full file system."""
    found = WriteError.of(error)
    if found.path is None and found.errno == errno.ENOSPC:
        try:
            full = os.fstatvfs(sys.stdout.fileno()).f_bavail == 0
        except (AttributeError, ValueError, OSError):  # io.UnsupportedOperation is an OSError
            full = False
        if full:
            return WriteError(error, "standard output")
    return found


def _log_to_stderr(*, quiet: bool) -> None:
    """knitframe's log records (``resuming from step …``) as ``knitframe: <message>`` lines on stderr."""
    log = logging.getLogger("knitframe")
    log.handlers = [h for h in log.handlers if not getattr(h, "_knitframe_cli", False)]
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("knitframe: %(message)s"))
    handler._knitframe_cli = True
    log.addHandler(handler)
    log.setLevel(logging.WARNING if quiet else logging.INFO)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings as one line on stderr: ``knitframe: warning: <message>`` (no source line)."""
    text = " ".join(str(message).split())
    prefix = (
        "knitframe: warning: "
        if issubclass(category, KnitframeWarning)
        else f"knitframe: warning: {category.__name__}: "
    )
    print(prefix + text, file=sys.stderr)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
