"""The points of a sweep: a grid or a list of ``[sweep]`` keys expanded into points, each merged
into the base ``[solver]``/``[fabric]``/``[scene]`` tables, validated by the simulate stage's own
code (an error names the sweep key that set the value) and turned into an executor job.
"""

from __future__ import annotations

import itertools
import json
import math
from typing import Any

import attrs

from knitframe.errors import ConfigError
from knitframe.geometry import checked_cell
from knitframe.records import Fabric, Response
from knitframe.schema import field_names, to_dict
from knitframe.sweep.validation import MEASURED_KEY, measured_tests

__all__ = [
    "FABRIC_KEYS",
    "SCENE_KEYS",
    "MEASURED_KEY",
    "MAX_POINTS",
    "Point",
    "expand",
    "merge",
    "remap",
    "resolve_point",
    "point_job",
    "loads_text",
]

#: [fabric] keys a point may set
FABRIC_KEYS = tuple(k for k in field_names(Fabric))
#: [scene] keys a point may set
SCENE_KEYS = ("load", "effects")
#: most points one sweep may have
MAX_POINTS = 100_000


@attrs.frozen
class Point:
    """One validated point: its name, its merged solver table, the validated simulate stage and its
    cell's sizes."""

    index: int
    name: str
    #: e.g. "jersey SL11 cotton"
    label: str
    #: [solver] as merged from the config
    solver_table: dict[str, Any]
    #: the simulate stage built from the point's tables (validated)
    stage: Any
    #: yarn per stitch of the knitted cell, mm
    arc_length: float
    #: the knitted cell's course and wale pitches, mm
    cell_pitches: tuple[float, float]
    #: the measured tests the point is compared with, one per load
    measured: tuple[Response, ...] = ()
    #: their files, as the config gives them
    measured_files: tuple[str, ...] = ()


def is_table(value: Any) -> bool:
    return isinstance(value, dict)


def merge(base: dict[str, Any], over: dict[str, Any]) -> tuple[dict, dict, dict, dict]:
    """``(solver, fabric, scene, origin)`` tables of a point: the base tables with the point's keys;
    ``origin`` maps a config path (``fabric.stitch_length``) to the key that set it."""
    solver, fabric, scene = dict(base["solver"]), dict(base["fabric"]), dict(base["scene"])
    origin: dict[str, str] = {}
    for key, (value, where) in over.items():
        if key in FABRIC_KEYS:
            fabric[key] = value
            origin[f"fabric.{key}"] = where
        elif key == "load":  # a table is merged into a base load table; an array of loads replaces it
            load = scene.get("load", {})
            scene["load"] = {**load, **value} if is_table(load) and is_table(value) else value
            origin["scene.load"] = where
        elif key == "effects":
            scene["effects"] = value
            origin["scene.effects"] = where
        elif key == "solver":
            solver.update(value)
            for opt in value:
                origin[f"solver.{opt}"] = f"{where}.{opt}"
        else:  # an option of the base solver by name (checked by expand)
            solver[key] = value
            origin[f"solver.{key}"] = where
    return solver, fabric, scene, origin


def remap(path: str, origin: dict[str, str]) -> str:
    """A simulate-stage error path (``fabric.yarn.dk``) as the sweep key that set it."""
    for key in sorted(origin, key=len, reverse=True):
        if path == key or path.startswith(key + ".") or path.startswith(key + "["):
            return origin[key] + path[len(key) :]
    top = path.split(".")[0].split("[")[0]
    return f"sweep.{path}" if top in ("solver", "fabric", "scene") else path


def size_label(fabric: Fabric) -> str:
    return f"SL{fabric.stitch_length:g}" if fabric.stitch_length is not None else f"{fabric.arc_length:g}mm"


def slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-." else "-" for c in text.lower()).strip("-")


