"""Strict CSV reading shared by the data readers: every problem names file, line and column.

Besides the format (:func:`read_table`) the readers share the checks of what the numbers mean:
strains given in percent are divided by 100 with one warning (:func:`strains_as_fractions`), a
tension that reads as a force in N is divided by a known width or refused
(:func:`tension_per_width`), a tension that is zero or negative everywhere is refused
(:func:`check_tension`), and so is a test whose strain falls back (an unloading branch,
:func:`check_loading`).
"""

from __future__ import annotations

import csv
import math
import re
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from knitframe.errors import DataError, KnitframeWarning

__all__ = [
    "read_table",
    "Table",
    "strains_as_fractions",
    "tension_per_width",
    "check_tension",
    "check_loading",
    "PERCENT_STRAIN",
    "FORCE_TENSION",
    "UNLOADING",
]

#: An engineering strain beyond this (500 %) reads as percent: no knit test goes that far.
PERCENT_STRAIN = 5.0
#: A tension beyond this (N/mm) reads as a force in N: knits break at a few N/mm.
FORCE_TENSION = 20.0
#: A strain that falls back by more than this fraction of its range holds an unloading branch.
UNLOADING = 0.1
#: A decimal comma: digits, a comma, digits.
_DECIMAL_COMMA = re.compile(r"[+-]?\d+,\d+")


class Table:
    """Columns of a CSV file: ``table["strain"]`` is a float64 array, ``table.text("video")`` a list."""

    def __init__(
        self,
        path: Path,
        header: list[str],
        rows: list[list[str]],
        lines: list[int],
        comments: list[str],
        header_line: int | None = None,
    ):
        self.path = path
        self.header = header
        self.header_line = header_line  #: 1-based file line number of the header row
        self.warnings: list[
            str
        ] = []  #: unit conversions made while reading (also issued as KnitframeWarning)
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
                hint = ""
                if _DECIMAL_COMMA.fullmatch(cell):
                    hint = ": write decimals with '.', not a decimal comma"
                elif not cell:
                    hint = " (the cell is empty)"
                raise DataError(
                    self.path, f"expected a number, got {cell!r}{hint}", line=self.lines[i], column=column
                ) from None
            if not math.isfinite(x):
                raise DataError(
                    self.path, f"expected a finite number, got {cell!r}", line=self.lines[i], column=column
                )
            out[i] = x
        return out


def _text(p: Path) -> str:
    """The file as text (UTF-8, with or without a byte-order mark); anything else is a DataError."""
    if p.is_dir():
        raise DataError(p, "is a directory, not a data file")
    if not p.is_file():
        raise DataError(p, "file not found")
    try:
        data = p.read_bytes()
    except OSError as e:
        raise DataError(p, f"cannot read: {e.strerror or e}") from None
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise DataError(p, "UTF-16 text; save the file as UTF-8 CSV")
    if b"\x00" in data:
        raise DataError(p, "binary file, not CSV text (it holds NUL bytes)")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        start = e.start + (3 if data.startswith(b"\xef\xbb\xbf") else 0)
        raise DataError(
            p,
            f"not UTF-8 text (byte 0x{data[start]:02x}); save the file as UTF-8",
            line=data[:start].count(b"\n") + 1,
        ) from None


def _delimiter_problem(header_text: str, lines: list[str], lineno: int) -> str | None:
    """What is wrong with a one-cell header that holds another delimiter (``;``, tab, ``|``), else None."""
    for sep, name in ((";", "';'"), ("\t", "tabs"), ("|", "'|'")):
        if sep in header_text:
            data = next((ln for ln in lines[lineno:] if ln.strip() and not ln.lstrip().startswith("#")), "")
            decimal = (
                " and the numbers use decimal commas (e.g. '0,5')" if _DECIMAL_COMMA.search(data) else ""
            )
            return (
                f"the columns are separated by {name}, not commas{decimal}: save it as comma-separated CSV "
                "with '.' as the decimal point"
            )
    return None


