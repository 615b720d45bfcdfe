"""Reader ``generic``: a documented CSV format for uniaxial (free-sides) fabric tension tests.

Format. Optional ``#`` lines first; a ``# key = value`` line sets file-wide metadata. Then a header
row and one row per measured point::

    # direction = course          course | wale (x | y); or give a 'direction' column
    # thickness_mm = 0.9          needed only for stress_MPa
    sample,strain,transverse_strain,tension_N_per_mm
    1,0.00,0.000,0.000
    1,0.05,-0.012,0.011
    2,0.00,0.000,0.000
    ...

Columns (case-insensitive; exactly one from each "one of" group):

======================================  ============================================================
``strain`` or ``stretch``               loaded direction: engineering strain (stretch = 1 + strain)
``tension_N_per_mm`` or ``stress_MPa``  force per unit width; stress × thickness (mm) = tension;
or ``force_N``                          or the force, divided by the specimen width (mm)
``transverse_strain`` / ``..._stretch`` optional: measured lateral strain of the free side
``sample``                              optional repeat id: repeats are averaged to mean ± sd
``direction``                           optional: course | wale per row (else the ``#`` key)
``thickness_mm``                        optional per-row thickness (else the ``#`` key or option)
``width_mm``                            optional per-row specimen width (else the ``#`` key or option)
======================================  ============================================================

Units are checked, not assumed. A loaded strain beyond 5 (500 %) reads as percent and is divided
by 100, and so is a transverse strain that reaches 1 (100 %) or more; one warning names what was
divided and what was kept (:func:`knitframe.csvio.strains_as_fractions`). A tension beyond ``max_tension``
(20 N/mm; knits break at a few N/mm) reads as a force in N: divided by the width when one is given
(with a warning), refused otherwise. A curve with no positive tension, and a test whose strain
falls back by more than a tenth of its range (an unloading branch), are refused.

Each (direction) group becomes one Response (``uniaxial-course`` or ``uniaxial-wale``: the free
side carries no tension). Repeats are put on a common strain grid and averaged (mean ± sample
sd). Without a transverse column the free-side stretch is unknown: it is set to 1 and marked
``provenance.extra["transverse_measured"] = False``, so fitters do not score it.

Every problem is one DataError line naming the file, the line and the column: a missing file, an
empty file, a missing or ambiguous column, a non-number or NaN, a non-positive stretch, an
unknown direction, a stress without a thickness, a force without a width.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.csvio import (
    FORCE_TENSION,
    Table,
    check_loading,
    check_tension,
    read_table,
    strains_as_fractions,
    tension_per_width,
)
from knitframe.curves import average_repeats, uniaxial_response
from knitframe.errors import DataError
from knitframe.records import Provenance, Response

_DIRECTIONS = {
    "course": "uniaxial-course",
    "x": "uniaxial-course",
    "wale": "uniaxial-wale",
    "y": "uniaxial-wale",
}


def _metadata(comments: list[str]) -> dict[str, str]:
    """``key = value`` (or ``key: value``) pairs from the leading comment lines, keys lower-case."""
    out = {}
    for c in comments:
        m = re.match(r"^\s*([A-Za-z_][\w\-]*)\s*[=:]\s*(.+?)\s*$", c)
        if m:
            out[m.group(1).lower()] = m.group(2)
    return out


def _one_of(table: Table, names: tuple[str, ...], what: str, required: bool = True) -> str | None:
    found = [n for n in names if n in table]
    if len(found) > 1:
        raise DataError(
            table.path,
            f"give only one of the columns {', '.join(found)} for the {what}",
            line=_header_line(table),
        )
    if not found and required:
        raise DataError(
            table.path,
            f"missing column for the {what}: one of {', '.join(names)} "
            f"(header has {', '.join(table.header)})",
            line=_header_line(table),
        )
    return found[0] if found else None


def _header_line(table: Table) -> int:
    return table.lines[0] - 1 if table.lines else 1


def _stretch(table: Table, column: str, x: np.ndarray) -> np.ndarray:
    """A strain or stretch column's values ``x`` as stretch; a stretch <= 0 is a DataError at its cell."""
    lam = x if column.endswith("stretch") else 1.0 + x
    if np.any(lam <= 0):
        i = int(np.flatnonzero(lam <= 0)[0])
        raise DataError(
            table.path, f"{column} {x[i]} gives a non-positive stretch", line=table.lines[i], column=column
        )
    return lam


