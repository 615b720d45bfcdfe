"""A small terminal progress bar, used as the ``progress(done, total, message)`` callback of solvers."""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["ProgressBar", "silent"]


def silent(done: float, total: float, message: str = "") -> None:
    """A progress callback that does nothing."""


class ProgressBar:
    """``[#####.....]  50%  step 5/10  12.3 s`` redrawn in place on a terminal.

    On a non-terminal stream only the final line is written, so logs stay readable.
    """

    def __init__(self, label: str = "", *, stream: TextIO | None = None, width: int = 28, enabled: bool | None = None):
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.width = width
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.enabled = self.tty if enabled is None else enabled
        self.t0 = time.perf_counter()
        self._last = ""

    def __call__(self, done: float, total: float, message: str = "") -> None:
        frac = 0.0 if total <= 0 else min(max(done / total, 0.0), 1.0)
        n = int(round(frac * self.width))
        line = (
            f"{self.label} [{'#' * n}{'.' * (self.width - n)}] {100 * frac:5.1f}%  {message}"
            f"  {time.perf_counter() - self.t0:6.1f} s"
        )
        self._last = line
        if self.enabled and self.tty:
            self.stream.write("\r" + line[:160].ljust(len(line)))
            self.stream.flush()
        if frac >= 1.0:
            self.close()

    def close(self) -> None:
        """Finish the bar with a newline (or print the last state on a non-terminal)."""
        if self.enabled and self._last:
            self.stream.write(("\n" if self.tty else self._last + "\n"))
            self.stream.flush()
        self._last = ""
