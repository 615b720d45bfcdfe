"""Fitted parameters as params.json holds them (angles in degrees, ``theta_deg``) and back, and
JSON with non-finite numbers made null.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from knitframe.errors import ConfigError, FieldError
from knitframe.validators import number_text


def _is_angle(name: str) -> bool:
    return name.startswith("theta")


def params_to_json(names: Sequence[str], params: Sequence[float]) -> dict[str, float]:
    """Parameters by name; angles (``theta*``) become ``<name>_deg`` in degrees."""
    out = {}
    for n, p in zip(names, params, strict=False):
        out[f"{n}_deg" if _is_angle(n) else n] = float(math.degrees(p)) if _is_angle(n) else float(p)
    return out


def params_from_json(names: Sequence[str], data: dict[str, Any], path: str = "params") -> np.ndarray:
    """Inverse of :func:`params_to_json`; a missing or non-numeric parameter is a ConfigError at ``path``."""
    out = []
    for n in names:
        key = f"{n}_deg" if _is_angle(n) else n
        if key not in data:
            raise ConfigError(
                f"{path}.{key}", f"required parameter is missing (model needs {', '.join(names)})"
            )
        v = data[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ConfigError(f"{path}.{key}", f"expected a finite number, got {v!r}")
        out.append(math.radians(v) if _is_angle(n) else float(v))
    extra = sorted(set(data) - {f"{n}_deg" if _is_angle(n) else n for n in names})
    if extra:
        raise ConfigError(f"{path}.{extra[0]}", f"unknown parameter; the model has {', '.join(names)}")
    return np.array(out)


def finite_json(data: Any, path: str = "") -> tuple[Any, list[str]]:
    """``data`` with every non-finite float replaced by None, and the dotted keys where that happened."""
    if isinstance(data, dict):
        out, bad = {}, []
        for k, v in data.items():
            out[k], b = finite_json(v, f"{path}.{k}" if path else str(k))
            bad += b
        return out, bad
    if isinstance(data, (list, tuple)):
        pairs = [finite_json(v, f"{path}[{i}]") for i, v in enumerate(data)]
        return [v for v, _ in pairs], [b for _, bs in pairs for b in bs]
    if isinstance(data, (float, np.floating)) and not math.isfinite(data):
        return None, [path]
    return data, []


def within_model_bounds(model: Any, params: Any) -> None:
    """Reduced-model parameters inside the model's own box ``model.bounds()``; FieldError names the first
    outside.

    The field is the parameter as a config or a params.json writes it (``a``, ``theta_deg``), and
    the message gives the bounds the same way (angles in degrees). Values within 1e-9 (relative)
    of a bound count as on it, so a fit that stopped at a bound is accepted. A model without
    ``bounds`` takes any finite values.
    """
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
                f"must be in [{number_text(low[key])}, {number_text(high[key])}] (the bounds of model "
                f"'{getattr(model, 'name', type(model).__name__)}'), got {number_text(shown[key])}",
            )
