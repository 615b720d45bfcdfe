"""Running the ladder's rungs: in waves, cheapest first, through an executor, each rung's cost
estimated before it starts (:class:`~knitframe.ladder.cost.CostModel`, refitted as rungs finish)
and the rungs estimated over the time budget skipped; then the reduced model fitted to the best
rung, and every rung compared with the best one, with the measured curves and, for the volumetric
rungs of three or more seeds, by Richardson extrapolation.
"""

from __future__ import annotations

import logging
import warnings
from typing import Any

import numpy as np

from knitframe.errors import KnitframeWarning
from knitframe.ladder.compare import tension_errors, within_range
from knitframe.ladder.convergence import mesh_convergence
from knitframe.ladder.cost import CostModel, TimingPoint, format_duration, format_memory
from knitframe.ladder.jobs import curve_response, run_rung
from knitframe.ladder.rungs import rung
from knitframe.records import Scene

__all__ = [
    "WAVE_SPAN",
    "WAVE_FLOOR_S",
    "MAX_ATTEMPTS",
    "fabric_label",
    "scene_label",
    "rung_size",
    "rung_rows",
    "run_waves",
    "record",
    "run_reduced",
    "measured_curves",
    "compare",
    "convergence_rows",
    "map_rungs",
]

log = logging.getLogger("knitframe.ladder")

#: a wave holds the pending rungs estimated at most this many times the cheapest one ...
WAVE_SPAN = 10.0
#: ... or at most this many seconds
WAVE_FLOOR_S = 30.0
#: a crashed rung found in the cache is run again, at most this many times in one ladder
MAX_ATTEMPTS = 20


def fabric_label(fabric: Any) -> str:
    size = f"SL{fabric.stitch_length:g}" if fabric.stitch_length else f"{fabric.arc_length:g} mm per stitch"
    return f"{fabric.pattern} {size} {fabric.yarn.name}"


def scene_label(scene: Scene) -> str:
    load = scene.load
    kind = f"uniaxial ({load.direction}, free side)" if load.kind == "uniaxial" else load.kind
    text = (
        f"{kind} 0→{100 * load.max_strain:g} % in {load.steps} steps"
        if load.kind != "general"
        else (f"general path of {len(load.lambda1)} points")
    )
    return ("pre-stress + " if "prestress" in scene.effects else "") + text


def rung_size(stage: Any, registry) -> tuple[int, int]:
    """A simulated rung's unknowns (the solver's own set-up: mesh or rod nodes) and its load increments."""
    solver, scene = stage.solver, stage.scene
    model = solver.setup(stage.fabric, scene, registry)
    model = model[0] if isinstance(model, tuple) else model
    cm = getattr(model, "cm", None)
    dofs = 3 * int(cm.n_nodes) if cm is not None else int(model.n_dof)
    steps = len(scene.load.stretches()[0])
    if "prestress" in scene.effects:
        steps += int(getattr(solver, "prestress_steps", 0))
    return dofs, steps


def rung_rows(
    stages: dict[str, Any], jobs: dict[str, dict[str, Any]], scene: Scene, registry: Any, fabric: Any
) -> dict[str, dict[str, Any]]:
    """A row per simulated rung (the columns of ``ladder.csv`` known before it runs): its family,
    solver options, effects, unknowns and increments, fabric and load."""
    rows: dict[str, dict[str, Any]] = {}
    for name, st in stages.items():
        rg = rung(name)
        dofs, increments = rung_size(st, registry)
        rows[name] = {
            "rung": name,
            "family": rg.family,
            "solver": rg.solver,
            "options": dict(jobs[name]["solver"]),
            "effects": " ".join(sorted(st.scene.effects)),
            "dofs": dofs,
            "increments": increments,
            "fabric": fabric_label(fabric),
            "load": scene.load.response_kind,
            "cached": False,
            "reference": False,
        }
    return rows


def _estimate(pending: list[str], rows: dict[str, dict[str, Any]], cost: CostModel, budget) -> dict:
    """Each pending rung's estimate, put in its row; a rung estimated over ``budget`` is skipped."""
    est = {n: cost.estimate(rows[n]["family"], rows[n]["dofs"], rows[n]["increments"]) for n in pending}
    for n in pending:
        e = est[n]
        rows[n].update(
            estimated_time_s=None if e is None else e.seconds,
            estimated_rss_mb=None if e is None else e.rss_mb,
            estimate_basis=None if e is None else e.basis,
        )
        if budget is not None and e is not None and e.seconds > budget:
            rows[n]["status"] = f"skipped: {e.text()}, over max_time {format_duration(budget)}"
            log.warning(
                f"ladder: skipping {n}: {e.text()}, over max_time {format_duration(budget)} ({budget:g} s)"
            )
    return est


