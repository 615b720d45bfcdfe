"""Every exception knitframe raises on purpose.

User-facing errors derive from :class:`KnitframeError`; the CLI prints ``str(error)`` as a single
line and exits with :attr:`KnitframeError.exit_code`, never a traceback. An :class:`OSError` from
writing becomes a :class:`WriteError` (exit code 1), which names the file and the way on.
"""

from __future__ import annotations

import errno
import io
import os
from types import TracebackType

__all__ = [
    "KnitframeError",
    "ConfigError",
    "DataError",
    "PluginError",
    "UnknownPluginError",
    "UnsupportedEffectError",
    "GeometryError",
    "NumericalError",
    "WriteError",
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


#: what to do before running again, by errno (others: just run again)
_WAY = {
    errno.ENOSPC: "free space",
    errno.EDQUOT: "free space or raise your quota",
    errno.EROFS: "make the file system writable",
    errno.EACCES: "allow writing there",
    errno.EPERM: "allow writing there",
}
#: what a bare reason leaves unsaid, by errno
_HINT = {errno.ENOENT: " (was the folder removed during the run?)"}
#: errors that only a write can cause
_WRITING = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS}


class WriteError(KnitframeError, OSError):
    """The file system refused to write an output or a checkpoint: a full disk, a quota, a read-only
    or removed folder, no permission.

    ``str()`` is one line naming the path and the way on,
    ``writing results/fit.png: no space left on device; free space, then run again``, and, when the
    run's checkpoints are kept, ``... then run again with --resume (its checkpoints are kept)``.
    It is an :class:`OSError` too, with the ``errno`` of the refusal.
    """

    exit_code = 1

    def __init__(
        self, error: OSError, path: str | None = None, *, writing: bool = True, checkpoints: bool = False
    ):
        super().__init__(error.errno, error.strerror or str(error), path)
        self.path = path
        self.writing = writing
        #: the failed run's checkpoints are kept: ``--resume`` continues from them
        self.checkpoints = checkpoints

    @classmethod
    def of(cls, error: OSError) -> WriteError:
        """The error as it stands, its path from the error or from the file it was writing."""
        if isinstance(error, WriteError):
            return error
        found = written_file(error.__traceback__)
        path = found if error.filename is None else os.fsdecode(error.filename)
        writing = (path is not None and path == found) or error.errno in _WRITING
        return cls(error, path, writing=writing)

    def line(self, *, resume: bool = True) -> str:
        """The message; ``resume``: the command has ``--resume`` (it is named when checkpoints are kept)."""
        text = self.strerror or "failed"
        reason = text[:1].lower() + text[1:] + _HINT.get(self.errno, "")
        if self.errno == errno.EPIPE:
            return reason if self.path is None else f"{self.path}: {reason}"
        way = _WAY.get(self.errno)
        again = "run again" if way is None else f"{way}, then run again"
        if self.checkpoints:
            again += " with --resume (its checkpoints are kept)" if resume else " with --overwrite"
        if self.path is None:
            return f"{reason}; {again}"
        return f"{'writing ' if self.writing else ''}{self.path}: {reason}; {again}"

    def __str__(self) -> str:
        return self.line()

    def __reduce__(self):  # pickled as made, not as OSError's (errno, strerror)
        return type(self), (OSError(self.errno, self.strerror), self.path), dict(self.__dict__)


def written_file(tb: TracebackType | None) -> str | None:
    """The file a failed call was writing: the innermost file open for writing among the failed
    frames' variables (an error from ``write`` or ``close`` does not name its file)."""
    frames = []
    while tb is not None:
        frames.append(tb.tb_frame)
        tb = tb.tb_next
    for frame in reversed(frames):
        for value in list(frame.f_locals.values()):
            if not isinstance(value, io.IOBase):
                continue
            try:
                name, mode = value.name, value.mode
            except (AttributeError, ValueError):
                continue
            if isinstance(name, (str, bytes)) and isinstance(mode, str) and set(mode) & set("wax+"):
                return os.fsdecode(name)
    return None


def name_written(error: BaseException, path: str | os.PathLike, *temporary: str) -> None:
    """Name ``path`` in an :class:`OSError` raised while writing it (in place of its temporary file)."""
    if isinstance(error, OSError) and (error.filename is None or error.filename in temporary):
        error.filename = os.fspath(path)


class KnitframeWarning(UserWarning):
    """A result is suspect but usable: a fit at a bound, a unit converted, a curve that is zero.

    The CLI prints it as one line, ``knitframe: warning: <message>``; the pipeline also records
    every warning of a run in ``summary.json`` under ``warnings``.
    """
