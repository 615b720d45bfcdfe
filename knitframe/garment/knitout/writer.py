"""The knitout program writer: needles and layers, each pattern's purls, cast-on, courses, shaping,
bind-off."""

from __future__ import annotations

import numpy as np

from knitframe.garment.knitout.layout import Layout
from knitframe.garment.knitout.machine import Plan, check_patterns

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
    return _purl(pattern, np.arange(courses)[:, None], wales(needles)[None, :])


def _purl(pattern: str, c: np.ndarray, w: np.ndarray) -> np.ndarray:
    """True where the stitch of band course ``c`` on wale ``w`` is reverse (arrays that broadcast)."""
    shape = np.broadcast_shapes(c.shape, w.shape)
    if pattern == "jersey":
        return np.zeros(shape, dtype=bool)
    if pattern == "rib":
        return np.broadcast_to(w % 2 == 1, shape).copy()
    if pattern == "garter":
        return np.broadcast_to(c % 2 == 1, shape).copy()
    if pattern == "seed":
        return np.broadcast_to((w + c) % 2 == 1, shape).copy()
    check_patterns([pattern])
    raise AssertionError(pattern)  # pragma: no cover


def front_bed(p: Plan) -> np.ndarray:
    """(C, W) True where the loop of course c at needle position n is knitted on the front bed.

    W is the needles the tube uses (:attr:`.layout.Layout.width`, N for a tube that is not shaped);
    False also where course c has no stitch (:meth:`.layout.Layout.mask`).
    """
    lay = p.layout
    w = lay.wales()[None, :]
    home = lay.front()[None, :]
    purl = np.concatenate([_purl(b.pattern, np.arange(b.courses)[:, None], w) for b in p.kmap.bands])
    return (home ^ purl) & lay.mask()


def _needle(bed_front: bool, pos: int) -> str:
    return f"{'f' if bed_front else 'b'}{FIRST_NEEDLE + pos}"


def knitout_lines(p: Plan) -> list[str]:
    """The knitout program of a plan, one instruction per line (see the module docstring)."""
    head, courses, tail = _program(p)
    return head + [s for block in courses for s in block] + tail


def transfers_before(p: Plan) -> np.ndarray:
    """(C,) ``xfer`` instructions before each course: the loops whose bed changes, and on a shaping
    course the moves of its edge stitches (the cast-on puts course 0's loops in place)."""
    return np.array([sum(s.startswith("xfer ") for s in block) for block in _program(p)[1]], dtype=int)


def _program(p: Plan) -> tuple[list[str], list[list[str]], list[str]]:
    """The program in parts: the header and cast-on, the lines of each course, and the bind-off."""
    km, lay = p.kmap, p.layout
    front = front_bed(p)
    carriers = p.band_carriers
    band_of = np.repeat(np.arange(len(km.bands)), [b.courses for b in km.bands])
    out = _header(p)
    # the next course (from the start) at which each carrier is used, to decide between carrying and cutting
    uses: dict[int, list[int]] = {}
    for k in range(len(km.bands)):
        uses.setdefault(carriers[k], []).append(k)

    def next_use(c: int, after_band: int) -> int | None:
        later = [km.bands[k].start for k in uses[c] if k > after_band]
        return later[0] if later else None

    active: set[int] = set()
    c0 = carriers[0]
    out += _cast_on(p, front[0], *lay.orders(0))
    out.append(f"releasehook {c0}")
    active.add(c0)
    stitch = p.stitch_numbers[0]
    beds = np.where(lay.mask()[0], front[0], -1).astype(np.int8)  # 1 front, 0 back, -1 no loop
    hooked = None
    blocks: list[list[str]] = []
    for course in range(km.courses):
        block: list[str] = []
        blocks.append(block)
        k = int(band_of[course])
        b = km.bands[k]
        c = carriers[k]
        if course == b.start:
            block.append(f"; band {k}: {b.fabric}, carrier {c}")
            prev = carriers[k - 1] if k else None
            if prev is not None and prev != c:
                nu = next_use(prev, k - 1)
                if nu is None or nu - course > CARRY_COURSES:
                    block.append(f"outhook {prev}")
                    active.discard(prev)
            if c not in active:
                block.append(f"inhook {c}")
                active.add(c)
                hooked = c
        want = front[course]
        block += _shape(lay, course, beds, want)
        move = np.flatnonzero((beds >= 0) & (beds != want))
        block += [f"xfer {_needle(True, q)} {_needle(False, q)}" for q in move if beds[q]]
        block += [f"xfer {_needle(False, q)} {_needle(True, q)}" for q in move if not beds[q]]
        new = beds < 0  # the needles an increase left empty: tucked on this course
        beds = np.where(lay.mask()[course], want, -1).astype(np.int8)
        if p.stitch_numbers[k] != stitch:
            stitch = p.stitch_numbers[k]
            block.append(f"x-stitch-number {stitch}")
        front_order, back_order = lay.orders(course)
        block += [f"{'tuck' if new[q] else 'knit'} - {_needle(want[q], q)} {c}" for q in front_order]
        block += [f"{'tuck' if new[q] else 'knit'} + {_needle(want[q], q)} {c}" for q in back_order]
        if hooked is not None:
            block.append(f"releasehook {hooked}")
            hooked = None
    return out, blocks, _bind_off(beds == 1, carriers[-1], *lay.orders(km.courses - 1))


