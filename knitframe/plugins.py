"""Plugin registry: the only module that touches pluggy.

Plugins are modules listed under the ``knitframe`` entry-point group, built-in ones included.
Loading them:

* an entry point that fails to import produces a :class:`PluginWarning` naming it, and the rest
  keep working;
* ``pm.check_pending()`` makes a misspelled ``@hookimpl`` an error;
* ``KNITFRAME_DISABLE_EXTERNAL_PLUGINS=1`` loads only the plugins shipped with knitframe, which
  keeps test runs hermetic.

Other code asks the registry by kind and name: ``get_registry()["pattern"]["jersey"]``. An unknown
name raises :class:`~knitframe.errors.UnknownPluginError` listing what is available. An
implementation's ``aliases`` (a tuple of other names, e.g. jersey's ``("stockinette",)``) find it
too, and :meth:`Kind.canonical` turns an alias into the name it is registered under.
"""

from __future__ import annotations

import importlib.metadata as md
import inspect
import os
import warnings
from collections.abc import Iterator, Mapping
from types import ModuleType
from typing import Any, Protocol

import attrs
import pluggy

from knitframe import hookspecs
from knitframe.errors import PluginError, UnknownPluginError

__all__ = [
    "KINDS",
    "ENTRY_POINT_GROUP",
    "DISABLE_EXTERNAL_ENV",
    "PluginWarning",
    "Entry",
    "Kind",
    "Registry",
    "Register",
    "get_registry",
    "load_registry",
    "reset_registry",
]

ENTRY_POINT_GROUP = "knitframe"
DISABLE_EXTERNAL_ENV = "KNITFRAME_DISABLE_EXTERNAL_PLUGINS"
BUILTIN_DIST = "knitframe"

#: kind → hook name. The order is the order ``knitframe plugins`` prints.
KINDS: dict[str, str] = {
    "pattern": "register_patterns",
    "yarn": "register_yarns",
    "yarn_model": "register_yarn_models",
    "solver": "register_solvers",
    "contact_law": "register_contact_laws",
    "linear_solver": "register_linear_solvers",
    "homogenizer": "register_homogenizers",
    "fitter": "register_fitters",
    "design_objective": "register_design_objectives",
    "executor": "register_executors",
    "reader": "register_readers",
    "stage": "register_stages",
}


class PluginWarning(UserWarning):
    """A plugin failed to load or to register; knitframe carries on without it."""


class Register(Protocol):
    """The callback each ``register_<kind>s`` hook receives."""

    def __call__(self, impl: Any, name: str | None = None, description: str | None = None) -> None: ...


@attrs.frozen
class Entry:
    """One registered implementation and where it came from."""

    kind: str
    name: str
    obj: Any
    description: str
    #: module (or object) name the hook implementation lives in
    plugin: str
    #: distribution that provides it
    package: str
    #: distribution version
    version: str
    #: other names that find this implementation
    aliases: tuple[str, ...] = ()

    @property
    def builtin(self) -> bool:
        """True for the plugins shipped with knitframe."""
        return self.package == BUILTIN_DIST


def _describe(obj: Any) -> str:
    desc = getattr(obj, "description", None)
    if isinstance(desc, str) and desc:
        return desc
    doc = inspect.getdoc(obj) or ""
    return doc.strip().splitlines()[0] if doc.strip() else ""


class Kind(Mapping[str, Any]):
    """Implementations of one kind by name; ``kind["jersey"]`` returns the registered object."""

    def __init__(self, kind: str):
        self.kind = kind
        self._entries: dict[str, Entry] = {}
        self._aliases: dict[str, str] = {}  # alias -> registered name

    def __getitem__(self, name: str) -> Any:
        return self.entry(name).obj

    def entry(self, name: str) -> Entry:
        """The :class:`Entry` for ``name`` or one of its aliases; unknown names list the available ones."""
        try:
            return self._entries[self.canonical(name)]
        except KeyError:
            raise UnknownPluginError(self.kind.replace("_", " "), name, list(self._entries)) from None

    def canonical(self, name: str) -> str:
        """The name ``name`` is registered under: an alias gives its implementation's name
        (``stockinette`` -> ``jersey``); any other name is returned as it is."""
        return self._aliases.get(name, name)

    def __iter__(self) -> Iterator[str]:
        return iter(sorted(self._entries))

    def __len__(self) -> int:
        return len(self._entries)

    def entries(self) -> list[Entry]:
        """All entries, sorted by name."""
        return [self._entries[k] for k in sorted(self._entries)]

    def _add(self, entry: Entry) -> None:
        for name in (entry.name, *entry.aliases):
            if name in self._entries or name in self._aliases:
                old = self.entry(name)
                raise PluginError(
                    f"{self.kind} '{name}' from {entry.package} ({entry.plugin}) clashes with the one from "
                    f"{old.package} ({old.plugin})"
                )
        self._entries[entry.name] = entry
        self._aliases.update(dict.fromkeys(entry.aliases, entry.name))


