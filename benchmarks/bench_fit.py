"""Fit time of the reduced models and their stress throughput.

Fit problem: 2 directions × 3 samples × 100 points, the first three repeats of the cotton jersey
tests of Singal et al. 2024 (packaged example data, course and wale), each resampled to 100
strains; all six curves fitted jointly. Throughput: stress evaluations per second at 10⁶ points.

    python benchmarks/bench_fit.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from knitframe.examples import EXAMPLE_DIR
from knitframe.plugins import get_registry
from knitframe.records import Response


def samples(n_per_direction: int = 3, points: int = 100) -> list[Response]:
    """Three repeats per direction, each resampled onto ``points`` strains of its own range."""
    reg = get_registry()
    reader = reg["reader"]["singal2024"](average=False)
    out = []
    for name in ("cotton-stockinette-x.csv", "cotton-stockinette-y.csv"):
        for r in reader.read(EXAMPLE_DIR / "data" / name)[:n_per_direction]:
            d = r.loaded_direction
            lam = (r.lambda1, r.lambda2)[d]
            o = np.argsort(lam)
            grid = np.linspace(lam.min(), lam.max(), points)
            free = np.interp(grid, lam[o], (r.lambda1, r.lambda2)[1 - d][o])
            T = np.interp(grid, lam[o], (r.T1, r.T2)[d][o])
            pair = (grid, free) if d == 0 else (free, grid)
            tens = (T, 0 * T) if d == 0 else (0 * T, T)
            out.append(Response(*pair, *tens, load=r.load, label=r.label))
    return out


def bench_fits(repeats: int) -> list[tuple]:
    reg = get_registry()
    data = samples()
    rows = []
    for model in ("hgo", "hgo2m"):
        for fitter in ("lbfgs", "mads"):
            times, res = [], None
            for _ in range(repeats):
                t0 = time.perf_counter()
                res = reg["fitter"][fitter]().fit(reg["homogenizer"][model](), data)
                times.append(time.perf_counter() - t0)
            tra = res.nrmse_transverse.get("overall")
            rows.append(
                (
                    model,
                    fitter,
                    sum(len(r) for r in data),
                    min(times),
                    float(np.median(times)),
                    res.n_evals,
                    res.nrmse["overall"],
                    tra,
                )
            )
    return rows


def bench_throughput(repeats: int, n: int = 1_000_000) -> list[tuple]:
    reg = get_registry()
    rng = np.random.default_rng(0)
    l1, l2 = rng.uniform(0.8, 1.6, n), rng.uniform(0.8, 1.6, n)
    rows = []
    for model in ("hgo", "hgo2m"):
        m = reg["homogenizer"][model]()
        p = m.x0()
        for what, fn in (("stress", m.stress), ("stress_grad", m.stress_grad)):
            best = min(_timed(fn, p, l1, l2) for _ in range(repeats))
            rows.append((model, what, n, best, n / best))
    return rows


def _timed(fn, *args) -> float:
    t0 = time.perf_counter()
    fn(*args)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print("fit: 2 directions x 3 samples x 100 points (cotton jersey, Singal et al. 2024)")
    print(
        "| model | fitter | points | best, s | median, s | evaluations | NRMSE tension | NRMSE transverse |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for m, f, n, best, med, ev, e, t in bench_fits(args.repeats):
        tr = "-" if t is None else f"{100 * t:.1f} %"
        print(f"| {m} | {f} | {n} | {best:.3f} | {med:.3f} | {ev} | {100 * e:.1f} % | {tr} |")
    print()
    print("throughput at 10^6 points")
    print("| model | call | points | best, s | evaluations/s |")
    print("|---|---|---|---|---|")
    for m, what, n, best, rate in bench_throughput(args.repeats):
        print(f"| {m} | {what} | {n} | {best:.3f} | {rate:.3g} |")


if __name__ == "__main__":
    main()
