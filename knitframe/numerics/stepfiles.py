"""One VTU file per converged step and a ParaView ``.pvd`` collection that lists every step.

A solver writes a step's file *before* it saves that step's checkpoint, so a run killed at any
moment has a file for every checkpointed step; a resumed run keeps the files of the steps before
its checkpoint (and lists them in the ``.pvd`` again), and replaces any file a killed run wrote
after its last checkpoint.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from knitframe.outdir import write_atomic

__all__ = ["StepSeries"]


class StepSeries:
    """``<prefix>-NNNN.vtu`` files in ``folder`` and ``<prefix>.pvd`` listing them by step index.

    Parameters
    ----------
    folder : path
        Where the files go (created if missing).
    prefix : str
        File name stem, e.g. ``"rod"`` or ``"solid"``.
    first : int
        Index of the first step this run writes (0, or the step after a resumed checkpoint).
    """

    def __init__(self, folder: str | Path, prefix: str, first: int = 0):
        self.folder = Path(folder)
        self.prefix = prefix
        self.folder.mkdir(parents=True, exist_ok=True)
        self.files: list[tuple[int, str]] = []
        pattern = re.compile(rf"{re.escape(prefix)}-(\d{{4,}})\.vtu")
        for path in sorted(self.folder.iterdir()):
            m = pattern.fullmatch(path.name)
            if m is None:
                continue
            if int(m.group(1)) < first:
                self.files.append((int(m.group(1)), path.name))
            else:  # written after the killed run's last checkpoint: that step is computed again
                path.unlink()
        if self.files:
            self._write_pvd()

    def write(self, index: int, write_vtu: Callable[[Path], object]) -> Path:
        """Write step ``index`` with ``write_vtu(path)`` and list it in the ``.pvd``."""
        path = self.folder / f"{self.prefix}-{index:04d}.vtu"
        write_vtu(path)
        self.files = [f for f in self.files if f[0] != index] + [(index, path.name)]
        self._write_pvd()
        return path

    @property
    def pvd(self) -> Path:
        return self.folder / f"{self.prefix}.pvd"

    def _write_pvd(self) -> None:
        rows = "\n".join(f'    <DataSet timestep="{i}" file="{name}"/>' for i, name in sorted(self.files))
        text = (
            f'<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n  <Collection>\n{rows}\n'
            "  </Collection>\n</VTKFile>\n"
        )
        write_atomic(self.pvd, text)
