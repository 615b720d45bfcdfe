"""Checks of library fields: numbers, strings, the model and its parameters, a whole entry; each error
names the JSON path of the bad field in one line."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from knitframe.errors import ConfigError

__all__ = [
    "REQUIRED_KEYS",
    "OPTIONAL_KEYS",
    "GAUGE_KEYS",
    "json_path",
    "short_repr",
    "is_number",
    "check_number",
    "check_string",
    "plugin_registry",
    "build_homogenizer",
    "check_pattern",
    "check_entry",
    "gauge_pitches",
    "gauge_pair",
    "gauge_text",
    "is_pitch_estimate",
    "float_or_keep",
    "float_dict",
    "plain_dict",
]

REQUIRED_KEYS = ("name", "pattern", "yarn", "model", "params", "course_pitch", "wale_pitch", "max_tension")
OPTIONAL_KEYS = (
    "stitch_length",
    "arc_length",
    "max_stretch",
    "tension_scatter",
    "source",
    "pitch_source",
    "pitch_measured",
    "gauge",
    "model_options",
    "fit",
)
#: the keys of an entry's ``gauge``: stitches (along the course) and courses (along the wale) per 10 cm
GAUGE_KEYS = ("stitches_per_10cm", "courses_per_10cm")
#: what a pitch_source says of pitches that were estimated (compared in lower case)
_ESTIMATE_WORDS = ("estimat", "munden", "not measured")
#: what it says of pitches that were measured or given (a whole word)
_MEASURED_WORDS = re.compile(r"\b(measured|given|gauge)\b")
#: model -> fibre angles shown by ``knitframe library show`` when the model fixes them
_FIXED_ANGLES = {"hgo2m": "0/90"}


def json_path(path: str, key: str | int) -> str:
    """The JSON path of ``key`` under ``path``: ``path.key``, ``path[i]`` for an index, ``key`` at the top."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def _fmt(x: Any) -> str:
    if isinstance(x, float) and math.isfinite(x) and x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def short_repr(value: Any, limit: int = 60) -> str:
    """``repr(value)``, cut after ``limit`` characters (with the full length) for an error message."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def is_number(value: Any) -> bool:
    """Whether ``value`` is an int or float (numpy's too), not a bool."""
    return not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))


def check_number(
    value: Any, path: str, *, above: float = 0.0, optional: bool = False, source: str | None = None
) -> float | None:
    """A finite number > ``above`` (None allowed if ``optional``), else a one-line ConfigError at ``path``."""
    if value is None and optional:
        return None
    if not is_number(value):
        raise ConfigError(
            path, f"expected a number{' or null' if optional else ''}, got {short_repr(value)}", source=source
        )
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(path, f"must be finite, got {short_repr(value)}", source=source)
    if not v > above:
        raise ConfigError(path, f"must be > {_fmt(float(above))}, got {_fmt(v)}", source=source)
    return v


def check_string(value: Any, path: str, *, empty: bool = False, source: str | None = None) -> str:
    """A one-line string (non-empty unless ``empty``), else a one-line ConfigError at ``path``."""
    if not isinstance(value, str):
        raise ConfigError(path, f"expected a string, got {short_repr(value)}", source=source)
    if not empty and not value.strip():
        raise ConfigError(path, "must not be empty", source=source)
    if "\n" in value or "\r" in value:
        raise ConfigError(path, "must be one line", source=source)
    return value


def plugin_registry():
    """The plugin registry (imported on first use, so that loading the library stays light)."""
    from knitframe.plugins import get_registry

    return get_registry()


def build_homogenizer(model: Any, options: Any, path: str, source: str | None = None) -> Any:
    """The registered homogenizer ``model`` built with ``options``; errors name ``path``.model /
    .model_options."""
    from knitframe.config import instantiate
    from knitframe.errors import UnknownPluginError

    name = check_string(model, json_path(path, "model"), source=source)
    kind = plugin_registry()["homogenizer"]
    try:
        kind.entry(name)
    except UnknownPluginError as e:
        raise ConfigError(json_path(path, "model"), str(e), source=source) from None
    if not isinstance(options, Mapping):
        raise ConfigError(
            json_path(path, "model_options"),
            f"expected a table of options, got {short_repr(options)}",
            source=source,
        )
    if "kind" in options:
        raise ConfigError(
            json_path(path, "model_options.kind"),
            "not an option; the model is named by 'model'",
            source=source,
        )
    return instantiate(
        plugin_registry(),
        "homogenizer",
        {"kind": name, **options},
        json_path(path, "model_options"),
        source=source,
    )