def _shape(lay: Layout, course: int, beds: np.ndarray, want: np.ndarray) -> list[str]:
    """The transfers of a shaping course (none on any other): each loop :meth:`.layout.Layout.moves`
    names goes along its layer, through the empty needle opposite when it stays on its bed, at the
    racking that aligns it with its new needle; ``beds`` is updated.

    A loop stacked onto a stitch (a decrease) goes to that stitch's bed; a loop moved out to a new edge
    (an increase) goes to the bed the course knits it on.
    """
    moves = lay.moves(course)
    if not moves:
        return []
    old, new = lay.needles(course - 1), lay.needles(course)
    what = "decrease" if new < old else "increase"
    edges = [
        f"{abs(a - b)} at the {side}"
        for side, a, b in (
            ("left", lay.left[course - 1], lay.left[course]),
            ("right", lay.right[course - 1], lay.right[course]),
        )
        if a != b
    ]
    out = [f"; course {course}: {what} from {old} to {new} stitches ({' and '.join(edges)})"]
    to_bed = [(q, t, bool(beds[q]), bool(beds[t]) if beds[t] >= 0 else bool(want[t])) for q, t in moves]
    out += [f"xfer {_needle(f, q)} {_needle(not f, q)}" for q, _, f, g in to_bed if f == g]
    racked: dict[int, list[str]] = {}
    for q, t, _, g in to_bed:
        racked.setdefault(t - q if g else q - t, []).append(f"xfer {_needle(not g, q)} {_needle(g, t)}")
    for r in sorted(racked):
        out += [f"rack {r}", *racked[r]]
    out.append("rack 0")
    for q, t, _, g in to_bed:
        beds[q], beds[t] = -1, int(g)
    return out


def _header(p: Plan) -> list[str]:
    """The program's header lines and its comments on the layout, the carriers and the bands."""
    km, spec = p.kmap, p.spec
    N = km.needles
    carriers = p.band_carriers
    counts = km.course_needles
    out = [
        ";!knitout-2",
        f";;Machine: {spec.machine}",
        f";;Gauge: {spec.gauge}",
        f";;Width: {spec.bed_width}",
        ";;Carriers: " + " ".join(str(c) for c in range(1, spec.carrier_count + 1)),
        f";;Position: {POSITION}",
    ]
    tube, layers = f"{km.courses} courses, {len(km.bands)} bands", "the others back layer (home b)"
    course = "a course is the front layer leftward then the back layer rightward"
    if not km.shaped:
        out += [
            f"; knitframe sleeve: a tube of {N} stitches per course, {tube}",
            f"; half gauge: needle {FIRST_NEEDLE}+p holds stitch p; p = N-1, N-3, ... front layer (home f), "
            f"{layers}; {course}",
        ]
    else:
        out += [
            f"; knitframe sleeve: a shaped tube cast on with {N} stitches, {min(counts)} to {max(counts)} "
            f"stitches per course, {tube}, {len(km.shaping_courses)} shaping courses",
            f"; half gauge: needle {FIRST_NEEDLE}+p holds stitch p; a course's rightmost stitch and every "
            f"other one leftward are the front layer (home f), {layers}; {course}",
            "; shaping: a decrease stacks an edge stitch onto its layer's next stitch, an increase moves a "
            "layer's edge stitch out and tucks the needle it leaves",
        ]
    for yarn, c in p.carriers.items():
        out.append(f"; carrier {c}: yarn {yarn}")
    for k, b in enumerate(km.bands):
        out.append(
            f"; band {k}: courses {b.start}-{b.end}, {b.fabric} ({b.pattern}, {b.yarn}, stitch length "
            f"{'-' if b.stitch_length is None else f'{b.stitch_length:g}'}), carrier {carriers[k]}, "
            f"x-stitch-number {p.stitch_numbers[k]}"
        )
    return out + [f"; {note}" for note in p.notes]


def _cast_on(p: Plan, beds: np.ndarray, front_order: list[int], back_order: list[int]) -> list[str]:
    """Alternating tucks around the tube by the first band's carrier, each on the bed course 0 needs."""
    c0 = p.band_carriers[0]
    out = [
        "; cast-on: alternating tucks around the tube",
        f"x-stitch-number {p.stitch_numbers[0]}",
        f"inhook {c0}",
    ]
    for half in (0, 1):
        out += [f"tuck - {_needle(beds[q], q)} {c0}" for i, q in enumerate(front_order) if i % 2 == half]
        out += [f"tuck + {_needle(beds[q], q)} {c0}" for i, q in enumerate(back_order) if i % 2 == half]
    return out


def _bind_off(beds: np.ndarray, c: int, front: list[int], back: list[int]) -> list[str]:
    """Bring every loop home, then a chain bind-off around the tube with a tail on the last loop.

    ``front`` lists the front layer's positions right to left, ``back`` the back layer's left to right.
    """
    out = ["; bind-off: a chain around the tube"]
    out += [f"xfer {_needle(False, q)} {_needle(True, q)}" for q in front if not beds[q]]
    out += [f"xfer {_needle(True, q)} {_needle(False, q)}" for q in back if beds[q]]
    order = [(q, True) for q in front] + [(q, False) for q in back]
    out.append(f"knit - {_needle(True, front[0])} {c}")
    for (a, fa), (b, fb) in zip(order[:-1], order[1:], strict=False):
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
