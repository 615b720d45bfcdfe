"""The job of one sweep point, :func:`run_point`, the plugin modules it runs (for the code-hashed
result cache, :mod:`knitframe.cache`), and the map of the points through an executor.
"""

from __future__ import annotations

import socket
import time
import warnings
from typing import Any

from knitframe.cache import JobCache, failure_reason, job_keys
from knitframe.config import instantiate
from knitframe.errors import KnitframeWarning
from knitframe.records import Fabric, Scene

__all__ = ["run_point", "point_modules", "map_points", "cached_points", "forget_partial"]


def run_point(job: dict[str, Any]) -> dict[str, Any]:
    """One sweep point (an executor job: plain data): simulate the cell under each of its loads, fit the
    reduced model to the simulated curves jointly.

    Runs with one BLAS/OpenMP thread (so a point gives the same bits in this process, a process
    pool or a Dask worker), numpy's floating-point warnings as errors (as on the command line) and
    knitframe's warnings collected into the result. Returns plain data: the fit (as params.json),
    the simulated Responses (as dicts), the timings, the warnings and the host.

    A point compared with measured tests (``job["validation"]``) keeps what it can: a load that
    fails gives None in ``responses`` and its reason in ``failed_loads``, the fit uses the other
    curves, and a fit that fails gives ``fit`` None and its reason in ``fit_error``. It raises only
    when no load finished.
    """
    from threadpoolctl import threadpool_limits

    from knitframe.plugins import get_registry

    registry = get_registry()
    t0 = time.perf_counter()
    with threadpool_limits(limits=1), warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", KnitframeWarning)
        warnings.simplefilter("error", RuntimeWarning)
        solver = instantiate(registry, "solver", job["solver"], "solver")
        fabric = Fabric.from_dict(job["fabric"], "fabric")
        keep_going = bool(job.get("validation"))
        responses: list[Any] = []
        failed_loads: dict[str, str] = {}
        for sc in job["scenes"]:
            scene = Scene.from_dict(sc, "scene")
            try:
                responses.append(solver.simulate(fabric, scene))
            except Exception as e:  # noqa: BLE001 - a validation point records the load's reason and goes on
                if not keep_going:
                    raise
                responses.append(None)
                failed_loads[scene.load.response_kind] = failure_reason(e)
        done = [r for r in responses if r is not None]
        if not done:
            raise RuntimeError("; ".join(f"{k}: {why}" for k, why in failed_loads.items()))
        t1 = time.perf_counter()
        model = instantiate(registry, "homogenizer", job["fit"]["model"], "fit.model")
        fitter = instantiate(registry, "fitter", job["fit"]["fitter"], "fit.fitter")
        fit, fit_error = None, ""
        try:
            fit = fitter.fit(model, done).to_json()
        except Exception as e:  # noqa: BLE001 - as above: the simulated curves still meet the measured ones
            if not keep_going:
                raise
            fit_error = failure_reason(e)
        t2 = time.perf_counter()
    notes = list(
        dict.fromkeys(
            " ".join(str(w.message).split()) for w in seen if issubclass(w.category, KnitframeWarning)
        )
    )
    out = {
        "fit": fit,
        "responses": [r.to_dict() if r is not None else None for r in responses],
        "simulate_s": t1 - t0,
        "fit_s": t2 - t1,
        "wall_time_s": t2 - t0,
        "warnings": notes,
        "host": socket.gethostname(),
    }
    if keep_going:
        out.update({"failed_loads": failed_loads, "fit_error": fit_error})
    return out


def _registered(registry: Any, kind: str, name: Any) -> Any:
    try:
        return registry[kind][name]
    except Exception:  # noqa: BLE001 - not a plugin of this kind
        return None


def _plugin_module(registry: Any, kind: str, name: Any) -> str | None:
    return getattr(_registered(registry, kind, name), "__module__", None)


def point_modules(job: dict[str, Any]) -> list[str]:
    """The plugin modules a point runs that no import names (chosen by name at run time): its solver
    and the solver's plugins (linear solver, contact law), pattern, yarn model, reduced model and
    fitter. The cache hashes their source and everything of knitframe they import."""
    from knitframe.plugins import get_registry

    reg = get_registry()
    found = [
        _plugin_module(reg, "solver", job["solver"].get("kind")),
        _plugin_module(reg, "pattern", job["fabric"].get("pattern")),
        _plugin_module(reg, "yarn_model", (job["fabric"].get("yarn") or {}).get("model")),
        _plugin_module(reg, "homogenizer", job["fit"]["model"].get("kind")),
        _plugin_module(reg, "fitter", job["fit"]["fitter"].get("kind")),
    ]
    solver = _registered(reg, "solver", job["solver"].get("kind"))
    choices = getattr(solver, "auto_plugins", {})  # option -> the plugins its "auto" may pick
    for key, value in job["solver"].items():  # options that name plugins: linear_solver, contact_law, ...
        name = value.get("kind") if isinstance(value, dict) else value
        for plugin in choices.get(key, ()) if name == "auto" else (name,):
            if isinstance(plugin, str):
                found += [_plugin_module(reg, kind, plugin) for kind in ("linear_solver", "contact_law")]
    return sorted({m for m in found if m})


run_point.cache_modules = point_modules  # type: ignore[attr-defined]


def map_points(executor: Any, jobs: list[dict[str, Any]], progress: Any) -> list[Any]:
    """The points' results in order, a JobFailure in place of each point that raised."""
    return list(executor.map(run_point, jobs, failures="keep", progress=progress))


def cached_points(executor: Any, jobs: list[dict[str, Any]]) -> tuple[JobCache | None, list[str], list[bool]]:
    """``(cache, keys, cached)``: the executor's result cache (None without one), each job's key
    (:func:`knitframe.cache.job_keys` of :func:`run_point`; empty without a cache) and whether it is
    cached already."""
    cache_dir = getattr(executor, "cache_dir", None)
    cache = JobCache(cache_dir) if cache_dir else None
    keys = job_keys(run_point, jobs) if cache else []
    cached = [cache.has(k) for k in keys] if cache else [False] * len(jobs)
    return cache, keys, cached


def forget_partial(cache: JobCache | None, keys: list[str], results: list[Any]) -> None:
    """Drop from the cache the points compared with measured tests whose load or fit failed: they
    are tried again next run."""
    for key, res in zip(keys, results, strict=False):
        if isinstance(res, dict) and (res.get("failed_loads") or res.get("fit_error")):
            path = cache.path(key) if cache else None
            if path is not None:
                path.unlink(missing_ok=True)
