"""attrs validators that raise :class:`~knitframe.errors.FieldError` with a readable problem.

Each message has the form ``must be > 0, got -1`` so that the config layer can print
``fabric.stitch_length: must be > 0, got -1``.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Iterable

import numpy as np

from knitframe.errors import FieldError

__all__ = ["positive", "non_negative", "in_range", "one_of", "finite", "optional", "subset_of", "finite_array", "boolean"]

Validator = Callable[[Any, Any, Any], None]


def _fmt(value: Any) -> str:
    """Numbers as the user would write them: -1 rather than -1.0."""
    if isinstance(value, (float, np.floating)) and math.isfinite(value) and float(value).is_integer() and abs(value) < 1e15:
        return str(int(value))
    return repr(value.item() if isinstance(value, np.generic) else value)


def _num(attribute, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise FieldError(attribute.name, f"must be a number, got {value!r}")
    if not math.isfinite(float(value)):
        raise FieldError(attribute.name, f"must be finite, got {value!r}")
    return float(value)


def positive(instance, attribute, value) -> None:
    """Value is a finite number > 0."""
    if _num(attribute, value) <= 0:
        raise FieldError(attribute.name, f"must be > 0, got {_fmt(value)}")


def non_negative(instance, attribute, value) -> None:
    """Value is a finite number >= 0."""
    if _num(attribute, value) < 0:
        raise FieldError(attribute.name, f"must be >= 0, got {_fmt(value)}")


def finite(instance, attribute, value) -> None:
    """Value is a finite number."""
    _num(attribute, value)


def in_range(lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False) -> Validator:
    """Value lies in [lo, hi]; ``lo_open``/``hi_open`` exclude an end."""

    def check(instance, attribute, value) -> None:
        v = _num(attribute, value)
        bad = (v <= lo if lo_open else v < lo) or (v >= hi if hi_open else v > hi)
        if bad:
            lb, rb = ("(" if lo_open else "["), (")" if hi_open else "]")
            raise FieldError(attribute.name, f"must be in {lb}{lo}, {hi}{rb}, got {_fmt(value)}")

    return check


def boolean(instance, attribute, value) -> None:
    """Value is true or false (not a number or a string that looks like one)."""
    if not isinstance(value, (bool, np.bool_)):
        raise FieldError(attribute.name, f"must be true or false, got {value!r}")


def one_of(choices: Iterable[str]) -> Validator:
    """Value is one of ``choices``."""
    allowed = tuple(choices)

    def check(instance, attribute, value) -> None:
        if value not in allowed:
            raise FieldError(attribute.name, f"must be one of {', '.join(map(repr, allowed))}, got {value!r}")

    return check


def subset_of(choices: Iterable[str]) -> Validator:
    """Every element of the value is one of ``choices``."""
    allowed = tuple(choices)

    def check(instance, attribute, value) -> None:
        bad = sorted(set(value) - set(allowed))
        if bad:
            raise FieldError(
                attribute.name, f"unknown {', '.join(map(repr, bad))}; expected some of {', '.join(allowed)}"
            )

    return check


def optional(validator: Validator) -> Validator:
    """Apply ``validator`` unless the value is None."""

    def check(instance, attribute, value) -> None:
        if value is not None:
            validator(instance, attribute, value)

    return check


def finite_array(instance, attribute, value) -> None:
    """Value is an array of finite float64 numbers (no NaN, no inf)."""
    if value is None:
        return
    arr = np.asarray(value)
    if not np.all(np.isfinite(arr)):
        i = int(np.flatnonzero(~np.isfinite(arr.ravel()))[0])
        raise FieldError(attribute.name, f"must be finite, got {arr.ravel()[i]} at index {i}")
