"""Reading config files and turning config tables into plugin instances.

A plugin is selected by name, with its options in the same table::

    [solver]
    kind = "rod"          # registry name
    segments_per_loop = 48

or, where a stage field takes a plugin, either a bare name (``fitter = "lbfgs"``) or a table with
``kind`` (``fitter = { kind = "mads", max_evals = 500 }``). The registered class is the schema:
unknown keys, wrong types and out-of-range values fail with the TOML path of the offending key.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import attrs

from knitframe.errors import ConfigError, FieldError, KnitframeError, UnknownPluginError
from knitframe.plugins import Registry
from knitframe.schema import build
from knitframe.validators import shown

__all__ = ["load_toml", "instantiate", "PluginSpec"]


def load_toml(path: str | Path) -> dict[str, Any]:
    """Parse a TOML file; a missing or malformed file raises a one-line ConfigError."""
    p = Path(path)
    if not p.exists():
        raise ConfigError("", f"config file not found: {p}")
    if not p.is_file():
        raise ConfigError("", f"config path is not a file: {p}")
    try:
        text = p.read_text(encoding="utf-8-sig")  # a byte-order mark from a Windows editor is fine
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError("", f"cannot read config file: {e}", source=str(p)) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError("", f"malformed TOML: {e}", source=str(p)) from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise ConfigError(
            "", "malformed TOML: arrays or inline tables nested too deeply", source=str(p)
        ) from None
    except ValueError as e:  # e.g. an integer of more digits than Python converts
        raise ConfigError(
            "", f"malformed TOML: {' '.join(str(e).split(';')[0].split())}", source=str(p)
        ) from None


@attrs.frozen
class PluginSpec:
    """A plugin chosen by name with its option table, as written in a config."""

    #: registry name of the implementation
    kind: str
    options: dict[str, Any] = attrs.Factory(dict)

    @classmethod
    def parse(cls, value: Any, path: str) -> PluginSpec:
        """From ``"name"`` or ``{kind = "name", ...options}``."""
        if isinstance(value, PluginSpec):
            return value
        if isinstance(value, str):
            return cls(value)
        if isinstance(value, dict):
            if "kind" not in value:
                raise ConfigError(f"{path}.kind", "required key is missing")
            if not isinstance(value["kind"], str):
                raise ConfigError(f"{path}.kind", f"expected a string, got {shown(value['kind'])}")
            return cls(value["kind"], {k: v for k, v in value.items() if k != "kind"})
        raise ConfigError(path, f"expected a plugin name or a table with 'kind', got {shown(value)}")


def instantiate(registry: Registry, kind: str, value: Any, path: str, *, source: str | None = None) -> Any:
    """Build the plugin of ``kind`` selected by ``value`` (a name, a table with ``kind`` or a PluginSpec).

    attrs classes are built from the options with full validation; other classes and factory
    functions are called with the options as keyword arguments.
    """
    try:
        spec = PluginSpec.parse(value, path)
    except ConfigError as e:
        raise ConfigError(e.path, e.problem, source=source) from None
    try:
        impl = registry[kind][spec.kind]
    except UnknownPluginError as e:
        key = f"{path}.kind" if isinstance(value, dict) else path
        raise ConfigError(key, str(e), source=source) from None
    if isinstance(impl, type) and attrs.has(impl):
        return build(impl, spec.options, path, source=source)
    if callable(impl):
        try:
            return impl(**spec.options)
        except TypeError as e:
            raise ConfigError(path, f"bad options for {kind} '{spec.kind}': {e}", source=source) from None
        except FieldError as e:  # a factory checking its options names them relative to its table
            raise ConfigError(f"{path}.{e.field}", e.problem, source=source) from None
        except ConfigError as e:
            raise ConfigError(f"{path}.{e.path}" if e.path else path, e.problem, source=source) from None
        except KnitframeError:
            raise
    if spec.options:
        raise ConfigError(path, f"{kind} '{spec.kind}' takes no options", source=source)
    return impl
