"""Reading JSON files of the library: library.json and the params.json of fits, and their metadata."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from knitframe.errors import ConfigError

__all__ = ["read_json", "params_metadata", "default_name"]


def read_json(path: Path, what: str) -> Any:
    """The JSON of the file at ``path`` (``what`` names it in errors), else a one-line ConfigError."""
    if not path.exists():
        raise ConfigError("", f"{what} not found: {path}")
    if not path.is_file():
        raise ConfigError("", f"{what} is not a file: {path}")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError("", f"cannot read {what}: {e}", source=str(path)) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise ConfigError(
            "", f"not valid JSON: {e.msg} (line {e.lineno}, column {e.colno})", source=str(path)
        ) from None
    except RecursionError:
        raise ConfigError("", "not valid JSON: nested too deeply", source=str(path)) from None


def params_metadata(data: Mapping[str, Any], key: str) -> Any:
    """A fabric metadata value of a params.json: in its ``fabric`` table, else at the top level."""
    fabric = data.get("fabric")
    if isinstance(fabric, Mapping) and fabric.get(key) is not None:
        return fabric[key]
    return data.get(key)


def default_name(path: Path) -> str:
    """An entry's name from its params file: a params.json's folder, else the stem less ``-params``."""
    if path.name == "params.json" and path.parent.name:
        return path.parent.resolve().name
    stem = path.stem
    return stem[: -len("-params")] if stem.endswith("-params") and len(stem) > 7 else stem
