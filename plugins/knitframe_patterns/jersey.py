"""Jersey (single jersey, plain knit): every loop is a knit loop on Crane's curve."""

from __future__ import annotations

from typing import ClassVar

import attrs

from knitframe import hookimpl
from knitframe_patterns.loops import KnitLoopPattern


@attrs.frozen
class Jersey(KnitLoopPattern):
    """Jersey (plain knit) unit cell: layout (("k", "k"), ("k", "k")) (rows x columns, k = knit, p = purl)."""

    name: ClassVar[str] = "jersey"
    description: ClassVar[str] = "jersey / plain knit: every stitch knit (Crane 2023 curve)"
    #: the name of the shipped data files and of US usage; a fabric given it is recorded as jersey
    aliases: ClassVar[tuple[str, ...]] = ("stockinette",)
    layout: ClassVar[tuple[tuple[str, str], tuple[str, str]]] = (("k", "k"), ("k", "k"))


@hookimpl
def register_patterns(register) -> None:
    register(Jersey)
