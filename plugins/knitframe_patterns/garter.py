"""Garter: knit and purl alternate by row (course)."""

from __future__ import annotations

from typing import ClassVar

import attrs

from knitframe import hookimpl
from knitframe import validators as v
from knitframe_patterns.loops import KnitLoopPattern


@attrs.frozen
class Garter(KnitLoopPattern):
    """Garter unit cell: layout (("k", "k"), ("p", "p")) (rows x columns, k = knit, p = purl)."""

    name: ClassVar[str] = "garter"
    description: ClassVar[str] = "garter: knit and purl rows alternate"
    layout: ClassVar[tuple[tuple[str, str], tuple[str, str]]] = (("k", "k"), ("p", "p"))

    # Garter is shorter along the wale than jersey (knit and purl rows nest). 6.5 keeps the loop
    # height near Crane's 0.89 wale pitches at SL11 and every SL10-12 cell interlocked: a
    # modelling default, not a measurement.
    #: course constant for garter (jersey's 5.3 x ~1.2), -
    Kc: float = attrs.field(default=6.5, validator=v.positive)


@hookimpl
def register_patterns(register) -> None:
    register(Garter)
