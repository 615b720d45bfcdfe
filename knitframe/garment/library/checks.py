"""Checks of library fields: numbers, strings, the model and its parameters, a whole entry; each error
names the JSON path of the bad field in one line."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from knitframe.errors import ConfigError

_REQUIRED = ("name", "pattern", "yarn", "model", "params", "course_pitch", "wale_pitch", "max_tension")
_OPTIONAL = (
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


def _at(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def _fmt(x: Any) -> str:
    if isinstance(x, float) and math.isfinite(x) and x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def _shown(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _is_number(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))


def _number(
    value: Any, path: str, *, above: float = 0.0, optional: bool = False, source: str | None = None
) -> float | None:
    """A finite number > ``above`` (None allowed if ``optional``), else a one-line ConfigError at ``path``."""
    if value is None and optional:
        return None
    if not _is_number(value):
        raise ConfigError(
            path, f"expected a number{' or null' if optional else ''}, got {_shown(value)}", source=source
        )
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(path, f"must be finite, got {_shown(value)}", source=source)
    if not v > above:
        raise ConfigError(path, f"must be > {_fmt(float(above))}, got {_fmt(v)}", source=source)
    return v


def _string(value: Any, path: str, *, empty: bool = False, source: str | None = None) -> str:
    if not isinstance(value, str):
        raise ConfigError(path, f"expected a string, got {_shown(value)}", source=source)
    if not empty and not value.strip():
        raise ConfigError(path, "must not be empty", source=source)
    if "\n" in value or "\r" in value:
        raise ConfigError(path, "must be one line", source=source)
    return value


def _registry():
    from knitframe.plugins import get_registry

    return get_registry()


def _homogenizer(model: Any, options: Any, path: str, source: str | None = None) -> Any:
    """The registered homogenizer ``model`` built with ``options``; errors name ``path``.model /
    .model_options."""
    from knitframe.config import instantiate
    from knitframe.errors import UnknownPluginError

    name = _string(model, _at(path, "model"), source=source)
    kind = _registry()["homogenizer"]
    try:
        kind.entry(name)
    except UnknownPluginError as e:
        raise ConfigError(_at(path, "model"), str(e), source=source) from None
    if not isinstance(options, Mapping):
        raise ConfigError(
            _at(path, "model_options"), f"expected a table of options, got {_shown(options)}", source=source
        )
    if "kind" in options:
        raise ConfigError(
            _at(path, "model_options.kind"), "not an option; the model is named by 'model'", source=source
        )
    return instantiate(
        _registry(), "homogenizer", {"kind": name, **options}, _at(path, "model_options"), source=source
    )


def _check_pattern(pattern: Any, path: str, source: str | None = None) -> str:
    from knitframe.errors import UnknownPluginError

    name = _string(pattern, path, source=source)
    try:
        _registry()["pattern"].entry(name)
    except UnknownPluginError as e:
        raise ConfigError(path, str(e), source=source) from None
    return name


def _params(model: Any, params: Any, path: str, source: str | None = None) -> np.ndarray:
    """The parameter array (radians inside) of ``params`` as written in a params.json, inside
    ``model.bounds()``."""
    from knitframe.fitting import params_from_json, params_to_json

    if not isinstance(params, Mapping):
        raise ConfigError(path, f"expected a table of parameters, got {_shown(params)}", source=source)
    names = tuple(model.param_names)
    for key, v in params.items():  # a non-number anywhere is named before a missing key
        if not _is_number(v) or not math.isfinite(float(v)):
            raise ConfigError(
                _at(path, str(key)), f"expected a finite number, got {_shown(v)}", source=source
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
                    _at(path, key),
                    f"must be in [{_fmt(low[key])}, {_fmt(high[key])}] (the bounds of "
                    f"model '{model.name}'), got {_fmt(shown[key])}",
                    source=source,
                )
    return arr


def _check_entry(values: Mapping[str, Any], path: str, source: str | None = None) -> tuple[Any, np.ndarray]:
    """Check every field of an entry (as in library.json); returns the homogenizer and the parameter array."""
    from knitframe.fitting import finite_json

    _string(values.get("name"), _at(path, "name"), source=source)
    _check_pattern(values.get("pattern"), _at(path, "pattern"), source)
    _string(values.get("yarn"), _at(path, "yarn"), source=source)
    for key in ("stitch_length", "arc_length"):
        _number(values.get(key), _at(path, key), optional=True, source=source)
    model = _homogenizer(values.get("model"), values.get("model_options", {}), path, source)
    arr = _params(model, values.get("params"), _at(path, "params"), source)
    for key in ("course_pitch", "wale_pitch", "max_tension"):
        _number(values.get(key), _at(path, key), source=source)
    _number(values.get("max_stretch"), _at(path, "max_stretch"), above=1.0, optional=True, source=source)
    scatter = _number(
        values.get("tension_scatter"),
        _at(path, "tension_scatter"),
        above=-math.inf,
        optional=True,
        source=source,
    )
    if scatter is not None and scatter < 0:
        raise ConfigError(_at(path, "tension_scatter"), f"must be >= 0, got {_fmt(scatter)}", source=source)
    for key in ("source", "pitch_source"):
        _string(values.get(key, ""), _at(path, key), empty=True, source=source)
    _check_pitch_basis(values, path, source)
    fit = values.get("fit", {})
    if not isinstance(fit, Mapping):
        raise ConfigError(_at(path, "fit"), f"expected a table, got {_shown(fit)}", source=source)
    _, bad = finite_json(dict(fit))
    if bad:
        raise ConfigError(_at(_at(path, "fit"), bad[0]), "must be finite", source=source)
    return model, arr


def gauge_pitches(stitches: Any, courses: Any, path: str, source: str | None = None) -> tuple[float, float]:
    """``(course pitch, wale pitch)`` in mm of a knitter's gauge: ``stitches`` and ``courses`` per 10 cm
    of relaxed fabric give 100/stitches and 100/courses; each must be a finite number > 0 (errors name
    ``path``.stitches_per_10cm / .courses_per_10cm)."""
    s, c = (_number(v, _at(path, k), source=source) for v, k in zip((stitches, courses), GAUGE_KEYS))
    return 100.0 / s, 100.0 / c


def _gauge_pair(value: Any, path: str, source: str | None = None) -> tuple[Any, Any]:
    """A gauge given as a pair ``(stitches, courses)`` per 10 cm, else a one-line ConfigError at ``path``."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Sequence) or len(value) != 2:
        raise ConfigError(
            path,
            f"expected [stitches, courses] per 10 cm of relaxed fabric, got {_shown(value)}",
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
            path, f"expected a table {{{', '.join(GAUGE_KEYS)}}} or null, got {_shown(gauge)}", source=source
        )
    unknown = sorted(set(map(str, gauge)) - set(GAUGE_KEYS))
    if unknown:
        raise ConfigError(
            _at(path, unknown[0]), f"unknown key; a gauge has {', '.join(GAUGE_KEYS)}", source=source
        )
    for key in GAUGE_KEYS:
        if key not in gauge:
            raise ConfigError(_at(path, key), "required key is missing", source=source)
    return gauge_pitches(*(gauge[k] for k in GAUGE_KEYS), path, source)


