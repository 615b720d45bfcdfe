"""Yarns from configs: library names, full tables, or ``like = "cotton"`` with overrides.

A config may define its own yarns in a top-level ``[yarns]`` table and refer to them by name::

    [yarns.wool]
    like = "cotton"          # start from a library yarn
    E_axial = 600.0

    [fabric]
    pattern = "jersey"
    stitch_length = 11
    yarn = "wool"
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from knitframe.errors import ConfigError, FieldError, UnknownPluginError
from knitframe.records import Yarn
from knitframe.schema import build
from knitframe.validators import shown

__all__ = ["resolve_yarn", "config_yarns", "yarn_model"]


def resolve_yarn(registry, value: Any, path: str) -> Yarn:
    """A Yarn from a config value at TOML ``path``.

    ``value`` is a library name (``"cotton"``), a Yarn, or a table of Yarn fields. A table may
    start from a library yarn with ``like = "cotton"`` and override some fields; its ``name``
    defaults to the last key of ``path`` (``yarns.myyarn`` -> ``myyarn``). Errors are
    ConfigErrors naming ``path``.
    """
    if isinstance(value, Yarn):
        return value
    if isinstance(value, str):
        try:
            return registry["yarn"][value]
        except UnknownPluginError as e:
            raise ConfigError(path, str(e)) from None
    if not isinstance(value, dict):
        raise ConfigError(path, f"expected a yarn name or a table of yarn fields, got {shown(value)}")
    table = dict(value)
    base: dict[str, Any] = {}
    if "like" in table:
        like = table.pop("like")
        if not isinstance(like, str):
            raise ConfigError(f"{path}.like", f"expected a yarn name, got {shown(like)}")
        base = resolve_yarn(registry, like, f"{path}.like").to_dict()
        base.pop("name")
        base["source"] = f"{base.get('source', '')}; modified in config at {path}".lstrip("; ")
    table = {**base, **table}
    table.setdefault("name", path.rsplit(".", 1)[-1] if path else "yarn")
    table.setdefault("source", f"config table {path}")
    yarn = build(Yarn, table, path)
    yarn_model(registry, yarn, path)  # an unknown model or moduli it cannot take fail here, not in a run
    return yarn


#: Yarn-model fields that come from a differently named Yarn field
_MODEL_FIELDS = {"radius": "dk", "bending_modulus": "bending_stiffness"}


def yarn_model(registry, yarn: Yarn, path: str = "fabric.yarn") -> Any:
    """The yarn-model plugin instance of ``yarn`` (``yarn.model`` built from the Yarn's numbers).

    An unknown model name is a ConfigError at ``<path>.model``; numbers the model refuses (say a
    transverse modulus above the axial one) at ``<path>.<field>`` of the Yarn field concerned.
    """
    try:
        cls = registry["yarn_model"][yarn.model]
    except UnknownPluginError as e:
        raise ConfigError(f"{path}.model", str(e)) from None
    try:
        return cls.from_yarn(yarn)
    except FieldError as e:
        raise ConfigError(f"{path}.{_MODEL_FIELDS.get(e.field, e.field)}", e.problem) from None


def config_yarns(registry, table: Any, path: str = "yarns") -> dict[str, Yarn]:
    """Yarns defined in a config's ``[yarns]`` table, by name."""
    if not isinstance(table, Mapping):
        raise ConfigError(path, f"expected a table of yarn tables, got {shown(table)}")
    return {name: resolve_yarn(registry, value, f"{path}.{name}") for name, value in table.items()}