def check_pattern(pattern: Any, path: str, source: str | None = None) -> str:
    """A registered pattern plugin's name, else a one-line ConfigError at ``path``."""
    from knitframe.errors import UnknownPluginError

    name = check_string(pattern, path, source=source)
    try:
        plugin_registry()["pattern"].entry(name)
    except UnknownPluginError as e:
        raise ConfigError(path, str(e), source=source) from None
    return name


def _params(model: Any, params: Any, path: str, source: str | None = None) -> np.ndarray:
    """The parameter array (radians inside) of ``params`` as written in a params.json, inside
    ``model.bounds()``."""
    from knitframe.fitting import params_from_json, params_to_json

    if not isinstance(params, Mapping):
        raise ConfigError(path, f"expected a table of parameters, got {short_repr(params)}", source=source)
    names = tuple(model.param_names)
    for key, v in params.items():  # a non-number anywhere is named before a missing key
        if not is_number(v) or not math.isfinite(float(v)):
            raise ConfigError(
                json_path(path, str(key)), f"expected a finite number, got {short_repr(v)}", source=source
            )
    try:
        arr = params_from_json(names, dict(params), path)
    except ConfigError as e:
        raise ConfigError(e.path, e.problem, source=source) from None
    bounds = getattr(model, "bounds", None)
    if bounds is not None:
        lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds())
        slack = 1e-9 * np.maximum(np.abs(lo), np.abs(hi))  # a fit that stopped on a bound is on it
        shown, low, high = (params_to_json(names, x) for x in (arr, lo, hi))
        for i, key in enumerate(shown):
            if not lo[i] - slack[i] <= arr[i] <= hi[i] + slack[i]:
                raise ConfigError(
                    json_path(path, key),
                    f"must be in [{_fmt(low[key])}, {_fmt(high[key])}] (the bounds of "
                    f"model '{model.name}'), got {_fmt(shown[key])}",
                    source=source,
                )
    return arr


def check_entry(values: Mapping[str, Any], path: str, source: str | None = None) -> tuple[Any, np.ndarray]:
    """Check every field of an entry (as in library.json); returns the homogenizer and the parameter array."""
    from knitframe.fitting import finite_json

    check_string(values.get("name"), json_path(path, "name"), source=source)
    check_pattern(values.get("pattern"), json_path(path, "pattern"), source)
    check_string(values.get("yarn"), json_path(path, "yarn"), source=source)
    for key in ("stitch_length", "arc_length"):
        check_number(values.get(key), json_path(path, key), optional=True, source=source)
    model = build_homogenizer(values.get("model"), values.get("model_options", {}), path, source)
    arr = _params(model, values.get("params"), json_path(path, "params"), source)
    for key in ("course_pitch", "wale_pitch", "max_tension"):
        check_number(values.get(key), json_path(path, key), source=source)
    check_number(
        values.get("max_stretch"), json_path(path, "max_stretch"), above=1.0, optional=True, source=source
    )
    scatter = check_number(
        values.get("tension_scatter"),
        json_path(path, "tension_scatter"),
        above=-math.inf,
        optional=True,
        source=source,
    )
    if scatter is not None and scatter < 0:
        raise ConfigError(
            json_path(path, "tension_scatter"), f"must be >= 0, got {_fmt(scatter)}", source=source
        )
    for key in ("source", "pitch_source"):
        check_string(values.get(key, ""), json_path(path, key), empty=True, source=source)
    _check_pitch_basis(values, path, source)
    fit = values.get("fit", {})
    if not isinstance(fit, Mapping):
        raise ConfigError(json_path(path, "fit"), f"expected a table, got {short_repr(fit)}", source=source)
    _, bad = finite_json(dict(fit))
    if bad:
        raise ConfigError(json_path(json_path(path, "fit"), bad[0]), "must be finite", source=source)
    return model, arr


def gauge_pitches(stitches: Any, courses: Any, path: str, source: str | None = None) -> tuple[float, float]:
    """``(course pitch, wale pitch)`` in mm of a knitter's gauge: ``stitches`` and ``courses`` per 10 cm
    of relaxed fabric give 100/stitches and 100/courses; each must be a finite number > 0 (errors name
    ``path``.stitches_per_10cm / .courses_per_10cm)."""
    s, c = (
        check_number(v, json_path(path, k), source=source) for v, k in zip((stitches, courses), GAUGE_KEYS)
    )
    return 100.0 / s, 100.0 / c