def _ragged(row: list[str], n: int, raw: str) -> str:
    """The message for a row with the wrong number of cells, naming a decimal comma when that is the cause."""
    msg = f"expected {n} cells, got {len(row)}"
    if len(row) > n and _DECIMAL_COMMA.search(raw) and not any("." in c for c in row):
        msg += ": the numbers look like decimal commas (e.g. '0,5'); write decimals with '.'"
    elif ";" in raw:
        msg += ": the row is separated by ';', not commas"
    return msg


def read_table(path: str | Path, required: tuple[str, ...] = (), *, need_rows: bool = True) -> Table:
    """Read a comma-separated file with ``#`` comment lines before a header row.

    Raises :class:`~knitframe.errors.DataError` for a missing, empty, binary or non-UTF-8 file, a
    directory, another delimiter or decimal commas, a duplicate or missing column, or a row with
    the wrong number of cells. ``need_rows=False`` accepts a header without data rows.
    """
    p = Path(path)
    text = _text(p)
    raw_lines = text.splitlines()
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
            problem = _delimiter_problem(header[0], raw_lines, lineno) if len(header) == 1 else None
            if problem:
                raise DataError(p, problem, line=lineno)
            _check_unique(p, header, lineno)
            continue
        if len(row) != len(header):
            raise DataError(
                p,
                _ragged(row, len(header), raw_lines[lineno - 1] if lineno <= len(raw_lines) else ""),
                line=lineno,
            )
        rows.append(row)
        lines.append(lineno)
    if header is None:
        raise DataError(p, "empty file (no header row)")
    for col in required:
        if col not in header:
            raise DataError(p, f"missing column '{col}' (header has {', '.join(header)})", line=header_line)
    if not rows and need_rows:
        raise DataError(p, "no data rows after the header", line=header_line)
    return Table(p, header, rows, lines, comments, header_line)


def _check_unique(p: Path, header: list[str], lineno: int) -> None:
    """A column name given twice (ignoring case) is a DataError: which one would be read?"""
    seen: dict[str, int] = {}
    for j, name in enumerate(header):
        key = name.lower()
        if key and key in seen:
            raise DataError(
                p,
                f"the header names this column twice (columns {seen[key] + 1} and {j + 1})",
                line=lineno,
                column=name,
            )
        seen.setdefault(key, j)


def _is_stretch(column: str) -> bool:
    return column.lower().endswith("stretch")


def strains_as_fractions(table: Table, columns: dict[str, np.ndarray], lead: str) -> dict[str, np.ndarray]:
    """Strain (or stretch) columns as fractions: percent is divided by 100, with one warning.

    The ``lead`` column (the loaded strain) reads as percent beyond :data:`PERCENT_STRAIN` (a
    stretch beyond 1 + PERCENT_STRAIN). Another column reads as percent beyond the same limit, or,
    when the lead is in percent, from 1 up (a strain of 1 is 100 %, which no free side reaches,
    while a contraction in percent passes 1 % early in any test). Percent columns are divided by
    100 and the warning names what was divided and what was kept. A column in percent next to a
    lead that is not is a DataError at its cell: give every strain in the same unit.
    """

    def size(name: str) -> tuple[float, int]:
        x = np.abs(columns[name] - (1.0 if _is_stretch(name) else 0.0))
        i = int(np.argmax(x))
        return float(x[i]), i

    lead_percent = size(lead)[0] > PERCENT_STRAIN
    percent = [n for n in columns if size(n)[0] > PERCENT_STRAIN or (lead_percent and size(n)[0] >= 1.0)]
    if not lead_percent:
        if percent:
            name = percent[0]
            i = size(name)[1]
            raise DataError(
                table.path,
                f"{columns[name][i]:g} reads as percent while '{lead}' reads as a fraction: "
                "give every strain in the same unit",
                line=table.lines[i],
                column=name,
            )
        return dict(columns)
    unit = "stretch" if _is_stretch(lead) else "strain"
    kept = [n for n in columns if n not in percent]
    note = "".join(f"; kept '{n}' (at most {size(n)[0]:g}, a fraction)" for n in kept)
    _warn(
        table,
        f"{table.path}: column '{lead}' reaches {columns[lead][size(lead)[1]]:g}, which reads as percent, "
        f"not {unit} (beyond {PERCENT_STRAIN:g}): divided {', '.join(repr(c) for c in percent)} by 100{note}",
    )
    return {name: x / 100.0 if name in percent else x for name, x in columns.items()}


