"""Refusals of a sliced scan: sections that are not one closed loop, and shapes that are not tubular."""

from __future__ import annotations

import numpy as np

from knitframe.errors import DataError

__all__ = [
    "MIN_LENGTH_OVER_DIAMETER",
    "MIN_SECTION_ASPECT",
    "MAX_CIRCUMFERENCE_RATIO",
    "check_sections",
    "check_tubular",
]

#: tubularity: the scan's length along its axis must be at least this many mean section diameters
MIN_LENGTH_OVER_DIAMETER = 1.5
#: tubularity: the thinnest/widest second-moment ratio of every section must be at least this
MIN_SECTION_ASPECT = 0.2
#: tubularity: the largest station circumference may be at most this many times the smallest
MAX_CIRCUMFERENCE_RATIO = 5.0


def check_sections(label: str, found: list[tuple[list[np.ndarray], int]], positions: np.ndarray) -> None:
    """Refuse a scan unless every station's section is one closed loop (names the first bad station).

    ``found`` holds, per station, the closed loops and the count of open pieces from
    :func:`~knitframe.garment.limb.slicing.closed_loops`; ``positions`` (n_stations,) mm.
    """
    if not any(loops for loops, _ in found):
        raise DataError(
            label, "not tubular along its axis: no cross-section is a closed loop (an open sheet or plate?)"
        )
    problems = []
    for i, (loops, n_open) in enumerate(found):
        where = f"station {i} at {positions[i]:.1f} mm"
        if n_open:
            problems.append(
                f"{where}: section is not closed ({n_open} open piece{'s' if n_open > 1 else ''}: "
                "a hole or tear in the scan)"
            )
        elif len(loops) == 0:
            problems.append(f"{where}: section is empty (a gap in the scan)")
        elif len(loops) > 1:
            problems.append(f"{where}: section has {len(loops)} loops")
    if problems:
        more = f" ({len(problems) - 1} more stations too)" if len(problems) > 1 else ""
        raise DataError(label, problems[0] + more)


def check_tubular(
    label: str, length: float, perimeter: np.ndarray, xy: np.ndarray, positions: np.ndarray
) -> None:
    """Refuse a scan that is short for its width, has a flat section, or whose sections vary too much.

    ``length`` mm along the axis, ``perimeter`` (n_stations,) mm, ``xy`` (n_stations, n_around, 2)
    the resampled loops, ``positions`` (n_stations,) mm. The aspect of a section is
    √(λmin/λmax) of its points' second moments.
    """
    n_around = xy.shape[1]
    diameter = float(np.mean(perimeter)) / np.pi
    if length < MIN_LENGTH_OVER_DIAMETER * diameter:
        raise DataError(
            label,
            f"not tubular along its axis: {length:.1f} mm long, only {length / diameter:.2f} "
            f"times its mean diameter {diameter:.1f} mm (needs {MIN_LENGTH_OVER_DIAMETER:g}; "
            "a sphere or box?)",
        )
    centred = xy - xy.mean(axis=1, keepdims=True)
    lam = np.linalg.eigvalsh(np.einsum("sni,snj->sij", centred, centred) / n_around)
    aspect = np.sqrt(np.clip(lam[:, 0], 0.0, None) / lam[:, 1])
    if aspect.min() < MIN_SECTION_ASPECT:
        i = int(np.argmin(aspect))
        raise DataError(
            label,
            f"not tubular along its axis: station {i} at {positions[i]:.1f} mm is flat "
            f"(thickness/width {aspect[i]:.2f} < {MIN_SECTION_ASPECT:g}; a plate?)",
        )
    ratio = perimeter.max() / perimeter.min()
    if ratio > MAX_CIRCUMFERENCE_RATIO:
        raise DataError(
            label,
            f"not tubular along its axis: cross-section length varies {ratio:.1f} times "
            f"(over {MAX_CIRCUMFERENCE_RATIO:g}; a cone to a point or a blob?)",
        )
