"""Build attrs records from plain dicts (TOML tables) and back, with path-named errors.

The attrs class *is* the schema: its fields, their type annotations and their validators define
what a TOML table may hold. :func:`build` checks unknown keys, coerces and type-checks each value
against the annotation, runs the validators, and reports any problem as a
:class:`~knitframe.errors.ConfigError` whose path is the dotted TOML path of the field::

    fabric.stitch_length: must be > 0, got -1

Supported annotations: ``bool``, ``int``, ``float`` (ints accepted), ``str``, ``Literal``,
``X | None``, ``list[X]``, ``tuple[X, ...]``, ``frozenset[X]``, ``dict[str, X]``,
``numpy.ndarray`` (list of numbers → float64 array), ``pathlib.Path`` and nested attrs classes.
"""

from __future__ import annotations

import math
import types
import typing
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

import attrs
import numpy as np

from knitframe.errors import ConfigError, FieldError
from knitframe.validators import shown

__all__ = ["build", "to_dict", "field_names", "type_name"]

_NoneType = type(None)


def field_names(cls: type) -> list[str]:
    """Names of the init fields of attrs class ``cls`` (private fields excluded)."""
    return [f.alias or f.name for f in attrs.fields(cls) if f.init]


def type_name(tp: Any) -> str:
    """Human-readable name of a type annotation, for error messages and docs."""
    origin = get_origin(tp)
    if tp is _NoneType:
        return "none"
    if origin in (typing.Union, types.UnionType):
        args = [a for a in get_args(tp) if a is not _NoneType]
        text = " or ".join(type_name(a) for a in args)
        return text + (" (optional)" if len(args) < len(get_args(tp)) else "")
    if origin is Literal:
        return " | ".join(repr(a) for a in get_args(tp))
    if origin in (list, tuple, frozenset, set):
        return f"array of {type_name(get_args(tp)[0])}"
    if origin is dict:
        val = get_args(tp)[1] if get_args(tp) else Any
        return "table" if val is Any else f"table of {type_name(val)}"
    if tp is np.ndarray:
        return "array of float"
    if tp is float:
        return "float"
    if tp is str:
        return "string"
    if attrs.has(tp):
        return "table"
    return getattr(tp, "__name__", str(tp))


def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls, include_extras=False)


def _mismatch(value: Any, expected: str, path: str, source: str | None) -> ConfigError:
    """The ConfigError at ``path`` for a ``value`` that is not the ``expected`` kind."""
    what = value if not isinstance(value, (dict, list)) else type(value).__name__
    return ConfigError(path, f"expected {expected}, got {shown(what)}", source=source)


