"""Garment design timings: a 100 000-triangle scan to a finished design, and the optimiser alone.

    python benchmarks/bench_design.py            # prints two Markdown tables

1. A scan of the example arm (its surface, 100 000 triangles, written as STL) goes through
   ``Limb.from_scan``, ``design`` (knitting mode, needles searched, pressure_profile) and the
   outputs (design.json, knit-map.csv/.png, pressure.png, design.vtu).
2. The course-band optimiser alone on 200 element rows × 64 columns × 24 fabrics, with the costs
   of a real design (the built-in fabrics at three relaxed pitches each): dynamic programming for
   a target objective (one solve) and for a uniformity objective (the level τ searched too).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import attrs
import numpy as np


def arm_scan(path: Path, triangles: int = 100_000) -> int:
    """Write the example arm's surface as a closed STL of about ``triangles`` triangles."""
    import trimesh

    from knitframe.garment.limb import example_arm

    around = 250
    stations = triangles // (2 * around) + 1
    limb = example_arm(n_stations=stations, n_around=around)
    P = limb.sections.reshape(-1, 3)
    i, j = np.meshgrid(np.arange(stations - 1), np.arange(around), indexing="ij")
    a = i * around + j
    b = i * around + (j + 1) % around
    c = a + around
    d = b + around
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    caps = []
    for k, flip in ((0, True), (stations - 1, False)):  # close the ends with fans around their centroids
        centre = len(P) + len(caps)
        ring = k * around + np.arange(around)
        fan = np.stack([np.full(around, centre), np.roll(ring, -1), ring], -1)
        caps.append((limb.sections[k].mean(axis=0), fan[:, ::-1] if flip else fan))
    verts = np.vstack([P] + [c for c, _ in caps])
    mesh = trimesh.Trimesh(verts, np.vstack([faces] + [f for _, f in caps]), process=False)
    mesh.export(path)
    return len(mesh.faces)


def big_library(copies: int = 3):
    """The built-in fabrics at ``copies`` relaxed pitches each (0.9, 1.0, 1.1 ×): 24 fabrics."""
    from knitframe.garment.library import FabricLibrary, builtin_library

    lib = builtin_library()
    scales = np.linspace(0.9, 1.1, copies)
    entries = [
        attrs.evolve(
            e, name=f"{e.name}@{s:.2f}", course_pitch=e.course_pitch * s, wale_pitch=e.wale_pitch * s
        )
        for e in lib.entries
        for s in scales
    ]
    return FabricLibrary("bench-24", tuple(entries), source="built-in fabrics at three pitches")


def main() -> int:
    import knitframe
    from knitframe.garment import assign
    from knitframe.garment.core import design
    from knitframe.garment.library import builtin_library
    from knitframe.garment.limb import Limb, example_arm
    from knitframe.garment.optimise import solve_bands_dp
    from knitframe.garment.outputs import write_design
    from knitframe.garment.tube import Tube, element_geometry

    reg = knitframe.get_registry()
    profile = reg["design_objective"]["pressure_profile"](target_mmHg=20.0)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        n = arm_scan(tmp / "arm.stl")
        t0 = time.perf_counter()
        limb = Limb.from_scan(tmp / "arm.stl")
        t1 = time.perf_counter()
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = design(limb, builtin_library(), profile, tube=Tube("knitting"))
        t2 = time.perf_counter()
        (tmp / "out").mkdir()
        write_design(d, tmp / "out")
        t3 = time.perf_counter()
    rows += [
        ("read and slice the scan", t1 - t0),
        ("design (needles searched)", t2 - t1),
        ("write the outputs", t3 - t2),
        ("**scan to finished design**", t3 - t0),
    ]
    print(
        f"\nScan of {n} triangles, {limb.n_stations} stations x {limb.n_around} around, "
        f"{d.tube.needles} needles, {len(d.regions())} regions\n"
    )
    print("| step | time (s) |\n|---|---|")
    for name, t in rows:
        print(f"| {name} | {t:.3f} |")

    lib = big_library()
    arm = example_arm(n_stations=201, n_around=64)
    geo = element_geometry(arm)
    lam1, lam2, T1, T2, courses, feasible = assign._fabric_fields(
        lib, Tube("knitting", needles=60), geo, float(arm.circumference[0]), None
    )
    timings = []
    for name, obj in (
        ("pressure_profile (target)", profile),
        ("stress_variance (level searched)", reg["design_objective"]["stress_variance"]()),
    ):
        V = assign._evaluate(obj, T1, geo, "equivalent")
        t0 = time.perf_counter()
        sol = assign._solve_bands(obj, V, feasible, geo, courses, 10.0, None)
        timings.append((name, time.perf_counter() - t0, len(np.unique(sol.rows))))
    cost = np.random.default_rng(0).random((200, 24))
    t0 = time.perf_counter()
    solve_bands_dp(cost, np.full((200, 24), 3.0), 20.0)
    timings.append(("random costs, one DP solve", time.perf_counter() - t0, None))
    print(
        f"\nOptimiser alone: {geo.shape[0]} rows x {geo.shape[1]} columns x {len(lib.entries)} fabrics "
        "(element fields precomputed)\n"
    )
    print("| objective | time (s) | fabrics used |\n|---|---|---|")
    for name, t, k in timings:
        print(f"| {name} | {t:.3f} | {'' if k is None else k} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
