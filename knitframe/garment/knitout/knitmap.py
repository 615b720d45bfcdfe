"""The knit map: a tube of course bands and the stitches of every course, from a design or its folder."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError, DataError, FieldError

#: why a paper-mode design cannot be knitted
PAPER_MODE = (
    "machine output needs a knitting-mode tube (design.tube.mode = 'knitting'): a paper-mode tube is a "
    "cylinder of a given circumference with no needle count or courses to knit"
)
_COLUMNS = ("row", "course_start", "course_end", "fabric", "pattern", "yarn", "stitch_length")


# ---------------------------------------------------------------------------------------------- the knit map


@attrs.frozen
class Band:
    """Courses [start, end) of the tube knitted in one fabric."""

    start: int
    end: int
    fabric: str
    pattern: str
    yarn: str
    #: machine setting, or None when the fabric has none
    stitch_length: float | None = None

    @property
    def courses(self) -> int:
        return self.end - self.start


@attrs.frozen
class KnitMap:
    """A tube made of course bands, as a machine knits it: ``needles`` stitches cast on, and
    ``course_needles[c]`` stitches on course c (``needles`` on every course unless given; a shaped
    tube changes it by increases and decreases, see the package docstring)."""

    needles: int
    bands: tuple[Band, ...] = attrs.field(converter=tuple)
    source: str = ""
    course_needles: tuple[int, ...] = attrs.field(
        default=attrs.Factory(lambda self: (self.needles,) * self.bands[-1].end, takes_self=True),
        converter=lambda v: tuple(int(x) for x in v),
    )

    def __attrs_post_init__(self) -> None:
        problem = _course_needles_problem(self.course_needles, self.courses)
        if problem is None and self.course_needles[0] != self.needles:
            problem = f"starts at {self.course_needles[0]} stitches but the tube casts on {self.needles}"
        if problem:
            raise FieldError("tube.needles_per_course", problem)

    @property
    def courses(self) -> int:
        return self.bands[-1].end

    @property
    def shaped(self) -> bool:
        """Whether the stitches per course change along the tube."""
        return len(set(self.course_needles)) > 1

    @property
    def shaping_courses(self) -> list[int]:
        """The courses whose stitches differ from the course below's."""
        n = self.course_needles
        return [c for c in range(1, len(n)) if n[c] != n[c - 1]]

    @property
    def description(self) -> str:
        """The tube in words: its stitches and courses."""
        n = self.course_needles
        if not self.shaped:
            return f"a tube of {self.needles} stitches × {self.courses} courses"
        return (
            f"a tube of {min(n)}–{max(n)} stitches (cast on with {self.needles}, "
            f"{len(self.shaping_courses)} shaping courses) × {self.courses} courses"
        )

    @property
    def yarns(self) -> list[str]:
        """Yarns in the order the tube first uses them."""
        return list(dict.fromkeys(b.yarn for b in self.bands))

    @classmethod
    def from_design(cls, d: Any) -> KnitMap:
        """The knit map of a :class:`~knitframe.garment.core.Design` (the rows of ``knit-map.csv``)."""
        if d.tube.mode != "knitting" or not d.tube.needles:
            raise FieldError("tube", PAPER_MODE)
        per_course = getattr(d, "needles_per_course", None)
        first = np.concatenate([[0], np.cumsum(d.courses)]).astype(int)
        rows = []
        for i in range(d.fabric.shape[0]):
            used = [d.library.entries[int(f)] for f in dict.fromkeys(d.fabric[i].tolist())]
            rows.append(
                (
                    i,
                    int(first[i]),
                    int(first[i + 1]),
                    [(e.name, e.pattern, e.yarn, e.stitch_length) for e in used],
                )
            )
        bands = _bands(rows, "design")
        values = per_course() if callable(per_course) else per_course
        if values is None:
            return cls(int(d.tube.needles), bands, "design")
        return cls(int(d.tube.needles), bands, "design", _integers(values))

    @classmethod
    def read(cls, folder: str | Path, option: str = "DESIGN_DIR") -> KnitMap:
        """The knit map of a design folder: ``design.json`` (the tube) and ``knit-map.csv`` (the rows)."""
        folder = Path(folder)
        if not folder.is_dir():
            raise ConfigError(option, f"{folder}: not a folder; give the output folder of knitframe design")
        dj, km = folder / "design.json", folder / "knit-map.csv"
        for p in (dj, km):
            if not p.is_file():
                raise ConfigError(
                    option, f"{folder}: no {p.name}; give the output folder of knitframe design"
                )
        try:
            data = json.loads(dj.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError) as e:
            raise DataError(dj, f"not readable JSON ({e})") from None
        tube = data.get("tube") if isinstance(data, dict) else None
        if not isinstance(tube, dict):
            raise DataError(dj, "no 'tube' table; is this a knitframe design.json?")
        if tube.get("mode") != "knitting" or tube.get("needles") is None:
            raise DataError(dj, PAPER_MODE)
        needles = tube["needles"]
        if isinstance(needles, bool) or not isinstance(needles, int) or needles < 4:
            raise DataError(dj, f"tube.needles must be an integer >= 4, got {needles!r}")
        bands = _bands(_read_rows(km), str(km))
        total = tube.get("courses")
        if total is not None and total != bands[-1].end:
            raise DataError(dj, f"tube.courses is {total} but {km.name} ends at course {bands[-1].end}")
        per_course = tube.get("needles_per_course")
        if per_course is None:
            return cls(needles, bands, str(folder))
        try:
            return cls(needles, bands, str(folder), _integers(per_course))
        except (TypeError, ValueError, FieldError) as e:
            problem = e.problem if isinstance(e, FieldError) else "must be a list of integers, one per course"
            raise DataError(dj, f"tube.needles_per_course {problem}") from None


