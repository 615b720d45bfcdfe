"""The accuracy ladder: one fabric and scene through rungs of fidelity, with what each costs.

The rungs are defined once, in :data:`RUNGS`, with their solver options. The ``[ladder]`` stage
(``knitframe_stages.ladder``), the ``knitframe ladder`` command and :func:`ladder` all run them
through this module:

- :func:`run_rung` is the job an executor runs for one rung: it starts a fresh Python process for
  the rung, so that the rung's peak memory (the high-water mark of that process) and wall time are
  its own, whatever ran before it in the executor's worker;
- :class:`CostModel` estimates a rung's time and memory before it starts, from a power law in its
  degrees of freedom fitted per solver family to the rungs already run, to timing files the user
  names, and to the timings shipped with knitframe (``knitframe/data/ladder-timings.json``);
- :func:`tension_errors`, :func:`write_table`, :func:`plot_pareto` and :func:`plot_curves` make
  the outputs.

``knitframe.ladder`` is the function :func:`ladder` (the Python twin of the command); import the
helpers with ``from knitframe.ladder import RUNGS, CostModel``.
"""

from __future__ import annotations

import csv
import json
import math
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.records import Provenance, Response

__all__ = [
    "Rung",
    "RUNGS",
    "DEFAULT_RUNGS",
    "rung",
    "richardson",
    "mesh_convergence",
    "Estimate",
    "CostModel",
    "TimingPoint",
    "shipped_timings_path",
    "read_timings",
    "run_rung",
    "tension_errors",
    "format_duration",
    "format_memory",
    "LadderResult",
    "ladder_config",
    "ladder",
]


# ---------------------------------------------------------------------------------------------- rungs
@attrs.frozen
class Rung:
    """One rung of the ladder: a solver with the options that make its fidelity."""

    #: what ``--rungs`` and ``[ladder] rungs`` call it
    name: str
    #: solver plugin
    solver: str
    #: the solver options that define the rung
    options: Mapping[str, Any]
    #: the cost model's solver family (time and memory fitted per family)
    family: str
    #: run when no rungs are named
    default: bool
    description: str

    @property
    def fidelity(self) -> tuple[int, float]:
        """Sort key of fidelity (higher is more faithful): the solver family, then the resolution.

        reduced < rod (by segments per stitch) < volumetric P1 < volumetric P2 (each by the mesh
        divisor: seed r/x has resolution x).
        """
        if self.solver == "rod":
            return 1, float(self.options["segments_per_stitch"])
        if self.solver == _VOL:
            return 1 + int(self.options["order"]), 1.0 / float(self.options["seed"])
        return 0, 0.0


_VOL = "volumetric"

#: Every rung, from the cheapest and least faithful to the most faithful. The best rung that ran
#: (converged) is the reference of the others; ``reduced`` is fitted to it.
RUNGS: dict[str, Rung] = {
    r.name: r
    for r in (
        Rung(
            "reduced",
            "reduced",
            {},
            "reduced",
            True,
            "the paper's reduced model (hgo; hgo2m under a free side) fitted by L-BFGS to the best rung's curve",
        ),
        Rung("rod:8", "rod", {"segments_per_stitch": 8}, "rod", True, "rod, 8 segments per stitch"),
        Rung("rod:16", "rod", {"segments_per_stitch": 16}, "rod", True, "rod, 16 segments per stitch"),
        Rung("rod:32", "rod", {"segments_per_stitch": 32}, "rod", True, "rod, 32 segments per stitch"),
        Rung("rod:64", "rod", {"segments_per_stitch": 64}, "rod", False, "rod, 64 segments per stitch"),
        Rung(
            "volumetric:p1:coarse",
            _VOL,
            {"order": 1, "seed": 1.0},
            "volumetric:p1",
            True,
            "volumetric, P1 tetrahedra, seed r (coarse); locks in bending: a quick look",
        ),
        Rung(
            "volumetric:p1:r/1.67",
            _VOL,
            {"order": 1, "seed": 0.6},
            "volumetric:p1",
            False,
            "volumetric, P1 tetrahedra, seed r/1.67; locks in bending: a quick look",
        ),
        Rung(
            "volumetric:p1:r/3",
            _VOL,
            {"order": 1, "seed": 1.0 / 3.0},
            "volumetric:p1",
            True,
            "volumetric, P1 tetrahedra, seed r/3; locks in bending: a quick look",
        ),
        Rung(
            "volumetric:p2:coarse",
            _VOL,
            {"order": 2, "seed": 1.0},
            "volumetric:p2",
            False,
            "volumetric, P2 tetrahedra, seed r (coarse)",
        ),
        Rung(
            "volumetric:p2:r/1.67",
            _VOL,
            {"order": 2, "seed": 0.6},
            "volumetric:p2",
            True,
            "volumetric, P2 tetrahedra, seed r/1.67",
        ),
        Rung(
            "volumetric:p2:r/3",
            _VOL,
            {"order": 2, "seed": 1.0 / 3.0},
            "volumetric:p2",
            False,
            "volumetric, P2 tetrahedra, seed r/3 (the paper's mesh)",
        ),
    )
}

