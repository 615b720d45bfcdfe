"""knitframe: multi-level mechanics of weft-knitted fabrics.

Public API::

    import knitframe
    result = knitframe.run("example.toml", out="out")   # same as `knitframe run example.toml --out out`
    sleeve = knitframe.design("example", objective={"kind": "pressure_profile", "target_mmHg": 25})
    registry = knitframe.get_registry()
    registry["pattern"]["jersey"]
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("knitframe")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"

from knitframe.errors import (  # noqa: E402
    ConfigError,
    DataError,
    GeometryError,
    KnitframeError,
    NumericalError,
    PluginError,
    UnknownPluginError,
    UnsupportedEffectError,
)
from knitframe.examples import example_config  # noqa: E402
from knitframe.garment.api import design  # noqa: E402
from knitframe.hookspecs import hookimpl  # noqa: E402
from knitframe.ladder import ladder  # noqa: E402
from knitframe.pipeline import PipelineResult, run  # noqa: E402
from knitframe.plugins import Registry, get_registry, load_registry  # noqa: E402
from knitframe.records import EFFECTS, Fabric, LoadPath, Provenance, Response, Scene, Yarn  # noqa: E402

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
