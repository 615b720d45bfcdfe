"""The checks against knitout-interpreter, and the conversion to a Shima DAT file."""

from __future__ import annotations

import importlib.util
import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from knitframe.errors import KnitframeError
from knitframe.garment.knitout.machine import Plan
from knitframe.garment.knitout.writer import FILES

#: what to install for machine output
INSTALL = "pip install 'knitframe[machine]'"
#: what to install for a DAT file: knitout-to-dat-python 0.0.4 with the interpreter release it imports
INSTALL_DAT = "pip install 'knitframe[dat]'"


class MachineOutputError(KnitframeError):
    """A program knitframe wrote failed the interpreter's check: a knitframe bug, not bad input."""

    exit_code = 3


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
                f"knitout-to-dat-python {_version('knitout-to-dat-python')} does not work with "
                f"knitout-interpreter {_version('knitout-interpreter')} ({type(e).__name__}: {why}); "
                f"it works with knitout-interpreter 0.1.2: {INSTALL_DAT}"
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

    The checks: no error, violation or warning; the graph's courses are the cast-on's loops, then
    exactly the map's courses with the map's stitches on each (then the bind-off); every loop of a
    band's courses is made by that band's carrier; the machine ends with no loop on any needle.
    Returns what was checked.
    """
    program, machine, graph, warned = run_interpreter(lines)
    if warned:
        raise MachineOutputError(
            f"knitout-interpreter warned: {warned[0]}; this is a knitframe bug, please report it"
        )
    km = p.kmap
    want = list(km.course_needles)
    courses = graph.get_courses()
    sizes = [len(c) for c in courses]
    body = courses[1 : 1 + km.courses]
    problems = []
    if sizes[0] != km.needles:
        problems.append(f"the cast-on made {sizes[0]} loops, not {km.needles}")
    if len(body) != km.courses:
        problems.append(f"the knit graph has {len(body)} courses after the cast-on, not {km.courses}")
    else:
        wrong = [(c, len(body[c]), n) for c, n in enumerate(want) if len(body[c]) != n]
        if wrong:
            c, got, n = wrong[0]
            problems.append(
                f"{len(wrong)} courses have the wrong number of loops (course {c}: {got}, not {n})"
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
        "stitches_per_course": km.needles,
        "stitches_range": [min(want), max(want)],
        "shaping_courses": len(km.shaping_courses),
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
