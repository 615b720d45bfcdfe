"""The sweep's progress line: the project's bar with the counts of done, failed and running points."""

from __future__ import annotations

import time

from knitframe.progress import ProgressBar

__all__ = ["SweepProgress"]


def _fmt(seconds: float) -> str:
    from tqdm import tqdm

    return tqdm.format_interval(seconds)


class SweepProgress(ProgressBar):
    """The sweep's progress (the project's bar): a tqdm bar on a terminal, a line every 30 s elsewhere,
    with the counts of done, failed and running points and the time left; ``note`` prints a one-off line."""

    def line(self) -> str:
        elapsed = time.perf_counter() - self.t0
        if not self.total:
            return f"knitframe: {self.label}: starting, {_fmt(elapsed)} elapsed"
        left = (
            "unknown"
            if self.done <= 0
            else "about " + _fmt(elapsed * max(self.total - self.done, 0.0) / self.done)
        )
        return (
            f"knitframe: {self.label}: {self.done:g}/{self.total:g} finished ({self.message}), "
            f"{_fmt(elapsed)} elapsed, {left} left"
        )

    def note(self, text: str) -> None:
        if self._bar is not None:
            self._bar.write(f"knitframe: {text}", file=self.stream)
        else:
            self._print(f"knitframe: {text}")
