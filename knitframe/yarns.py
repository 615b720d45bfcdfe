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

from typing import Any, Mapping

from knitframe.errors import ConfigError, UnknownPluginError
from knitframe.records import Yarn
from knitframe.schema import build

__all__ = ["resolve_yarn", "config_yarns"]


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
        raise ConfigError(path, f"expected a yarn name or a table of yarn fields, got {value!r}")
    table = dict(value)
    base: dict[str, Any] = {}
    if "like" in table:
        like = table.pop("like")
        if not isinstance(like, str):
            raise ConfigError(f"{path}.like", f"expected a yarn name, got {like!r}")
        base = resolve_yarn(registry, like, f"{path}.like").to_dict()
        base.pop("name")
        base["source"] = f"{base.get('source', '')}; modified in config at {path}".lstrip("; ")
    table = {**base, **table}
    table.setdefault("name", path.rsplit(".", 1)[-1] if path else "yarn")
    table.setdefault("source", f"config table {path}")
    return build(Yarn, table, path)


def config_yarns(registry, table: Any, path: str = "yarns") -> dict[str, Yarn]:
    """Yarns defined in a config's ``[yarns]`` table, by name."""
    if not isinstance(table, Mapping):
        raise ConfigError(path, f"expected a table of yarn tables, got {table!r}")
    return {name: resolve_yarn(registry, value, f"{path}.{name}") for name, value in table.items()}
