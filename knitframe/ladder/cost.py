"""What a rung costs: durations and memory in words, the measured timings (:class:`TimingPoint`,
the shipped file and earlier ladders' ``ladder.csv``) and :class:`CostModel`, which estimates a
rung's wall time and peak memory before it starts.
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np


def format_duration(seconds: float) -> str:
    """``0.2 ms``, ``3.4 s``, ``12 min``, ``2.5 h``."""
    if seconds < 0.01:
        return f"{seconds * 1e3:.2g} ms"
    if seconds < 10:
        return f"{seconds:.2g} s"
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def format_memory(mb: float) -> str:
    """``350 MB``, ``3.1 GB``."""
    return f"{mb:.0f} MB" if mb < 1000 else f"{mb / 1000:.1f} GB"


# ------------------------------------------------------------------------------------ cost model
@attrs.frozen
class TimingPoint:
    """One measured rung: its family, size and cost."""

    family: str
    dofs: int
    #: load steps plus pre-stress steps
    increments: int
    wall_time_s: float
    peak_rss_mb: float | None
    #: "run" (this ladder), "given" (a timings file named in the config) or "shipped"
    source: str
    rung: str = ""


@attrs.frozen
class Estimate:
    """A rung's estimated wall time and peak memory, and what they were fitted to."""

    seconds: float
    rss_mb: float | None
    #: e.g. "2 timings of this run" or "3 timings shipped"
    basis: str

    def text(self) -> str:
        mem = "" if self.rss_mb is None else f", {format_memory(self.rss_mb)}"
        return f"estimated {format_duration(self.seconds)}{mem}"


#: the exponent of DOFs assumed when a family has measurements at one size only
FALLBACK_EXPONENT = 1.0
#: exponents are kept in this range (two close sizes with noisy times can give anything)
EXPONENT_RANGE = (0.0, 3.0)
_TIERS = ("run", "given", "shipped")
_TIER_TEXT = {"run": "of this run", "given": "from the timings files", "shipped": "shipped"}


def _power_law(points: Sequence[tuple[float, float]]) -> float | None:
    """Least-squares exponent p of y = c·x^p in log-log, or None with fewer than two sizes."""
    x = np.log([p[0] for p in points])
    if len(points) < 2 or np.ptp(x) < 1e-9:
        return None
    y = np.log([p[1] for p in points])
    p = float(np.polyfit(x, y, 1)[0])
    return min(max(p, EXPONENT_RANGE[0]), EXPONENT_RANGE[1])


def _scale(points: Sequence[tuple[float, float]], p: float) -> float:
    """c of y = c·x^p: the geometric mean of y / x^p."""
    return float(np.exp(np.mean([math.log(y) - p * math.log(x) for x, y in points])))


