"""knitframe: multi-level mechanics of weft-knitted fabrics.

Public API::

    import knitframe
    result = knitframe.run("example.toml", out="out")   # same as `knitframe run example.toml --out out`
    sleeve = knitframe.design("example", objective={"kind": "pressure_profile", "target_mmHg": 25})
    registry = knitframe.get_registry()
    registry["pattern"]["jersey"]
"""

from __future__ import annotations

from knitframe.errors import (
    ConfigError,
    DataError,
    GeometryError,
    KnitframeError,
    NumericalError,
    PluginError,
    UnknownPluginError,
    UnsupportedEffectError,
)
from knitframe.examples import example_config
from knitframe.garment.api import design
from knitframe.hookspecs import hookimpl
from knitframe.ladder import ladder
from knitframe.pipeline import PipelineResult, run
from knitframe.plugins import Registry, get_registry, load_registry
from knitframe.records import EFFECTS, Fabric, LoadPath, Provenance, Response, Scene, Yarn
from knitframe.version import __version__

__all__ = [
    "__version__",
    "hookimpl",
    "run",
    "design",
    "ladder",
    "example_config",
    "get_registry",
    "load_registry",
    "Registry",
    "PipelineResult",
    "EFFECTS",
    "Yarn",
    "Fabric",
    "LoadPath",
    "Scene",
    "Provenance",
    "Response",
    "KnitframeError",
    "ConfigError",
    "DataError",
    "GeometryError",
    "NumericalError",
    "PluginError",
    "UnknownPluginError",
    "UnsupportedEffectError",
]
