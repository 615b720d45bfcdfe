r"""Machine output for a designed sleeve: a knitout program for a V-bed machine, its stitch chart and a DAT file.

A knitting-mode design (:class:`~knitframe.garment.core.Design`, or its ``design.json`` and
``knit-map.csv``) is a tube of N stitches per course whose regions are course bands (stripes), each
knitted in one fabric: a pattern, a yarn and a stitch length. :class:`KnitMap` holds exactly that;
:func:`plan` resolves the machine settings of every band (:class:`MachineSpec`: carrier, stitch
number) and refuses, in one line, what the machine cannot knit; :func:`knitout_lines` writes the
`knitout <https://textiles-lab.github.io/knitout/knitout.html>`_ program, :func:`plot_chart` its
stitch chart, :func:`verify` runs it through ``knitout-interpreter`` (a simulated Shima SWG091N2) and
checks the knit graph it makes, and :func:`write_dat` converts it to a Shima DAT file through
``knitout-to-dat-python``.

Conventions
-----------
**Needles (half gauge).** The tube is knitted in the round on both beds at half gauge. Needle
positions p = 0 … N−1 (knitout needle ``FIRST_NEEDLE + p``) hold one stitch each, alternately of
the two layers, the rightmost of the front layer (:func:`front_layer`):

- p = N−1, N−3, …: the tube's front layer (⌈N/2⌉ stitches), at home on the front bed;
- p = N−2, N−4, …: the back layer (⌊N/2⌋ stitches), at home on the back bed.

A carrier brought in starts on the rightmost stitch, so the yarn-inserting hook, parked just right
of it until ``releasehook``, blocks no needle of the tube. The needle opposite every stitch is
empty, so any stitch can be turned into a purl by moving its loop across (``xfer`` at rack 0) and
knitting it on the other bed; that is how rib, garter and seed are knitted in a tube. A tube of N
stitches takes N needles of each bed (``width`` ≥ N). The fabric's gauge is half the machine's.

**Courses.** One course is one round: the front layer leftward (``knit -``, from the right), then the
back layer rightward (``knit +``), a spiral with the yarn passing from the front to the back at the
left edge and from the back to the front at the right edge. Before a course, the loops whose bed
changes are transferred (front to back first, then back to front).

**Wales and patterns.** Around the tube, wale w runs along the front layer from its left edge
(w = j for its j-th stitch from the left) and back along the back layer (w = N − 1 − k for its
k-th). Seen from outside, a stitch is plain (knit on its home bed) or reverse (purl, knit on the
other bed). Course c counts from the start of its band:

=========  ========================  =========================================
pattern    reverse stitches           needs
=========  ========================  =========================================
jersey     none                       nothing
rib        odd wales (1×1)            purls on the opposite bed (no transfers)
garter     odd courses                a transfer of every loop between courses
seed       odd w + c                  a transfer of every loop between courses
=========  ========================  =========================================

With an odd N, the rib and seed meet themselves out of step once around the tube (two plain or two
reverse wales side by side at its left edge, w = N − 1 next to w = 0). Any other pattern is refused,
and so is a course that changes fabric along its length: intarsia cannot be knitted in the round.

**Carriers.** One carrier per yarn: ``carriers`` maps yarn → carrier number, and yarns it does not
name take the lowest free carriers in the order the tube first uses them. A stripe changes carrier
between courses. A carrier brought in uses the yarn-inserting hook (``inhook``, released with
``releasehook`` after its first course); a yarn that is not used again within
:data:`CARRY_COURSES` courses is cut (``outhook``) after its last course, otherwise it is carried up
inside the tube. The SWG091N2 has 10 carriers; more yarns are refused.

**Stitch numbers.** ``x-stitch-number N`` (an index, 1–120, into the machine's stitch table) is set
for each band from its fabric's stitch length through a table keyed by the machine setting (``"11"``)
with a ``"default"`` for fabrics without one: :data:`DEFAULT_STITCH_NUMBERS`, overridden key by key
by the user's table. The numbers are indices into the stitch table set up on your machine; calibrate
them there.

**Cast-on and bind-off.** The first band's carrier casts on with alternating tucks (every other
stitch of the front layer leftward, of the back layer rightward, then the others), each on the bed
its first course needs. The last band's carrier binds off in a chain around the tube: every loop is
knitted, then moved onto the next stitch's needle (through the empty needle opposite and at rack −2
along a layer; directly at rack ±1 from the front layer's left stitch to the back layer's) and
knitted with it. The last loop is knitted :data:`TAIL` more times, the yarn is cut and the loop
dropped.

**Checking and DAT.** :func:`verify` runs :func:`interpreter_text` of the program: knitout-interpreter
0.1's grammar has neither the ``;;Width:`` header nor ``x-`` extensions, so exactly those lines
become comments (line numbers kept). It fails on any error, machine-state violation or warning
(a knit on an empty needle, a dropped loop, a long float …) and checks the knit graph: the
cast-on's N loops, then each course of the map with N loops, each band in its carrier, and no loop
left on the needles. knitout-to-dat-python 0.0.4 imports names that knitout-interpreter moved after
0.1.2 (``knitframe[dat]`` pins that set) and ignores ``x-stitch-number``; :func:`write_dat` gives its
passes the stitch numbers itself.

Units: mm (stitch lengths are machine settings, as in the fabric library).
"""

