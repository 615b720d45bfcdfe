"""Fit both reduced models to every uniaxial test of Singal et al. 2024 and print markdown tables.

For each fabric (3 yarns × 4 patterns) the course (x) and wale (y) tests (mean of the repeats)
are fitted jointly, as the paper fits its model to both directions at once:

* ``hgo`` (paper) with the measured lateral stretch imposed; reported: tension NRMSE, the
  free-side tension the fit implies (should be 0), and the NRMSE when the same parameters must
  *predict* the test (free side solved from P = 0);
* ``hgo2m`` with the free side solved from P = 0; reported: tension and transverse-strain NRMSE.

NRMSE = RMS error / maximum measured value of that curve (tension, or |transverse strain|).

    python benchmarks/validate_reduced.py [--data DIR] [--fitter lbfgs|mads]

The default data directory is ``../shared/data/knit-uniaxial-singal2024`` next to the repository.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from knitframe.plugins import get_registry

YARNS = ("acrylic", "cotton", "glove")
PATTERNS = ("stockinette", "garter", "rib", "seed")
DEFAULT_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "knit-uniaxial-singal2024"


def nrmse(pred: np.ndarray, meas: np.ndarray) -> float:
    return float(np.sqrt(np.mean((pred - meas) ** 2)) / np.abs(meas).max())


def curve_scores(fit, r, predictive: bool) -> dict:
    """Tension (and transverse) NRMSE of one uniaxial Response under a fitted model."""
    d = r.loaded_direction
    lam, free = (r.lambda1, r.lambda2)[d], (r.lambda1, r.lambda2)[1 - d]
    T = (r.T1, r.T2)[d]
    if predictive:
        lf, P = fit.solve_uniaxial(lam, d)
        return {"tension": nrmse(P, T), "transverse": nrmse(lf - 1, free - 1)}
    P = fit.stress(*((lam, free) if d == 0 else (free, lam)))
    return {"tension": nrmse(P[d], T), "free_tension": float(np.abs(P[1 - d]).max() / np.abs(T).max())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--fitter", default="lbfgs")
    args = ap.parse_args()
    reg = get_registry()
    reader = reg["reader"]["singal2024"]()
    fitter = reg["fitter"][args.fitter]()
    rows, params = [], []
    t0 = time.perf_counter()
    for yarn in YARNS:
        for pattern in PATTERNS:
            data = [reader.read(args.data / f"{yarn}-{pattern}-{x}.csv")[0] for x in ("x", "y")]
            hgo = fitter.fit(reg["homogenizer"]["hgo"](), data)
            h2m = fitter.fit(reg["homogenizer"]["hgo2m"](), data)
            params.append((yarn, pattern, hgo, h2m))
            for r in data:
                a = curve_scores(hgo, r, predictive=False)
                p = curve_scores(hgo, r, predictive=True)
                b = curve_scores(h2m, r, predictive=True)
                d = ("course", "wale")[r.loaded_direction]
                strain = float(((r.lambda1, r.lambda2)[r.loaded_direction]).max() - 1)
                rows.append(
                    (
                        yarn,
                        pattern,
                        d,
                        strain,
                        r.n_samples,
                        a["tension"],
                        a["free_tension"],
                        p["tension"],
                        b["tension"],
                        b["transverse"],
                    )
                )
    print(f"fitter: {args.fitter}; {time.perf_counter() - t0:.0f} s for 24 fits of each model\n")
    print(
        "| yarn | pattern | direction | max strain | repeats | hgo NRMSE (λ2 measured) "
        "| hgo free-side tension / max T "
        "| hgo NRMSE (free side solved) | hgo2m NRMSE tension | hgo2m NRMSE transverse |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for y, pat, d, s, n, a, ft, p, b, bt in rows:
        print(
            f"| {y} | {pat} | {d} | {100 * s:.0f} % | {n} | {100 * a:.1f} % "
            f"| {100 * ft:.0f} % | {100 * p:.0f} % "
            f"| {100 * b:.1f} % | {100 * bt:.1f} % |"
        )
    med = np.median(np.array([r[5:] for r in rows]), axis=0)
    print(
        f"| **median** | | | | | {100 * med[0]:.1f} % | {100 * med[1]:.0f} % | {100 * med[2]:.0f} % | "
        f"{100 * med[3]:.1f} % | {100 * med[4]:.1f} % |"
    )
    print("\nFitted parameters (a, μ, K in N/mm; θ in degrees)\n")
    print("| yarn | pattern | hgo a | hgo b | hgo θ | hgo2m μ1 | μ2 | K | a1 | b1 | a2 | b2 |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for y, pat, hgo, h2m in params:
        a, b, th = hgo.params
        q = h2m.params
        print(
            f"| {y} | {pat} | {a:.3g} | {b:.3g} | {math.degrees(th):.1f} | "
            + " | ".join(f"{v:.3g}" for v in q)
            + " |"
        )


if __name__ == "__main__":
    main()
