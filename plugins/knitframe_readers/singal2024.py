"""Reader for the uniaxial knit tests of Singal et al. 2024 (Nat Commun 15:2622, MIT licence).

File format: two ``#`` lines, then ``video,frame,strain_axial,strain_transverse,tension_N_per_mm``.
The file name ends in ``-x`` (stretched along the course) or ``-y`` (along the wale). The specimen
sides were free, so the lateral strain is measured and the lateral tension is zero.

Units are checked as in the generic reader: strains beyond 5 read as percent and are divided by
100 (one warning); a tension beyond 20 N/mm reads as a force in N and is divided by the clamp
width of the ``# ... fabric width at clamp <w> mm`` line (one warning), or refused without it.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.csvio import check_loading, check_tension, read_table, strains_as_fractions, tension_per_width
from knitframe.curves import average_repeats, uniaxial_response  # noqa: F401  (average_repeats re-exported)
from knitframe.errors import DataError
from knitframe.records import Provenance, Response

COLUMNS = ("video", "frame", "strain_axial", "strain_transverse", "tension_N_per_mm")
#: the clamp width in the files' second comment line: "fabric width at clamp 64.48 mm"
_WIDTH = re.compile(r"width at clamp\s*=?\s*([0-9]+(?:\.[0-9]*)?)\s*mm", re.IGNORECASE)


def clamp_width(comments: list[str]) -> float | None:
    """The specimen width (mm) stated in the comment lines, or None."""
    for c in comments:
        m = _WIDTH.search(c)
        if m and float(m.group(1)) > 0:
            return float(m.group(1))
    return None


@attrs.frozen
class Singal2024Reader:
    """Uniaxial tests of Singal et al. 2024: one Response per file (mean ± sd over repeats) or per repeat."""

    name: ClassVar[str] = "singal2024"
    description: ClassVar[str] = (
        "Singal et al. 2024 uniaxial knit tests (video, strain_axial, strain_transverse, N/mm)"
    )

    #: one mean ± sd Response per file; false gives one Response per repeat
    average: bool = True
    #: grid size when averaging
    points: int = attrs.field(default=40, validator=v.in_range(2, 100000))
    #: the header this reader expects, for the auto reader's message when no reader matches
    expects: ClassVar[str] = ", ".join(COLUMNS)

    @classmethod
    def accepts(cls, header: list[str]) -> bool:
        """True if ``header`` holds every column of the Singal et al. files."""
        return set(COLUMNS) <= {h.strip() for h in header}

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
            raise DataError(
                path, "cannot tell the direction: the file name must end in -x (course) or -y (wale)"
            )
        strains = strains_as_fractions(
            table, {c: table[c] for c in ("strain_axial", "strain_transverse")}, "strain_axial"
        )
        axial, lateral = strains["strain_axial"], strains["strain_transverse"]
        tension = tension_per_width(
            table,
            "tension_N_per_mm",
            table["tension_N_per_mm"],
            clamp_width(table.comments),
            "divide it by the specimen width, or state the width in a comment line "
            "'# fabric width at clamp <w> mm'",
        )
        check_tension(table, "tension_N_per_mm", tension)
        for col, arr in (("strain_axial", axial), ("strain_transverse", lateral)):
            if np.any(arr <= -1):
                i = int(np.flatnonzero(arr <= -1)[0])
                raise DataError(
                    path, f"strain {arr[i]} gives a non-positive stretch", line=table.lines[i], column=col
                )
        videos = table.text("video")
        ids = list(dict.fromkeys(videos))
        groups = [np.array([vv == k for vv in videos]) for k in ids]
        check_loading(table, "strain_axial", axial, groups)
        prov = Provenance(
            kind="experiment",
            source=path.name,
            notes="Singal et al. 2024, Nat Commun 15:2622, sabetta/stitch-by-stitch (MIT)",
            extra={"warnings": list(table.warnings)} if table.warnings else {},
        )
        base = path.stem
        if not self.average:
            return [
                uniaxial_response(load, axial[g], lateral[g], tension[g], None, None, 1, f"{base}/{k}", prov)
                for k, g in zip(ids, groups)
            ]
        try:
            grid, lat, lat_sd, ten, ten_sd = average_repeats(
                [axial[g] for g in groups],
                [lateral[g] for g in groups],
                [tension[g] for g in groups],
                self.points,
            )
        except ValueError as e:
            raise DataError(path, str(e)) from None
        return [uniaxial_response(load, grid, lat, ten, lat_sd, ten_sd, len(ids), base, prov)]


@hookimpl
def register_readers(register):
    register(Singal2024Reader)