class Registry:
    """Every plugin kind with its implementations, plus the pluggy manager that found them."""

    def __init__(self, pm: pluggy.PluginManager, dists: dict[str, tuple[str, str]]):
        self.pm = pm
        self._dists = dists  # plugin name → (distribution, version)
        self.kinds: dict[str, Kind] = {k: Kind(k) for k in KINDS}
        self.failed: list[tuple[str, str]] = []  # (plugin, reason) of plugins that failed to load
        self._collect()

    def __getitem__(self, kind: str) -> Kind:
        try:
            return self.kinds[kind]
        except KeyError:
            raise UnknownPluginError("plugin kind", kind, list(self.kinds)) from None

    def _collect(self) -> None:
        for kind, hookname in KINDS.items():
            caller = getattr(self.pm.hook, hookname)
            for impl in caller.get_hookimpls():
                dist, version = self._dists.get(impl.plugin_name, (BUILTIN_DIST, _version(BUILTIN_DIST)))
                register = self._register_fn(kind, impl.plugin_name, dist, version)
                try:
                    impl.function(register=register)
                except PluginError as e:
                    self._fail(impl.plugin_name, dist, str(e))
                except Exception as e:  # a third-party plugin's bug must not take the program down
                    self._fail(impl.plugin_name, dist, f"{type(e).__name__}: {e}")

    def _fail(self, plugin: str, dist: str, reason: str) -> None:
        self.failed.append((plugin, reason))
        warnings.warn(
            f"knitframe plugin '{plugin}' ({dist}) failed to register: {reason}", PluginWarning, stacklevel=3
        )

    def _register_fn(self, kind: str, plugin: str, dist: str, version: str) -> Register:
        def register(impl: Any, name: str | None = None, description: str | None = None) -> None:
            key = name or getattr(impl, "name", None)
            if not isinstance(key, str) or not key:
                raise PluginError(f"{kind} {impl!r} has no name; pass register(impl, name=...)")
            # a plugin's own aliases: a subclass of jersey (a variant) does not inherit "stockinette"
            own = vars(impl) if isinstance(impl, type) else {"aliases": getattr(impl, "aliases", ())}
            aliases = own.get("aliases", ())
            if not isinstance(aliases, tuple) or not all(isinstance(a, str) and a for a in aliases):
                raise PluginError(f"{kind} '{key}': aliases must be a tuple of names, got {aliases!r}")
            entry = Entry(kind, key, impl, description or _describe(impl), plugin, dist, version, aliases)
            self.kinds[kind]._add(entry)

        return register

    def entries(self) -> list[Entry]:
        """Every entry of every kind."""
        return [e for k in self.kinds.values() for e in k.entries()]


def _version(dist: str) -> str:
    try:
        return md.version(dist)
    except md.PackageNotFoundError:
        return "unknown"


def _external_disabled() -> bool:
    return os.environ.get(DISABLE_EXTERNAL_ENV, "").strip().lower() not in ("", "0", "false", "no")


def load_registry(
    extra: Mapping[str, ModuleType | object] | None = None, *, external: bool | None = None
) -> Registry:
    """Load every entry-point plugin (and ``extra`` plugin objects by name) into a new Registry.

    Parameters
    ----------
    extra : mapping, optional
        ``{name: module_or_object}`` registered in addition to the entry points (useful in tests
        and notebooks).
    external : bool, optional
        Load plugins from packages other than knitframe. Defaults to true unless
        ``KNITFRAME_DISABLE_EXTERNAL_PLUGINS`` is set.
    """
    if external is None:
        external = not _external_disabled()
    pm = pluggy.PluginManager(ENTRY_POINT_GROUP)
    pm.add_hookspecs(hookspecs)
    dists: dict[str, tuple[str, str]] = {}
    failed: list[tuple[str, str]] = []
    for ep in md.entry_points(group=ENTRY_POINT_GROUP):
        # a distribution whose metadata has no name (a package half installed, or one being removed while
        # this runs) counts as an external one called "unknown"
        dist = (ep.dist.name if ep.dist is not None else None) or "unknown"
        version = (ep.dist.version if ep.dist is not None else None) or "unknown"
        if dist.lower() != BUILTIN_DIST and not external:
            continue
        if pm.has_plugin(ep.name):
            continue
        try:
            plugin = ep.load()
        except Exception as e:  # warn and keep going: one broken plugin must not stop the rest
            failed.append((ep.name, f"{type(e).__name__}: {e}"))
            warnings.warn(
                f"knitframe plugin '{ep.name}' ({dist}) failed to load: {type(e).__name__}: {e}",
                PluginWarning,
                stacklevel=2,
            )
            continue
        _register(pm, plugin, ep.name, dist)
        dists[ep.name] = (dist, version)
    for name, plugin in (extra or {}).items():
        _register(pm, plugin, name, "extra")
        dists[name] = ("extra", "0")
    try:
        pm.check_pending()
    except pluggy.PluginValidationError as e:
        raise PluginError(f"plugin '{e.plugin}' implements an unknown hook: {e}") from None
    registry = Registry(pm, dists)
    registry.failed[:0] = failed
    return registry


def _register(pm: pluggy.PluginManager, plugin: object, name: str, dist: str) -> None:
    try:
        pm.register(plugin, name=name)
    except pluggy.PluginValidationError as e:
        raise PluginError(f"plugin '{name}' ({dist}) has an invalid hook implementation: {e}") from None


_REGISTRY: Registry | None = None


def get_registry() -> Registry:
    """The process-wide registry, loaded on first use."""
    global _REGISTRY
    if _REGISTRY is None:
        _REGISTRY = load_registry()
    return _REGISTRY


def reset_registry(registry: Registry | None = None) -> None:
    """Drop (or replace) the process-wide registry; the next :func:`get_registry` reloads."""
    global _REGISTRY
    _REGISTRY = registry
