"""Reader for the uniaxial knit tests of Singal et al. 2024 (Nat Commun 15:2622, MIT licence).

File format: two ``#`` lines, then ``video,frame,strain_axial,strain_transverse,tension_N_per_mm``.
The file name ends in ``-x`` (stretched along the course) or ``-y`` (along the wale). The specimen
sides were free, so the lateral strain is measured and the lateral tension is zero.
"""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl, validators as v
from knitframe.csvio import read_table
from knitframe.curves import average_repeats, uniaxial_response  # noqa: F401  (average_repeats re-exported)
from knitframe.errors import DataError
from knitframe.records import Provenance, Response

COLUMNS = ("video", "frame", "strain_axial", "strain_transverse", "tension_N_per_mm")


@attrs.frozen
class Singal2024Reader:
    """Uniaxial tests of Singal et al. 2024: one Response per file (mean ± sd over repeats) or per repeat."""

    name: ClassVar[str] = "singal2024"
    description: ClassVar[str] = "Singal et al. 2024 uniaxial knit tests (video, strain_axial, strain_transverse, N/mm)"

    average: bool = True  #: one mean ± sd Response per file; false gives one Response per repeat
    points: int = attrs.field(default=40, validator=v.in_range(2, 100000))  #: grid size when averaging

    def read(self, path: Path) -> list[Response]:
        path = Path(path)
        table = read_table(path, COLUMNS)
        stem = path.stem.lower()
        header = " ".join(table.comments).lower()
        if stem.endswith("-x") or "stockinette x" in header or header.rstrip("'").endswith(" x"):
            load = "uniaxial-course"
        elif stem.endswith("-y") or header.rstrip("'").endswith(" y"):
            load = "uniaxial-wale"
        else:
            raise DataError(path, "cannot tell the direction: the file name must end in -x (course) or -y (wale)")
        axial, lateral, tension = table["strain_axial"], table["strain_transverse"], table["tension_N_per_mm"]
        for col, arr in (("strain_axial", axial), ("strain_transverse", lateral)):
            if np.any(arr <= -1):
                i = int(np.flatnonzero(arr <= -1)[0])
                raise DataError(path, f"strain {arr[i]} gives a non-positive stretch", line=table.lines[i], column=col)
        videos = table.text("video")
        ids = list(dict.fromkeys(videos))
        groups = [np.array([vv == k for vv in videos]) for k in ids]
        prov = Provenance(
            kind="experiment",
            source=path.name,
            notes="Singal et al. 2024, Nat Commun 15:2622, sabetta/stitch-by-stitch (MIT)",
        )
        base = path.stem
        if not self.average:
            return [
                uniaxial_response(load, axial[g], lateral[g], tension[g], None, None, 1, f"{base}/{k}", prov)
                for k, g in zip(ids, groups)
            ]
        try:
            grid, lat, lat_sd, ten, ten_sd = average_repeats(
                [axial[g] for g in groups], [lateral[g] for g in groups], [tension[g] for g in groups], self.points
            )
        except ValueError as e:
            raise DataError(path, str(e)) from None
        return [uniaxial_response(load, grid, lat, ten, lat_sd, ten_sd, len(ids), base, prov)]


@hookimpl
def register_readers(register):
    register(Singal2024Reader)
