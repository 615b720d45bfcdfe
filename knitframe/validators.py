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
    "shown",
    "positive",
    "non_negative",
    "at_least",
    "at_most",
    "in_range",
    "one_of",
    "finite",
    "optional",
    "subset_of",
    "finite_array",
    "boolean",
    "within_model_bounds",
    "near_own",
    "OVERRIDE_FACTOR",
]

Validator = Callable[[Any, Any, Any], None]


def _fmt(value: Any) -> str:
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


def at_least(lo: float) -> Validator:
    """Value is a finite number >= ``lo`` (pair it with :func:`positive` to keep "must be > 0" for signs)."""

    def check(instance, attribute, value) -> None:
        if _num(attribute, value) < lo:
            raise FieldError(attribute.name, f"must be >= {_fmt(lo)}, got {_fmt(value)}")

    return check


def at_most(hi: float) -> Validator:
    """Value is a finite number <= ``hi``."""

    def check(instance, attribute, value) -> None:
        if _num(attribute, value) > hi:
            raise FieldError(attribute.name, f"must be <= {_fmt(hi)}, got {_fmt(value)}")

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


def within_model_bounds(model: Any, params: Any) -> None:
    """Reduced-model parameters inside the model's own box ``model.bounds()``; FieldError names the first
    outside.

    The field is the parameter as a config or a params.json writes it (``a``, ``theta_deg``), and
    the message gives the bounds the same way (angles in degrees). Values within 1e-9 (relative)
    of a bound count as on it, so a fit that stopped at a bound is accepted. A model without
    ``bounds`` takes any finite values.
    """
    from knitframe.fitting import params_to_json

    if getattr(model, "bounds", None) is None:
        return
    lo, hi = (np.asarray(b, dtype=np.float64) for b in model.bounds())
    p = np.asarray(params, dtype=np.float64)
    names = tuple(model.param_names)
    shown, low, high = (params_to_json(names, x) for x in (p, lo, hi))
    slack = 1e-9 * np.maximum(np.abs(lo), np.abs(hi))
    for i, key in enumerate(shown):
        if not lo[i] - slack[i] <= p[i] <= hi[i] + slack[i]:
            raise FieldError(
                key,
                f"must be in [{_fmt(low[key])}, {_fmt(high[key])}] (the bounds of model "
                f"'{getattr(model, 'name', type(model).__name__)}'), got {_fmt(shown[key])}",
            )


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
