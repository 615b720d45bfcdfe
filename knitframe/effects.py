"""Effects are opt-in: a scene names the effects it needs, solvers declare what they can model.

:func:`require_effects` runs before any work: a scene asking for an effect (or load path) the
chosen solver cannot model stops with an error that names the effect and lists the solvers that
support it.
"""

from __future__ import annotations

from typing import Any

from knitframe.errors import ConfigError, UnsupportedEffectError
from knitframe.plugins import Registry
from knitframe.records import Scene

__all__ = ["require_effects", "solvers_supporting"]


def solvers_supporting(registry: Registry, effect: str) -> list[str]:
    """Names of the registered solvers whose ``effects`` include ``effect``."""
    kind = registry["solver"]
    return [name for name in kind if effect in kind[name].effects]


def require_effects(scene: Scene, solver: Any, registry: Registry, *, name: str | None = None) -> None:
    """Raise if ``solver`` (class or instance) cannot model every effect and the load of ``scene``.

    Effects are checked in sorted order so the message is deterministic.
    """
    solver_name = name or solver.name
    supported = frozenset(solver.effects)
    for effect in sorted(scene.effects):
        if effect not in supported:
            raise UnsupportedEffectError(effect, solver_name, solvers_supporting(registry, effect))
    loads = solver.loads
    key = scene.load.response_kind
    if key not in loads and scene.load.kind not in loads:
        kind = registry["solver"]
        others = [n for n in kind if key in kind[n].loads or scene.load.kind in kind[n].loads]
        raise ConfigError(
            "scene.load.kind",
            f"solver '{solver_name}' cannot follow load '{key}'; "
            f"solvers that can: {', '.join(others) or 'none installed'}",
        )
