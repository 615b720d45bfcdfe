"""The built-in example config and its data (see ``data/README.md`` for the data's source)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["example_config", "EXAMPLE_DIR"]

EXAMPLE_DIR = Path(__file__).resolve().parent


def example_config() -> Path:
    """Path of the built-in example pipeline config."""
    return EXAMPLE_DIR / "example.toml"
