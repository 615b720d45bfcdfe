"""``knitframe yarn NAME``: what the solvers read from a yarn, and whether each number is measured.

Every quantity the rod and volumetric solvers take from the yarn record (diameters, moduli, axial
shear, bending stiffness, contact stiffness, packing and compaction limit, core modulus), with its
value, unit and status: ``measured`` (the record's ``measured`` list names it), ``estimate`` (given
but not measured) or ``derived`` (computed from the other rows, with the formula). Example::

    knitframe yarn cotton
    knitframe yarn wool --config my-fabric.toml     # a yarn of the config's [yarns] table
"""

from __future__ import annotations

import json

import attrs


def add_parser(sub) -> None:
    p = sub.add_parser("yarn", help="show what the solvers read from a yarn record", description=__doc__)
    p.add_argument("name", help="library yarn (see `knitframe plugins`) or a yarn of --config")
    p.add_argument("--config", default=None, help="a config whose [yarns] table defines NAME")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=main)


def main(args) -> int:
    from knitframe.plugins import get_registry
    from knitframe.yarn import config_yarns, resolve_yarn, yarn_properties

    reg = get_registry()
    if args.config is not None:
        from knitframe.config import load_toml

        own = config_yarns(reg, load_toml(args.config).get("yarns", {}), "yarns")
        yarn = own[args.name] if args.name in own else resolve_yarn(reg, args.name, "NAME")
    else:
        yarn = resolve_yarn(reg, args.name, "NAME")
    rows = yarn_properties(yarn)
    if args.json:
        print(json.dumps([attrs.asdict(r) for r in rows], indent=2, ensure_ascii=False))
        return 0
    print(f"{yarn.name}: {yarn.source}" if yarn.source else yarn.name)
    w = max(len(r.name) for r in rows)
    for r in rows:
        value = "–" if r.value is None else f"{r.value:.4g}"
        print(f"  {r.name:<{w}}  {r.symbol:<6} {value:>10} {r.unit:<6} {r.status:<9} {r.how}  [{r.used_by}]")
    return 0