from __future__ import annotations

import csv
import importlib.util
import json
import math
import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError, DataError, FieldError, KnitframeError

__all__ = [
    "Band",
    "KnitMap",
    "MachineSpec",
    "Plan",
    "MachineOutputError",
    "plan",
    "purl_mask",
    "knitout_lines",
    "interpreter_text",
    "verify",
    "write_dat",
    "plot_chart",
    "write_machine_outputs",
    "missing",
    "stitch_numbers_by_line",
    "MACHINES",
    "PAPER_MODE",
    "DEFAULT_STITCH_NUMBERS",
    "PATTERNS",
    "FILES",
]

#: machine model -> needles per bed and yarn carriers, as knitout-interpreter and the DAT writer model it
MACHINES: dict[str, dict[str, int]] = {"SWG091N2": {"width": 540, "carriers": 10}}
DEFAULT_MACHINE = "SWG091N2"
DEFAULT_GAUGE = 15
#: machine setting (stitch length) -> x-stitch-number; "default" for fabrics without a stitch length
DEFAULT_STITCH_NUMBERS: dict[str, int] = {"10": 4, "11": 5, "12": 6, "default": 5}
#: the range of x-stitch-number on Shima SWG N2 machines (an index into the machine's stitch table)
STITCH_NUMBER_RANGE = (1, 120)
#: patterns the writer knits in a tube (see the module docstring)
PATTERNS = ("jersey", "rib", "garter", "seed")
#: a yarn unused for more courses than this is cut and brought in again rather than carried up the tube
CARRY_COURSES = 6
#: knitout needle number of position 0
FIRST_NEEDLE = 1
#: extra knits on the last loop of the bind-off, a chain tail that keeps it from unravelling
TAIL = 4
#: the ;;Position: header: the tube is centred on the bed
POSITION = "Center"
#: output file names
FILES = {"knitout": "sleeve.k", "chart": "sleeve-chart.png", "dat": "sleeve.dat"}
#: what to install for machine output
INSTALL = "pip install 'knitframe[machine]'"
#: what to install for a DAT file: knitout-to-dat-python 0.0.4 with the interpreter release it imports
INSTALL_DAT = "pip install 'knitframe[dat]'"


class MachineOutputError(KnitframeError):
    """A program knitframe wrote failed the interpreter's check: a knitframe bug, not bad input."""

    exit_code = 3


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
    """A tube of ``needles`` stitches per course made of course bands, as a machine knits it."""

    needles: int
    bands: tuple[Band, ...] = attrs.field(converter=tuple)
    source: str = ""

    @property
    def courses(self) -> int:
        return self.bands[-1].end

    @property
    def yarns(self) -> list[str]:
        """Yarns in the order the tube first uses them."""
        return list(dict.fromkeys(b.yarn for b in self.bands))

    @classmethod
    def from_design(cls, d: Any) -> KnitMap:
        """The knit map of a :class:`~knitframe.garment.core.Design` (the rows of ``knit-map.csv``)."""
        if d.tube.mode != "knitting" or not d.tube.needles:
            raise FieldError("tube", PAPER_MODE)
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
        return cls(int(d.tube.needles), _bands(rows, "design"), "design")

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
        rows = _read_rows(km)
        kmap = cls(needles, _bands(rows, str(km)), str(folder))
        total = tube.get("courses")
        if total is not None and total != kmap.courses:
            raise DataError(dj, f"tube.courses is {total} but {km.name} ends at course {kmap.courses}")
        return kmap


#: why a paper-mode design cannot be knitted
PAPER_MODE = (
    "machine output needs a knitting-mode tube (design.tube.mode = 'knitting'): a paper-mode tube is a "
    "cylinder of a given circumference with no needle count or courses to knit"
)
_COLUMNS = ("row", "course_start", "course_end", "fabric", "pattern", "yarn", "stitch_length")


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


# ---------------------------------------------------------------------------------------------- machine settings


def _setting_key(key: str) -> str:
    """A stitch-number table key as written: "default", or a machine setting printed with :g ("11")."""
    if key == "default":
        return key
    try:
        value = float(key)
    except ValueError:
        raise FieldError(
            "stitch_numbers", f'key {key!r} must be a stitch length (machine setting, e.g. "11") or "default"'
        ) from None
    if not (math.isfinite(value) and value > 0):
        raise FieldError("stitch_numbers", f"key {key!r} must be a stitch length > 0")
    return f"{value:g}"


