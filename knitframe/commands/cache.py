"""``knitframe cache clear|info [--dir DIR]``: the executors' result cache.

Finished jobs (a sweep's points) are kept so that a rerun only computes what changed; the key covers
every input, the versions and the code (see ``docs/sweeps.md``). ``clear`` deletes the cached
results, and only them: other files in the folder are never touched. The default folder is
``$KNITFRAME_CACHE_DIR``, else ``$XDG_CACHE_HOME/knitframe/jobs``, else ``~/.cache/knitframe/jobs``
(an ``[executor] cache_dir`` names another; give it with ``--dir``).
"""

from __future__ import annotations

from pathlib import Path


def add_parser(sub) -> None:
    p = sub.add_parser("cache", help="clear or show the executors' result cache", description=__doc__)
    actions = p.add_subparsers(dest="cache_command", metavar="ACTION", parser_class=type(p))
    actions.required = True
    for name, text in (
        ("clear", "delete the cached results (nothing else in the folder)"),
        ("info", "the folder, the number of cached results and their size"),
    ):
        a = actions.add_parser(name, help=text, description=text)
        a.add_argument(
            "--dir", type=Path, default=None, help="cache folder (default: knitframe's user cache folder)"
        )
        a.set_defaults(func=main)


def _size(n: int) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n} B"  # pragma: no cover


def main(args) -> int:
    from knitframe.cache import JobCache, default_cache_dir
    from knitframe.errors import ConfigError

    folder = args.dir if args.dir is not None else default_cache_dir()
    if str(folder) == "":
        raise ConfigError("--dir", "an empty path is not a folder")
    if folder.exists() and not folder.is_dir():
        raise ConfigError("--dir", f"not a folder: {folder}")
    if not folder.exists():
        print(f"{folder}: no cache (nothing to {'clear' if args.cache_command == 'clear' else 'show'})")
        return 0
    cache = JobCache(folder, create=False)
    if args.cache_command == "clear":
        n, size = cache.clear()
        print(f"{folder}: removed {n} cached result{'s' if n != 1 else ''} ({_size(size)})")
    else:
        n, size = cache.info()
        print(f"{folder}: {n} cached result{'s' if n != 1 else ''} ({_size(size)})")
    return 0
