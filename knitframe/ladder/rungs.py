"""The rungs of the accuracy ladder: each a solver with the options that make its fidelity
(:data:`RUNGS`), and :func:`rung`, which also names rungs at any resolution (``rod:N``,
``volumetric:pK:r/X``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

import attrs


@attrs.frozen
class Rung:
    """One rung of the ladder: a solver with the options that make its fidelity."""

    #: what ``--rungs`` and ``[ladder] rungs`` call it
    name: str
    #: solver plugin
    solver: str
    #: the solver options that define the rung
    options: Mapping[str, Any]
    #: the cost model's solver family (time and memory fitted per family)
    family: str
    #: run when no rungs are named
    default: bool
    description: str

    @property
    def fidelity(self) -> tuple[int, float]:
        """Sort key of fidelity (higher is more faithful): the solver family, then the resolution.

        reduced < rod (by segments per stitch) < volumetric P1 < volumetric P2 (each by the mesh
        divisor: seed r/x has resolution x).
        """
        if self.solver == "rod":
            return 1, float(self.options["segments_per_stitch"])
        if self.solver == _VOL:
            return 1 + int(self.options["order"]), 1.0 / float(self.options["seed"])
        return 0, 0.0


_VOL = "volumetric"

#: Every rung, from the cheapest and least faithful to the most faithful. The best rung that ran
#: (converged) is the reference of the others; ``reduced`` is fitted to it.
RUNGS: dict[str, Rung] = {
    r.name: r
    for r in (
        Rung(
            "reduced",
            "reduced",
            {},
            "reduced",
            True,
            "the paper's reduced model (hgo; hgo2m under a free side) fitted by L-BFGS to the best "
            "rung's curve",
        ),
        Rung("rod:8", "rod", {"segments_per_stitch": 8}, "rod", True, "rod, 8 segments per stitch"),
        Rung("rod:16", "rod", {"segments_per_stitch": 16}, "rod", True, "rod, 16 segments per stitch"),
        Rung("rod:32", "rod", {"segments_per_stitch": 32}, "rod", True, "rod, 32 segments per stitch"),
        Rung("rod:64", "rod", {"segments_per_stitch": 64}, "rod", False, "rod, 64 segments per stitch"),
        Rung(
            "volumetric:p1:coarse",
            _VOL,
            {"order": 1, "seed": 1.0},
            "volumetric:p1",
            True,
            "volumetric, P1 tetrahedra, seed r (coarse); locks in bending: a quick look",
        ),
        Rung(
            "volumetric:p1:r/1.67",
            _VOL,
            {"order": 1, "seed": 0.6},
            "volumetric:p1",
            False,
            "volumetric, P1 tetrahedra, seed r/1.67; locks in bending: a quick look",
        ),
        Rung(
            "volumetric:p1:r/3",
            _VOL,
            {"order": 1, "seed": 1.0 / 3.0},
            "volumetric:p1",
            True,
            "volumetric, P1 tetrahedra, seed r/3; locks in bending: a quick look",
        ),
        Rung(
            "volumetric:p2:coarse",
            _VOL,
            {"order": 2, "seed": 1.0},
            "volumetric:p2",
            False,
            "volumetric, P2 tetrahedra, seed r (coarse)",
        ),
        Rung(
            "volumetric:p2:r/1.67",
            _VOL,
            {"order": 2, "seed": 0.6},
            "volumetric:p2",
            True,
            "volumetric, P2 tetrahedra, seed r/1.67",
        ),
        Rung(
            "volumetric:p2:r/3",
            _VOL,
            {"order": 2, "seed": 1.0 / 3.0},
            "volumetric:p2",
            False,
            "volumetric, P2 tetrahedra, seed r/3 (the paper's mesh)",
        ),
    )
}

#: The rungs run when none are named.
DEFAULT_RUNGS: tuple[str, ...] = tuple(name for name, r in RUNGS.items() if r.default)

_ROD_RE = re.compile(r"rod:(\d+)")
_VOL_RE = re.compile(r"volumetric:p([12]):r/(\d+(?:\.\d+)?)")
#: the range of a named rung's segments per stitch and mesh divisor
ROD_SEGMENTS = (4, 256)
MESH_DIVISORS = (0.5, 8.0)
RUNG_FORMS = "reduced, rod:N (N segments per stitch), volumetric:p1:r/X or volumetric:p2:r/X (seed r/X)"


def rung(name: str) -> Rung:
    """The rung called ``name``: one of :data:`RUNGS`, or ``rod:N`` / ``volumetric:pK:r/X`` at any
    resolution in :data:`ROD_SEGMENTS` / :data:`MESH_DIVISORS` (a mesh-convergence study names
    three or more seeds of one order, e.g. ``volumetric:p2:r/1.5,volumetric:p2:r/2.25,volumetric:p2:r/3``).

    Raises ValueError with a one-line reason for any other name.
    """
    if name in RUNGS:
        return RUNGS[name]
    if m := _ROD_RE.fullmatch(name):
        n = int(m.group(1))
        if not ROD_SEGMENTS[0] <= n <= ROD_SEGMENTS[1]:
            raise ValueError(
                f"rung {name!r}: segments per stitch must be {ROD_SEGMENTS[0]}..{ROD_SEGMENTS[1]}"
            )
        return Rung(name, "rod", {"segments_per_stitch": n}, "rod", False, f"rod, {n} segments per stitch")
    if m := _VOL_RE.fullmatch(name):
        order, x = int(m.group(1)), float(m.group(2))
        if not MESH_DIVISORS[0] <= x <= MESH_DIVISORS[1]:
            raise ValueError(
                f"rung {name!r}: the mesh divisor X of r/X must be {MESH_DIVISORS[0]:g}..{MESH_DIVISORS[1]:g}"
            )
        return Rung(
            name,
            _VOL,
            {"order": order, "seed": 1.0 / x},
            f"volumetric:p{order}",
            False,
            f"volumetric, P{order} tetrahedra, seed r/{m.group(2)}",
        )
    raise ValueError(f"unknown rung {name!r}; the rungs are {', '.join(RUNGS)}, or any of {RUNG_FORMS}")