def _wave(pending: list[str], est: dict, rows: dict[str, dict[str, Any]], parallel: bool) -> list[str]:
    """The next wave: the pending rungs estimated at most :data:`WAVE_SPAN` times the cheapest (or
    :data:`WAVE_FLOOR_S`), each logged with its estimate."""
    known = [est[n].seconds for n in pending if est[n] is not None]
    limit = max(WAVE_SPAN * min(known), WAVE_FLOOR_S) if known else np.inf
    wave = [n for n in pending if est[n] is None or est[n].seconds <= limit]
    if not parallel:  # one rung at a time: each estimate uses every rung before it
        wave = wave[:1]
    for n in wave:
        e = est[n]
        what = f"{e.text()} ({e.basis})" if e is not None else "no estimate (no timings of its family)"
        dofs = f"{rows[n]['dofs']:,}".replace(",", " ")
        log.info(f"ladder: {n} ({dofs} DOFs): {what}")
    return wave


def run_waves(
    executor: Any,
    jobs: dict[str, dict[str, Any]],
    rows: dict[str, dict[str, Any]],
    cost: CostModel,
    *,
    budget: float | None,
    parallel: bool,
    t_start: float,
    curves: dict[str, Any],
) -> None:
    """Run the rungs of ``rows`` in waves, cheapest first, through ``executor``: before each wave the
    pending rungs are estimated (``cost``, which learns from every rung that finishes) and those over
    ``budget`` seconds skipped; ``parallel``: the executor runs a wave's rungs side by side. Each
    row gets its status and cost; each finished curve goes to ``curves``."""
    pending = list(rows)
    while pending:
        est = _estimate(pending, rows, cost, budget)
        pending = [n for n in pending if "status" not in rows[n]]
        if not pending:
            break
        wave = _wave(pending, est, rows, parallel)
        results = map_rungs(executor, [jobs[n] for n in wave], t_start)
        for n, res in zip(wave, results, strict=False):
            record(rows[n], res, t_start, curves)
            if rows[n]["status"] == "ok":
                cost.add(
                    TimingPoint(
                        rows[n]["family"],
                        rows[n]["dofs"],
                        rows[n]["increments"],
                        rows[n]["wall_time_s"],
                        rows[n].get("peak_rss_mb"),
                        "run",
                        n,
                    )
                )
        pending = [n for n in pending if n not in wave]


def record(row: dict[str, Any], res: dict[str, Any], t_start: float, curves: dict[str, Any]) -> None:
    row["status"] = res.get("status", "crashed: no result")
    row["cached"] = res.get("finished_unix", t_start) < t_start
    row["started_unix"], row["finished_unix"] = res.get("started_unix"), res.get("finished_unix")
    row["wall_time_s"] = res.get("wall_time_s")
    row["peak_rss_mb"] = res.get("peak_rss_mb")
    row["notes"] = res.get("mesh") or res.get("notes") or ""
    if res.get("curve"):
        r = curve_response(res["curve"], label=row["rung"])
        curves[row["rung"]] = r
        row["T1_end_N_per_mm"], row["T2_end_N_per_mm"] = float(r.T1[-1]), float(r.T2[-1])
    for w in res.get("warnings", []):
        warnings.warn(f"ladder rung {row['rung']}: {w}", KnitframeWarning, stacklevel=2)
    if row["wall_time_s"] is not None:
        mem = "" if row["peak_rss_mb"] is None else f", {format_memory(row['peak_rss_mb'])}"
        log.info(
            f"ladder: {row['rung']}: {row['status']}, {format_duration(row['wall_time_s'])}{mem}"
            + (" (cached)" if row["cached"] else "")
        )
    else:
        log.warning(f"ladder: {row['rung']}: {row['status']}")


def run_reduced(
    executor: Any,
    reduced: dict[str, Any],
    scene: Scene,
    reference: str | None,
    curves: dict[str, Any],
    t_start: float,
    fabric: Any,
) -> dict:
    """The reduced rung's row: its job ``reduced`` fitted to the ``reference`` rung's curve (skipped
    when no rung converged), its curve added to ``curves``."""
    job = dict(reduced)
    model = job["solver"]["model"]
    row = {
        "rung": "reduced",
        "family": "reduced",
        "solver": "reduced",
        "fabric": fabric_label(fabric),
        "load": scene.load.response_kind,
        "effects": " ".join(job["scene"]["effects"]),
        "cached": False,
        "reference": False,
        "increments": scene.load.steps,
        "options": {"model": model, "fitter": job["solver"]["fitter"]},
    }
    if reference is None:
        row["status"] = "skipped: no rung converged to fit the reduced model to"
        return row
    ref = curves[reference]
    job["reference"] = {
        "lambda1": ref.lambda1.tolist(),
        "lambda2": ref.lambda2.tolist(),
        "T1": ref.T1.tolist(),
        "T2": ref.T2.tolist(),
        "load": ref.load,
        "label": reference,
    }
    res = map_rungs(executor, [job], t_start)[0]
    record(row, res, t_start, curves)
    if res.get("params"):
        row["dofs"] = len(res["params"])
        row["options"] = {
            **row["options"],
            "model": res.get("model", model),
            "params": res["params"],
            "fitted_to": reference,
        }
        row["notes"] = (
            f"fitted to {reference} in {format_duration(res.get('fit_time_s') or 0.0)}; "
            f"time is one evaluation of the path"
        )
    return row


