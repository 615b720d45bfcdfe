"""Benchmark of fabric sweeps: a 36-fabric rod sweep on 1 and 2 Dask workers, and Dask's overhead per task.

    python benchmarks/bench_sweep.py sweep --workers 1 2 --out bench-sweep     # 36 fabrics, about 10 minutes
    python benchmarks/bench_sweep.py overhead --tasks 400                      # trivial tasks, about 30 s

``sweep`` writes ``<out>/sweep-36.toml`` (4 patterns x 3 stitch lengths x 3 yarns, rod solver with 10
segments per stitch, pre-stress and equibiaxial 0-20 % in 4 steps, hgo by lbfgs) and runs
``knitframe run <out>/sweep-36.toml --out <out>/dask-<n> --no-cache`` with ``[executor] kind = "dask",
workers = n`` for each n (and ``--local`` adds the local executor in one process), in a fresh process
each; it prints the wall time of the command and of the sweep stage, the sum of the points' own wall
times, the speed-up over the first worker count and the load average before and after.

``overhead`` measures what Dask adds per task: ``--tasks`` trivial jobs through a running
LocalCluster's ``client.map`` (Dask's own cost), and through the ``dask`` executor's ``map``
(cluster start, keys, progress and results included), less the same map of one job.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import time
from pathlib import Path

CONFIG = """\
[pipeline]
name = "sweep-36"
description = "36 fabrics: 4 patterns x 3 stitch lengths x 3 yarns, rod solver, hgo fits"

[sweep]
name = "rod-36"
grid = {{ pattern = ["jersey", "garter", "rib", "seed"], stitch_length = [10, 11, 12], \
yarn = ["cotton", "nylon", "pet"] }}

[sweep.solver]
kind = "rod"
segments_per_stitch = 10

[sweep.scene]
effects = ["large_deformation", "bending", "contact", "prestress"]
load = {{ kind = "equibiaxial", max_strain = 0.2, steps = 4 }}

[sweep.fit]
model = "hgo"
fitter = "lbfgs"

[executor]
{executor}
"""


def noop(job):
    """A trivial task."""
    return job["i"]


def run_sweep(out: Path, name: str, executor: str) -> dict:
    cfg = out / f"sweep-36-{name}.toml"
    cfg.write_text(CONFIG.format(executor=executor))
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "knitframe",
            "run",
            str(cfg),
            "--out",
            str(out / name),
            "--no-cache",
            "--overwrite",
            "--quiet",
        ],
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{name}: knitframe run failed: {proc.stderr.strip()}")
    summary = json.loads((out / name / "summary.json").read_text())
    stage = next(s["seconds"] for s in summary["stages"] if s["stage"] == "sweep")
    with open(out / name / "sweep.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    work = sum(float(r["wall_time_s"]) for r in rows if r["wall_time_s"])
    return {
        "name": name,
        "wall": wall,
        "stage": stage,
        "work": work,
        "done": sum(r["status"] == "done" for r in rows),
        "failed": sum(r["status"] == "failed" for r in rows),
        "load": (load0, os.getloadavg()),
        "params": [(r["name"], r["a"], r["b"], r["theta_deg"]) for r in rows],
    }


def sweep(args) -> None:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = []
    if args.local:
        runs.append(run_sweep(out, "local-1", 'kind = "local"\nworkers = 1'))
    for n in args.workers:
        runs.append(run_sweep(out, f"dask-{n}", f'kind = "dask"\nworkers = {n}\ndashboard_address = ":0"'))
    base = next(r for r in runs if r["name"].startswith("dask"))
    print(
        f"| run | fabrics done / failed | `knitframe run` wall, s | sweep stage, s | sum of point times, s | "
        f"speed-up over {base['name']} | load average before → after |"
    )
    print("|---|---|---|---|---|---|---|")
    for r in runs:
        (b1, b5, _), (a1, a5, _) = r["load"]
        print(
            f"| {r['name']} | {r['done']} / {r['failed']} | {r['wall']:.1f} | "
            f"{r['stage']:.1f} | {r['work']:.1f} | "
            f"{base['stage'] / r['stage']:.2f} | {b1:.2f} → {a1:.2f} |"
        )
    same = all(r["params"] == runs[0]["params"] for r in runs)
    print(f"fitted parameters identical in every run: {same}")


def overhead(args) -> None:
    import dask
    from distributed import Client, LocalCluster
    from knitframe_executors.dask import TRIM_KEY, DaskExecutor

    n = args.tasks
    with dask.config.set({TRIM_KEY: None}):
        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0")
        client = Client(cluster)
        start = time.perf_counter() - t0
    client.gather(
        client.map(noop, [{"i": -1 - k} for k in range(20)])
    )  # warm up: the function reaches the workers
    t0 = time.perf_counter()
    futures = client.map(noop, [{"i": i} for i in range(n)], pure=False)
    client.gather(futures)
    raw = time.perf_counter() - t0
    client.close()
    cluster.close()
    ex = DaskExecutor(workers=2, dashboard_address=":0", cache_dir=None)
    t0 = time.perf_counter()
    ex.map(noop, [{"i": 0}])
    one = time.perf_counter() - t0
    t0 = time.perf_counter()
    ex.map(noop, [{"i": i} for i in range(n)])
    many = time.perf_counter() - t0
    print(f"LocalCluster(2 workers) start: {start:.2f} s")
    print(
        f"client.map of {n} trivial tasks on a running cluster: {raw:.2f} s = {1e3 * raw / n:.2f} ms per task"
    )
    print(f"dask executor map of 1 trivial job (cluster start and close included): {one:.2f} s")
    print(
        f"dask executor map of {n} trivial jobs: {many:.2f} s = "
        f"{1e3 * (many - one) / (n - 1):.2f} ms per task "
        "beyond the first"
    )
    print(f"load average: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="what", required=True)
    s = sub.add_parser("sweep", help="the 36-fabric rod sweep on Dask LocalClusters")
    s.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    s.add_argument("--local", action="store_true", help="also run it with the local executor in one process")
    s.add_argument("--out", default="bench-sweep")
    s.set_defaults(func=sweep)
    o = sub.add_parser("overhead", help="Dask's overhead per trivial task")
    o.add_argument("--tasks", type=int, default=400)
    o.set_defaults(func=overhead)
    args = p.parse_args()
    args.func(args)


if __name__ == "__main__":
    main()