@attrs.frozen
class MachineSpec:
    """The machine a sleeve is knitted on, and how the design's yarns and stitch lengths map onto it.

    Attributes
    ----------
    machine : str
        The knitout ``;;Machine:`` (only models in :data:`MACHINES`).
    gauge : int
        Needles per inch of the machine (``;;Gauge:``); the tube is knitted at half of it.
    width : int, optional
        Needles per bed the program may use (``;;Width:``; default: the machine's bed).
    carriers : dict
        Yarn -> carrier number (1 … the machine's carriers); unnamed yarns take the lowest free ones.
    stitch_numbers : dict
        Stitch length (machine setting, as a string) or "default" -> x-stitch-number; overrides
        :data:`DEFAULT_STITCH_NUMBERS` key by key.
    dat : bool
        Also write a Shima DAT file.
    """

    machine: str = DEFAULT_MACHINE
    gauge: int = DEFAULT_GAUGE
    width: int | None = None
    carriers: dict[str, int] = attrs.Factory(dict)
    stitch_numbers: dict[str, int] = attrs.Factory(dict)
    dat: bool = False

    def __attrs_post_init__(self) -> None:
        if self.machine not in MACHINES:
            raise FieldError(
                "machine",
                f"must be one of {', '.join(MACHINES)} (the model knitout-interpreter "
                f"checks), got {self.machine!r}",
            )
        if isinstance(self.gauge, bool) or not isinstance(self.gauge, int) or not 1 <= self.gauge <= 30:
            raise FieldError("gauge", f"must be an integer in [1, 30] (needles per inch), got {self.gauge!r}")
        bed = MACHINES[self.machine]["width"]
        if self.width is not None and (
            isinstance(self.width, bool) or not isinstance(self.width, int) or not 4 <= self.width <= bed
        ):
            raise FieldError(
                "width",
                f"must be an integer in [4, {bed}] (needles per bed of the {self.machine}), "
                f"got {self.width!r}",
            )
        n = self.carrier_count
        seen: dict[int, str] = {}
        for yarn, c in self.carriers.items():
            if isinstance(c, bool) or not isinstance(c, int) or not 1 <= c <= n:
                raise FieldError(f"carriers.{yarn}", f"must be a carrier number in [1, {n}], got {c!r}")
            if c in seen:
                raise FieldError(f"carriers.{yarn}", f"carrier {c} is also given to yarn '{seen[c]}'")
            seen[c] = yarn
        lo, hi = STITCH_NUMBER_RANGE
        keys: dict[str, str] = {}
        for key, value in self.stitch_numbers.items():
            k = _setting_key(str(key))
            if k in keys:
                raise FieldError("stitch_numbers", f"keys {keys[k]!r} and {key!r} are the same stitch length")
            keys[k] = str(key)
            if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
                raise FieldError(
                    f"stitch_numbers.{key}",
                    f"must be an integer in [{lo}, {hi}] (an index into the "
                    f"machine's stitch table), got {value!r}",
                )

    @property
    def bed_width(self) -> int:
        return self.width if self.width is not None else MACHINES[self.machine]["width"]

    @property
    def carrier_count(self) -> int:
        return MACHINES[self.machine]["carriers"]

    @property
    def stitch_table(self) -> dict[str, int]:
        """The stitch-number table in use: the defaults overridden by the user's entries."""
        return {**DEFAULT_STITCH_NUMBERS, **{_setting_key(str(k)): v for k, v in self.stitch_numbers.items()}}

    def stitch_number(self, stitch_length: float | None, fabric: str) -> int:
        """The x-stitch-number of a fabric's stitch length (None: the table's "default")."""
        table = self.stitch_table
        key = "default" if stitch_length is None else f"{float(stitch_length):g}"
        if key not in table:
            what = "has no stitch length" if stitch_length is None else f"has stitch length {key}"
            raise FieldError(
                "stitch_numbers",
                f"fabric '{fabric}' {what}, which the stitch-number table does not "
                f'hold (keys {", ".join(table)}); add "{key}" = N',
            )
        return table[key]


@attrs.frozen
class Plan:
    """A knit map with every band's machine settings resolved: what the program is written from."""

    kmap: KnitMap
    spec: MachineSpec
    #: yarn -> carrier
    carriers: dict[str, int]
    #: per band
    stitch_numbers: tuple[int, ...]

    @property
    def band_carriers(self) -> list[int]:
        return [self.carriers[b.yarn] for b in self.kmap.bands]


def check_patterns(patterns: Sequence[str]) -> None:
    """Refuse, in one line, a pattern the writer cannot knit in a tube."""
    bad = [p for p in dict.fromkeys(patterns) if p not in PATTERNS]
    if bad:
        raise FieldError(
            "pattern",
            f"pattern '{bad[0]}' cannot be knitted by the machine output (it knits "
            f"{', '.join(PATTERNS)} in a tube at half gauge); leave it out of the library",
        )