def _integers(values: Any) -> tuple[int, ...]:
    """A sequence of whole numbers as ints (ValueError or TypeError for anything else)."""
    out = []
    for v in list(values):
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise TypeError(v)
        if not float(v).is_integer():
            raise ValueError(v)
        out.append(int(v))
    return tuple(out)


def _course_needles_problem(values: tuple[int, ...], courses: int) -> str | None:
    """What is wrong with stitches per course for a tube of ``courses`` courses, or None."""
    if len(values) != courses:
        return f"has {len(values)} entries for {courses} courses"
    low = [(c, n) for c, n in enumerate(values) if n < 4]
    if low:
        return f"gives course {low[0][0]} {low[0][1]} stitches; a course needs at least 4"
    return None


def _read_rows(path: Path) -> list[tuple[int, int, int, list[tuple[str, str, str, float | None]]]]:
    """The element rows of a ``knit-map.csv``: (row, first course, end course, fabrics along the course)."""
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            absent = [c for c in _COLUMNS if c not in (reader.fieldnames or [])]
            if absent:
                raise DataError(path, f"missing column '{absent[0]}'; is this a knitframe knit-map.csv?")
            rows: dict[int, Any] = {}
            for line, rec in enumerate(reader, start=2):
                try:
                    i, c0, c1 = int(rec["row"]), int(rec["course_start"]), int(rec["course_end"])
                    sl = float(rec["stitch_length"]) if rec["stitch_length"].strip() else None
                except (TypeError, ValueError):
                    raise DataError(
                        path,
                        "row, course_start and course_end must be integers and stitch_length "
                        "a number or empty",
                        line=line,
                    ) from None
                if sl is not None and not (math.isfinite(sl) and sl > 0):
                    raise DataError(
                        path, f"stitch_length must be > 0, got {sl:g}", line=line, column="stitch_length"
                    )
                fabric = (rec["fabric"], rec["pattern"], rec["yarn"], sl)
                if not all(fabric[:3]):
                    raise DataError(path, "fabric, pattern and yarn must not be empty", line=line)
                if i in rows:
                    if rows[i][:2] != (c0, c1):
                        raise DataError(path, f"row {i} has two course ranges", line=line)
                    if fabric not in rows[i][2]:
                        rows[i][2].append(fabric)
                else:
                    rows[i] = (c0, c1, [fabric])
    except UnicodeDecodeError:
        raise DataError(path, "not UTF-8 text") from None
    except OSError as e:
        raise DataError(path, f"cannot read it: {e.strerror}") from None
    if not rows:
        raise DataError(path, "no rows")
    return [(i, *rows[i]) for i in sorted(rows)]


def _bands(rows: Sequence[tuple[int, int, int, list]], where: str) -> list[Band]:
    """Course bands from element rows, checking that rows follow one another and hold one fabric each."""
    bands: list[Band] = []
    expect = 0
    for i, c0, c1, fabrics in rows:
        if c0 != expect or c1 <= c0:
            raise DataError(
                where,
                f"row {i} covers courses {c0}-{c1}; rows must follow one another from course 0, "
                "each at least one course long",
            )
        if len(fabrics) > 1:
            names = ", ".join(f[0] for f in fabrics)
            raise FieldError(
                "pattern",
                f"row {i} (courses {c0}-{c1}) changes fabric along the course ({names}): "
                "that needs intarsia, which a tube knitted in the round cannot do; the "
                "machine output knits course bands (stripes), as the 'optimal' method designs",
            )
        name, pattern, yarn, sl = fabrics[0]
        if (
            bands
            and (bands[-1].fabric, bands[-1].pattern, bands[-1].yarn, bands[-1].stitch_length) == fabrics[0]
        ):
            bands[-1] = attrs.evolve(bands[-1], end=c1)
        else:
            bands.append(Band(c0, c1, name, pattern, yarn, sl))
        expect = c1
    return bands
