"""``knitframe plugins``: every registered plugin by kind, with description and package."""

from __future__ import annotations

import json


def add_parser(sub) -> None:
    p = sub.add_parser("plugins", help="list registered plugins", description=__doc__)
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=main)


def main(args) -> int:
    from knitframe.plugins import get_registry

    reg = get_registry()
    if args.json:
        rows = [
            {
                "kind": e.kind,
                "name": e.name,
                "description": e.description,
                "package": e.package,
                "version": e.version,
            }
            for e in reg.entries()
        ]
        print(json.dumps(rows, indent=2))
        return 0
    for kind, entries in reg.kinds.items():
        print(f"{kind}:")
        if not len(entries):
            print("  (none)")
        for e in entries.entries():
            print(f"  {e.name:<22s} {e.description}  [{e.package} {e.version}]")
    for plugin, reason in reg.failed:
        print(f"failed: {plugin}: {reason}")
    return 0
