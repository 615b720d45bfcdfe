"""Garment design timings: a 100 000-triangle scan to a shaped design, and the shaped optimiser alone.

    python benchmarks/bench_design.py            # prints three Markdown tables
    python benchmarks/bench_design.py --profile  # and the optimiser's and the design's top cProfile rows

1. A scan of the example arm (its surface, about 100 000 triangles, written as STL) goes through
   ``knitframe design SCAN --out DIR`` (the defaults: pressure_profile class II, a shaped tube, needles
   and fabrics chosen together), median wall time of 3 runs, with Python's bytecode cached (as after an
   install) and as the calling environment starts Python. Then the same steps in-process, warm
   (imports done), each the median of 3: ``Limb.from_scan``, ``design`` and the outputs (design.json,
   knit-map.csv/.png, pressure.png, design.vtu, the station table). What the command takes beyond them
   is start-up, imports, the plugins and the config checks.
2. The shaped optimiser ``solve_shaped`` alone: 200 rows × 24 fabrics × 150 needle counts (a sleeve's
   range), 4 to 6 courses per row, the default shaping rules, min_courses 10, random costs; median of
   5. And ``solve_knitted`` on the example arm at 201 stations with the built-in fabrics at three
   relaxed pitches each (24 fabrics): the tables and the solve of a real design.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
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


def median_time(run, repeats: int) -> tuple[float, float, float]:
    """(median, least, largest) wall time of ``repeats`` calls of ``run``, s."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), min(times), max(times)


def scan_to_design(tmp: Path, profile: bool) -> None:
    """Table 1: the command's wall time and the in-process split."""
    from knitframe.garment.core import design
    from knitframe.garment.library import builtin_library
    from knitframe.garment.limb import Limb
    from knitframe.garment.outputs import station_table, write_design

    scan = tmp / "arm.stl"
    n = arm_scan(scan)
    runs = iter(range(100))

    def command(env: dict[str, str]) -> None:
        out = tmp / f"cli-{next(runs)}"
        proc = subprocess.run(
            [sys.executable, "-m", "knitframe", "design", str(scan), "--out", str(out)],
            capture_output=True,
            text=True,
            env=env,
        )
        if proc.returncode != 0 or "stations within" not in proc.stdout:
            raise SystemExit(f"knitframe design failed ({proc.returncode}): {proc.stderr.strip()}")

    # as this environment starts Python, and with the bytecode cached (as after an install; warmed once)
    here = dict(os.environ)
    cached = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    cached["PYTHONPYCACHEPREFIX"] = str(tmp / "pycache")
    command(cached)
    as_here = "as this environment starts it"
    if here.get("PYTHONDONTWRITEBYTECODE"):
        as_here += " (no bytecode written: compiled at every start)"
    cli = {
        "bytecode cached": median_time(lambda: command(cached), 3),
        as_here: median_time(lambda: command(here), 3),
    }
    import knitframe

    prof = knitframe.get_registry()["design_objective"]["pressure_profile"]()
    steps: dict[str, list[float]] = {"read": [], "design": [], "write": []}
    for k in range(4):  # the first pass imports and warms up; the median of the other 3 is kept
        t0 = time.perf_counter()
        limb = Limb.from_scan(scan)
        t1 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = design(limb, builtin_library(), prof)
        t2 = time.perf_counter()
        (tmp / f"out-{k}").mkdir()
        write_design(d, tmp / f"out-{k}")
        station_table(d)
        t3 = time.perf_counter()
        if k:
            for key, t in zip(steps, (t1 - t0, t2 - t1, t3 - t2), strict=True):
                steps[key].append(t)
    read, made, written = (statistics.median(v) for v in steps.values())
    rx = d.prescription()["all"]
    print(
        f"\nScan of {n} triangles, {limb.n_stations} stations x {limb.n_around} around: "
        f"{d.row_needles.min()}–{d.row_needles.max()} stitches per course, {len(d.regions())} regions, "
        f"{rx['stations_inside']} of {rx['stations']} stations within ±20 %\n"
    )
    print("| step | time (s) |\n|---|---|")
    rows = [
        (f"`knitframe design SCAN --out DIR`, {how}: median of 3 ({lo:.2f}–{hi:.2f})", t)
        for how, (t, lo, hi) in cli.items()
    ]
    rows += [
        ("in-process, warm, median of 3: read and slice the scan", read),
        ("in-process: design (fabrics and needles, shaped)", made),
        ("in-process: write the outputs and the station table", written),
        ("in-process: scan to finished design", read + made + written),
        (
            "the command beyond these, bytecode cached: start-up, imports, plugins, config checks",
            cli["bytecode cached"][0] - (read + made + written),
        ),
    ]
    for name, t in rows:
        print(f"| {name} | {t:.3f} |")
    if profile:
        top(lambda: design(limb, builtin_library(), prof), "design()")
        top(lambda: write_design(d, tmp / "out"), "write_design()")


def optimiser_alone(profile: bool) -> None:
    """Table 2: solve_shaped on random costs; solve_knitted on a real 200-row arm."""
    from knitframe.garment.knitted import solve_knitted
    from knitframe.garment.limb import example_arm
    from knitframe.garment.optimise_shaped import solve_shaped
    from knitframe.garment.shaping import MachineRules, allowed_change
    from knitframe.garment.tube import Tube, element_geometry

    rng = np.random.default_rng(0)
    R, F, n = 200, 24, 150
    cost = rng.random((R, F, n))
    courses = rng.integers(4, 7, (R, F))
    change = allowed_change(courses, MachineRules())
    random_t = median_time(lambda: solve_shaped(cost, courses, change, 10.0), 5)

    import knitframe

    prof = knitframe.get_registry()["design_objective"]["pressure_profile"](compression_class="II")
    lib = big_library()
    geo = element_geometry(example_arm(n_stations=201, n_around=64))
    found = {}

    def real() -> None:
        found["sol"], found["needles"], _ = solve_knitted(
            lib, prof, Tube("knitting"), [geo], MachineRules(), min_courses=10.0, ceiling=60.0
        )

    real_t = median_time(real, 5)
    needles = found["needles"]
    print("\nShaped optimiser alone, min_courses 10, default shaping rules (median of 5)\n")
    print("| problem | rows × fabrics × needle counts | time (s) | least–most (s) |\n|---|---|---|---|")
    print(
        f"| `solve_shaped`, random costs, 4–6 courses a row | {R} × {F} × {n} | {random_t[0]:.3f} | "
        f"{random_t[1]:.3f}–{random_t[2]:.3f} |"
    )
    print(
        f"| `solve_knitted`, example arm, pressure_profile class II (tables and solve) | "
        f"{geo.shape[0]} × {len(lib.entries)} × {len(needles)} ({needles[0]}–{needles[-1]}) | "
        f"{real_t[0]:.3f} | {real_t[1]:.3f}–{real_t[2]:.3f} |"
    )
    if profile:
        top(lambda: solve_shaped(cost, courses, change, 10.0), "solve_shaped()")


def top(run, label: str, rows: int = 12) -> None:
    """Print the ``rows`` functions of most cumulative time of one call of ``run``."""
    import cProfile
    import io
    import pstats

    p = cProfile.Profile()
    p.runcall(run)
    s = io.StringIO()
    pstats.Stats(p, stream=s).sort_stats("cumulative").print_stats(rows)
    print(f"\ncProfile of {label}:\n{s.getvalue()}")


def main(argv: list[str]) -> int:
    profile = "--profile" in argv
    with tempfile.TemporaryDirectory() as tmp:
        scan_to_design(Path(tmp), profile)
    optimiser_alone(profile)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
