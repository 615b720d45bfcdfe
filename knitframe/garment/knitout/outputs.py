"""The machine outputs of a plan: the checked program, ``sleeve.k``, its chart and the DAT file."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from knitframe.garment.knitout.chart import plot_chart
from knitframe.garment.knitout.checking import verify, write_dat
from knitframe.garment.knitout.machine import Plan
from knitframe.garment.knitout.writer import FILES, knitout_lines


def program(p: Plan, *, check: bool = True) -> tuple[list[str], dict[str, Any] | None]:
    """The knitout lines of a plan and, with ``check``, the report of :func:`verify` (which raises on a
    failure)."""
    lines = knitout_lines(p)
    return lines, (verify(p, lines) if check else None)


def write_machine_outputs(
    p: Plan, lines: Sequence[str], folder: str | Path, *, dat: bool = False
) -> tuple[list[str], dict[str, Any]]:
    """Write ``sleeve.k``, ``sleeve-chart.png`` and, with ``dat``, ``sleeve.dat`` into ``folder``.

    Returns the file names and a summary: machine, needles (cast on), the stitches of every course,
    the needles of each bed the tube uses, courses, bands with their carrier and stitch number, the
    notes of :attr:`~.machine.Plan.notes` (one line each) and the DAT passes given a stitch number.
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
        "needles_per_course": list(p.kmap.course_needles),
        "shaping_courses": len(p.kmap.shaping_courses),
        "needles_used": p.layout.width,
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
            for b, c, n in zip(p.kmap.bands, p.band_carriers, p.stitch_numbers, strict=False)
        ],
        "notes": p.notes,
    }
    if dat:
        applied = write_dat(lines, folder / FILES["dat"])
        names.append(FILES["dat"])
        info["dat_passes_with_stitch_number"] = len(applied)
    return names, info