#: The rungs run when none are named.
DEFAULT_RUNGS: tuple[str, ...] = tuple(name for name, r in RUNGS.items() if r.default)

_ROD_RE = re.compile(r"rod:(\d+)")
_VOL_RE = re.compile(r"volumetric:p([12]):r/(\d+(?:\.\d+)?)")
#: the range of a named rung's segments per stitch and mesh divisor
ROD_SEGMENTS = (4, 256)
MESH_DIVISORS = (0.5, 8.0)
RUNG_FORMS = "reduced, rod:N (N segments per stitch), volumetric:p1:r/X or volumetric:p2:r/X (seed r/X)"


def rung(name: str) -> Rung:
    """The rung called ``name``: one of :data:`RUNGS`, or ``rod:N`` / ``volumetric:pK:r/X`` at any
    resolution in :data:`ROD_SEGMENTS` / :data:`MESH_DIVISORS` (a mesh-convergence study names
    three or more seeds of one order, e.g. ``volumetric:p2:r/1.5,volumetric:p2:r/2.25,volumetric:p2:r/3``).

    Raises ValueError with a one-line reason for any other name.
    """
    if name in RUNGS:
        return RUNGS[name]
    if m := _ROD_RE.fullmatch(name):
        n = int(m.group(1))
        if not ROD_SEGMENTS[0] <= n <= ROD_SEGMENTS[1]:
            raise ValueError(
                f"rung {name!r}: segments per stitch must be {ROD_SEGMENTS[0]}..{ROD_SEGMENTS[1]}"
            )
        return Rung(name, "rod", {"segments_per_stitch": n}, "rod", False, f"rod, {n} segments per stitch")
    if m := _VOL_RE.fullmatch(name):
        order, x = int(m.group(1)), float(m.group(2))
        if not MESH_DIVISORS[0] <= x <= MESH_DIVISORS[1]:
            raise ValueError(
                f"rung {name!r}: the mesh divisor X of r/X must be {MESH_DIVISORS[0]:g}..{MESH_DIVISORS[1]:g}"
            )
        return Rung(
            name,
            _VOL,
            {"order": order, "seed": 1.0 / x},
            f"volumetric:p{order}",
            False,
            f"volumetric, P{order} tetrahedra, seed r/{m.group(2)}",
        )
    raise ValueError(f"unknown rung {name!r}; the rungs are {', '.join(RUNGS)}, or any of {RUNG_FORMS}")


# ------------------------------------------------------------------------------------ formatting
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


# ------------------------------------------------------------------------------------ rung jobs
_CHILD = (
    "import sys; from knitframe.ladder import _child_main; sys.exit(_child_main(sys.argv[1], sys.argv[2]))"
)