def plan(kmap: KnitMap, spec: MachineSpec) -> Plan:
    """Resolve carriers and stitch numbers and check that the machine can knit the map.

    Raises :class:`~knitframe.errors.FieldError` naming ``pattern``, ``width``, ``carriers`` or
    ``stitch_numbers`` with a one-line reason: a pattern other than :data:`PATTERNS`, a tube wider
    than the bed, more yarns than carriers, a stitch length the table does not hold.
    """
    check_patterns([b.pattern for b in kmap.bands])
    if kmap.needles > spec.bed_width:
        raise FieldError(
            "width",
            f"the tube needs {kmap.needles} needles per bed (half gauge: one per stitch of "
            f"the course) but the machine width is {spec.bed_width}",
        )
    yarns = kmap.yarns
    n = spec.carrier_count
    if len(yarns) > n:
        raise FieldError(
            "carriers",
            f"the design uses {len(yarns)} yarns ({', '.join(yarns)}) but the "
            f"{spec.machine} has {n} carriers: one carrier per yarn",
        )
    unknown = [y for y in spec.carriers if y not in yarns]
    if unknown:
        raise FieldError(
            f"carriers.{unknown[0]}", f"the design has no yarn '{unknown[0]}'; it uses {', '.join(yarns)}"
        )
    carriers = {y: spec.carriers[y] for y in yarns if y in spec.carriers}
    free = iter(c for c in range(1, n + 1) if c not in carriers.values())
    for y in yarns:
        if y not in carriers:
            carriers[y] = next(free)
    numbers = tuple(spec.stitch_number(b.stitch_length, b.fabric) for b in kmap.bands)
    return Plan(kmap, spec, {y: carriers[y] for y in yarns}, numbers)


# ---------------------------------------------------------------------------------------------- the program


def front_layer(needles: int) -> np.ndarray:
    """(N,) True at the needle positions of the tube's front layer: N−1, N−3, … (the rightmost is front)."""
    return (needles - 1 - np.arange(needles)) % 2 == 0


def wales(needles: int) -> np.ndarray:
    """(N,) wale index around the tube of each needle position (see the module docstring)."""
    p = np.arange(needles)
    j = p // 2  # rank from the left within the position's layer
    return np.where(front_layer(needles), j, needles - 1 - j)


def purl_mask(pattern: str, courses: int, needles: int) -> np.ndarray:
    """(courses, needles) True where a stitch is reverse (purl) seen from outside the tube.

    Course 0 is the band's first; columns are needle positions (:func:`front_layer`)
    """
    c = np.arange(courses)[:, None]
    w = wales(needles)[None, :]
    if pattern == "jersey":
        return np.zeros((courses, needles), dtype=bool)
    if pattern == "rib":
        return np.broadcast_to(w % 2 == 1, (courses, needles)).copy()
    if pattern == "garter":
        return np.broadcast_to(c % 2 == 1, (courses, needles)).copy()
    if pattern == "seed":
        return (w + c) % 2 == 1
    check_patterns([pattern])
    raise AssertionError(pattern)  # pragma: no cover


def front_bed(p: Plan) -> np.ndarray:
    """(C, N) True where the loop of course c at needle position n is knitted on the front bed."""
    N = p.kmap.needles
    home = front_layer(N)
    return np.concatenate([home[None, :] ^ purl_mask(b.pattern, b.courses, N) for b in p.kmap.bands])


def _needle(bed_front: bool, pos: int) -> str:
    return f"{'f' if bed_front else 'b'}{FIRST_NEEDLE + pos}"