@attrs.frozen
class GenericReader:
    """Documented CSV: strain or stretch, course or wale, N/mm or MPa with a thickness; repeats → mean ±
    sd."""

    name: ClassVar[str] = "generic"
    description: ClassVar[str] = (
        "generic CSV: strain|stretch, course|wale, tension_N_per_mm|stress_MPa (+ thickness)"
        "|force_N (+ width)"
    )
    #: the header this reader expects, for the auto reader's message when no reader matches
    expects: ClassVar[str] = (
        "strain or stretch, and tension_N_per_mm, stress_MPa or force_N (optional: sample, "
        "direction, transverse_strain or transverse_stretch, thickness_mm, width_mm)"
    )

    #: one mean ± sd Response per direction; false gives one Response per sample
    average: bool = True
    #: grid size when averaging
    points: int = attrs.field(default=50, validator=v.in_range(2, 100000))
    #: default direction
    direction: str | None = attrs.field(default=None, validator=v.optional(v.one_of(tuple(_DIRECTIONS))))
    #: default thickness, mm
    thickness_mm: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: default specimen width, mm
    width_mm: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: N/mm; beyond it a tension reads as a force in N
    max_tension: float = attrs.field(default=FORCE_TENSION, validator=v.positive)

    @classmethod
    def accepts(cls, header: list[str]) -> bool:
        """True if ``header`` has a loaded strain (or stretch) column and a load column."""
        cols = {h.strip().lower() for h in header}
        return bool(cols & {"strain", "stretch"}) and bool(
            cols & {"tension_n_per_mm", "stress_mpa", "force_n"}
        )

    def read(self, path: Path) -> list[Response]:
        path = Path(path)
        table = read_table(path)
        table.header = [h.lower() for h in table.header]
        meta = _metadata(table.comments)
        axial_col = _one_of(table, ("strain", "stretch"), "loaded strain")
        load_col = _one_of(table, ("tension_n_per_mm", "stress_mpa", "force_n"), "load")
        lat_col = _one_of(
            table, ("transverse_strain", "transverse_stretch"), "transverse strain", required=False
        )
        strains = strains_as_fractions(table, {c: table[c] for c in (axial_col, lat_col) if c}, axial_col)
        lam = _stretch(table, axial_col, strains[axial_col])
        lat = _stretch(table, lat_col, strains[lat_col]) if lat_col else np.ones_like(lam)
        tension = table[load_col]
        if load_col == "stress_mpa":
            tension = tension * self._thickness(table, meta)
        elif load_col == "force_n":
            tension = tension / self._positive(
                table,
                meta,
                "width_mm",
                self.width_mm,
                "force_N needs the specimen width: add a '# width_mm = ...' line or a width_mm column",
            )
        else:
            width = self._positive(table, meta, "width_mm", self.width_mm, None)
            tension = tension_per_width(
                table,
                load_col,
                tension,
                width,
                "give the specimen width ('# width_mm = ...' line or width_mm column) to "
                "convert it, or name the column force_N",
                limit=self.max_tension,
            )
        loads = self._directions(table, meta)
        samples = table.text("sample") if "sample" in table else ["1"] * len(table)
        check_loading(
            table,
            axial_col,
            lam,
            [
                np.array([ld == load and s == k for ld, s in zip(loads, samples)])
                for load, k in dict.fromkeys(zip(loads, samples))
            ],
        )
        out = []
        for load in dict.fromkeys(loads):
            rows = np.array([ld == load for ld in loads])
            check_tension(table, load_col, tension, rows, load.split("-")[1] if len(set(loads)) > 1 else "")
            out += self._responses(
                path,
                load,
                lam[rows],
                lat[rows],
                tension[rows],
                [s for s, r in zip(samples, rows) if r],
                lat_col is not None,
                {"warnings": list(table.warnings)} if table.warnings else {},
            )
        return out

    def _thickness(self, table: Table, meta: dict[str, str]) -> np.ndarray | float:
        return self._positive(
            table,
            meta,
            "thickness_mm",
            self.thickness_mm,
            "stress_MPa needs a thickness: add a '# thickness_mm = ...' line or a thickness_mm column",
            column="stress_mpa",
        )

    @staticmethod
    def _positive(
        table: Table,
        meta: dict[str, str],
        key: str,
        default: float | None,
        missing: str | None,
        column: str | None = None,
    ) -> np.ndarray | float | None:
        """A length in mm from the ``key`` column, the ``# key = ...`` line or the option, in that order.

        Values must be > 0. Without any of them: a DataError saying ``missing``, or None if that is None.
        """
        if key in table:
            t = table[key]
            if np.any(t <= 0):
                i = int(np.flatnonzero(t <= 0)[0])
                raise DataError(
                    table.path,
                    f"{key.split('_')[0]} must be > 0, got {t[i]}",
                    line=table.lines[i],
                    column=key,
                )
            return t
        if key in meta:
            try:
                t = float(meta[key])
            except ValueError:
                t = float("nan")
            if not (t > 0 and math.isfinite(t)):
                raise DataError(table.path, f"'# {key}' must be a number > 0, got {meta[key]!r}")
            return t
        if default is not None or missing is None:
            return default
        raise DataError(table.path, missing, column=column or _load_column(table))

    def _directions(self, table: Table, meta: dict[str, str]) -> list[str]:
        if "direction" in table:
            cells = [c.strip().lower() for c in table.text("direction")]
            for i, c in enumerate(cells):
                if c not in _DIRECTIONS:
                    raise DataError(
                        table.path,
                        f"direction must be course or wale (x or y), got {c!r}",
                        line=table.lines[i],
                        column="direction",
                    )
            return [_DIRECTIONS[c] for c in cells]
        d = meta.get("direction", self.direction)
        if d is None:
            raise DataError(
                table.path,
                "cannot tell the direction: add a '# direction = course|wale' line or a direction column",
            )
        if d.strip().lower() not in _DIRECTIONS:
            raise DataError(table.path, f"'# direction' must be course or wale (x or y), got {d!r}")
        return [_DIRECTIONS[d.strip().lower()]] * len(table)

    def _responses(self, path, load, lam, lat, tension, samples, measured, notes) -> list[Response]:
        ids = list(dict.fromkeys(samples))
        groups = [np.array([s == k for s in samples]) for k in ids]
        prov = Provenance(
            kind="experiment", source=path.name, extra={"transverse_measured": measured, **notes}
        )
        d = 0 if load == "uniaxial-course" else 1
        base = f"{path.stem}-{('course', 'wale')[d]}"
        if not self.average:
            return [
                _response(d, lam[g], lat[g], tension[g], None, None, 1, f"{base}/{k}", load, prov)
                for k, g in zip(ids, groups)
            ]
        if len(ids) == 1:  # nothing to average: keep the measured points, sorted by strain
            o = np.argsort(lam, kind="stable")
            return [_response(d, lam[o], lat[o], tension[o], None, None, 1, base, load, prov)]
        try:
            grid, lat_m, lat_sd, ten_m, ten_sd = average_repeats(
                [lam[g] - 1 for g in groups],
                [lat[g] - 1 for g in groups],
                [tension[g] for g in groups],
                self.points,
            )
        except ValueError as e:
            raise DataError(path, f"{('course', 'wale')[d]} samples: {e}") from None
        return [
            _response(
                d,
                1 + grid,
                1 + lat_m,
                ten_m,
                lat_sd if measured else None,
                ten_sd,
                len(ids),
                base,
                load,
                prov,
            )
        ]


def _load_column(table: Table) -> str | None:
    return next((c for c in ("force_n", "stress_mpa") if c in table), None)


def _response(d, lam, lat, tension, lat_sd, ten_sd, n, label, load, prov) -> Response:
    """The same Response layout as the Singal et al. reader (loaded side measured, free side T = 0)."""
    return uniaxial_response(load, lam - 1.0, lat - 1.0, tension, lat_sd, ten_sd, n, label, prov)


@hookimpl
def register_readers(register):
    register(GenericReader)