def run_rung(job: Mapping[str, Any]) -> dict[str, Any]:
    """Run one rung (an executor job: plain data) in a fresh Python process; returns plain data.

    The result holds ``status`` ("ok", "stopped: …" for a solver that stopped early with the
    converged steps, "failed: …", or "crashed: …" when the process died without a result),
    ``wall_time_s`` (the solve, measured in that process), ``peak_rss_mb`` (its peak resident memory),
    ``curve`` (the Response as lists), ``warnings``, ``started_unix`` and ``finished_unix``.
    """
    started = time.time()
    with tempfile.TemporaryDirectory(prefix="knitframe-rung-") as tmp:
        job_path, out_path = Path(tmp) / "job.json", Path(tmp) / "result.json"
        job_path.write_text(json.dumps(job), encoding="utf-8")
        proc = subprocess.run(
            [sys.executable, "-c", _CHILD, str(job_path), str(out_path)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            errors="replace",
        )
        if out_path.is_file():
            result = json.loads(out_path.read_text(encoding="utf-8"))
        else:
            lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
            how = (
                f"killed by signal {-proc.returncode}"
                if proc.returncode < 0
                else f"exit code {proc.returncode}"
            )
            result = {
                "status": f"crashed: {how}" + (f": {lines[-1].strip()}" if lines else ""),
                "crashed": True,
            }
    result.setdefault("rung", job.get("rung"))
    result["started_unix"], result["finished_unix"] = started, time.time()
    return result


def rung_modules(job: Mapping[str, Any]) -> list[str]:
    """The plugin modules a rung runs that no import statement names (chosen by name at run time):
    the simulate stage, the solver and the plugins its options name, the pattern and yarn model, or
    the reduced model's homogenizer and fitter. A cache that hashes code reads this as
    ``run_rung.cache_modules``."""
    from knitframe.config import PluginSpec
    from knitframe.plugins import get_registry

    reg = get_registry()

    def module(kind: str, value: Any) -> str | None:
        try:
            return getattr(reg[kind][PluginSpec.parse(value, kind).kind], "__module__", None)
        except Exception:  # noqa: BLE001 - not a plugin of this kind
            return None

    solver = job["solver"]
    found = [module("solver", solver["kind"]), module("stage", "simulate")]
    if solver["kind"] == "reduced":
        found += [module("homogenizer", solver["model"]), module("fitter", solver["fitter"])]
    else:
        fabric = job["config"].get("fabric", {})
        yarn = fabric.get("yarn")
        if isinstance(yarn, str) and yarn in reg["yarn"]:
            yarn = {"model": getattr(reg["yarn"][yarn], "model", None)}
        found += [
            module("pattern", fabric.get("pattern")),
            module("yarn_model", yarn.get("model") if isinstance(yarn, dict) else None),
        ]
        cls = reg["solver"][solver["kind"]]
        defaults = {f.name: f.default for f in attrs.fields(cls)} if attrs.has(cls) else {}
        options = {**{k: d for k, d in defaults.items() if isinstance(d, (str, dict))}, **solver}
        found += [
            module(kind, value) for value in options.values() for kind in ("linear_solver", "contact_law")
        ]
    return sorted({m for m in found if m})


run_rung.cache_modules = rung_modules  # type: ignore[attr-defined]


def _child_main(job_path: str, out_path: str) -> int:
    """Body of a rung's process: run the job, write its result as JSON."""
    import warnings

    from knitframe.errors import KnitframeError, KnitframeWarning

    job = json.loads(Path(job_path).read_text(encoding="utf-8"))
    caught: list[str] = []
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", KnitframeWarning)
        warnings.simplefilter(
            "error", RuntimeWarning
        )  # as the command line does: a non-finite value is an error
        try:
            result = _reduced(job) if job["solver"]["kind"] == "reduced" else _simulate(job)
        except KnitframeError as e:
            result = {"status": f"failed: {' '.join(str(e).split())}"}
        except RuntimeWarning as e:
            result = {"status": f"failed: numerical failure (non-finite value): {e}"}
        caught = [" ".join(str(w.message).split()) for w in seen if issubclass(w.category, KnitframeWarning)]
    result["peak_rss_mb"] = _peak_rss_mb()
    result["warnings"] = list(dict.fromkeys(caught))
    Path(out_path).write_text(json.dumps(result), encoding="utf-8")
    return 0


def _peak_rss_mb() -> float:
    """This process's peak resident memory, MB.

    On Linux ``VmHWM`` of ``/proc/self/status``: the high-water mark of the process's own address
    space since its ``exec``. ``ru_maxrss`` is not used there because it also counts the copy of the
    parent made by ``fork`` before the ``exec`` (a parent of 300 MB gives every rung at least 300 MB).
    Elsewhere ``ru_maxrss``.
    """
    import resource

    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0 * 1024.0 if sys.platform == "darwin" else 1024.0)


