"""The scenes of the solver-rebuild benchmark: one run, its wall time and its tensions as JSON.

    python benchmarks/bench_rebuild.py rod          # jersey cotton SL11, the rod's defaults
    python benchmarks/bench_rebuild.py volumetric   # jersey cotton SL12, P2 seed r, ipc
    python benchmarks/bench_rebuild.py rod --perturb 1   # every rod Hessian scaled by 1 + 1·2⁻⁵² (one ulp)

Both: pre-stress, friction, self-contact and equibiaxial 0 -> 30 % in 6 steps (docs/performance.md,
"What the solvers rebuild"). Run it under two versions of the code to compare curves and times.
``--perturb K`` scales every rod Hessian by 1 + K·2⁻⁵²: the spread of the curves over a few K is what
round-off alone moves this path by (docs/validation.md, section 5).
"""

from __future__ import annotations

import json
import sys
import time

from knitframe import get_registry
from knitframe.records import Fabric, LoadPath, Scene

EFFECTS = ("large_deformation", "bending", "contact", "prestress", "friction", "self_contact")


def main(which: str) -> dict:
    reg = get_registry()
    sl, solver = (
        (11, reg["solver"]["rod"]())
        if which == "rod"
        else (12, reg["solver"]["volumetric"](order=2, seed=1.0))
    )
    fab = Fabric(pattern="jersey", yarn=reg["yarn"]["cotton"], stitch_length=sl)
    scene = Scene(load=LoadPath(kind="equibiaxial", max_strain=0.3, steps=6), effects=EFFECTS)
    t = time.perf_counter()
    r = solver.simulate(fab, scene)
    return {"time_s": time.perf_counter() - t, "T1": [float(x) for x in r.T1], "T2": [float(x) for x in r.T2]}


def perturb(k: float) -> None:
    """Scale every Hessian the rod assembles by 1 + k·2⁻⁵²."""
    from knitframe.numerics import pattern

    real = pattern.PatternCache.matrix

    def scaled(self, parts, values):
        A = real(self, parts, values)
        A.data *= 1.0 + k * 2.0**-52
        return A

    pattern.PatternCache.matrix = scaled


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--perturb" in args:
        at = args.index("--perturb")
        perturb(float(args[at + 1]))
        del args[at : at + 2]
    print(json.dumps(main(args[0] if args else "rod")))