def gauge_pair(value: Any, path: str, source: str | None = None) -> tuple[Any, Any]:
    """A gauge given as a pair ``(stitches, courses)`` per 10 cm, else a one-line ConfigError at ``path``."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Sequence) or len(value) != 2:
        raise ConfigError(
            path,
            f"expected [stitches, courses] per 10 cm of relaxed fabric, got {short_repr(value)}",
            source=source,
        )
    return value[0], value[1]


def gauge_text(gauge: Mapping[str, float]) -> str:
    """The ``pitch_source`` of pitches from a knitter's ``gauge`` table."""
    s, c = (gauge[k] for k in GAUGE_KEYS)
    return (
        f"knitter's gauge: {s:g} stitches and {c:g} courses per 10 cm of relaxed fabric "
        f"(course pitch = 100/{s:g} mm, wale pitch = 100/{c:g} mm), measured"
    )


def _check_gauge(gauge: Any, path: str, source: str | None = None) -> tuple[float, float] | None:
    """The pitches of an entry's ``gauge`` table (None if there is none)."""
    if gauge is None:
        return None
    if not isinstance(gauge, Mapping):
        raise ConfigError(
            path,
            f"expected a table {{{', '.join(GAUGE_KEYS)}}} or null, got {short_repr(gauge)}",
            source=source,
        )
    unknown = sorted(set(map(str, gauge)) - set(GAUGE_KEYS))
    if unknown:
        raise ConfigError(
            json_path(path, unknown[0]), f"unknown key; a gauge has {', '.join(GAUGE_KEYS)}", source=source
        )
    for key in GAUGE_KEYS:
        if key not in gauge:
            raise ConfigError(json_path(path, key), "required key is missing", source=source)
    return gauge_pitches(*(gauge[k] for k in GAUGE_KEYS), path, source)


def _check_pitch_basis(values: Mapping[str, Any], path: str, source: str | None = None) -> None:
    """``pitch_measured`` is a bool or null; a ``gauge`` is measured and gives the pitches."""
    measured = values.get("pitch_measured")
    if measured is not None and not isinstance(measured, bool):
        raise ConfigError(
            json_path(path, "pitch_measured"),
            f"expected true, false or null, got {short_repr(measured)}",
            source=source,
        )
    pitches = _check_gauge(values.get("gauge"), json_path(path, "gauge"), source)
    if pitches is None:
        return
    if measured is False:
        raise ConfigError(
            json_path(path, "pitch_measured"),
            "false with a gauge: a gauge is counted on a relaxed swatch",
            source=source,
        )
    for key, pitch, count in zip(("course_pitch", "wale_pitch"), pitches, GAUGE_KEYS):
        given = float(values[key])
        if not math.isclose(given, pitch, rel_tol=1e-9):
            raise ConfigError(
                json_path(path, key),
                f"{_fmt(given)} mm does not match the gauge (100/{count} = {pitch:.6g} mm)",
                source=source,
            )


def is_pitch_estimate(pitch_measured: bool | None, gauge: Any, pitch_source: str) -> bool:
    """True unless a gauge or ``pitch_measured`` says the pitches were measured; when neither is
    recorded (a library.json written before they were), True unless ``pitch_source`` says measured,
    given or gauge and nothing of an estimate (estimate, Munden, not measured)."""
    if gauge is not None:
        return False
    if pitch_measured is not None:
        return not pitch_measured
    text = pitch_source.lower()
    return any(w in text for w in _ESTIMATE_WORDS) or not _MEASURED_WORDS.search(text)


def float_or_keep(value: Any) -> Any:
    """A number as a float; anything else as it is (for the entry's checks to name it)."""
    return float(value) if is_number(value) else value


def float_dict(value: Any) -> Any:
    """A mapping with str keys and its numbers as floats; anything else as it is."""
    if isinstance(value, Mapping):
        return {str(k): float_or_keep(v) for k, v in value.items()}
    return value


def plain_dict(value: Any) -> Any:
    """A mapping as a plain dict; anything else as it is."""
    return dict(value) if isinstance(value, Mapping) else value