def _simulate(job: Mapping[str, Any]) -> dict[str, Any]:
    """A simulated rung: the ``simulate`` stage's own validation builds solver, fabric and scene."""
    from knitframe.pipeline import BuildContext
    from knitframe.plugins import get_registry

    registry = get_registry()
    stage = registry["stage"]["simulate"].from_config(job["config"], BuildContext(registry, Path.cwd()))
    t0 = time.perf_counter()
    response = stage.solver.simulate(stage.fabric, stage.scene)
    wall = time.perf_counter() - t0
    prov = response.provenance
    status = "ok" if prov.converged else f"stopped: {prov.notes or 'the solver stopped early'}"
    return {
        "status": status,
        "wall_time_s": wall,
        "curve": _curve(response),
        "mesh": prov.mesh or "",
        "notes": prov.notes,
    }


def _reduced(job: Mapping[str, Any]) -> dict[str, Any]:
    """The reduced rung: fit the model to the reference curve, then time its evaluation of the path."""
    from knitframe.config import instantiate
    from knitframe.fitting import params_to_json
    from knitframe.plugins import get_registry
    from knitframe.records import Scene
    from knitframe.schema import build

    registry = get_registry()
    solver_table = job["solver"]
    model = instantiate(registry, "homogenizer", solver_table["model"], "ladder.reduced_model")
    fitter = instantiate(registry, "fitter", solver_table["fitter"], "ladder.reduced_fitter")
    reference = _response(job["reference"])
    fit = fitter.fit(model, [reference])
    solver = registry["solver"]["reduced"].from_fit(fit)
    scene = build(Scene, job["scene"], "scene")
    solver.simulate(None, scene)  # once before timing: imports and first-call costs are not the model's
    n, t0 = 0, time.perf_counter()
    while True:  # one evaluation takes well under a millisecond: time enough of them
        response = solver.simulate(None, scene)
        n += 1
        wall = time.perf_counter() - t0
        if wall > 0.2 or n >= 10000:
            break
    return {
        "status": "ok",
        "wall_time_s": wall / n,
        "curve": _curve(response),
        "fit_time_s": fit.wall_time,
        "params": params_to_json(fit.param_names, fit.params),
        "model": model.name,
        "nrmse_fit": fit.nrmse.get("overall"),
        "notes": response.provenance.notes,
    }


def _curve(r: Response) -> dict[str, Any]:
    return {
        "lambda1": r.lambda1.tolist(),
        "lambda2": r.lambda2.tolist(),
        "T1": r.T1.tolist(),
        "T2": r.T2.tolist(),
        "load": r.load,
        "label": r.label,
    }


def _response(curve: Mapping[str, Any], label: str | None = None, kind: str = "simulation") -> Response:
    return Response(
        np.asarray(curve["lambda1"]),
        np.asarray(curve["lambda2"]),
        np.asarray(curve["T1"]),
        np.asarray(curve["T2"]),
        load=curve["load"],
        label=label or curve.get("label", ""),
        provenance=Provenance(kind=kind, source="ladder"),
    )


# ------------------------------------------------------------------------------------ errors
def loaded_directions(load: str) -> tuple[int, ...]:
    """Indices (0 course, 1 wale) of the directions a load kind pulls on."""
    return {"uniaxial-course": (0,), "uniaxial-wale": (1,)}.get(load, (0, 1))


def tension_errors(ref: Response, r: Response) -> dict[str, float | None]:
    """NRMSE of ``r``'s course and wale tension against ``ref``, and overall.

    The normalisation is :func:`knitframe.curves.nrmse_between`'s (the reference's largest
    tension), so with both directions loaded ``overall`` is ``nrmse_between(ref, r)``. Under a
    uniaxial load the free direction carries no tension in either curve: it is left out (None),
    and ``overall`` is the loaded direction's.
    """
    from knitframe.curves import nrmse_between

    dirs = loaded_directions(ref.load)
    scale = max(np.abs(ref.T1).max(), np.abs(ref.T2).max())
    out: dict[str, float | None] = {"course": None, "wale": None}
    for d, name in ((0, "course"), (1, "wale")):
        if d in dirs:
            lam_ref, T_ref = (ref.lambda1, ref.T1) if d == 0 else (ref.lambda2, ref.T2)
            lam, T = (r.lambda1, r.T1) if d == 0 else (r.lambda2, r.T2)
            o = np.argsort(lam)
            out[name] = float(np.sqrt(np.mean((np.interp(lam_ref, lam[o], T[o]) - T_ref) ** 2)) / scale)
    out["overall"] = nrmse_between(ref, r) if len(dirs) == 2 else out["course" if dirs == (0,) else "wale"]
    return out


