"""Rod solver benchmark and science sweep.

    python benchmarks/bench_rod.py              # pre-stress + equibiaxial 0→30 % for jersey SL11 cotton, 3 runs
    python benchmarks/bench_rod.py --science    # docs/validation.md "Rod solver" tables (several minutes)

Prints Markdown tables. Timings are wall-clock seconds on whatever machine runs this.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from knitframe import get_registry
from knitframe.records import Fabric, LoadPath, Scene

EFFECTS = ("large_deformation", "bending", "contact", "prestress")


def run(pattern: str, sl: float, yarn: str, load: LoadPath, **options):
    """One rod simulation; returns the Response (on failure the partial curve, converged = False)."""
    reg = get_registry()
    fabric = Fabric(pattern=pattern, yarn=reg["yarn"][yarn], stitch_length=sl)
    solver = reg["solver"]["rod"](on_failure="truncate", **options)
    return solver.simulate(fabric, Scene(load=load, effects=EFFECTS))


def bench(repeats: int) -> None:
    load = LoadPath(kind="equibiaxial", max_strain=0.3, steps=10)
    print(f"| case | run | wall time, s | steps | T1 at 30 %, N/mm | T2 at 30 %, N/mm | converged |")
    print("|---|---|---|---|---|---|---|")
    for k in range(repeats):
        t0 = time.perf_counter()
        r = run("jersey", 11, "cotton", load)
        dt = time.perf_counter() - t0
        print(f"| jersey SL11 cotton, pre-stress + equibiaxial 0→30 % | {k + 1} | {dt:.2f} | {len(r)} | "
              f"{r.T1[-1]:.4g} | {r.T2[-1]:.4g} | {r.provenance.converged} |")


def _fit(responses):
    reg = get_registry()
    model = reg["homogenizer"]["hgo"]()
    res = reg["fitter"]["lbfgs"]().fit(model, responses)
    return dict(zip(model.param_names, np.asarray(res.params, dtype=float))), res


def science() -> None:
    eq = LoadPath(kind="equibiaxial", max_strain=0.3, steps=10)
    print("### Jersey, cotton, equibiaxial 0→30 %: stitch length\n")
    print("| SL | T1 at 10/20/30 %, N/mm | T2 at 10/20/30 %, N/mm | hgo a, N/mm | hgo b | hgo θ, deg | NRMSE | wall, s |")
    print("|---|---|---|---|---|---|---|---|")
    for sl in (10, 11, 12):
        t0 = time.perf_counter()
        r = run("jersey", sl, "cotton", eq)
        dt = time.perf_counter() - t0
        fit = ""
        try:
            p, res = _fit([r])
            fit = f"{p['a']:.4g} | {p['b']:.4g} | {np.degrees(p['theta']):.1f} | {res.nrmse.get('overall', float('nan')):.3g}"
        except Exception as e:  # report, do not hide
            fit = f"fit failed: {type(e).__name__}: {str(e)[:60]} | | |"
        pick = [2, 5, 9][: len(r)]
        print(f"| {sl} | {' / '.join(f'{r.T1[i]:.3g}' for i in pick)} | {' / '.join(f'{r.T2[i]:.3g}' for i in pick)} | "
              f"{fit} | {dt:.1f}{'' if r.provenance.converged else ' (stopped: ' + r.provenance.notes[:80] + ')'} |")
    print("\n### Patterns at SL11, cotton, equibiaxial 0→30 %\n")
    print("| pattern | T1/T2 at 30 % | hgo θ, deg | hgo b | converged |")
    print("|---|---|---|---|---|")
    for pat in ("jersey", "garter", "rib", "seed"):
        r = run(pat, 11, "cotton", eq)
        try:
            p, _ = _fit([r])
            th, b = f"{np.degrees(p['theta']):.1f}", f"{p['b']:.4g}"
        except Exception as e:
            th, b = f"fit failed ({type(e).__name__})", ""
        print(f"| {pat} | {r.T1[-1] / r.T2[-1]:.3g} | {th} | {b} | {r.provenance.converged} {r.provenance.notes[:80]} |")
    print("\n### Patterns at SL11, cotton, uniaxial with free sides 0→30 %\n")
    print("| pattern | direction | T at 10/20/30 %, N/mm | lateral stretch at 30 % | converged |")
    print("|---|---|---|---|---|")
    for pat in ("jersey", "garter", "rib", "seed"):
        for d in ("course", "wale"):
            r = run(pat, 11, "cotton", LoadPath(kind="uniaxial", direction=d, max_strain=0.3, steps=10))
            T = r.T1 if d == "course" else r.T2
            lat = r.lambda2 if d == "course" else r.lambda1
            pick = [i for i in (2, 5, 9) if i < len(r)]
            print(f"| {pat} | {d} | {' / '.join(f'{T[i]:.3g}' for i in pick)} | {lat[-1]:.3f} | "
                  f"{r.provenance.converged} {r.provenance.notes[:80]} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--science", action="store_true", help="run the validation sweep instead of the timing")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print(f"cores: {os.cpu_count()}, load average: {os.getloadavg()[0]:.2f}\n")
    science() if args.science else bench(args.repeats)


if __name__ == "__main__":
    main()
