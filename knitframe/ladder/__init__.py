"""The accuracy ladder: one fabric and scene through rungs of fidelity, with what each costs.

The rungs are defined once, in :data:`RUNGS` (:mod:`~knitframe.ladder.rungs`), with their solver
options. The ``[ladder]`` stage (``knitframe_stages.ladder``), the ``knitframe ladder`` command and
:func:`ladder` all run them through this package:

- :func:`run_rung` (:mod:`~knitframe.ladder.jobs`) is the job an executor runs for one rung: it
  starts a fresh Python process for the rung, so that the rung's peak memory (the high-water mark
  of that process) and wall time are its own, whatever ran before it in the executor's worker;
- :class:`CostModel` (:mod:`~knitframe.ladder.cost`) estimates a rung's time and memory before it
  starts, from a power law in its degrees of freedom fitted per solver family to the rungs
  already run, to timing files the user names, and to the timings shipped with knitframe
  (``knitframe/data/ladder-timings.json``);
- :mod:`~knitframe.ladder.runner` runs the rungs in waves, cheapest first, and compares them;
- :func:`tension_errors` (:mod:`~knitframe.ladder.compare`), :func:`write_table`
  (:mod:`~knitframe.ladder.outputs`), :func:`plot_pareto` and :func:`plot_curves`
  (:mod:`~knitframe.ladder.plots`) make the outputs;
- :mod:`~knitframe.ladder.convergence`: the mesh convergence of the volumetric rungs (the
  observed order and a Richardson estimate of the finest mesh's error).

``knitframe.ladder`` is the function :func:`ladder` (the Python twin of the command,
:mod:`~knitframe.ladder.api`); import the helpers with ``from knitframe.ladder import RUNGS,
CostModel``.
"""

from knitframe.ladder.api import LadderResult, ladder, ladder_config
from knitframe.ladder.compare import loaded_directions, tension_errors, within_range
from knitframe.ladder.convergence import convergence_table, mesh_convergence, richardson, write_convergence
from knitframe.ladder.cost import (
    CostModel,
    Estimate,
    TimingPoint,
    format_duration,
    format_memory,
    read_timings,
    shipped_timings_path,
    timings_json,
)
from knitframe.ladder.jobs import curve_response, run_rung, rung_modules
from knitframe.ladder.outputs import CSV_COLUMNS, write_csv, write_table
from knitframe.ladder.plots import plot_curves, plot_pareto
from knitframe.ladder.rungs import DEFAULT_RUNGS, MESH_DIVISORS, ROD_SEGMENTS, RUNGS, Rung, rung

__all__ = [
    "Rung",
    "RUNGS",
    "DEFAULT_RUNGS",
    "ROD_SEGMENTS",
    "MESH_DIVISORS",
    "rung",
    "Estimate",
    "CostModel",
    "TimingPoint",
    "shipped_timings_path",
    "read_timings",
    "timings_json",
    "run_rung",
    "rung_modules",
    "curve_response",
    "loaded_directions",
    "tension_errors",
    "within_range",
    "format_duration",
    "format_memory",
    "CSV_COLUMNS",
    "write_csv",
    "write_table",
    "plot_pareto",
    "plot_curves",
    "LadderResult",
    "ladder_config",
    "ladder",
    "richardson",
    "mesh_convergence",
    "convergence_table",
    "write_convergence",
]
