"""The job an executor runs for one rung, :func:`run_rung`: the rung in a fresh Python process, so
that its peak memory and wall time are its own; the plugin modules it runs (for the code-hashed
result cache, :mod:`knitframe.cache`); the simulated and the reduced rung's bodies; and the
curves as plain data.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.records import Provenance, Response

_CHILD = (
    "import sys; from knitframe.ladder.jobs import _child_main; "
    "sys.exit(_child_main(sys.argv[1], sys.argv[2]))"
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
            # -P: the working folder is not put first on the import path, so a folder named knitframe
            # there (the parent of a clone) cannot shadow the installed package
            [sys.executable, "-P", "-c", _CHILD, str(job_path), str(out_path)],
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
    reference = curve_response(job["reference"])
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


def curve_response(curve: Mapping[str, Any], label: str | None = None, kind: str = "simulation") -> Response:
    return Response(
        np.asarray(curve["lambda1"]),
        np.asarray(curve["lambda2"]),
        np.asarray(curve["T1"]),
        np.asarray(curve["T2"]),
        load=curve["load"],
        label=label or curve.get("label", ""),
        provenance=Provenance(kind=kind, source="ladder"),
    )