def _check_pitch_basis(values: Mapping[str, Any], path: str, source: str | None = None) -> None:
    """``pitch_measured`` is a bool or null; a ``gauge`` is measured and gives the pitches."""
    measured = values.get("pitch_measured")
    if measured is not None and not isinstance(measured, bool):
        raise ConfigError(
            _at(path, "pitch_measured"),
            f"expected true, false or null, got {_shown(measured)}",
            source=source,
        )
    pitches = _check_gauge(values.get("gauge"), _at(path, "gauge"), source)
    if pitches is None:
        return
    if measured is False:
        raise ConfigError(
            _at(path, "pitch_measured"),
            "false with a gauge: a gauge is counted on a relaxed swatch",
            source=source,
        )
    for key, pitch, count in zip(("course_pitch", "wale_pitch"), pitches, GAUGE_KEYS):
        given = float(values[key])
        if not math.isclose(given, pitch, rel_tol=1e-9):
            raise ConfigError(
                _at(path, key),
                f"{_fmt(given)} mm does not match the gauge (100/{count} = {pitch:.6g} mm)",
                source=source,
            )


def _pitch_is_estimate(pitch_measured: bool | None, gauge: Any, pitch_source: str) -> bool:
    """True unless a gauge or ``pitch_measured`` says the pitches were measured; when neither is
    recorded (a library.json written before they were), True unless ``pitch_source`` says measured,
    given or gauge and nothing of an estimate (estimate, Munden, not measured)."""
    if gauge is not None:
        return False
    if pitch_measured is not None:
        return not pitch_measured
    text = pitch_source.lower()
    return any(w in text for w in _ESTIMATE_WORDS) or not _MEASURED_WORDS.search(text)


def _float_or_keep(value: Any) -> Any:
    return float(value) if _is_number(value) else value


def _float_dict(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _float_or_keep(v) for k, v in value.items()}
    return value


def _plain_dict(value: Any) -> Any:
    return dict(value) if isinstance(value, Mapping) else value