def tension_per_width(
    table: Table,
    column: str,
    tension: np.ndarray,
    width: float | np.ndarray | None,
    how_to_give_width: str,
    *,
    limit: float = FORCE_TENSION,
) -> np.ndarray:
    """A tension column (N/mm) that reaches past ``limit`` reads as a force in N.

    With a known specimen ``width`` (mm) it is divided by it, with one warning; without one it is
    a DataError saying what was detected and ``how_to_give_width``. Below the limit it is returned
    unchanged.
    """
    i = int(np.argmax(tension))
    if not tension[i] > limit:
        return tension
    detected = (
        f"{tension[i]:g} is more than a knit carries (above {limit:g} N/mm): "
        "the column reads as a force in N, not a tension in N/mm"
    )
    if width is None:
        raise DataError(table.path, f"{detected}; {how_to_give_width}", line=table.lines[i], column=column)
    w = np.asarray(width, dtype=np.float64)
    shown = f"{float(w):g} mm" if w.ndim == 0 else "the width_mm column"
    _warn(
        table,
        f"{table.path}: column '{column}' reaches {tension[i]:g}, which reads as a force in N, not N/mm "
        f"(above {limit:g}): divided by the specimen width, {shown}",
    )
    return tension / w


def _warn(table: Table, message: str) -> None:
    """A unit conversion: one KnitframeWarning line, and kept in ``table.warnings`` for the Responses'
    provenance."""
    table.warnings.append(message)
    warnings.warn(message, KnitframeWarning, stacklevel=3)


def check_tension(
    table: Table, column: str, tension: np.ndarray, rows: np.ndarray | None = None, what: str = ""
) -> None:
    """A curve whose tension is zero on every row, or nowhere positive, is a DataError: nothing to fit."""
    idx = np.flatnonzero(np.ones(len(tension), bool) if rows is None else rows)
    t = tension[idx]
    of = f" of the {what} rows" if what else ""
    if np.all(t == 0):
        raise DataError(
            table.path,
            f"the tension is zero on every row{of}: the file holds no load",
            line=table.lines[idx[0]],
            column=column,
        )
    if t.max() <= 0:
        raise DataError(
            table.path,
            f"the tension is negative on every row{of} (down to {t.min():g}): "
            "knitframe reads tension as positive",
            line=table.lines[idx[int(np.argmin(t))]],
            column=column,
        )


def check_loading(table: Table, column: str, strain: np.ndarray, groups: Sequence[np.ndarray]) -> None:
    """Each test (rows of one group, in file order) must load: a strain that falls back by more
    than :data:`UNLOADING` of its range is an unloading branch, which would be averaged with the
    loading one. Noise of a few percent passes."""
    for g in groups:
        idx = np.flatnonzero(g)
        s = strain[idx]
        top = np.maximum.accumulate(s)
        span = s.max() - s.min()
        fall = top - s
        if span > 0 and fall.max() > UNLOADING * span:
            k = int(np.argmax(fall > UNLOADING * span))
            raise DataError(
                table.path,
                f"the strain falls from {top[k]:g} back to {s[k]:g}: the test holds an "
                "unloading branch; keep the loading part only",
                line=table.lines[idx[k]],
                column=column,
            )
