"""The accuracy ladder benchmark: a thin caller of ``knitframe ladder``.

Writes the config of one fabric and scene (default: jersey SL11 cotton, pre-stress + equibiaxial
0→30 % in 6 steps) and runs ``knitframe ladder`` on it; every option after ``--`` goes to the
command. ``--timings FILE`` also writes the converged rungs' timings in the format of the timings
shipped with knitframe (``knitframe/data/ladder-timings.json``), which the cost model reads;
``--check-estimates CSV`` prints how well the cost model, fitted to an earlier ladder's
``ladder.csv`` alone, estimated each rung of this one.

    python benchmarks/ladder.py --out ladder-out                               # the default rungs
    python benchmarks/ladder.py --out ladder-out -- --rungs rod:8,rod:16,rod:32 --max-time 900
    python benchmarks/ladder.py --out ladder-out --timings knitframe/data/ladder-timings.json
    # the cost model on another fabric:
    python benchmarks/ladder.py --pattern garter --stitch-length 12 --out garter-out \
        --check-estimates ladder-out/ladder.csv -- --rungs rod:8,rod:16,rod:32
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import tempfile
from pathlib import Path

import tomli_w

EFFECTS = ["large_deformation", "bending", "contact", "self_contact", "prestress", "anisotropy"]


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    passed = argv[argv.index("--") + 1 :] if "--" in argv else []
    own = argv[: argv.index("--")] if "--" in argv else argv
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pattern", default="jersey")
    ap.add_argument("--stitch-length", type=float, default=11.0)
    ap.add_argument("--yarn", default="cotton")
    ap.add_argument("--max-strain", type=float, default=0.3)
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--out", required=True, help="output folder of the ladder")
    ap.add_argument("--timings", default=None, help="also write the converged rungs' timings (JSON) here")
    ap.add_argument(
        "--check-estimates",
        default=None,
        metavar="CSV",
        help="after the run, print each rung's time estimated from this earlier ladder.csv alone "
        "against the measured one",
    )
    args = ap.parse_args(own)

    from knitframe.cli import main as knitframe_main

    config = {
        "pipeline": {"name": f"ladder-{args.pattern}-sl{args.stitch_length:g}-{args.yarn}"},
        "fabric": {"pattern": args.pattern, "stitch_length": args.stitch_length, "yarn": args.yarn},
        "scene": {
            "effects": EFFECTS,
            "load": {"kind": "equibiaxial", "max_strain": args.max_strain, "steps": args.steps},
        },
        "ladder": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"{config['pipeline']['name']}.toml"
        path.write_text(tomli_w.dumps(config), encoding="utf-8")
        code = knitframe_main(["ladder", str(path), "--out", args.out, *passed])
    if code != 0:
        return code
    import csv

    with open(Path(args.out) / "ladder.csv", encoding="utf-8") as fh:
        rows = [
            {
                **r,
                "dofs": int(r["dofs"]),
                "increments": int(r["increments"]),
                "wall_time_s": float(r["wall_time_s"]),
                "peak_rss_mb": float(r["peak_rss_mb"]) if r["peak_rss_mb"] else None,
            }
            for r in csv.DictReader(fh)
            if r["status"] == "ok" and r["family"] != "reduced"
        ]
    if args.check_estimates:
        from knitframe.ladder import CostModel, format_duration, read_timings

        model = CostModel(read_timings(args.check_estimates))
        print(
            f"| rung | DOFs | estimated from {Path(args.check_estimates).name} | "
            "measured | measured / estimated |"
        )
        print("|---|---|---|---|---|")
        for r in rows:
            e = model.estimate(r["family"], r["dofs"], r["increments"])
            if e is not None:
                print(
                    f"| {r['rung']} | {r['dofs']} | {format_duration(e.seconds)} | "
                    f"{format_duration(r['wall_time_s'])} | {r['wall_time_s'] / e.seconds:.2f} |"
                )
    if args.timings:
        from knitframe.ladder import timings_json

        command = "python benchmarks/ladder.py " + shlex.join(argv)
        data = timings_json(rows, command=command, note="wall time and peak RSS of each rung's own process")
        Path(args.timings).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
        print(f"wrote {len(data['rows'])} timings to {args.timings}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
