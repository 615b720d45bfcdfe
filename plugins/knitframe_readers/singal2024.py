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
from knitframe.errors import DataError
from knitframe.records import Provenance, Response

COLUMNS = ("video", "frame", "strain_axial", "strain_transverse", "tension_N_per_mm")


def average_repeats(
    strain: list[np.ndarray], lateral: list[np.ndarray], tension: list[np.ndarray], points: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean and sd of lateral strain and tension over repeats on a common axial-strain grid.

    Each repeat is sorted by axial strain and interpolated linearly onto ``points`` strains
    spanning the range every repeat covers. Returns ``(grid, lat_mean, lat_sd, T_mean, T_sd)``;
    the sd is the sample standard deviation (ddof = 1), zero for a single repeat.
    """
    lo = max(s.min() for s in strain)
    hi = min(s.max() for s in strain)
    if not hi > lo:
        raise ValueError("repeats share no strain range")
    grid = np.linspace(lo, hi, points)
    lat = np.empty((len(strain), points))
    ten = np.empty((len(strain), points))
    for k, (s, l, t) in enumerate(zip(strain, lateral, tension)):
        order = np.argsort(s, kind="stable")
        lat[k] = np.interp(grid, s[order], l[order])
        ten[k] = np.interp(grid, s[order], t[order])
    ddof = 1 if len(strain) > 1 else 0
    return grid, lat.mean(0), lat.std(0, ddof=ddof), ten.mean(0), ten.std(0, ddof=ddof)


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
                self._response(load, axial[g], lateral[g], tension[g], None, None, 1, f"{base}/{k}", prov)
                for k, g in zip(ids, groups)
            ]
        try:
            grid, lat, lat_sd, ten, ten_sd = average_repeats(
                [axial[g] for g in groups], [lateral[g] for g in groups], [tension[g] for g in groups], self.points
            )
        except ValueError as e:
            raise DataError(path, str(e)) from None
        return [self._response(load, grid, lat, ten, lat_sd, ten_sd, len(ids), base, prov)]

    @staticmethod
    def _response(load, axial, lateral, tension, lat_sd, ten_sd, n, label, prov) -> Response:
        zero = np.zeros_like(tension)
        if load == "uniaxial-course":
            return Response(1 + axial, 1 + lateral, tension, zero, load=load, label=label, n_samples=n,
                            T1_sd=ten_sd, lambda2_sd=lat_sd, provenance=prov)
        return Response(1 + lateral, 1 + axial, zero, tension, load=load, label=label, n_samples=n,
                        T2_sd=ten_sd, lambda1_sd=lat_sd, provenance=prov)


@hookimpl
def register_readers(register):
    register(Singal2024Reader)
