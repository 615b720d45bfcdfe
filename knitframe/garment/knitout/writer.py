"""The knitout program writer: needles and layers, each pattern's purls, cast-on, courses, bind-off."""

from __future__ import annotations

import numpy as np

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
    km = p.kmap
    N = km.needles
    front = front_bed(p)
    layer = front_layer(N)
    front_order = [int(q) for q in np.flatnonzero(layer)[::-1]]  # front layer, leftward from the right edge
    back_order = [int(q) for q in np.flatnonzero(~layer)]  # back layer, rightward from the left edge
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
    out += _cast_on(p, front[0], front_order, back_order)
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


def _header(p: Plan) -> list[str]:
    """The program's header lines and its comments on the layout, the carriers and the bands."""
    km, spec = p.kmap, p.spec
    N = km.needles
    carriers = p.band_carriers
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
    return out


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


def _bind_off(beds: np.ndarray, N: int, c: int, front: list[int], back: list[int]) -> list[str]:
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
