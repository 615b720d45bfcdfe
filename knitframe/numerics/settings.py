"""Solver tuning settings picked by preset: the machinery of the ``[solver.newton]`` table.

A solver keeps the options a user chooses (element order, seed, contact law, tolerances, what to
do on failure) in its own table, and its tuning knobs (Newton safeguards, step caps, cut-back,
when the contact search runs) in one frozen attrs class held in a field ``newton``. The class's
field defaults are the solver's measured defaults (the ``"default"`` preset); its ``presets``
class variable names other documented sets of values. A config writes::

    [solver]
    newton = "robust"                               # a named preset

    [solver]
    newton = { preset = "fast", max_step = 0.2 }    # a preset with keys overridden

    [solver.newton]                                 # keys over the defaults
    max_step = 0.2

:func:`settings_field` declares that field; its converter, :func:`from_config`, turns a preset
name, a table or an instance into the settings instance. Unknown keys and bad values fail with a
one-line :class:`~knitframe.errors.ConfigError` at the key's path below ``newton``
(``newton.max_step: must be > 0, got -1``); the solver's table puts ``solver.`` in front.
"""

from __future__ import annotations

from typing import Any

import attrs

from knitframe.errors import ConfigError
from knitframe.schema import build, field_names
from knitframe.validators import shown

__all__ = ["Preset", "from_config", "settings_field", "preset_names", "DEFAULT_PRESET"]

#: the preset of a settings class's own field defaults
DEFAULT_PRESET = "default"


@attrs.frozen
class Preset:
    """A named set of tuning values and why it exists.

    ``values`` are keys of the settings class with their values in this preset (keys not given
    keep the class defaults); ``reason`` says in a user's words when to pick it.
    """

    values: dict[str, Any]
    reason: str


def preset_names(cls: type) -> list[str]:
    """The preset names of settings class ``cls``: ``"default"`` first, then its ``presets``."""
    return [DEFAULT_PRESET, *(n for n in getattr(cls, "presets", {}) if n != DEFAULT_PRESET)]


def _preset_values(cls: type, name: Any, path: str) -> dict[str, Any]:
    """The values of preset ``name`` of ``cls``; ConfigError at ``path`` if there is no such preset."""
    names = preset_names(cls)
    if not isinstance(name, str) or name not in names:
        raise ConfigError(path, f"unknown preset {shown(name)}; expected one of {', '.join(names)}")
    if name == DEFAULT_PRESET:
        return {}
    return dict(cls.presets[name].values)


def from_config(cls: type, value: Any, path: str = "newton") -> Any:
    """The settings instance of ``cls`` selected by ``value``.

    Parameters
    ----------
    cls : attrs class
        The settings schema; its ``presets`` class variable maps names to :class:`Preset`.
    value : None, str, dict or cls
        None: the defaults; a preset name; a table whose optional ``preset`` key picks the base
        values and whose other keys override them; an instance (returned as is).
    path : str
        Dotted path of the value in the solver's table, the prefix of every error.
    """
    if isinstance(value, cls):
        return value
    if value is None:
        return cls()
    if isinstance(value, str):
        return build(cls, _preset_values(cls, value, path), path)
    if isinstance(value, dict):
        keys = field_names(cls)
        unknown = [k for k in value if k != "preset" and k not in keys]
        if unknown:
            raise ConfigError(
                f"{path}.{unknown[0]}", f"unknown key; expected one of {', '.join(sorted([*keys, 'preset']))}"
            )
        table = {k: v for k, v in value.items() if k != "preset"}
        base = _preset_values(cls, value.get("preset", DEFAULT_PRESET), f"{path}.preset")
        return build(cls, {**base, **table}, path)
    raise ConfigError(path, f"expected a preset name or a table, got {shown(value)}")


def settings_field(cls: type, path: str = "newton") -> Any:
    """An attrs field holding settings of ``cls``: default the class defaults, set by :func:`from_config`.

    Annotate it ``str | dict[str, Any]`` (what a config may write: a preset name or a table); the
    stored value is always an instance of ``cls``.
    """
    return attrs.field(factory=cls, converter=lambda value: from_config(cls, value, path))
