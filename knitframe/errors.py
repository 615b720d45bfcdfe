"""Every exception knitframe raises on purpose.

User-facing errors derive from :class:`KnitframeError`; the CLI prints ``str(error)`` as a single
line and exits with :attr:`KnitframeError.exit_code`, never a traceback.
"""

from __future__ import annotations

__all__ = [
    "KnitframeError",
    "ConfigError",
    "DataError",
    "PluginError",
    "UnknownPluginError",
    "UnsupportedEffectError",
    "GeometryError",
    "NumericalError",
    "FieldError",
    "KnitframeWarning",
]


class KnitframeError(Exception):
    """Base class of errors caused by the user's input or a failed computation."""

    exit_code = 2


class FieldError(ValueError):
    """A record field failed validation; ``field`` names it so callers can prefix a path.

    Raised by the validators in :mod:`knitframe.validators`. The config layer turns it into a
    :class:`ConfigError` whose message starts with the full TOML path of the field.
    """

    def __init__(self, field: str, problem: str):
        self.field = field
        self.problem = problem
        super().__init__(f"{field}: {problem}")


class ConfigError(KnitframeError):
    """A configuration value is wrong. ``str()`` is ``"<toml.path>: <problem>"``."""

    def __init__(self, path: str, problem: str, *, source: str | None = None):
        self.path = path
        self.problem = problem
        self.source = source
        where = f"{source}: " if source else ""
        super().__init__(f"{where}{path}: {problem}" if path else f"{where}{problem}")


class DataError(KnitframeError):
    """A data file (CSV, mesh) is malformed. Names the file, and the line and column when known."""

    def __init__(self, file: str, problem: str, *, line: int | None = None, column: str | None = None):
        self.file = str(file)
        self.line = line
        self.column = column
        self.problem = problem
        where = self.file
        if line is not None:
            where += f", line {line}"
        if column is not None:
            where += f", column '{column}'"
        super().__init__(f"{where}: {problem}")


class PluginError(KnitframeError):
    """A plugin could not be loaded or does not honour its contract."""


class UnknownPluginError(PluginError, KeyError):
    """A lookup by name found nothing; the message lists the available names of that kind."""

    def __init__(self, kind: str, name: str, available: list[str]):
        self.kind = kind
        self.name = name
        self.available = sorted(available)
        names = ", ".join(self.available) if self.available else "(none installed)"
        msg = f"unknown {kind} '{name}'; available: {names}"
        self.message = msg
        super().__init__(msg)

    def __str__(self) -> str:  # KeyError would quote the message
        return self.message


class UnsupportedEffectError(KnitframeError):
    """A scene asks for an effect that the chosen solver cannot model."""

    def __init__(self, effect: str, solver: str, supporting: list[str]):
        self.effect = effect
        self.solver = solver
        self.supporting = sorted(supporting)
        alt = ", ".join(self.supporting) if self.supporting else "none installed"
        super().__init__(
            f"scene.effects: solver '{solver}' does not support effect '{effect}'; solvers that do: {alt}"
        )


class GeometryError(KnitframeError):
    """A geometry request is impossible (for example an arc length shorter than the pitch)."""


class NumericalError(KnitframeError):
    """A computation failed to converge or produced non-finite values; carries a diagnostic."""

    exit_code = 3


class KnitframeWarning(UserWarning):
    """A result is suspect but usable: a fit at a bound, a unit converted, a curve that is zero.

    The CLI prints it as one line, ``knitframe: warning: <message>``; the pipeline also records
    every warning of a run in ``summary.json`` under ``warnings``.
    """
