"""Progress of long runs, as the ``progress(done, total, message)`` callback solvers call per step.

On a terminal it is a :mod:`tqdm` bar redrawn in place::

    rod jersey [##########..................]  35.7%  load step 2/6  00:04<00:07

On anything else (a log file, CI) a line is printed every ``interval`` seconds (30 by default,
``KNITFRAME_PROGRESS_INTERVAL`` to change it), whether or not a step finished meanwhile, with the
step, the elapsed time and an estimate of the time left; and one last line at the end::

    knitframe: volumetric jersey: step 7/14 (load step 1/6), 05:12 elapsed, about 05:12 left
"""

from __future__ import annotations

import os
import shutil
import sys
import threading
import time
from typing import TextIO

from tqdm import tqdm

__all__ = ["ProgressBar"]


def _bar_format(message: str) -> str:
    """``label [####....]  35.7%  message  00:04<00:07`` (the message's braces escaped for tqdm)."""
    text = message.replace("{", "{{").replace("}", "}}")
    return "{desc} [{bar}] {percentage:5.1f}%  " + text + "  {elapsed}<{remaining}"


def _interval() -> float:
    try:
        return max(float(os.environ.get("KNITFRAME_PROGRESS_INTERVAL", "30")), 0.05)
    except ValueError:
        return 30.0


class ProgressBar:
    """A progress callback: a tqdm bar on a terminal, a line every ``interval`` seconds elsewhere."""

    def __init__(self, label: str = "", *, stream: TextIO | None = None, interval: float | None = None):
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval = _interval() if interval is None else interval
        self.t0 = time.perf_counter()
        self.done, self.total, self.message = 0.0, 0.0, ""
        self._bar: tqdm | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if self.tty:
            # a terminal that reports no size (a fresh pseudo-terminal) would get no bar at all
            size = shutil.get_terminal_size((100, 24))
            self._bar = tqdm(
                total=1,
                desc=label,
                bar_format=_bar_format(""),
                ascii=".#",
                file=self.stream,
                leave=True,
                ncols=size.columns if size.columns >= 40 else 100,
                nrows=size.lines if size.lines >= 2 else 24,
                mininterval=0,
            )
        else:
            self._thread = threading.Thread(target=self._tick, name="knitframe-progress", daemon=True)
            self._thread.start()

    def __call__(self, done: float, total: float, message: str = "") -> None:
        self.done, self.total, self.message = float(done), float(total), message
        if self._bar is not None:
            self._bar.total = max(total, 1)
            self._bar.n = min(max(done, 0), max(total, 1))
            self._bar.bar_format = _bar_format(message)
            self._bar.refresh()

    def line(self) -> str:
        """The state as one line: step, elapsed time and an estimate of the time left."""
        elapsed = time.perf_counter() - self.t0
        if not self.total:  # before the first step: meshing, assembly, the first solve
            return f"knitframe: {self.label}: setting up, {tqdm.format_interval(elapsed)} elapsed"
        left = (
            "unknown"
            if self.done <= 0
            else "about " + tqdm.format_interval(elapsed * max(self.total - self.done, 0.0) / self.done)
        )
        what = f" ({self.message})" if self.message else ""
        return (
            f"knitframe: {self.label}: step {self.done:g}/{self.total:g}{what}, "
            f"{tqdm.format_interval(elapsed)} elapsed, {left} left"
        )

    def _tick(self) -> None:
        while not self._stop.wait(self.interval):
            self._print(self.line())

    def _print(self, text: str) -> None:
        try:
            self.stream.write(text + "\n")
            self.stream.flush()
        except (OSError, ValueError):  # the stream was closed under us: stop reporting
            self._stop.set()

    def close(self) -> None:
        """Finish: the bar stays on the screen; elsewhere the last state is printed once."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        if self._thread is not None:
            self._stop.set()
            self._thread.join(timeout=1.0)
            self._thread = None
            if self.total:
                self._print(self.line())
