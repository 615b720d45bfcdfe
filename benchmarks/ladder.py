"""The accuracy ladder: what each rung of fidelity costs in time, and how far it is from the top.

One fabric and one scene (default: jersey SL11 cotton, pre-stress + equibiaxial 0→30 %) go through
a ladder of solvers from cheap to expensive. The most accurate rung that finished is the reference;
every rung reports its wall time and the NRMSE of its course and wale tension against the
reference (normalised by the reference's maximum tension, as the fits are scored). The cheapest
rung, the reduced model, uses hgo parameters fitted to the reference, so its error is the price of
the paper's three-parameter model and its time is the price of evaluating it.

    python benchmarks/ladder.py                                  # rod 8/16/32 segments per stitch
    python benchmarks/ladder.py --rungs rod:8 rod:16 rod:32 volumetric:1:0.6
    python benchmarks/ladder.py --json ladder.json               # also keep the numbers

Rungs: ``rod:<segments_per_stitch>``, ``volumetric:<order>:<seed>`` (seed = element size / radius).
"""

from __future__ import annotations

import argparse
import json
import time


import knitframe
from knitframe.curves import nrmse_between
from knitframe.errors import KnitframeError
from knitframe.records import Fabric, LoadPath, Scene


def rung_solver(spec: str):
    """Solver instance for ``rod:16`` or ``volumetric:2:0.333``."""
    reg = knitframe.get_registry()
    kind, *args = spec.split(":")
    if kind == "rod":
        return reg["solver"]["rod"](segments_per_stitch=int(args[0]) if args else 16)
    if kind == "volumetric":
        order = int(args[0]) if args else 2
        seed = float(args[1]) if len(args) > 1 else 1.0 / 3.0
        return reg["solver"]["volumetric"](order=order, seed=seed)
    raise SystemExit(f"unknown rung {spec!r}; use rod:<n> or volumetric:<order>:<seed>")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pattern", default="jersey")
    ap.add_argument("--stitch-length", type=float, default=11.0)
    ap.add_argument("--yarn", default="cotton")
    ap.add_argument("--max-strain", type=float, default=0.3)
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--rungs", nargs="+", default=["rod:8", "rod:16", "rod:32"])
    ap.add_argument("--json", default=None, help="write the table as JSON here")
    args = ap.parse_args()

    reg = knitframe.get_registry()
    fabric = Fabric(args.pattern, reg["yarn"][args.yarn], stitch_length=args.stitch_length)
    scene = Scene(LoadPath("equibiaxial", max_strain=args.max_strain, steps=args.steps),
                  effects={"large_deformation", "bending", "contact", "self_contact", "prestress", "anisotropy"})
    rows, responses = [], {}
    for spec in args.rungs:
        solver = rung_solver(spec)
        t0 = time.perf_counter()
        try:  # each rung simulates the effects it models (the rod has no anisotropic section)
            responses[spec] = solver.simulate(fabric, Scene(scene.load, effects=scene.effects & solver.effects))
            status = "ok"
        except KnitframeError as e:
            status = f"stopped: {e}"[:80]
        rows.append({"rung": spec, "wall_time_s": time.perf_counter() - t0, "status": status})
    done = [s for s in args.rungs if s in responses]
    if not done:
        raise SystemExit("no rung finished")
    ref = responses[done[-1]]
    for row in rows:
        r = responses.get(row["rung"])
        row["T1_end"] = float(r.T1[-1]) if r is not None else None
        row["T2_end"] = float(r.T2[-1]) if r is not None else None
        row["nrmse_vs_ref"] = nrmse_between(ref, r) if r is not None else None

    # cheapest rung: the paper's reduced model fitted to the reference
    fit = reg["fitter"]["lbfgs"]().fit(reg["homogenizer"]["hgo"](), [ref])
    reduced = reg["solver"]["reduced"](model="hgo", params={k: v for k, v in fit.to_json().items()
                                                           if k in ("a", "b", "theta_deg")})
    # the reduced model has no contact, bending or pre-stress: the scene may only ask for what it models
    reduced_scene = Scene(scene.load, effects={"large_deformation", "anisotropy"})
    t0 = time.perf_counter()
    n = 1000
    for _ in range(n):
        r = reduced.simulate(fabric, reduced_scene)
    rows.insert(0, {"rung": "reduced hgo (fitted to ref)", "wall_time_s": (time.perf_counter() - t0) / n,
                    "status": f"fit {fit.wall_time:.2f} s", "T1_end": float(r.T1[-1]), "T2_end": float(r.T2[-1]),
                    "nrmse_vs_ref": nrmse_between(ref, r)})

    print(f"accuracy ladder: {args.pattern} SL{args.stitch_length:g} {args.yarn}, pre-stress + equibiaxial "
          f"0→{100 * args.max_strain:g} % in {args.steps} steps; reference = {done[-1]}")
    print(f"| rung | wall time, s | T1 at end, N/mm | T2 at end, N/mm | NRMSE vs reference | status |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        f = lambda x, fmt: "–" if x is None else format(x, fmt)  # noqa: E731
        print(f"| {row['rung']} | {f(row['wall_time_s'], '.3g')} | {f(row['T1_end'], '.4g')} | "
              f"{f(row['T2_end'], '.4g')} | {f(row['nrmse_vs_ref'], '.2%')} | {row['status']} |")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=2)


if __name__ == "__main__":
    main()
