"""Reader ``force-extension``: raw tensile-machine exports (extension in mm, force in N).

Many test machines export two columns, ``extension_mm,force_N``. With the specimen's gauge
length ``L0`` and width ``w`` the reader turns them into a uniaxial Response:

    λ = 1 + extension / L0,    T = force / w   (N/mm)

The lateral stretch is not measured by such machines, so it is recorded as 1 (unknown) and the
Response is labelled accordingly; fit it with a model that does not need λ2, or use measured data.
"""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar, Literal

import attrs
import numpy as np

import knitframe
from knitframe.csvio import read_table
from knitframe.errors import DataError
from knitframe.validators import positive


@attrs.frozen
class ForceExtensionReader:
    """Tensile-machine export: extension (mm) and force (N) → stretch and tension per width."""

    name: ClassVar[str] = "force-extension"
    description: ClassVar[str] = "tensile-machine export (extension_mm, force_N) with gauge length and width"

    gauge_length: float = attrs.field(default=50.0, validator=positive)  #: clamp distance at rest, mm
    width: float = attrs.field(default=50.0, validator=positive)  #: specimen width, mm
    direction: Literal["course", "wale"] = "course"  #: direction of the pull

    def read(self, path: Path) -> list[knitframe.Response]:
        table = read_table(path, ("extension_mm", "force_N"))
        ext, force = table["extension_mm"], table["force_N"]
        lam = 1.0 + ext / self.gauge_length
        if np.any(lam <= 0):
            i = int(np.flatnonzero(lam <= 0)[0])
            raise DataError(path, f"extension {ext[i]} mm gives a non-positive stretch", line=table.lines[i],
                            column="extension_mm")
        tension = force / self.width
        ones, zero = np.ones_like(lam), np.zeros_like(lam)
        prov = knitframe.Provenance(kind="experiment", source=Path(path).name,
                                    notes="lateral stretch not measured (set to 1)")
        if self.direction == "course":
            r = knitframe.Response(lam, ones, tension, zero, load="uniaxial-course", label=Path(path).stem, provenance=prov)
        else:
            r = knitframe.Response(ones, lam, zero, tension, load="uniaxial-wale", label=Path(path).stem, provenance=prov)
        return [r]


@knitframe.hookimpl
def register_readers(register):
    register(ForceExtensionReader)
