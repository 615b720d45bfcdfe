"""attrs validators that raise :class:`~knitframe.errors.FieldError` with a readable problem.

Each message has the form ``must be > 0, got -1`` so that the config layer can print
``fabric.stitch_length: must be > 0, got -1``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from knitframe.errors import FieldError

__all__ = [
    "number_text",
    "shown",
    "positive",
    "non_negative",
    "at_least",
    "at_most",
    "in_range",
    "strain_limit",
    "MAX_STRAIN",
    "one_of",
    "finite",
    "optional",
    "subset_of",
    "finite_array",
    "boolean",
    "near_own",
    "OVERRIDE_FACTOR",
]

Validator = Callable[[Any, Any, Any], None]


def number_text(value: Any) -> str:
    """Numbers as the user would write them: -1 rather than -1.0."""
    if (
        isinstance(value, (float, np.floating))
        and math.isfinite(value)
        and float(value).is_integer()
        and abs(value) < 1e15
    ):
        return str(int(value))
    return repr(value.item() if isinstance(value, np.generic) else value)


def shown(value: Any, limit: int = 60) -> str:
    """``repr`` of a value for an error line, cut to about ``limit`` characters (a pasted array stays
    short)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _num(attribute, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise FieldError(attribute.name, f"must be a number, got {shown(value)}")
    if not math.isfinite(float(value)):
        raise FieldError(attribute.name, f"must be finite, got {shown(value)}")
    return float(value)


def positive(instance, attribute, value) -> None:
    """Value is a finite number > 0."""
    if _num(attribute, value) <= 0:
        raise FieldError(attribute.name, f"must be > 0, got {number_text(value)}")


def non_negative(instance, attribute, value) -> None:
    """Value is a finite number >= 0."""
    if _num(attribute, value) < 0:
        raise FieldError(attribute.name, f"must be >= 0, got {number_text(value)}")


def finite(instance, attribute, value) -> None:
    """Value is a finite number."""
    _num(attribute, value)


def in_range(
    lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False, unit: str = ""
) -> Validator:
    """Value lies in [lo, hi]; ``lo_open``/``hi_open`` exclude an end; ``unit`` follows the range in
    the message, e.g. ``must be in (0.0, 5.0] (a fraction: 0.3 = 30 %), got 30``."""

    def check(instance, attribute, value) -> None:
        v = _num(attribute, value)
        bad = (v <= lo if lo_open else v < lo) or (v >= hi if hi_open else v > hi)
        if bad:
            lb, rb = ("(" if lo_open else "["), (")" if hi_open else "]")
            note = f" {unit}" if unit else ""
            raise FieldError(attribute.name, f"must be in {lb}{lo}, {hi}{rb}{note}, got {number_text(value)}")

    return check


#: The largest engineering strain a load may reach: a stretch of 6.
MAX_STRAIN = 5.0

#: An engineering strain a load goes to, in (0, MAX_STRAIN], as a fraction (0.3 is 30 %): its
#: message says so, since a percentage is the likely slip.
strain_limit: Validator = in_range(0.0, MAX_STRAIN, lo_open=True, unit="(a fraction: 0.3 = 30 %)")


def at_least(lo: float) -> Validator:
    """Value is a finite number >= ``lo`` (pair it with :func:`positive` to keep "must be > 0" for signs)."""

    def check(instance, attribute, value) -> None:
        if _num(attribute, value) < lo:
            raise FieldError(attribute.name, f"must be >= {number_text(lo)}, got {number_text(value)}")

    return check


def at_most(hi: float) -> Validator:
    """Value is a finite number <= ``hi``."""

    def check(instance, attribute, value) -> None:
        if _num(attribute, value) > hi:
            raise FieldError(attribute.name, f"must be <= {number_text(hi)}, got {number_text(value)}")

    return check


def boolean(instance, attribute, value) -> None:
    """Value is true or false (not a number or a string that looks like one)."""
    if not isinstance(value, (bool, np.bool_)):
        raise FieldError(attribute.name, f"must be true or false, got {shown(value)}")


def one_of(choices: Iterable[str]) -> Validator:
    """Value is one of ``choices``."""
    allowed = tuple(choices)

    def check(instance, attribute, value) -> None:
        if value not in allowed:
            raise FieldError(
                attribute.name, f"must be one of {', '.join(map(repr, allowed))}, got {shown(value)}"
            )

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


#: Furthest a stiffness override may be from the value it replaces, as a factor either way.
OVERRIDE_FACTOR = 1e6


def near_own(field: str, value: float | None, own: float, unit: str) -> None:
    """An override ``value`` within :data:`OVERRIDE_FACTOR` of the yarn's ``own`` value it replaces; else
    FieldError.

    Further off is a slip of units rather than a yarn, and it overflows the solvers' arithmetic.
    """
    if value is not None and not own / OVERRIDE_FACTOR <= value <= own * OVERRIDE_FACTOR:
        raise FieldError(
            field,
            f"{value:.4g} {unit} is more than {OVERRIDE_FACTOR:g} times off the yarn's own {own:.4g} {unit}",
        )
