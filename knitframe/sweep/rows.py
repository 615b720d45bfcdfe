"""A finished (or failed) sweep point as a row of ``sweep.csv`` and an entry of ``library.json``:
its inputs, status, fitted parameters, relaxed pitches, limits and timings.
"""

from __future__ import annotations

import json
from typing import Any

import attrs
import numpy as np

from knitframe.cache import JobFailure
from knitframe.errors import ConfigError
from knitframe.sweep.points import Point, loads_text

__all__ = ["SweepFits", "relaxed_pitches"]


@attrs.frozen
class SweepFits:
    """What every row and library entry of one sweep shares: the sweep's name and the reduced model
    and fitter fitted to every point."""

    #: the sweep's name (``[sweep] name``)
    name: str
    #: the homogenizer instance
    model: Any
    model_name: str
    fitter_name: str

    def param_keys(self) -> list[str]:
        """The fitted parameters' columns (θ in degrees: ``theta_deg``)."""
        from knitframe.fitting import params_to_json

        return list(params_to_json(self.model.param_names, [0.0] * len(self.model.param_names)).keys())

    def title(self, points: tuple[Point, ...]) -> str:
        p = points[0]
        return (
            f"{self.model_name} fitted by {self.fitter_name} to {p.stage.solver_name} simulations "
            f"({loads_text(p)}): sweep {self.name}"
        )

    def library_source(self, points: tuple[Point, ...], n: int) -> str:
        return (
            f"knitframe sweep '{self.name}': {n} fabrics simulated by "
            f"{', '.join(sorted({p.stage.solver_name for p in points}))} and fitted with "
            f"{self.model_name} by {self.fitter_name} (knitframe run, [sweep] stage)"
        )

    def row(self, p: Point, res: Any, hit: bool) -> tuple[dict[str, Any], Any]:
        """The point's row of sweep.csv and its library entry (None when it has none): ``res`` is the
        point's result (:func:`knitframe.sweep.job.run_point`) or its JobFailure, ``hit`` whether it
        came from the cache."""
        row = self._inputs(p)
        names = list(self.param_keys())
        row.update({k: "" for k in names})
        row.update(
            {
                "nrmse": "",
                "nrmse_course": "",
                "nrmse_wale": "",
                "converged": "",
                "course_pitch_mm": "",
                "wale_pitch_mm": "",
                "max_tension_N_per_mm": "",
                "max_stretch": "",
                "wall_time_s": "",
                "simulate_s": "",
                "fit_s": "",
                "cached": "yes" if hit else "no",
                "in_library": "no",
                "library_note": "",
                "at_bound": "",
                "warnings": "",
                "host": "",
            }
        )
        if isinstance(res, JobFailure) or not isinstance(res, dict):
            row["status"] = "failed"
            row["reason"] = (
                str(res) if isinstance(res, JobFailure) else f"unexpected result {type(res).__name__}"
            )
            row["cached"] = "no"
            return row, None
        return self._results(p, res, row, names)

    def _inputs(self, p: Point) -> dict[str, Any]:
        """The point's input columns: fabric, loads, effects, solver, model and fitter."""
        fabric, scene = p.stage.fabric, p.stage.scene
        loads = [sc.load for sc in (p.stage.scenes or (scene,))]
        row: dict[str, Any] = {
            "index": p.index,
            "name": p.name,
            "status": "done",
            "reason": "",
            "pattern": fabric.pattern,
            "yarn": fabric.yarn.name,
            "stitch_length": fabric.stitch_length,
            "arc_length_mm": fabric.arc_length if fabric.arc_length is not None else p.arc_length,
            "load": "+".join(ld.response_kind for ld in loads),
            "max_strain": "/".join(f"{ld.max_strain:g}" for ld in loads),
            "steps": "/".join(str(ld.steps) for ld in loads),
            "effects": " ".join(sorted(scene.effects)),
            "solver": p.stage.solver_name,
            "solver_options": json.dumps(
                {k: v for k, v in p.solver_table.items() if k != "kind"}, sort_keys=True
            ),
            "model": self.model_name,
            "fitter": self.fitter_name,
        }
        return row

    def _results(
        self, p: Point, res: dict[str, Any], row: dict[str, Any], names: list[str]
    ) -> tuple[dict[str, Any], Any]:
        """The finished point's columns filled in ``row``: fit, NRMSE, timings, pitches and limits."""
        sims = [
            r for r in res["responses"] if r is not None
        ]  # a validation point keeps the loads that finished
        fit = res["fit"] or {}
        row["reason"] = "; ".join(
            [f"{load} failed: {why}" for load, why in (res.get("failed_loads") or {}).items()]
            + ([f"fit failed: {res['fit_error']}"] if res.get("fit_error") else [])
        )
        row.update({k: fit.get(k) for k in names})
        nrmse = fit.get("nrmse") or {}
        row.update(
            {
                "nrmse": nrmse.get("overall"),
                "nrmse_course": nrmse.get("course"),
                "nrmse_wale": nrmse.get("wale"),
                "converged": all(r["provenance"].get("converged", True) for r in sims),
                "wall_time_s": round(res["wall_time_s"], 3),
                "simulate_s": round(res["simulate_s"], 3),
                "fit_s": round(res["fit_s"], 3),
                "at_bound": " ".join(fit.get("at_bound") or ()),
                "warnings": " | ".join(res.get("warnings", ())),
                "host": res.get("host", ""),
            }
        )
        cp, wp, pitch_source = relaxed_pitches(p, sims[0])
        # the limits: the largest course tension and stretch of any simulated curve
        t_max = max(float(np.max(np.asarray(r["T1"], dtype=np.float64))) for r in sims)
        l_max = max(float(np.max(np.asarray(r["lambda1"], dtype=np.float64))) for r in sims)
        row.update(
            {"course_pitch_mm": cp, "wale_pitch_mm": wp, "max_tension_N_per_mm": t_max, "max_stretch": l_max}
        )
        if res["fit"] is None:
            entry, note = None, f"no fit: {res.get('fit_error', '')}"
        else:
            entry, note = self.entry(p, fit, cp, wp, pitch_source, t_max, l_max)
        row["in_library"] = "yes" if entry is not None else "no"
        row["library_note"] = note
        return row, entry

    def entry(
        self,
        p: Point,
        fit: dict[str, Any],
        cp: float,
        wp: float,
        pitch_source: str,
        t_max: float,
        l_max: float,
    ) -> tuple[Any, str]:
        from knitframe.garment.library import FabricEntry

        fabric = p.stage.fabric
        nrmse = (fit.get("nrmse") or {}).get("overall")
        source = (
            f"sweep '{self.name}' point {p.index}: {p.stage.solver_name} simulation of {p.label}, "
            f"{loads_text(p)} ({', '.join(sorted(p.stage.scene.effects))}); "
            f"{self.model_name} fitted by {self.fitter_name}"
            + (f", NRMSE {100 * nrmse:.2f} %" if isinstance(nrmse, (int, float)) else "")
            + "; limits: max_tension and max_stretch are the largest simulated course tension and "
            "stretch (the end of the simulated load path, not a measured failure)"
        )
        keys = self.param_keys()
        info = {
            k: fit[k]
            for k in (
                "fitter",
                "nrmse",
                "nrmse_transverse",
                "objective",
                "n_evals",
                "converged",
                "at_bound",
                "warnings",
            )
            if k in fit
        }
        try:
            entry = FabricEntry(
                name=p.name,
                pattern=fabric.pattern,
                yarn=fabric.yarn.name,
                stitch_length=fabric.stitch_length,
                arc_length=fabric.arc_length if fabric.arc_length is not None else p.arc_length,
                model=self.model_name,
                model_options=dict(fit.get("options") or {}),
                params={k: fit[k] for k in keys},
                course_pitch=cp,
                wale_pitch=wp,
                max_tension=t_max,
                max_stretch=l_max if l_max > 1.0 else None,
                source=source,
                pitch_source=pitch_source,
                fit=info,
            )
        except (ConfigError, TypeError, ValueError) as e:
            return None, " ".join(str(e).split())
        return entry, ""


