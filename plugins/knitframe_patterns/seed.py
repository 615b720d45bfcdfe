"""Seed (moss) stitch: knit and purl alternate by row and by column (checkerboard)."""

from __future__ import annotations

from typing import ClassVar

import attrs

from knitframe import hookimpl
from knitframe_patterns.loops import KnitLoopPattern


@attrs.frozen
class Seed(KnitLoopPattern):
    """Seed (moss) unit cell: layout (("k", "p"), ("p", "k")) (rows x columns, k = knit, p = purl)."""

    name: ClassVar[str] = "seed"
    description: ClassVar[str] = "seed / moss: knit-purl checkerboard"
    layout: ClassVar[tuple[tuple[str, str], tuple[str, str]]] = (("k", "p"), ("p", "k"))


@hookimpl
def register_patterns(register) -> None:
    register(Seed)