def within_range(measured: Response, top: float) -> Response | None:
    """The measured points up to the simulated path's largest stretch ``top`` (None if fewer than 2)."""
    d = loaded_directions(measured.load)
    lam = (
        measured.lambda1
        if d == (0,)
        else measured.lambda2
        if d == (1,)
        else np.maximum(measured.lambda1, measured.lambda2)
    )
    keep = lam <= top + 1e-9
    if keep.sum() < 2:
        return None
    arrays = {k: getattr(measured, k)[keep] for k in Response._ARRAYS if getattr(measured, k) is not None}
    return measured.evolve(**arrays)


# ------------------------------------------------------------------------------------ outputs
CSV_COLUMNS = (
    "rung",
    "family",
    "solver",
    "options",
    "effects",
    "dofs",
    "increments",
    "status",
    "cached",
    "reference",
    "wall_time_s",
    "peak_rss_mb",
    "estimated_time_s",
    "estimated_rss_mb",
    "estimate_basis",
    "T1_end_N_per_mm",
    "T2_end_N_per_mm",
    "nrmse_vs_best",
    "nrmse_course_vs_best",
    "nrmse_wale_vs_best",
    "nrmse_vs_measured",
    "nrmse_course_vs_measured",
    "nrmse_wale_vs_measured",
    "fabric",
    "load",
    "notes",
)


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """``ladder.csv``: one row per rung, :data:`CSV_COLUMNS`."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS)
        for row in rows:
            w.writerow([_cell(row.get(c)) for c in CSV_COLUMNS])


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (dict, list)):
        return json.dumps(value, sort_keys=True)
    return str(value)


def _pct(x: float | None) -> str:
    if x is None:
        return "–"
    return f"{100 * x:.0f} %" if abs(x) >= 10 else f"{100 * x:.3g} %"


def _tension(x: float) -> str:
    return "0" if abs(x) < 1e-9 else f"{x:.4g}"


def write_table(path: Path, rows: Sequence[Mapping[str, Any]], *, title: str, measured: Sequence[str]) -> str:
    """``ladder.md``: the Markdown table (returned as well)."""
    has_measured = bool(measured)
    head = (
        [
            "rung",
            "DOFs",
            "wall time",
            "peak memory",
            "estimated before",
            "T1, T2 at the end (N/mm)",
            "NRMSE vs best (course, wale)",
        ]
        + (["NRMSE vs measured"] if has_measured else [])
        + ["status"]
    )
    lines = [f"**{title}**", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        ok = row.get("wall_time_s") is not None
        best = (
            "reference"
            if row.get("reference")
            else f"{_pct(row.get('nrmse_vs_best'))} ({_pct(row.get('nrmse_course_vs_best'))}, "
            f"{_pct(row.get('nrmse_wale_vs_best'))})"
            if row.get("nrmse_vs_best") is not None
            else "–"
        )
        est = (
            "–"
            if row.get("estimated_time_s") is None
            else (
                format_duration(row["estimated_time_s"])
                + (
                    ""
                    if row.get("estimated_rss_mb") is None
                    else f", {format_memory(row['estimated_rss_mb'])}"
                )
            )
        )
        ends = (
            "–"
            if row.get("T1_end_N_per_mm") is None
            else f"{_tension(row['T1_end_N_per_mm'])}, {_tension(row['T2_end_N_per_mm'])}"
        )
        status = row.get("status", "")
        if row.get("cached"):
            status += " (cached)"
        cells = [
            row["rung"],
            f"{row['dofs']:,}".replace(",", " ") if row.get("dofs") else "–",
            format_duration(row["wall_time_s"]) if ok else "–",
            format_memory(row["peak_rss_mb"]) if row.get("peak_rss_mb") else "–",
            est,
            ends,
            best,
        ]
        if has_measured:
            cells.append(_pct(row.get("nrmse_vs_measured")))
        cells.append(status.replace("|", "/"))
        lines.append("| " + " | ".join(cells) + " |")
    if has_measured:
        lines += ["", f"Measured: {', '.join(measured)} (points up to the path's largest stretch)."]
    text = "\n".join(lines) + "\n"
    path.write_text(text, encoding="utf-8")
    return text


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_pareto(path: Path, rows: Sequence[Mapping[str, Any]], *, title: str) -> None:
    """``ladder.png``: wall time against error, log axes, each rung labelled, the Pareto front dashed.

    Error against the best rung (filled), and against the measurement (open) when there is one;
    the front is drawn on the measured errors when there are any.
    """
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.0, 4.8), dpi=110)
    series = [("nrmse_vs_best", "vs best rung", "o", "C0", True)]
    if any(r.get("nrmse_vs_measured") is not None for r in rows):
        series.append(("nrmse_vs_measured", "vs measured", "s", "C3", False))
    front_key = series[-1][0]
    plotted = 0
    for key, label, marker, color, filled in series:
        pts = [
            (r["wall_time_s"], r[key], r["rung"])
            for r in rows
            if r.get("wall_time_s") and r.get(key) is not None and r[key] > 0
        ]
        if not pts:
            continue
        plotted += len(pts)
        ax.scatter(
            [p[0] for p in pts],
            [p[1] for p in pts],
            marker=marker,
            s=42,
            label=label,
            zorder=3,
            facecolors=color if filled else "none",
            edgecolors=color,
        )
        for x, y, name in pts:
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(5, 4), fontsize=7.5, color=color)
        if key == front_key:
            pts.sort()
            front, low = [], math.inf
            for x, y, _ in pts:
                if y < low:
                    front.append((x, y))
                    low = y
            if len(front) > 1:
                ax.step(
                    [p[0] for p in front],
                    [p[1] for p in front],
                    where="post",
                    ls="--",
                    lw=1,
                    color=color,
                    alpha=0.6,
                    label="Pareto front",
                )
    if plotted:
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.legend(fontsize=8, loc="best")
    else:
        ax.text(
            0.5,
            0.5,
            "only one rung finished: nothing to compare",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
    ref = next((r for r in rows if r.get("reference")), None)
    if ref is not None and ref.get("wall_time_s"):
        # the best rung has no error against itself: a vertical line at its time
        ax.axvline(ref["wall_time_s"], color="C0", ls=":", lw=1.2)
        ax.annotate(
            f"{ref['rung']} (best rung)",
            (ref["wall_time_s"], 0.03),
            xycoords=("data", "axes fraction"),
            rotation=90,
            ha="right",
            va="bottom",
            fontsize=7.5,
            color="C0",
            xytext=(-3, 0),
            textcoords="offset points",
        )
        if not plotted:
            ax.set_xscale("log")
    ax.set_xlabel("wall time of the rung, s")
    ax.set_ylabel("NRMSE of tension")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.25)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_curves(
    path: Path,
    curves: Mapping[str, Response],
    measured: Sequence[Response],
    *,
    title: str,
    load: str,
    reference: str | None = None,
) -> None:
    """``curves.png``: every rung's tension curves over the measured ones.

    Equibiaxial and general loads: course and wale tension; uniaxial: the loaded tension and the
    free side's lateral strain. The best rung's curve is drawn thicker; the tension axis is
    logarithmic when the curves' last tensions differ more than tenfold.
    """
    plt = _plt()
    dirs = loaded_directions(load)
    panels = (
        [("course", 0, "T"), ("wale", 1, "T")]
        if len(dirs) == 2
        else [("course" if dirs[0] == 0 else "wale", dirs[0], "T"), ("lateral", dirs[0], "lateral")]
    )
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.2), dpi=110)

    def xy(r: Response, d: int, what: str):
        lam = r.lambda1 if d == 0 else r.lambda2
        if what == "lateral":
            return 100 * (lam - 1), 100 * ((r.lambda2 if d == 0 else r.lambda1) - 1)
        return 100 * (lam - 1), r.T1 if d == 0 else r.T2

    for ax, (name, d, what) in zip(axes, panels):
        for m in measured:
            x, y = xy(m, d, what)
            sd = (
                (m.T1_sd if d == 0 else m.T2_sd)
                if what == "T"
                else (m.lambda2_sd if d == 0 else m.lambda1_sd)
            )
            ax.plot(x, y, "k.", ms=4, label=f"measured: {m.label}")
            if sd is not None:
                scale = 1.0 if what == "T" else 100.0
                ax.fill_between(x, y - scale * sd, y + scale * sd, color="k", alpha=0.12, lw=0)
        ends, low = [], np.inf
        for i, (rung, r) in enumerate(curves.items()):
            x, y = xy(r, d, what)
            best = rung == reference
            ax.plot(
                x,
                y,
                "-",
                marker=".",
                ms=3,
                lw=2.6 if best else 1.3,
                color=f"C{i % 10}",
                label=f"{rung} (best rung)" if best else rung,
                zorder=2 if best else 3,
            )
            ends.append(float(y[-1]))
            low = min(low, float(np.min(y[y > 0], initial=np.inf)))
        if what == "T" and ends and min(ends) > 0 and max(ends) > 10 * min(ends):
            ax.set_yscale("log")
            ax.set_ylim(bottom=0.5 * low)  # the rungs' range: a measured point near zero strain is below it
        strain = "course" if d == 0 else "wale"
        ax.set_xlabel(f"{strain} strain, %")
        ax.set_ylabel(f"{name} tension, N/mm" if what == "T" else "lateral strain (free side), %")
        ax.grid(True, alpha=0.25)
    axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# ------------------------------------------------------------------------------------ API
@attrs.frozen
class LadderResult:
    """What a ladder run gives back: a row per rung (as in ``ladder.csv``) and the curves."""

    #: one dict per rung, keys as :data:`CSV_COLUMNS`
    rows: list[dict[str, Any]]
    #: each finished rung's Response, by rung name
    curves: dict[str, Response]
    #: the measured curves compared against
    measured: list[Response]
    #: the best rung that ran
    reference: str | None
    #: the Markdown table
    table: str
    out: Path | None = None

    def row(self, rung: str) -> dict[str, Any]:
        """The row of one rung."""
        return next(r for r in self.rows if r["rung"] == rung)


def ladder_config(
    config: str | Path | Mapping[str, Any],
    *,
    rungs: Sequence[str] | None = None,
    max_time: float | None = None,
) -> tuple[dict[str, Any], Path, str | None]:
    """A config with its ``[ladder]`` table given or amended: ``(config, base_dir, source)``."""
    from knitframe.config import load_toml

    if isinstance(config, Mapping):
        data, base, source = dict(config), Path.cwd(), None
    else:
        path = Path(config)
        data, base, source = load_toml(path), path.resolve().parent, str(path)
    table = dict(data.get("ladder", {})) if isinstance(data.get("ladder", {}), Mapping) else data["ladder"]
    if isinstance(table, dict):
        if rungs is not None:
            table["rungs"] = list(rungs)
        if max_time is not None:
            table["max_time"] = max_time
    data["ladder"] = table
    return data, base, source


def ladder(
    config: str | Path | Mapping[str, Any],
    out: str | Path | None = None,
    *,
    rungs: Sequence[str] | None = None,
    max_time: float | None = None,
    overwrite: bool = False,
    quiet: bool = True,
) -> LadderResult:
    """Run a config's pipeline with the ladder stage; the Python twin of ``knitframe ladder``.

    Parameters
    ----------
    config : path or mapping
        A TOML file or parsed dict with ``[fabric]`` and ``[scene]`` (and ``[data]`` for measured
        curves); its ``[ladder]`` table, if any, is amended by ``rungs`` and ``max_time``.
    out : path, optional
        Writes ``ladder.csv``, ``ladder.md``, ``ladder.png``, ``curves.png`` and
        ``ladder-curves.csv`` there; None keeps no files.
    rungs : names from :data:`RUNGS`; default :data:`DEFAULT_RUNGS`.
    max_time : float, optional
        Skip the rungs whose estimated time exceeds this many seconds.
    """
    from knitframe.pipeline import Pipeline

    data, base, source = ladder_config(config, rungs=rungs, max_time=max_time)
    result = Pipeline(data, base_dir=base, source=source).run(out, overwrite=overwrite, quiet=quiet)
    return attrs.evolve(result.objects["ladder"], out=result.out)
