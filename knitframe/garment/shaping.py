r"""Shaping a knitted tube: the machine's rules for changing the number of stitches per course.

A flat V-bed machine shapes a tube by increases and decreases at its edges: on a *shaping course*
the edge stitches are transferred outwards (an increase) or inwards onto their neighbours (a
decrease), by at most ``max_change`` stitches in all, and two shaping courses are at least
``every`` courses apart. The tube never has fewer than ``min_needles`` nor more than
``max_needles`` stitches per course (the bed width at the gauge: the tube is knitted at half gauge,
one needle of each bed per stitch).

The design gives each element row i a needle count :math:`N_i` (the stitches of its first course)
and :math:`k_i` courses. The change to :math:`N_{i+1}` is made on the last shaping courses of row i,
``every`` courses apart and ending on the first course of row i+1 (:func:`course_needles`); at most
:math:`\lfloor k_i/\text{every}\rfloor` shaping courses fit in the row whatever the phase of its
neighbours, so the design keeps

.. math:: |N_{i+1} - N_i| \le \text{max\_change}\,\lfloor k_i / \text{every} \rfloor ,

which :func:`allowed_change` gives and the optimiser enforces exactly.

Defaults (:class:`MachineRules`): two stitches per shaping course (one at each edge of the tube)
at most every second course, and 8 to 540 stitches (an SWG091N2's 540 needles per bed). Hand and
machine knitting practice spaces shaping evenly, one stitch per edge every 2 to 6 rows (a classic
sleeve loses 18 stitches per side over 96 rows, one per side every 5 rows), so these defaults allow
the fastest shaping a machine knitter would use; slow them down to your own practice.
"""

from __future__ import annotations

import attrs
import numpy as np

from knitframe.errors import FieldError

__all__ = ["MachineRules", "allowed_change", "course_needles", "check_course_needles"]


def _positive_int(name: str, lo: int):
    def check(_, __, value) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
            raise FieldError(name, f"must be an integer >= {lo}, got {value!r}")

    return check


@attrs.frozen
class MachineRules:
    """How a machine may change the stitches per course of a tube (see the module docstring)."""

    #: most stitches added or removed on one shaping course (both edges together)
    max_change: int = attrs.field(default=2, validator=_positive_int("max_change", 0))
    #: least courses from one shaping course to the next
    every: int = attrs.field(default=2, validator=_positive_int("every", 1))
    #: fewest stitches per course
    min_needles: int = attrs.field(default=8, validator=_positive_int("min_needles", 4))
    #: most stitches per course (the bed width at the gauge)
    max_needles: int = attrs.field(default=540, validator=_positive_int("max_needles", 4))

    def __attrs_post_init__(self) -> None:
        if self.max_needles < self.min_needles:
            raise FieldError(
                "max_needles", f"must be >= min_needles ({self.min_needles}), got {self.max_needles}"
            )

    def to_json(self) -> dict[str, int]:
        return attrs.asdict(self)


def allowed_change(courses, rules: MachineRules) -> np.ndarray:
    """Most stitches the count may change by over rows of ``courses`` courses (any shape, integers)."""
    k = np.asarray(courses)
    return rules.max_change * (np.floor(k + 1e-9).astype(np.int64) // rules.every)


def course_needles(row_needles, row_courses, rules: MachineRules) -> np.ndarray:
    """(C,) stitches knitted on every course of a shaped tube, C = Σ row_courses.

    Row i starts at ``row_needles[i]``; the change to the next row's count is spread over the fewest
    shaping courses (each ≤ ``max_change``, as even as can be), ``every`` courses apart and ending on
    the next row's first course. Raises ValueError where a change does not fit its row.
    """
    N = np.asarray(row_needles, dtype=np.int64)
    k = np.asarray(row_courses).astype(np.int64)
    if N.shape != k.shape or N.ndim != 1 or len(N) == 0 or np.any(k < 1):
        raise ValueError("row_needles and row_courses must be 1-D of one length, courses >= 1")
    out = np.repeat(N, k)
    start = np.concatenate([[0], np.cumsum(k)])
    for i in range(len(N) - 1):
        delta = int(N[i + 1] - N[i])
        if delta == 0:
            continue
        if rules.max_change == 0:
            raise ValueError(f"row {i}: a change of {delta} stitches but max_change is 0")
        s = -(-abs(delta) // rules.max_change)
        if s > k[i] // rules.every:
            raise ValueError(
                f"row {i}: a change of {delta} stitches needs {s} shaping courses, "
                f"but its {k[i]} courses hold {k[i] // rules.every}"
            )
        steps = np.full(s, abs(delta) // s) + (np.arange(s) < abs(delta) % s)
        # the count reached after each shaping course, the last on the next row's first course
        at = start[i + 1] - rules.every * np.arange(s)[::-1]
        reached = N[i] + np.sign(delta) * np.cumsum(steps)
        for c, n in zip(at[:-1], reached[:-1], strict=True):
            out[c : start[i + 1]] = n
    return out


def check_course_needles(needles, rules: MachineRules) -> list[str]:
    """What in a per-course stitch count breaks the machine's rules (empty when nothing does)."""
    n = np.asarray(needles, dtype=np.int64)
    problems = []
    if n.min() < rules.min_needles or n.max() > rules.max_needles:
        problems.append(
            f"stitches per course {n.min()}–{n.max()} outside {rules.min_needles}–{rules.max_needles}"
        )
    change = np.flatnonzero(np.diff(n)) + 1
    if np.any(np.abs(np.diff(n)) > rules.max_change):
        problems.append(f"a shaping course changes more than {rules.max_change} stitches")
    if len(change) > 1 and np.min(np.diff(change)) < rules.every:
        problems.append(f"two shaping courses closer than {rules.every} courses")
    return problems