def _coerce(value: Any, tp: Any, path: str, source: str | None) -> Any:
    """Check ``value`` against annotation ``tp`` and convert it; raise ConfigError at ``path``."""
    origin = get_origin(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        return _coerce_union(value, tp, path, source)
    if origin is Literal:
        if value not in get_args(tp):
            raise ConfigError(
                path,
                f"must be one of {', '.join(map(repr, get_args(tp)))}, got {shown(value)}",
                source=source,
            )
        return value
    if tp is bool or tp is int or tp is float or tp is str or tp is Path or tp is np.ndarray:
        return _coerce_scalar(value, tp, path, source)
    if origin in (list, tuple, frozenset, set) or origin is dict:
        return _coerce_collection(value, tp, origin, path, source)
    if isinstance(tp, type) and attrs.has(tp):
        if isinstance(value, tp):
            return value
        if not isinstance(value, dict):
            raise _mismatch(value, "a table", path, source)
        return build(tp, value, path, source=source)
    if isinstance(tp, type):
        if not isinstance(value, tp):
            raise _mismatch(value, type_name(tp), path, source)
        return value
    return value


def _coerce_union(value: Any, tp: Any, path: str, source: str | None) -> Any:
    """``X | Y | None``: None if allowed, else the first member that accepts ``value``.

    When a single member is tried its own error is raised, else one naming the whole union.
    """
    args = get_args(tp)
    if value is None and _NoneType in args:
        return None
    errors = []
    for arg in args:
        if arg is _NoneType:
            continue
        try:
            return _coerce(value, arg, path, source)
        except ConfigError as e:
            errors.append(e)
    if len(errors) == 1:
        raise errors[0]
    raise _mismatch(value, type_name(tp), path, source)


def _coerce_scalar(value: Any, tp: Any, path: str, source: str | None) -> Any:
    """``bool``, ``int`` (integral floats accepted), finite ``float``, ``str``, ``Path`` and
    ``numpy.ndarray`` (numbers → finite float64 array)."""
    if tp is bool:
        if not isinstance(value, bool):
            raise _mismatch(value, "true or false", path, source)
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            if isinstance(value, float) and value.is_integer():
                return int(value)
            raise _mismatch(value, "an integer", path, source)
        return int(value)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise _mismatch(value, "a number", path, source)
        if not math.isfinite(float(value)):
            raise ConfigError(path, f"must be finite, got {shown(value)}", source=source)
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise _mismatch(value, "a string", path, source)
        return value
    if tp is Path:
        if not isinstance(value, (str, Path)):
            raise _mismatch(value, "a path string", path, source)
        return Path(value)
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise _mismatch(value, "an array of numbers", path, source) from None
    if not np.all(np.isfinite(arr)):
        raise ConfigError(path, "must contain only finite numbers", source=source)
    return arr


def _coerce_collection(value: Any, tp: Any, origin: Any, path: str, source: str | None) -> Any:
    """``list[X]``, ``tuple[X, ...]``, ``frozenset[X]`` / ``set[X]`` (both → frozenset) and
    ``dict[str, X]``, each item coerced at ``path[i]`` or ``path.key``."""
    if origin is dict:
        if not isinstance(value, dict):
            raise _mismatch(value, "a table", path, source)
        _, val_tp = get_args(tp) or (str, Any)
        return {str(k): _coerce(v, val_tp, f"{path}.{k}", source) for k, v in value.items()}
    if isinstance(value, (str, bytes, dict)) or not isinstance(value, (list, tuple, set, frozenset)):
        raise _mismatch(value, type_name(tp), path, source)
    (item_tp, *_) = get_args(tp) or (Any,)
    items = [_coerce(v, item_tp, f"{path}[{i}]", source) for i, v in enumerate(value)]
    return origin(items) if origin is not set else frozenset(items)


def build(cls: type, table: dict[str, Any], path: str = "", *, source: str | None = None) -> Any:
    """Construct attrs class ``cls`` from ``table``; every error names ``path.<field>``.

    Parameters
    ----------
    cls : attrs class
        The schema. Its ``__attrs_post_init__`` and validators may raise
        :class:`~knitframe.errors.FieldError`; those are re-raised as ConfigError at the field path.
    table : dict
        Plain data, e.g. a parsed TOML table.
    path : str
        Dotted path of ``table`` in the config, used as the error prefix.
    source : str, optional
        File name shown in front of the path.
    """
    if not isinstance(table, dict):
        raise ConfigError(path, f"expected a table, got {shown(table)}", source=source)
    prefix = f"{path}." if path else ""
    fields = {(f.alias or f.name): f for f in attrs.fields(cls) if f.init}
    unknown = [k for k in table if k not in fields]
    if unknown:
        raise ConfigError(
            prefix + unknown[0], f"unknown key; expected one of {', '.join(sorted(fields))}", source=source
        )
    hints = _hints(cls)
    kwargs = {}
    for name, f in fields.items():
        if name in table:
            kwargs[name] = _coerce(table[name], hints.get(f.name, Any), prefix + name, source)
        elif f.default is attrs.NOTHING:
            raise ConfigError(prefix + name, "required key is missing", source=source)
    try:
        return cls(**kwargs)
    except FieldError as e:
        raise ConfigError(prefix + e.field, e.problem, source=source) from None
    except ConfigError as e:
        raise ConfigError(prefix + e.path, e.problem, source=source) from None
    except (TypeError, ValueError) as e:
        raise ConfigError(path or cls.__name__, str(e), source=source) from None


def _plain(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, (frozenset, set)):
        return sorted(value)
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def to_dict(record: Any, *, drop_none: bool = True) -> dict[str, Any]:
    """Plain-data dict of an attrs record: arrays → lists, sets → sorted lists, None dropped.

    Dropping None keeps the dict TOML-serialisable; :func:`build` restores the defaults.
    """

    def ser(inst, field, value):
        return _plain(value)

    def keep(attribute, value):
        return attribute.init and not (drop_none and value is None)

    return attrs.asdict(record, recurse=True, filter=keep, value_serializer=ser)
