"""The scenes of the solver-rebuild benchmark: one run, its wall time and its tensions as JSON.

    python benchmarks/bench_rebuild.py rod          # jersey cotton SL11, the rod's defaults
    python benchmarks/bench_rebuild.py volumetric   # jersey cotton SL12, P2 seed r, ipc

Both: pre-stress, friction, self-contact and equibiaxial 0 -> 30 % in 6 steps (docs/performance.md,
"What the solvers rebuild"). Run it under two versions of the code to compare curves and times.
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


if __name__ == "__main__":
    print(json.dumps(main(sys.argv[1] if len(sys.argv) > 1 else "rod")))
