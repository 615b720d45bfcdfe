"""The goals of a validation sweep against Singal et al. 2024, from its validation.csv.

    python benchmarks/singal_goals.py OUT/validation.csv [--examples knitframe/examples]

Prints, for the simulated curves of the sweep (knitframe run singal-validation.toml):
* the median simulated/measured tension over every ratio at 10/20/30 % (and per yarn);
* how many curves have every ratio within 3x of 1, and the range of the ratios;
* the order of stiffness among the four patterns at 10 % strain, per yarn and direction: how many
  of the 6 pattern pairs the simulation puts in the measured order (the simulated tension is the
  ratio times the measured one, read from the data files);
* how many curves have a lateral strain within 0.05 of the measured one.
"""

from __future__ import annotations

import argparse
import csv
import itertools
from pathlib import Path

import numpy as np

import knitframe


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv", help="validation.csv of the sweep")
    ap.add_argument(
        "--examples", default="knitframe/examples", help="folder the measured paths are relative to"
    )
    args = ap.parse_args(argv)
    rows = [r for r in csv.DictReader(open(args.csv)) if r["measured_status"] == "done"]
    reader = knitframe.get_registry()["reader"]["singal2024"]()

    def num(x):
        return float(x) if x not in ("", None) else np.nan

    ratios = {
        (r["yarn"], r["pattern"], r["direction"]): [num(r[f"ratio_{p}"]) for p in (10, 20, 30)] for r in rows
    }
    allr = np.array([v for vs in ratios.values() for v in vs if np.isfinite(v)])
    print(f"median ratio: {np.median(allr):.3g} over {len(allr)} ratios at 10/20/30 %")
    for yarn in sorted({k[0] for k in ratios}):
        ys = np.array([v for k, vs in ratios.items() if k[0] == yarn for v in vs if np.isfinite(v)])
        print(f"  {yarn}: {np.median(ys):.3g}")
    within = [k for k, vs in ratios.items() if all(1 / 3 <= v <= 3 for v in vs if np.isfinite(v))]
    print(f"curves within 3x: {len(within)} of {len(ratios)}; ratios {allr.min():.2g} to {allr.max():.2g}")
    # order of stiffness at 10 %
    meas10 = {}
    for r in rows:
        resp = reader.read(Path(args.examples) / r["measured"])[0]
        d = 0 if r["direction"] == "course" else 1
        lam, T = (resp.lambda1, resp.T1) if d == 0 else (resp.lambda2, resp.T2)
        meas10[(r["yarn"], r["pattern"], r["direction"])] = float(np.interp(1.1, lam, T))
    for yarn in sorted({k[0] for k in ratios}):
        for direction in ("course", "wale"):
            keys = [k for k in ratios if k[0] == yarn and k[2] == direction and np.isfinite(ratios[k][0])]
            good = sum(
                (meas10[a] - meas10[b]) * (meas10[a] * ratios[a][0] - meas10[b] * ratios[b][0]) > 0
                for a, b in itertools.combinations(keys, 2)
            )
            print(f"order at 10 %: {yarn} {direction}: {good} of {len(keys) * (len(keys) - 1) // 2} pairs")
    lat = [abs(num(r["lateral_simulated"]) - num(r["lateral_measured"])) <= 0.05 for r in rows]
    print(f"lateral within 0.05: {sum(lat)} of {len(lat)}")


if __name__ == "__main__":
    main()
