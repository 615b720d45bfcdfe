"""Reader ``auto``: each file is read by the reader whose expected header it has.

Every installed reader that recognises its files by their header
(:class:`~knitframe.interfaces.HeaderReader`: ``accepts(header) -> bool`` and ``expects``) is asked
about the file's header row (the first line after the ``#`` comments). The Singal et al. files
(``video, frame, strain_axial, …``) go to ``singal2024``, files with ``strain``/``stretch`` and a
load column to ``generic``; a more specific reader wins over ``generic`` when both accept. A
header no reader accepts is one DataError line listing the columns each reader expects. Other
readers are listed as "select by name".
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar

import attrs

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.csvio import read_table
from knitframe.errors import DataError
from knitframe.interfaces import HeaderReader
from knitframe.records import Response

#: the fallback reader: chosen only when no more specific reader accepts the header
FALLBACK = "generic"


def _expects(reader: Any) -> str | None:
    """The header a reader declares it reads, or None for a reader chosen by name only."""
    return reader.expects if isinstance(reader, HeaderReader) else None


@attrs.frozen
class AutoReader:
    """Detect the reader from each file's header row, then read the file with it."""

    name: ClassVar[str] = "auto"
    description: ClassVar[str] = (
        "detect the reader from the file's header (singal2024, generic, or an installed one)"
    )

    #: passed to the chosen reader: one mean ± sd Response per curve; false: one per repeat
    average: bool = True
    #: passed to the chosen reader (its default if unset)
    points: int | None = attrs.field(default=None, validator=v.optional(v.in_range(2, 100000)))

    def detect(self, path: Path) -> str:
        """Name of the reader for ``path``; a header no reader accepts is a DataError listing what each
        expects."""
        from knitframe import get_registry

        table = read_table(path, need_rows=False)
        readers = get_registry()["reader"]
        matches = [
            n
            for n in readers
            if n != self.name
            and isinstance(readers[n], HeaderReader)
            and readers[n].accepts(list(table.header))
        ]
        if matches:
            return sorted(matches, key=lambda n: (n == FALLBACK, n))[0]
        expected = "; ".join(
            f"{n}: {_expects(readers[n]) or 'its own format (select it by name)'}"
            for n in readers
            if n != self.name
        )
        raise DataError(
            path,
            f"no reader knows the header ({', '.join(table.header)}); readers expect: {expected}",
            line=table.header_line,
        )

    def reader_for(self, path: Path) -> Any:
        """The chosen reader for ``path``, built with this reader's ``average`` and ``points``."""
        from knitframe import get_registry
        from knitframe.config import instantiate

        reg = get_registry()
        name = self.detect(path)
        impl = reg["reader"][name]
        fields = attrs.fields_dict(impl) if isinstance(impl, type) and attrs.has(impl) else {}
        options = {
            k: val
            for k, val in (("average", self.average), ("points", self.points))
            if k in fields and val is not None
        }
        return instantiate(reg, "reader", {"kind": name, **options}, "reader")

    def read(self, path: Path) -> list[Response]:
        path = Path(path)
        return self.reader_for(path).read(path)


@hookimpl
def register_readers(register):
    register(AutoReader)