def relaxed_pitches(p: Point, response: dict[str, Any]) -> tuple[float, float, str]:
    """``(course pitch, wale pitch, source)``, mm: the relaxed pitches from the simulated cell's
    lattice, or the knitted cell's when the solver gives none.

    The rod solver reports its lattice vectors L1 = 2 course pitches and L2 = 2 wale pitches and the
    stretches λ the relaxation reached: pitch = |L|·λ/2.
    """
    extra = response["provenance"].get("extra", {})
    L1, L2, lam = extra.get("L1_mm"), extra.get("L2_mm"), extra.get("relaxed_stretch")
    if L1 is not None and L2 is not None and lam is not None and all(x is not None for x in lam):
        cp = float(np.linalg.norm(L1)) * float(lam[0]) / 2.0
        wp = float(np.linalg.norm(L2)) * float(lam[1]) / 2.0
        return (
            cp,
            wp,
            (
                f"relaxed {p.stage.solver_name} cell: course pitch |L1|·λ1/2, wale pitch |L2|·λ2/2 "
                f"with the knitted lattice L1 = {float(np.linalg.norm(L1)):.4g} mm, "
                f"L2 = {float(np.linalg.norm(L2)):.4g} mm and the relaxation's stretches "
                f"λ1 = {float(lam[0]):.4g}, λ2 = {float(lam[1]):.4g}"
            ),
        )
    cp, wp = p.cell_pitches
    return (
        cp,
        wp,
        (
            f"the knitted cell's pitches ({p.stage.solver_name} reports no relaxed lattice): "
            "not relaxed, measure them"
        ),
    )
