"""Sweep points against measured tests: the ``measured`` table of a point, the tests read and
turned into the loads that simulate them, and each simulated curve compared with its test
(:func:`knitframe.report.validate_uniaxial`) for ``sweep.csv``, ``validation.csv`` and
``validation.png``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import attrs
import numpy as np

from knitframe import validators as v
from knitframe.config import instantiate
from knitframe.curves import value_at
from knitframe.errors import ConfigError, DataError, FieldError
from knitframe.interfaces import DispatchingReader
from knitframe.records import Response
from knitframe.report import curve, validate_uniaxial
from knitframe.schema import build

if TYPE_CHECKING:
    from knitframe.sweep.points import Point

__all__ = [
    "MEASURED_KEY",
    "VALIDATION_COLUMNS",
    "MeasuredTable",
    "measured_tests",
    "validate_point",
    "validation_headline",
]

#: the point key that carries measured tests
MEASURED_KEY = "measured"
#: the strain at which validation.csv gives the measured tension (``measured_10``)
GOAL_ORDER_AT = 0.10
#: per-curve columns of sweep.csv for points with measured tests, each once per direction
#: (``_course``, ``_wale``)
VALIDATION_COLUMNS = (
    "measured",
    "measured_status",
    "measured_to",
    "simulated_to",
    "nrmse_measured",
    "ratio_10",
    "ratio_20",
    "ratio_30",
    "lateral_at",
    "lateral_simulated",
    "lateral_measured",
    "suspect",
)


@attrs.frozen
class MeasuredTable:
    """Schema of a point's ``measured`` table: the tests the point is simulated as and compared
    with."""

    #: test files, relative to the config file: uniaxial tests with free sides, at most one per direction
    files: list[str]
    #: reader plugin name, or a table with ``kind`` and options
    reader: str | dict[str, Any] = "auto"
    #: simulate at most to this strain; unset: to the end of each test
    max_strain: float | None = attrs.field(default=None, validator=v.optional(v.strain_limit))

    def __attrs_post_init__(self) -> None:
        if not self.files:
            raise FieldError("files", "must list at least one file")


def measured_tests(
    value: Any, where: str, base_load: Any, ctx: Any
) -> tuple[tuple[Response, ...], tuple[str, ...], list[dict[str, Any]]]:
    """A point's measured tests: the curves read (one per load), the file of each, and the loads that
    simulate them: uniaxial along the test's direction with free sides, from the relaxed cell to the
    test's largest strain (at most ``max_strain``), in the base load's number of steps."""
    src = ctx.source
    table = build(MeasuredTable, value, where, source=src)
    reader = instantiate(ctx.registry, "reader", table.reader, f"{where}.reader", source=src)
    steps = {"steps": base_load["steps"]} if isinstance(base_load, dict) and "steps" in base_load else {}
    curves: list[Response] = []
    files: list[str] = []
    loads: list[dict[str, Any]] = []
    for j, name in enumerate(table.files):
        key = f"{where}.files[{j}]"
        path = ctx.path(name, key)
        try:
            read = (reader.reader_for(path) if isinstance(reader, DispatchingReader) else reader).read(path)
        except DataError as e:
            raise ConfigError(key, str(e), source=src) from None
        except OSError as e:
            raise ConfigError(key, f"cannot read {name}: {e.strerror or e}", source=src) from None
        if not read:
            raise ConfigError(key, f"{name} holds no curve", source=src)
        for r in read:
            if r.loaded_direction is None:
                raise ConfigError(
                    key,
                    f"a {r.load} test; a point simulates uniaxial tests (one direction pulled, "
                    "the sides free) only",
                    source=src,
                )
            ((_, e, _, _),) = curve(r)
            top = float(np.max(e)) if table.max_strain is None else min(float(np.max(e)), table.max_strain)
            if not top > 0:
                raise ConfigError(
                    key,
                    f"the test in {name} never stretches (largest strain {float(np.max(e)):g})",
                    source=src,
                )
            curves.append(r)
            files.append(name)
            loads.append(
                {
                    "kind": "uniaxial",
                    "direction": "course" if r.loaded_direction == 0 else "wale",
                    "max_strain": round(top, 4),
                    **steps,
                }
            )
    return tuple(curves), tuple(files), loads


def validation_headline(curves: list[dict[str, Any]]) -> str:
    """The measured tests in one line: how many were simulated and the spread of the tension ratios."""
    done = [c for c in curves if c["measured_status"] == "done"]
    text = f"{len(done)} of {len(curves)} measured tests simulated"
    suspect = [c for c in done if c.get("suspect")]
    if suspect:
        text += f" ({len(suspect)} suspect: see the column suspect of validation.csv)"
    for key in ("ratio_10", "ratio_20", "ratio_30"):
        values = [c[key] for c in done if c[key] is not None]
        if values:
            text += (
                f"; sim/meas tension at {key[6:]} %: median {float(np.median(values)):.2g} "
                f"({min(values):.2g}-{max(values):.2g}, {len(values)} curves)"
            )
    return text


def validate_point(p: Point, res: Any) -> tuple[dict[str, Any], list[dict[str, Any]], list[dict[str, Any]]]:
    """The point's per-curve columns of sweep.csv (empty for a point without measured tests), its
    panels of validation.png and its rows of validation.csv."""
    columns: dict[str, Any] = {f"{c}_{d}": "" for d in ("course", "wale") for c in VALIDATION_COLUMNS}
    sims: dict[str, Response] = {}
    failed_loads: dict[str, str] = {}
    if isinstance(res, dict):
        sims = {r["load"]: Response.from_dict(r, "response") for r in res["responses"] if r is not None}
        failed_loads = res.get("failed_loads") or {}
    panels, curves = [], []
    for mea, file in zip(p.measured, p.measured_files, strict=False):
        d = "course" if mea.loaded_direction == 0 else "wale"
        sim = sims.get(mea.load)
        metrics: dict[str, Any] | None = None
        reason = ""
        if sim is not None:
            metrics = validate_uniaxial(sim, mea)
        else:
            reason = failed_loads.get(mea.load) or (
                str(res) if not isinstance(res, dict) else "not simulated"
            )
        curve_row = {
            "index": p.index,
            "name": p.name,
            "pattern": p.stage.fabric.pattern,
            "yarn": p.stage.fabric.yarn.name,
            "direction": d,
            "measured": file,
            "measured_status": "done" if metrics is not None else "failed",
            "reason": reason,
        }
        for c in VALIDATION_COLUMNS[2:]:  # validate_uniaxial's "nrmse" is the column nrmse_measured
            curve_row[c] = metrics.get(c.replace("nrmse_measured", "nrmse")) if metrics is not None else None
        ((_, e, t, _),) = curve(mea)
        if metrics is None:
            curve_row["measured_to"] = float(np.max(e))
        # the measured tension at 10 % (N/mm), for the order of the patterns (knitframe.sweep.goals)
        curve_row["measured_10"] = value_at(e, t, GOAL_ORDER_AT)
        columns.update({f"{c}_{d}": curve_row[c] for c in VALIDATION_COLUMNS})
        curves.append(curve_row)
        panels.append(
            {
                "title": f"{p.name}: pulled along the {d}",
                "measured": mea,
                "simulated": sim,
                "metrics": metrics,
                "reason": reason,
            }
        )
    return columns, panels, curves
