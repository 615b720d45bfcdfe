"""Volumetric against rod: the same fabric and scene through both solvers, compared as curves and as fits.

Input is one or more volumetric runs saved by ``bench_volumetric.py run --save FILE`` (the fabric,
the scene and the Response). For each, the rod solver runs the same fabric and scene (minus
effects it does not model, which are named), and the table reports

* the NRMSE of the rod's course and wale tensions against the volumetric ones, on the volumetric
  stretches, normalised by the largest volumetric tension (as the fits are scored);
* the paper's reduced model ψ = a/b·[exp(b(I4 − 1)²) − 1] fitted by L-BFGS to each curve: a, b, θ
  and the fit's own NRMSE.

Usage::

    python benchmarks/bench_volumetric.py run --order 1 --seed 0.6 --save vol-p1.json
    python benchmarks/agreement.py vol-p1.json [more.json ...]
    python benchmarks/agreement.py vol-p1.json --rod-bending 0.0092   # also a rod with this EI, N·mm²
    python benchmarks/agreement.py vol-p2.json --rod '{}' --rod '{"relax": false}'   # rod option sets
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import attrs
import numpy as np

import knitframe
from knitframe.curves import nrmse_between
from knitframe.records import Fabric, Response, Scene


def fitted(reg, response: Response) -> dict:
    """a (N/mm), b (-), θ (deg) and NRMSE of the hgo reduced model fitted to one curve."""
    fit = reg["fitter"]["lbfgs"]().fit(reg["homogenizer"]["hgo"](), [response])
    out = fit.to_json()
    return {"a": out["a"], "b": out["b"], "theta_deg": out["theta_deg"], "nrmse": out["nrmse"]["overall"]}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="JSON files written by bench_volumetric.py run --save")
    ap.add_argument("--segments", type=int, default=None, help="rod segments per stitch (default: the rod's)")
    ap.add_argument(
        "--rod",
        action="append",
        default=None,
        help="rod options as JSON, one row each (repeatable; default: one row with the rod's defaults)",
    )
    ap.add_argument(
        "--rod-bending",
        type=float,
        nargs="*",
        default=[],
        help="also run the rod with these bending stiffnesses EI, N·mm² (default: the yarn's own)",
    )
    ap.add_argument("--json", help="also write the rows here")
    args = ap.parse_args(argv)
    reg = knitframe.get_registry()
    rods = [
        (opts, reg["solver"]["rod"](segments_per_stitch=args.segments, **json.loads(opts)))
        for opts in (args.rod or ["{}"])
    ]
    rows = []
    for path in args.runs:
        with open(path) as fh:
            data = json.load(fh)
        fabric = Fabric.from_dict(data["fabric"], "fabric")
        scene = Scene.from_dict(data["scene"], "scene")
        vol = Response.from_dict(data["response"], "response")
        dropped = sorted(scene.effects - rods[0][1].effects)
        rod_scene = Scene.from_dict(
            {**scene.to_dict(), "effects": sorted(scene.effects & rods[0][1].effects)}, "scene"
        )
        fv = fitted(reg, vol)
        for (opts, rod), EI in [(r, None) for r in rods] + [(rods[0], EI) for EI in args.rod_bending]:
            rod_fabric = (
                fabric
                if EI is None
                else attrs.evolve(fabric, yarn=attrs.evolve(fabric.yarn, bending_stiffness=EI))
            )
            t0 = time.perf_counter()
            rr = rod.simulate(rod_fabric, rod_scene)
            t_rod = time.perf_counter() - t0
            fr = fitted(reg, rr)
            rows.append({**row(vol, rr, t_rod, fv, fr, dropped, EI), "rod_options": opts})
    print(
        "| run | rod options | rod EI, N·mm² | mesh | volumetric s | rod s | last stretch | "
        "T1, T2 vol (N/mm) | T1, T2 rod (N/mm) | "
        "NRMSE rod vs vol | a, b, θ vol (fit NRMSE) | a, b, θ rod (fit NRMSE) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        fv, fr = r["fit_vol"], r["fit_rod"]
        ei = "yarn's own" if r["rod_EI"] is None else f"{r['rod_EI']:g}"
        print(
            f"| {r['run']}{'' if r['converged'] else ' (stopped early)'} | `{r['rod_options']}` | {ei} | "
            f"{r['mesh']} | "
            f"{r['volumetric_s']} | "
            f"{r['rod_s']} | {r['max_stretch']:.3f} | {r['T1_end_vol']:.4g}, {r['T2_end_vol']:.4g} | "
            f"{r['T1_rod_at_same']:.4g}, {r['T2_rod_at_same']:.4g} | {r['nrmse_rod_vs_vol']:.1%} | "
            f"{fv['a']:.4g}, {fv['b']:.4g}, {fv['theta_deg']:.1f}° ({fv['nrmse']:.1%}) | "
            f"{fr['a']:.4g}, {fr['b']:.4g}, {fr['theta_deg']:.1f}° ({fr['nrmse']:.1%}) |"
        )
        if r["rod_without"]:
            print(
                f"  (rod run without {', '.join(r['rod_without'])}: not modelled by the rod solver)",
                file=sys.stderr,
            )
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


def row(
    vol: Response, rr: Response, t_rod: float, fv: dict, fr: dict, dropped: list, EI: float | None
) -> dict:
    """One comparison: the volumetric curve against a rod curve."""
    return {
        "run": vol.label,
        "rod_EI": EI,
        "mesh": vol.provenance.mesh,
        "volumetric_s": round(vol.provenance.wall_time, 1),
        "rod_s": round(t_rod, 1),
        "converged": vol.provenance.converged,
        "max_stretch": float(vol.lambda1.max()),
        "T1_end_vol": float(vol.T1[-1]),
        "T2_end_vol": float(vol.T2[-1]),
        "T1_rod_at_same": float(np.interp(vol.lambda1[-1], rr.lambda1, rr.T1)),
        "T2_rod_at_same": float(np.interp(vol.lambda2[-1], rr.lambda2, rr.T2)),
        "nrmse_rod_vs_vol": nrmse_between(vol, rr),
        "fit_vol": fv,
        "fit_rod": fr,
        "rod_without": dropped,
    }


if __name__ == "__main__":
    main()
