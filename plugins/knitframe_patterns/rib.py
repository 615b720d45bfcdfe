"""1x1 rib: knit and purl alternate by column (wale)."""

from __future__ import annotations

from typing import ClassVar

import attrs

from knitframe import hookimpl
from knitframe_patterns.loops import KnitLoopPattern


@attrs.frozen
class Rib(KnitLoopPattern):
    """1x1 rib unit cell: layout (("k", "p"), ("k", "p")) (rows x columns, k = knit, p = purl)."""

    name: ClassVar[str] = "rib"
    description: ClassVar[str] = "1x1 rib: knit and purl columns alternate"
    layout: ClassVar[tuple[tuple[str, str], tuple[str, str]]] = (("k", "p"), ("k", "p"))


@hookimpl
def register_patterns(register) -> None:
    register(Rib)
