"""Checks of library fields: numbers, strings, the model and its parameters, a whole entry; each error
names the JSON path of the bad field in one line."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from knitframe.errors import ConfigError

_REQUIRED = ("name", "pattern", "yarn", "model", "params", "course_pitch", "wale_pitch", "max_tension")
_OPTIONAL = ("stitch_length", "arc_length", "max_stretch", "source", "pitch_source", "model_options", "fit")
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
    for key in ("source", "pitch_source"):
        _string(values.get(key, ""), _at(path, key), empty=True, source=source)
    fit = values.get("fit", {})
    if not isinstance(fit, Mapping):
        raise ConfigError(_at(path, "fit"), f"expected a table, got {_shown(fit)}", source=source)
    _, bad = finite_json(dict(fit))
    if bad:
        raise ConfigError(_at(_at(path, "fit"), bad[0]), "must be finite", source=source)
    return model, arr


def _float_or_keep(value: Any) -> Any:
    return float(value) if _is_number(value) else value


def _float_dict(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _float_or_keep(v) for k, v in value.items()}
    return value


def _plain_dict(value: Any) -> Any:
    return dict(value) if isinstance(value, Mapping) else value