class CostModel:
    """Time ≈ c·DOFs^p per load increment, and peak memory ≈ c'·DOFs^q, fitted per solver family.

    Each family is fitted to its most relevant measurements: the rungs of this run if there are
    any, else the timings files named in the config, else the timings shipped with knitframe. The
    exponent comes from the first of these sources with two or more sizes (so one measured rung of
    this run sets the scale, the machine's and the fabric's, and the shipped timings the slope);
    with one size only, from the same solver's other families (P1 for P2), else it is
    :data:`FALLBACK_EXPONENT`. A family with no rung in this run is scaled by how this run's rungs
    of the same solver compare with the same source (a P2 estimate from the shipped timings is
    doubled when this run's P1 rungs took twice their shipped estimate).
    """

    def __init__(self, points: Iterable[TimingPoint] = ()):
        self.points: list[TimingPoint] = [p for p in points if p.wall_time_s > 0 and p.dofs > 0]

    def add(self, point: TimingPoint) -> None:
        if point.wall_time_s > 0 and point.dofs > 0:
            self.points.append(point)

    def _series(self, family: str, tier: str, value) -> list[tuple[float, float]]:
        return [
            (p.dofs, y)
            for p in self.points
            if p.family == family and p.source == tier and (y := value(p)) is not None and y > 0
        ]

    def _siblings(self, family: str) -> list[str]:
        solver = family.split(":")[0]
        return sorted(
            {p.family for p in self.points if p.family != family and p.family.split(":")[0] == solver}
        )

    def _fit(self, family: str, value, tiers: tuple[str, ...] = _TIERS) -> tuple[float, float, str] | None:
        """``(c, p, tier)`` of value ≈ c·DOFs^p, the scale from ``tier``; None without measurements."""
        first = next((t for t in tiers if self._series(family, t, value)), None)
        if first is None:
            return None
        sources = [self._series(f, t, value) for f in [family, *self._siblings(family)] for t in tiers]
        p = next((q for q in map(_power_law, sources) if q is not None), FALLBACK_EXPONENT)
        return _scale(self._series(family, first, value), p), p, first

    def estimate(self, family: str, dofs: int, increments: int) -> Estimate | None:
        """Estimated cost of a rung of ``family`` with ``dofs`` unknowns over ``increments`` steps."""

        def per_increment(pt: TimingPoint) -> float:
            return pt.wall_time_s / max(pt.increments, 1)

        fit = self._fit(family, per_increment)
        if fit is None:
            return None
        c, p, tier = fit
        n = len(self._series(family, tier, per_increment))
        basis = f"{n} timing{'s' if n > 1 else ''} {_TIER_TEXT[tier]}"
        if tier != "run":
            logs, names = [], []
            for sib in self._siblings(family):
                run, ref = self._series(sib, "run", per_increment), self._fit(sib, per_increment, (tier,))
                if run and ref is not None:
                    logs += [math.log(y / (ref[0] * x ** ref[1])) for x, y in run]
                    names.append(sib)
            if logs:
                factor = math.exp(float(np.mean(logs)))
                c *= factor
                basis += f", ×{factor:.2g} as this run's {' and '.join(names)} rungs compare with them"
        m = self._fit(family, lambda pt: pt.peak_rss_mb)
        rss = None if m is None else m[0] * dofs ** m[1]
        return Estimate(c * dofs**p * max(increments, 1), rss, basis)


def shipped_timings_path() -> Path:
    """The timings measured on the reference machine and shipped with knitframe."""
    from importlib.resources import files

    return Path(str(files("knitframe").joinpath("data/ladder-timings.json")))


def read_timings(path: str | Path, source: str = "given") -> list[TimingPoint]:
    """Timing points from a timings JSON (the shipped format) or an earlier ladder's ``ladder.csv``.

    Only rungs that converged count. A malformed file raises DataError naming it.
    """
    from knitframe.errors import DataError

    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise DataError(str(p), f"cannot read it: {e}") from None
    try:
        if p.suffix.lower() == ".json":
            data = json.loads(text)
            rows = data["rows"] if isinstance(data, dict) else None
        else:
            rows = list(csv.DictReader(text.splitlines()))
        if not isinstance(rows, list):
            raise ValueError("no 'rows' list")
        out = []
        for row in rows:
            if str(row.get("status", "ok")) != "ok" or row.get("family") in (None, "", "reduced"):
                continue
            rss = row.get("peak_rss_mb")
            out.append(
                TimingPoint(
                    str(row["family"]),
                    int(float(row["dofs"])),
                    int(float(row["increments"])),
                    float(row["wall_time_s"]),
                    float(rss) if rss not in (None, "") else None,
                    source,
                    str(row.get("rung", "")),
                )
            )
    except (ValueError, KeyError, TypeError) as e:
        raise DataError(str(p), f"not a ladder.csv or a timings JSON ({type(e).__name__}: {e})") from None
    return out


def timings_json(rows: Sequence[Mapping[str, Any]], *, command: str, note: str = "") -> dict[str, Any]:
    """A timings file of a finished ladder's rows, in the shipped format."""
    keep = ("rung", "family", "dofs", "increments", "wall_time_s", "peak_rss_mb", "fabric", "load")
    return {
        "format": 1,
        "command": command,
        "note": note,
        "date": time.strftime("%Y-%m-%d"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.system()}",
        "rows": [
            {k: row[k] for k in keep} | {"status": "ok"}
            for row in rows
            if row.get("status") == "ok" and row.get("family") != "reduced"
        ],
    }
