"""``knitframe fit DATA... --model hgo --fitter lbfgs|mads --out DIR [--reader auto|singal2024|generic]``.

Fits one reduced model to every curve in the data files jointly and writes ``DIR/params.json``
(every parameter, θ as ``theta_deg``, NRMSE per direction and overall) and ``DIR/fit.png``.
The same work from a config: a ``[data]`` table plus a ``[fit]`` table.
"""

from __future__ import annotations

from pathlib import Path

from knitframe.outdir import OutputDir, add_overwrite_argument, fingerprint


def add_parser(sub) -> None:
    p = sub.add_parser("fit", help="fit a reduced model to test data", description=__doc__)
    p.add_argument("data", nargs="+", type=Path, help="data files (CSV)")
    p.add_argument("--model", default="hgo", help="homogenizer plugin (default: hgo)")
    p.add_argument("--fitter", default="lbfgs", help="fitter plugin: lbfgs or mads (default: lbfgs)")
    p.add_argument(
        "--reader",
        default="auto",
        help="reader plugin for the data files (default: auto, chosen from "
        "each file's header: singal2024 or generic)",
    )
    p.add_argument("--out", required=True, help="output folder (new, or empty; see --overwrite)")
    add_overwrite_argument(p)
    p.add_argument("--quiet", action="store_true", help="print nothing on success")
    p.set_defaults(func=main)


def main(args) -> int:
    from knitframe.config import instantiate
    from knitframe.fitting import write_fit_outputs
    from knitframe.plugins import get_registry
    from knitframe.version import __version__

    od = OutputDir(
        args.out,
        command="fit",
        overwrite=args.overwrite,
        fingerprint=fingerprint(
            {
                "data": [str(p.resolve()) for p in args.data],
                "model": args.model,
                "fitter": args.fitter,
                "reader": args.reader,
            }
        ),
    )
    od.check()  # before any work
    reg = get_registry()
    reader = instantiate(reg, "reader", args.reader, "--reader")
    model = instantiate(reg, "homogenizer", args.model, "--model")
    fitter = instantiate(reg, "fitter", args.fitter, "--fitter")
    responses = [r for path in args.data for r in reader.read(path)]  # DataError names file, line, column
    result = fitter.fit(model, responses)
    with od:
        write_fit_outputs(result, responses, od.staging / "params.json", od.staging / "fit.png")
        od.commit(
            {
                "knitframe": __version__,
                "command": "fit",
                "data": [str(p) for p in args.data],
                "model": args.model,
                "fitter": args.fitter,
            }
        )
    if not args.quiet:
        print(result.headline())
        print(f"wrote {od.out / 'params.json'} and {od.out / 'fit.png'}")
    return 0
