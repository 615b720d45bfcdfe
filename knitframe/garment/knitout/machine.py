"""Machine settings: the machines, :class:`MachineSpec`, and the :class:`Plan` that resolves every band."""

from __future__ import annotations

import math
from collections.abc import Sequence

import attrs

from knitframe.errors import FieldError
from knitframe.garment.knitout.knitmap import KnitMap
from knitframe.garment.knitout.layout import MAX_COURSE_CHANGE, Layout, tube_layout

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
    #: the needles of every course
    layout: Layout

    @property
    def band_carriers(self) -> list[int]:
        return [self.carriers[b.yarn] for b in self.kmap.bands]

    @property
    def notes(self) -> list[str]:
        """What the user should know about the settings, one line each: the fabrics whose stitch number is
        the table's default because the library gives them no stitch length."""
        loose = list(dict.fromkeys(b.fabric for b in self.kmap.bands if b.stitch_length is None))
        if not loose:
            return []
        what = f"fabric {loose[0]} has" if len(loose) == 1 else f"fabrics {', '.join(loose)} have"
        number = self.spec.stitch_table["default"]
        return [f"{what} no stitch length: x-stitch-number {number} is the table's default; calibrate it"]


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

    Raises :class:`~knitframe.errors.FieldError` naming ``pattern``, ``tube.needles_per_course``, ``width``,
    ``carriers`` or ``stitch_numbers`` with a one-line reason: a pattern other than :data:`PATTERNS`,
    a course changing more than :data:`~.layout.MAX_COURSE_CHANGE` stitches, a tube wider than the
    bed, more yarns than carriers, a stitch length the table does not hold.
    """
    check_patterns([b.pattern for b in kmap.bands])
    counts = kmap.course_needles
    jumps = [c for c in kmap.shaping_courses if abs(counts[c] - counts[c - 1]) > MAX_COURSE_CHANGE]
    if jumps:
        c = jumps[0]
        raise FieldError(
            "tube.needles_per_course",
            f"course {c} changes from {counts[c - 1]} to {counts[c]} stitches; the machine output "
            f"changes at most {MAX_COURSE_CHANGE} on one course (four at each edge)",
        )
    layout = tube_layout(counts)
    if layout.width > spec.bed_width:
        widest = f"the tube needs {layout.width} needles per bed (half gauge: one per stitch of the course"
        if kmap.shaped:
            widest += (
                f"; its {min(counts)} to {max(counts)} stitches per course move along the bed as it is shaped"
            )
        raise FieldError("width", f"{widest}) but the machine width is {spec.bed_width}")
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
    return Plan(kmap, spec, {y: carriers[y] for y in yarns}, numbers, layout)
