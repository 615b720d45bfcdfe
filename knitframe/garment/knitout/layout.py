"""The tube's needles course by course: where each course's stitches sit, and the moves that shape it."""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

#: most stitches one shaping course may add or remove: four at each edge, so that a stitch moves at most
#: two places along its layer (rack ±4, the SWG091N2's limit) and a needle holds at most three loops
MAX_COURSE_CHANGE = 8
_EDGE_MAX = MAX_COURSE_CHANGE // 2


@attrs.frozen
class Layout:
    """The needle positions of every course of a tube (see the package docstring, "Shaping").

    Course c has one stitch on every position ``left[c]`` … ``right[c]``. The front layer is on the
    positions of ``right``'s parity, which no course changes, and the back layer on the others.
    Positions count from the leftmost needle any course uses, so a tube of N stitches on every
    course has left 0 and right N−1 throughout.
    """

    left: tuple[int, ...] = attrs.field(converter=tuple)
    right: tuple[int, ...] = attrs.field(converter=tuple)

    @property
    def courses(self) -> int:
        return len(self.left)

    @property
    def width(self) -> int:
        """Needles of each bed the tube uses over all its courses."""
        return max(self.right) + 1

    def needles(self, course: int) -> int:
        return self.right[course] - self.left[course] + 1

    def front(self) -> np.ndarray:
        """(W,) True at the front layer's positions."""
        return (self.right[0] - np.arange(self.width)) % 2 == 0

    def mask(self) -> np.ndarray:
        """(C, W) True where course c has a stitch."""
        p = np.arange(self.width)[None, :]
        return (p >= np.array(self.left)[:, None]) & (p <= np.array(self.right)[:, None])

    def wales(self) -> np.ndarray:
        """(W,) wale index of every position, counted around the cast-on course (see :func:`.writer.wales`).

        The index belongs to the needle, not to the stitch's rank, so a change of count at the edges
        leaves the patterns of every other stitch where they were.
        """
        rel = np.arange(self.width) - self.left[0]
        return np.where(self.front(), rel // 2, self.needles(0) - 1 - rel // 2)

    def orders(self, course: int) -> tuple[list[int], list[int]]:
        """The positions of a course in knitting order: the front layer leftward, the back layer rightward."""
        front = self.front()
        span = range(self.left[course], self.right[course] + 1)
        return [q for q in reversed(span) if front[q]], [q for q in span if not front[q]]

    def moves(self, course: int) -> list[tuple[int, int]]:
        """(from, to) of every loop moved along its layer before ``course`` (empty but on a shaping course).

        A decrease stacks each stitch leaving the tube onto its layer's outermost remaining stitch; an
        increase moves each layer's outermost stitch out to the layer's new edge, leaving the empty
        needles just inside it for the course to tuck on.
        """
        if course == 0:
            return []
        l0, l1 = self.left[course - 1], self.left[course]
        r0, r1 = self.right[course - 1], self.right[course]
        out = []
        if l1 > l0:
            out += [(q, l1 + (q - l1) % 2) for q in range(l0, l1)]
        for q in (l0, l0 + 1) if l1 < l0 else ():
            if (t := l1 + (q - l1) % 2) < q:
                out.append((q, t))
        if r1 < r0:
            out += [(q, r1 - (q - r1) % 2) for q in range(r1 + 1, r0 + 1)]
        for q in (r0, r0 - 1) if r1 > r0 else ():
            if (t := r1 - (r1 - q) % 2) > q:
                out.append((q, t))
        return out


def _split(change: int, shift: int) -> tuple[int, int]:
    """Stitches changed at the (left, right) edge: the right edge changes by pairs (one stitch of each
    layer), the left takes any odd one; the split that keeps the tube nearest its first centre
    (``shift`` is twice the centre's move), then the most even split, then the left edge first."""
    n, sign = abs(change), 1 if change > 0 else -1
    options = [(n - y, y) for y in range(0, n + 1, 2) if n - y <= _EDGE_MAX and y <= _EDGE_MAX]
    if not options:
        raise ValueError(f"a change of {change} stitches on one course; at most {MAX_COURSE_CHANGE}")
    return min(options, key=lambda xy: (abs(shift + sign * (xy[1] - xy[0])), max(xy), xy[1]))


def tube_layout(course_needles: Sequence[int]) -> Layout:
    """The layout of a tube knitting ``course_needles[c]`` stitches on course c (each ≥ 4).

    The rightmost stitch stays on the front layer (where a carrier brought in starts: the
    yarn-inserting hook then blocks no needle of the tube), so the right edge moves by pairs of
    stitches and the left edge by any number; each change is split between the edges to keep the
    tube centred where it was cast on (:func:`_split`).
    """
    n = [int(v) for v in course_needles]
    left, right = [0], [n[0] - 1]
    for prev, now in zip(n[:-1], n[1:], strict=True):
        lo, hi = left[-1], right[-1]
        if now != prev:
            x, y = _split(now - prev, lo + hi - (n[0] - 1))
            sign = 1 if now > prev else -1
            lo, hi = lo - sign * x, hi + sign * y
        left.append(lo)
        right.append(hi)
    first = min(left)
    return Layout([q - first for q in left], [q - first for q in right])