def expand(table: Any, solver_fields: set[str], src: str | None):
    """The points of the ``[sweep]`` table (its ``grid`` or its ``points``) as ``[(keys, name,
    suffix, context)]``: each key with the sweep path
    that set it, the point's name if given, a name suffix for grid keys other than the fabric's, and
    a text naming a grid point in error messages."""
    allowed = set(FABRIC_KEYS) | set(SCENE_KEYS) | {"solver", MEASURED_KEY} | solver_fields
    shown = (
        ", ".join(list(FABRIC_KEYS) + list(SCENE_KEYS) + ["solver", MEASURED_KEY])
        + ", or an option of the solver"
    )
    if bool(table.grid) == bool(table.points):
        raise ConfigError(
            "sweep",
            "give the points as a grid (sweep.grid) or as a list (sweep.points), one of them",
            source=src,
        )

    def check_value(key: str, value: Any, where: str) -> None:
        if key == "solver" and not is_table(value):
            raise ConfigError(where, f"expected a table of solver options, got {short(value)}", source=src)
        if key == MEASURED_KEY and not is_table(value):
            raise ConfigError(
                where, f"expected a table (files, reader, max_strain), got {short(value)}", source=src
            )
        if key == "load" and not (
            is_table(value) or (isinstance(value, list) and value and all(is_table(v) for v in value))
        ):
            raise ConfigError(
                where, f"expected a load table or an array of load tables, got {short(value)}", source=src
            )

    out = []
    if table.grid:
        keys = list(table.grid)
        for key in keys:
            where = f"sweep.grid.{key}"
            if key not in allowed:
                raise ConfigError(where, f"unknown key; a grid varies {shown}", source=src)
            if not table.grid[key]:
                raise ConfigError(where, "needs at least one value", source=src)
            for j, value in enumerate(table.grid[key]):
                check_value(key, value, f"{where}[{j}]")
        n = math.prod(len(table.grid[k]) for k in keys)
        if n > MAX_POINTS:
            raise ConfigError("sweep.grid", f"{n} points; at most {MAX_POINTS}", source=src)
        # keys other than the fabric's that take several values name their value's index in the point's name
        varied = [
            k
            for k in keys
            if len(table.grid[k]) > 1 and k not in ("pattern", "yarn", "stitch_length", "arc_length")
        ]
        for i, combo in enumerate(itertools.product(*(range(len(table.grid[k])) for k in keys))):
            over = {k: (table.grid[k][j], f"sweep.grid.{k}[{j}]") for k, j in zip(keys, combo, strict=False)}
            text = ", ".join(f"{k} = {short(table.grid[k][j])}" for k, j in zip(keys, combo, strict=False))
            suffix = "".join(f"-{slug(k)}{j}" for k, j in zip(keys, combo, strict=False) if k in varied)
            out.append((over, None, suffix, f" (grid point {i}: {text})"))
        return out
    if len(table.points) > MAX_POINTS:
        raise ConfigError("sweep.points", f"{len(table.points)} points; at most {MAX_POINTS}", source=src)
    for i, point in enumerate(table.points):
        over = {}
        name = None
        for key, value in point.items():
            where = f"sweep.points[{i}].{key}"
            if key == "name":
                if not isinstance(value, str) or not value.strip() or "\n" in value:
                    raise ConfigError(where, f"expected one line of text, got {short(value)}", source=src)
                name = value
                continue
            if key not in allowed:
                raise ConfigError(where, f"unknown key; a point sets name, {shown}", source=src)
            check_value(key, value, where)
            over[key] = (value, where)
        out.append((over, name, "", ""))
    return out


def loads_text(p: Point) -> str:
    """The loads of a point in words: ``equibiaxial 0-20 % in 3 steps``."""
    parts = []
    for sc in p.stage.scenes or (p.stage.scene,):
        ld = sc.load
        what = ld.kind if ld.kind != "uniaxial" else f"uniaxial {ld.direction} (free side)"
        parts.append(f"{what} 0-{100 * ld.max_strain:g} % in {ld.steps} steps")
    return " and ".join(parts)


def short(value: Any) -> str:
    text = json.dumps(value, sort_keys=True) if isinstance(value, (dict, list)) else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def resolve_point(
    i: int,
    over: dict[str, Any],
    name: str | None,
    suffix: str,
    context: str,
    *,
    base: dict[str, Any],
    config: Any,
    ctx: Any,
    names: dict[str, int],
) -> Point:
    """Point ``i`` of :func:`expand` validated: its tables merged into ``base`` (``solver``,
    ``fabric``, ``scene``), its measured tests read, the simulate stage built and its cell knitted.

    ``names`` maps the names taken so far to their points and gets this point's. A ConfigError
    names the sweep key that set the faulty value.
    """
    src = ctx.source
    measured: tuple[Response, ...] = ()
    files: tuple[str, ...] = ()
    if MEASURED_KEY in over:  # the tests' own loads replace the point's load
        over = dict(over)
        value, where = over.pop(MEASURED_KEY)
        if "load" in over:
            raise ConfigError(
                over["load"][1],
                "a point with measured tests simulates their own loads; remove load (or measured)" + context,
                source=src,
            )
        measured, files, loads = measured_tests(value, where, base["scene"].get("load"), ctx)
        over["load"] = (loads, where)
    solver_table, fabric_table, scene_table, origin = merge(base, over)
    sub = {"solver": solver_table, "fabric": fabric_table, "scene": scene_table}
    if "yarns" in config:
        sub["yarns"] = config["yarns"]
    simulate = ctx.registry["stage"]["simulate"]
    try:  # exactly the simulate stage's checks, then the cell (for its arc length and pitches)
        stage = simulate.from_config(sub, ctx)
        cell = checked_cell(stage.fabric, ctx.registry)
    except ConfigError as e:
        raise ConfigError(remap(e.path, origin), e.problem + context, source=src) from None
    fabric = stage.fabric
    label = f"{fabric.pattern} {size_label(fabric)} {fabric.yarn.name}"
    auto = name is None
    if auto:
        name = slug(f"{fabric.pattern}-{size_label(fabric)}-{fabric.yarn.name}") + suffix
    if name in names:
        if not auto:
            raise ConfigError(
                f"sweep.points[{i}].name",
                f"'{name}' is also the name of point {names[name]}; names must be distinct",
                source=src,
            )
        name = f"{name}-{i}"
    names[name] = i
    return Point(
        i,
        name,
        label,
        solver_table,
        stage,
        float(cell.arc_length_per_stitch),
        (float(cell.course_pitch), float(cell.wale_pitch)),
        measured,
        files,
    )


def point_job(p: Point, fit: dict[str, Any]) -> dict[str, Any]:
    """The executor job of a point (plain data, :func:`knitframe.sweep.job.run_point`): its resolved
    solver, fabric (with the yarn's numbers) and scenes, and the ``fit`` table (model and fitter)."""
    stage = p.stage
    solver = stage.solver
    solver_job = {"kind": stage.solver_name, **(to_dict(solver) if attrs.has(type(solver)) else {})}
    scenes = stage.scenes or (stage.scene,)
    return {
        "solver": solver_job,
        "fabric": stage.fabric.to_dict(),
        "scenes": [sc.to_dict() for sc in scenes],
        "fit": fit,
        **({"validation": True} if p.measured else {}),
    }
