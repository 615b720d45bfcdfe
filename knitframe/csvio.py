"""Strict CSV reading shared by the data readers: every problem names file, line and column."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from knitframe.errors import DataError

__all__ = ["read_table", "Table"]


class Table:
    """Columns of a CSV file: ``table["strain"]`` is a float64 array, ``table.text("video")`` a list."""

    def __init__(self, path: Path, header: list[str], rows: list[list[str]], lines: list[int], comments: list[str]):
        self.path = path
        self.header = header
        self.rows = rows
        self.lines = lines  #: 1-based file line number of each row
        self.comments = comments  #: leading ``#`` lines without the ``#``

    def __len__(self) -> int:
        return len(self.rows)

    def __contains__(self, column: str) -> bool:
        return column in self.header

    def text(self, column: str) -> list[str]:
        """A column as strings."""
        j = self.header.index(column)
        return [r[j] for r in self.rows]

    def __getitem__(self, column: str) -> np.ndarray:
        """A column as finite float64 numbers; a bad cell raises DataError at its line and column."""
        j = self.header.index(column)
        out = np.empty(len(self.rows))
        for i, row in enumerate(self.rows):
            cell = row[j].strip()
            try:
                x = float(cell)
            except ValueError:
                raise DataError(self.path, f"expected a number, got {cell!r}", line=self.lines[i], column=column) from None
            if not math.isfinite(x):
                raise DataError(self.path, f"expected a finite number, got {cell!r}", line=self.lines[i], column=column)
            out[i] = x
        return out


def read_table(path: str | Path, required: tuple[str, ...] = ()) -> Table:
    """Read a comma-separated file with ``#`` comment lines before a header row.

    Raises :class:`~knitframe.errors.DataError` for a missing or empty file, a missing column, or
    a row with the wrong number of cells.
    """
    p = Path(path)
    if not p.is_file():
        raise DataError(p, "file not found")
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise DataError(p, f"cannot read: {e}") from None
    comments: list[str] = []
    header: list[str] | None = None
    rows: list[list[str]] = []
    lines: list[int] = []
    for lineno, row in enumerate(csv.reader(text.splitlines()), start=1):
        if not row or all(not c.strip() for c in row):
            continue
        if header is None and row[0].lstrip().startswith("#"):
            comments.append(",".join(row).lstrip()[1:].strip())
            continue
        if header is None:
            header = [c.strip() for c in row]
            header_line = lineno
            continue
        if len(row) != len(header):
            raise DataError(p, f"expected {len(header)} cells, got {len(row)}", line=lineno)
        rows.append(row)
        lines.append(lineno)
    if header is None:
        raise DataError(p, "empty file (no header row)")
    for col in required:
        if col not in header:
            raise DataError(p, f"missing column '{col}' (header has {', '.join(header)})", line=header_line)
    if not rows:
        raise DataError(p, "no data rows after the header", line=header_line)
    return Table(p, header, rows, lines, comments)