def knitout_lines(p: Plan) -> list[str]:
    """The knitout program of a plan, one instruction per line (see the module docstring)."""
    km, spec = p.kmap, p.spec
    N = km.needles
    front = front_bed(p)
    layer = front_layer(N)
    front_order = [int(q) for q in np.flatnonzero(layer)[::-1]]  # front layer, leftward from the right edge
    back_order = [int(q) for q in np.flatnonzero(~layer)]  # back layer, rightward from the left edge
    carriers = p.band_carriers
    band_of = np.repeat(np.arange(len(km.bands)), [b.courses for b in km.bands])
    out = [
        ";!knitout-2",
        f";;Machine: {spec.machine}",
        f";;Gauge: {spec.gauge}",
        f";;Width: {spec.bed_width}",
        ";;Carriers: " + " ".join(str(c) for c in range(1, spec.carrier_count + 1)),
        f";;Position: {POSITION}",
        f"; knitframe sleeve: a tube of {N} stitches per course, {km.courses} courses, {len(km.bands)} bands",
        f"; half gauge: needle {FIRST_NEEDLE}+p holds stitch p; p = N-1, N-3, ... front layer (home f), the "
        "others back layer (home b); a course is the front layer leftward then the back layer rightward",
    ]
    for yarn, c in p.carriers.items():
        out.append(f"; carrier {c}: yarn {yarn}")
    for k, b in enumerate(km.bands):
        out.append(
            f"; band {k}: courses {b.start}-{b.end}, {b.fabric} ({b.pattern}, {b.yarn}, stitch length "
            f"{'-' if b.stitch_length is None else f'{b.stitch_length:g}'}), carrier {carriers[k]}, "
            f"x-stitch-number {p.stitch_numbers[k]}"
        )
    # the next course (from the start) at which each carrier is used, to decide between carrying and cutting
    uses: dict[int, list[int]] = {}
    for k, b in enumerate(km.bands):
        uses.setdefault(carriers[k], []).append(k)

    def next_use(c: int, after_band: int) -> int | None:
        later = [km.bands[k].start for k in uses[c] if k > after_band]
        return later[0] if later else None

    active: set[int] = set()
    c0 = carriers[0]
    out += [
        "; cast-on: alternating tucks around the tube",
        f"x-stitch-number {p.stitch_numbers[0]}",
        f"inhook {c0}",
    ]
    for half in (0, 1):
        out += [f"tuck - {_needle(front[0, q], q)} {c0}" for i, q in enumerate(front_order) if i % 2 == half]
        out += [f"tuck + {_needle(front[0, q], q)} {c0}" for i, q in enumerate(back_order) if i % 2 == half]
    out.append(f"releasehook {c0}")
    active.add(c0)
    stitch = p.stitch_numbers[0]
    beds = front[0].copy()
    hooked = None
    for course in range(km.courses):
        k = int(band_of[course])
        b = km.bands[k]
        c = carriers[k]
        if course == b.start:
            out.append(f"; band {k}: {b.fabric}, carrier {c}")
            prev = carriers[k - 1] if k else None
            if prev is not None and prev != c:
                nu = next_use(prev, k - 1)
                if nu is None or nu - course > CARRY_COURSES:
                    out.append(f"outhook {prev}")
                    active.discard(prev)
            if c not in active:
                out.append(f"inhook {c}")
                active.add(c)
                hooked = c
        want = front[course]
        move = np.flatnonzero(beds != want)
        out += [f"xfer {_needle(True, q)} {_needle(False, q)}" for q in move if beds[q]]
        out += [f"xfer {_needle(False, q)} {_needle(True, q)}" for q in move if not beds[q]]
        beds = want
        if p.stitch_numbers[k] != stitch:
            stitch = p.stitch_numbers[k]
            out.append(f"x-stitch-number {stitch}")
        out += [f"knit - {_needle(want[q], q)} {c}" for q in front_order]
        out += [f"knit + {_needle(want[q], q)} {c}" for q in back_order]
        if hooked is not None:
            out.append(f"releasehook {hooked}")
            hooked = None
    return out + _bind_off(beds, N, carriers[-1], front_order, back_order)


def _bind_off(beds: np.ndarray, N: int, c: int, front: list[int], back: list[int]) -> list[str]:
    """Bring every loop home, then a chain bind-off around the tube with a tail on the last loop.

    ``front`` lists the front layer's positions right to left, ``back`` the back layer's left to right.
    """
    out = ["; bind-off: a chain around the tube"]
    out += [f"xfer {_needle(False, q)} {_needle(True, q)}" for q in front if not beds[q]]
    out += [f"xfer {_needle(True, q)} {_needle(False, q)}" for q in back if beds[q]]
    order = [(q, True) for q in front] + [(q, False) for q in back]
    out.append(f"knit - {_needle(True, front[0])} {c}")
    for (a, fa), (b, fb) in zip(order[:-1], order[1:]):
        d = "-" if fb else "+"
        if fa == fb:  # along a layer: through the empty needle opposite, then racked onto the next stitch
            out += [
                f"xfer {_needle(fa, a)} {_needle(not fa, a)}",
                f"rack {b - a if fa else a - b}",
                f"xfer {_needle(not fa, a)} {_needle(fb, b)}",
                "rack 0",
                f"knit {d} {_needle(fb, b)} {c}",
            ]
        else:  # from the front layer's left edge to the back layer's, one position across
            out += [
                f"rack {a - b}",
                f"xfer {_needle(True, a)} {_needle(False, b)}",
                "rack 0",
                f"knit {d} {_needle(False, b)} {c}",
            ]
    q, fq = order[-1]
    last = _needle(fq, q)
    direction = "-" if fq else "+"
    for _ in range(TAIL):
        direction = "-" if direction == "+" else "+"
        out.append(f"knit {direction} {last} {c}")
    out += [f"outhook {c}", f"drop {last}"]
    return out


# ---------------------------------------------------------------------------------------------- checking


def interpreter_text(lines: Sequence[str]) -> str:
    """The program as knitout-interpreter 0.1 reads it: the ``;;Width:`` header and ``x-`` extension lines
    turned into comments (its grammar has neither), every other line and every line number unchanged."""
    return "".join(("; " + s if s.startswith((";;Width:", "x-")) else s) + "\n" for s in lines)