def measured_curves(scene: Scene, responses: list[Any]) -> list[Any]:
    """The measured curves among ``responses`` of the scene's load, cut to the path's largest stretch;
    the others are named in the log, and a curve with fewer than 2 points within it in a warning."""
    kind = scene.load.response_kind
    experiments = [r for r in responses if r.provenance.kind == "experiment"]
    same = [r for r in experiments if r.load == kind]
    other = [r.label for r in experiments if r.load != kind]
    if other:
        log.info(f"ladder: measured curves of another load are not compared: {', '.join(other)}")
    if experiments and not same:
        warnings.warn(
            f"ladder: no measured curve is {kind} (the scene's load); the rungs are compared "
            f"with the best rung only",
            KnitframeWarning,
            stacklevel=2,
        )
    _, lam1, lam2 = scene.load.stretches()
    top = max(float(np.max(x)) for x in (lam1, lam2) if x is not None)
    out = []
    for r in same:
        cut = within_range(r, top)
        if cut is None:
            warnings.warn(
                f"ladder: measured curve '{r.label}' has fewer than 2 points within the path "
                f"(stretch ≤ {top:g}); not compared",
                KnitframeWarning,
                stacklevel=2,
            )
        else:
            out.append(cut)
    return out


def compare(rows, curves, reference, measured) -> None:
    """Each finished rung's NRMSE against the ``reference`` rung and the mean over the measured
    curves, put in its row."""
    ref = curves.get(reference) if reference else None
    for name, r in curves.items():
        row = rows[name]
        row["reference"] = name == reference
        if ref is not None:
            e = tension_errors(ref, r)
            row.update(
                nrmse_vs_best=e["overall"], nrmse_course_vs_best=e["course"], nrmse_wale_vs_best=e["wale"]
            )
        if measured:
            errs = [tension_errors(m, r) for m in measured]
            for key, col in (
                ("overall", "nrmse_vs_measured"),
                ("course", "nrmse_course_vs_measured"),
                ("wale", "nrmse_wale_vs_measured"),
            ):
                vals = [e[key] for e in errs if e[key] is not None]
                row[col] = float(np.mean(vals)) if vals else None


def convergence_rows(curves: dict[str, Any], scene: Scene) -> list[dict[str, Any]]:
    """Richardson rows of every volumetric order with three or more finished seeds
    (knitframe.ladder.convergence)."""
    rows: list[dict[str, Any]] = []
    for family in sorted({rung(n).family for n in curves if rung(n).solver == "volumetric"}):
        sizes = {n: float(rung(n).options["seed"]) for n in curves if rung(n).family == family}
        found = mesh_convergence(sizes, curves, scene.load.response_kind, family)
        rows += found
        if found:
            last = [r for r in found if r["strain"] == max(x["strain"] for x in found)]
            text = "; ".join(
                f"{r['direction']} T {r['T_finest']:.4g} N/mm, "
                + (
                    f"order {r['order']:.2f}, extrapolated {r['T_extrapolated']:.4g}, error of the finest "
                    f"{100 * r['error_finest']:.3g} %"
                    if r["order"] is not None
                    else r["behaviour"]
                )
                for r in last
            )
            log.info(
                f"ladder: mesh convergence of {family} ({found[0]['rungs']}) at "
                f"{100 * last[0]['strain']:g} %: {text}"
            )
    return rows


def map_rungs(executor: Any, jobs: list[dict[str, Any]], t_start: float) -> list[dict[str, Any]]:
    """executor.map over the jobs; a crash that comes from the cache (an earlier run's) is run again."""
    results = list(executor.map(run_rung, jobs))
    for _ in range(MAX_ATTEMPTS):
        stale = [i for i, r in enumerate(results) if r.get("crashed") and r.get("finished_unix", 0) < t_start]
        if not stale:
            break
        retry = [{**jobs[i], "attempt": jobs[i]["attempt"] + 1} for i in stale]
        for i, job in zip(stale, retry, strict=False):
            jobs[i] = job
        for i, r in zip(stale, executor.map(run_rung, retry), strict=False):
            results[i] = r
    return results
