"""Reading JSON files of the library: library.json and the params.json of fits, and their metadata."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from knitframe.errors import ConfigError


def _read_json(path: Path, what: str) -> Any:
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


def _metadata(data: Mapping[str, Any], key: str) -> Any:
    """A fabric metadata value of a params.json: in its ``fabric`` table, else at the top level."""
    fabric = data.get("fabric")
    if isinstance(fabric, Mapping) and fabric.get(key) is not None:
        return fabric[key]
    return data.get(key)


def _default_name(path: Path) -> str:
    if path.name == "params.json" and path.parent.name:
        return path.parent.resolve().name
    stem = path.stem
    return stem[: -len("-params")] if stem.endswith("-params") and len(stem) > 7 else stem