def missing(check: bool = True, dat: bool = False) -> str | None:
    """Why machine output cannot run here (one line: what to install), or None.

    ``check`` needs knitout-interpreter; ``dat`` needs a knitout-to-dat-python that imports with the
    installed interpreter (0.0.4 works with knitout-interpreter 0.1.2 only: ``knitframe[dat]``).
    """
    if check and importlib.util.find_spec("knitout_interpreter") is None:
        return f"checking the program needs knitout-interpreter: {INSTALL}"
    if dat:
        if importlib.util.find_spec("knitout_to_dat_python") is None:
            return f"a DAT file needs knitout-to-dat-python: {INSTALL_DAT}"
        try:
            import knitout_to_dat_python.dat_file_structure.knitout_to_dat_converter  # noqa: F401
        except Exception as e:  # an interpreter too new for it: the names it imports have moved
            why = " ".join(str(e).split(" (")[0].split())  # without the installed file's location
            return (
                f"knitout-to-dat-python {_version('knitout-to-dat-python')} does not work with knitout-interpreter "
                f"{_version('knitout-interpreter')} ({type(e).__name__}: {why}); it works with knitout-interpreter "
                f"0.1.2: {INSTALL_DAT}"
            )
    return None


def _version(dist: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(dist)
    except PackageNotFoundError:
        return "(not installed)"


def run_interpreter(lines: Sequence[str]) -> tuple[Any, Any, Any, list[str]]:
    """Execute the program with knitout-interpreter (full validation).

    Returns the executed program, the machine state, the knit graph and the warnings of the
    interpreter and its machine model (each one line). Errors and machine-state violations raise
    :class:`MachineOutputError`.
    """
    from knitout_interpreter.run_knitout import run_knitout

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / FILES["knitout"]
        path.write_text(interpreter_text(lines), encoding="utf-8")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                program, machine, graph = run_knitout(str(path))
            except Exception as e:  # the interpreter's parse errors, violations and machine-state errors
                text = " ".join(str(e).split())
                raise MachineOutputError(
                    f"the knitout program failed knitout-interpreter: {type(e).__name__}: "
                    f"{text}; this is a knitframe bug, please report it"
                ) from None
    ours = (
        "knitout_interpreter",
        "virtual_knitting_machine",
        "knit_graphs",
    )  # not, e.g., a dependency's deprecation
    return (
        program,
        machine,
        graph,
        [" ".join(str(w.message).split()) for w in caught if w.category.__module__.split(".")[0] in ours],
    )


def verify(p: Plan, lines: Sequence[str]) -> dict[str, Any]:
    """Run the program through knitout-interpreter and check the knit graph it makes against the knit map.

    The checks: no error, violation or warning; the graph's courses are the cast-on, then exactly
    the map's courses with N loops each (then the bind-off); every loop of a band's courses is made
    by that band's carrier; the machine ends with no loop on any needle. Returns what was checked.
    """
    program, machine, graph, warned = run_interpreter(lines)
    if warned:
        raise MachineOutputError(
            f"knitout-interpreter warned: {warned[0]}; this is a knitframe bug, please report it"
        )
    km = p.kmap
    N = km.needles
    courses = graph.get_courses()
    sizes = [len(c) for c in courses]
    body = courses[1 : 1 + km.courses]
    problems = []
    if sizes[0] != N:
        problems.append(f"the cast-on made {sizes[0]} loops, not {N}")
    if len(body) != km.courses or any(len(c) != N for c in body):
        problems.append(
            f"the knit graph has {len(body)} courses after the cast-on, of {min(sizes[1:] or [0])} to "
            f"{max(sizes[1:] or [0])} loops, not {km.courses} of {N}"
        )
    carriers = p.band_carriers
    for k, b in enumerate(km.bands):
        got = {loop.yarn.carrier.carrier_id for course in body[b.start : b.end] for loop in course}
        if got != {carriers[k]}:
            problems.append(f"band {k} ({b.fabric}) is knitted by carriers {sorted(got)}, not {carriers[k]}")
            break
    held = [n for bed in (machine.front_bed, machine.back_bed) for n in bed if n.has_loops]
    if held:
        problems.append(f"{len(held)} needles still hold loops at the end")
    if problems:
        raise MachineOutputError(
            "the knitout program does not knit the design: "
            + "; ".join(problems)
            + "; this is a knitframe bug, please report it"
        )
    return {
        "interpreter": f"knitout-interpreter {_version('knitout-interpreter')}",
        "lines": len(lines),
        "errors": 0,
        "warnings": 0,
        "courses": km.courses,
        "stitches_per_course": N,
        "cast_on_loops": sizes[0],
        "bind_off_courses": len(courses) - 1 - km.courses,
        "loops": int(sum(sizes)),
        "band_carriers": carriers,
    }


def stitch_numbers_by_line(lines: Sequence[str]) -> list[int | None]:
    """The x-stitch-number in force at each line of a program (None before the first)."""
    out: list[int | None] = []
    current = None
    for s in lines:
        if s.startswith("x-stitch-number "):
            current = int(s.split()[1])
        out.append(current)
    return out


def write_dat(lines: Sequence[str], path: str | Path) -> list[tuple[int, int]]:
    """Convert the program to a Shima DAT file with knitout-to-dat-python, carrying the stitch numbers.

    knitout-to-dat-python 0.0.4 reads neither ``;;Width:`` nor ``x-stitch-number`` (every pass gets
    its default stitch number 5), so each knitting and transfer pass it makes is given the
    x-stitch-number in force at its first instruction in the program. Returns (program line,
    stitch number) of every such pass, in order.
    """
    import contextlib
    import io

    from knitout_interpreter.knitout_execution_structures.Carriage_Pass import Carriage_Pass
    from knitout_to_dat_python.dat_file_structure.knitout_to_dat_converter import Knitout_to_Dat_Converter

    numbers = stitch_numbers_by_line(lines)
    applied: list[tuple[int, int]] = []

    class Converter(Knitout_to_Dat_Converter):
        def _get_pattern_rasters(self):
            passes = super()._get_pattern_rasters()
            for rp in passes:
                cp = getattr(rp, "carriage_pass", None)
                if type(rp).__name__ != "Raster_Carriage_Pass" or not isinstance(cp, Carriage_Pass):
                    continue  # hook and soft-miss passes keep the writer's settings
                line = next(iter(cp)).original_line_number  # 1-based, as the parser counts
                if line is None or numbers[line - 1] is None:
                    continue
                rp.stitch_number = numbers[line - 1]
                rp._set_stitch_number_option()
                applied.append((line, rp.stitch_number))
            return passes

    with warnings.catch_warnings(record=True), contextlib.redirect_stdout(io.StringIO()):
        warnings.simplefilter("always")
        try:
            Converter(interpreter_text(lines), str(path), knitout_in_file=False).process_knitout_to_dat()
        except Exception as e:
            text = " ".join(str(e).split())
            raise MachineOutputError(
                f"knitout-to-dat-python could not convert the program: {type(e).__name__}: {text}"
            ) from None
    return applied


# ---------------------------------------------------------------------------------------------- outputs


def transfers_before(p: Plan) -> np.ndarray:
    """(C,) loops transferred between beds before each course (the cast-on puts course 0's loops in place)."""
    front = front_bed(p)
    out = np.zeros(p.kmap.courses, dtype=int)
    out[1:] = (front[1:] != front[:-1]).sum(axis=1)
    return out


def _carrier_colours(p: Plan) -> dict[int, tuple[float, float, float]]:
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return {c: cmap((c - 1) % 10)[:3] for c in p.carriers.values()}


def plot_chart(p: Plan, path: str | Path) -> None:
    """The stitch chart of the program, as a technician reads it.

    Top: every course (up from the cast-on) × every needle, coloured by carrier, light where the
    stitch is plain seen from outside the tube (knitted on its layer's home bed) and dark where it
    is reverse (a purl, knitted on the other bed); each band's fabric, pattern, carrier and stitch
    number; the loops transferred before each course. Bottom: the first courses of each band at
    needle scale, each cell marked with the bed (F/B) that knits it.
    """
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    km = p.kmap
    N, C = km.needles, km.courses
    front = front_bed(p)
    colours = _carrier_colours(p)
    carriers = sorted(colours)
    band_of = np.repeat(np.arange(len(km.bands)), [b.courses for b in km.bands])
    cidx = np.array([carriers.index(c) for c in p.band_carriers])[band_of]  # (C,) carrier index per course
    reverse = front ^ front_layer(N)[None, :]
    code = 2 * cidx[:, None] + reverse.astype(int)  # light (plain) or dark (reverse) of the carrier colour
    palette = []
    for c in carriers:
        rgb = np.array(colours[c])
        palette += [tuple(0.45 * rgb + 0.55), tuple(0.75 * rgb)]
    detail = list(dict.fromkeys(range(len(km.bands))))[:6]
    fig = plt.figure(figsize=(12, 11), layout="constrained")
    grid = fig.add_gridspec(2, max(len(detail), 1), height_ratios=[3.2, 1])
    ax = fig.add_subplot(grid[0, :])
    needles = np.arange(FIRST_NEEDLE, FIRST_NEEDLE + N + 1) - 0.5
    ax.pcolormesh(
        needles, np.arange(C + 1), code, cmap=ListedColormap(palette), vmin=-0.5, vmax=len(palette) - 0.5
    )
    xfer = transfers_before(p)
    ax2 = ax.inset_axes((1.01, 0.0, 0.06, 1.0), sharey=ax)
    ax2.barh(np.arange(C) + 0.5, xfer, height=1.0, color="0.35")
    ax2.set_xlabel("xfers", fontsize=8)
    ax2.tick_params(labelleft=False, labelsize=7)
    nb = len(km.bands)
    for k, b in enumerate(km.bands):  # labels spread evenly on the right, each pointing at its band
        ax.axhline(b.start, color="k", lw=0.8)
        sl = "no stitch length (default)" if b.stitch_length is None else f"stitch length {b.stitch_length:g}"
        ax.annotate(
            f"courses {b.start}–{b.end}: {b.fabric}\n{b.pattern}, {b.yarn}, carrier {p.band_carriers[k]}\n"
            f"{sl} → x-stitch-number {p.stitch_numbers[k]}",
            xy=(1.07, (b.start + b.end) / 2 / C),
            xycoords="axes fraction",
            xytext=(1.12, (k + 0.5) / nb),
            textcoords="axes fraction",
            va="center",
            fontsize=7.5,
            arrowprops={"arrowstyle": "-", "lw": 0.6, "color": "0.4"},
        )
    ax.set_xlim(needles[0], needles[-1])
    ax.set_ylim(0, C)
    ax.set_xlabel(
        f"needle (front layer on {FIRST_NEEDLE + N - 1}, {FIRST_NEEDLE + N - 3}, …; back layer on the others)"
    )
    ax.set_ylabel("course, up from the cast-on (wrist)")
    fig.suptitle(
        f"{p.spec.machine}, gauge {p.spec.gauge} (knitted at half gauge), width {p.spec.bed_width}: a tube "
        f"of {N} stitches × {C} courses; cast-on below course 0, bind-off above course {C - 1}",
        fontsize=10,
    )
    ax.legend(
        handles=[
            h
            for c in carriers
            for h in (
                Patch(color=palette[2 * carriers.index(c)], label=f"carrier {c} ({_yarn_of(p, c)}): plain"),
                Patch(color=palette[2 * carriers.index(c) + 1], label=f"carrier {c}: reverse (purl)"),
            )
        ],
        loc="upper center",
        bbox_to_anchor=(0.5, -0.06),
        ncol=min(4, 2 * len(carriers)),
        fontsize=8,
    )
    rows, cols = 4, min(N, 12)
    for i, k in enumerate(detail):
        b = km.bands[k]
        axd = fig.add_subplot(grid[1, i])
        sub = front[b.start : b.start + min(rows, b.courses), N - cols :]
        img = reverse[b.start : b.start + len(sub), N - cols :].astype(float)
        rgb = np.array(colours[p.band_carriers[k]])
        axd.imshow(
            img,
            cmap=ListedColormap([tuple(0.45 * rgb + 0.55), tuple(0.75 * rgb)]),
            vmin=0,
            vmax=1,
            origin="lower",
            aspect="auto",
            extent=(FIRST_NEEDLE + N - cols - 0.5, FIRST_NEEDLE + N - 0.5, b.start, b.start + len(sub)),
        )
        for r in range(len(sub)):
            for j in range(cols):
                axd.text(
                    FIRST_NEEDLE + N - cols + j,
                    b.start + r + 0.5,
                    "F" if sub[r, j] else "B",
                    ha="center",
                    va="center",
                    fontsize=7,
                )
        axd.set_title(f"{b.pattern} ({b.yarn})", fontsize=8)
        axd.set_yticks(b.start + np.arange(len(sub)) + 0.5, [str(b.start + r) for r in range(len(sub))])
        axd.set_xlabel("needle; F/B: the bed that knits", fontsize=7)
        axd.tick_params(labelsize=6)
        if i == 0:
            axd.set_ylabel("course", fontsize=7)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _yarn_of(p: Plan, carrier: int) -> str:
    return next(y for y, c in p.carriers.items() if c == carrier)


def program(p: Plan, *, check: bool = True) -> tuple[list[str], dict[str, Any] | None]:
    """The knitout lines of a plan and, with ``check``, the report of :func:`verify` (which raises on a failure)."""
    lines = knitout_lines(p)
    return lines, (verify(p, lines) if check else None)


def write_machine_outputs(
    p: Plan, lines: Sequence[str], folder: str | Path, *, dat: bool = False
) -> tuple[list[str], dict[str, Any]]:
    """Write ``sleeve.k``, ``sleeve-chart.png`` and, with ``dat``, ``sleeve.dat`` into ``folder``.

    Returns the file names and a summary: machine, needles, courses, bands with their carrier and
    stitch number, and the DAT passes given a stitch number.
    """
    folder = Path(folder)
    (folder / FILES["knitout"]).write_text("\n".join(lines) + "\n", encoding="utf-8")
    plot_chart(p, folder / FILES["chart"])
    names = [FILES["knitout"], FILES["chart"]]
    info: dict[str, Any] = {
        "machine": p.spec.machine,
        "gauge": p.spec.gauge,
        "width": p.spec.bed_width,
        "half_gauge": True,
        "needles": p.kmap.needles,
        "courses": p.kmap.courses,
        "carriers": dict(p.carriers),
        "stitch_numbers": p.spec.stitch_table,
        "bands": [
            {
                "courses": [b.start, b.end],
                "fabric": b.fabric,
                "pattern": b.pattern,
                "yarn": b.yarn,
                "carrier": c,
                "stitch_number": n,
            }
            for b, c, n in zip(p.kmap.bands, p.band_carriers, p.stitch_numbers)
        ],
    }
    if dat:
        applied = write_dat(lines, folder / FILES["dat"])
        names.append(FILES["dat"])
        info["dat_passes_with_stitch_number"] = len(applied)
    return names, info
