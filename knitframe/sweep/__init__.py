"""Fabric sweeps: many fabrics through simulation and fitting, the capability behind the
``[sweep]`` stage (``knitframe_stages.sweep``), which reads the config into these pieces.

- :mod:`~knitframe.sweep.points`: a grid or a list of keys expanded into validated points, and
  each point's executor job;
- :mod:`~knitframe.sweep.job`: :func:`run_point`, the job of one point (simulate, then fit), the
  plugin modules it runs (for the code-hashed result cache) and the map through an executor;
- :mod:`~knitframe.sweep.rows`: a point's row of ``sweep.csv`` and its library entry;
- :mod:`~knitframe.sweep.validation`: points against measured tests;
- :mod:`~knitframe.sweep.outputs`: ``sweep.csv``, ``trends.md`` and ``params.png`` (Fig. 4);
- :mod:`~knitframe.sweep.trends`: the paper's four trends judged from the fitted parameters;
- :mod:`~knitframe.sweep.goals`: how a validation sweep meets its goals against measured tests;
- :mod:`~knitframe.sweep.progress`: the progress line.
"""

from knitframe.sweep.goals import (
    MET,
    NOT_MET,
    UNDETERMINED,
    GoalSettings,
    goals_markdown,
    held_fixed,
    validation_goals,
)
from knitframe.sweep.job import cached_points, forget_partial, map_points, point_modules, run_point
from knitframe.sweep.outputs import plot_params, write_csv, write_trends
from knitframe.sweep.points import (
    FABRIC_KEYS,
    MAX_POINTS,
    SCENE_KEYS,
    Point,
    expand,
    loads_text,
    point_job,
    resolve_point,
)
from knitframe.sweep.progress import SweepProgress
from knitframe.sweep.rows import SweepFits, relaxed_pitches
from knitframe.sweep.validation import (
    MEASURED_KEY,
    VALIDATION_COLUMNS,
    MeasuredTable,
    measured_tests,
    validate_point,
    validation_headline,
)

__all__ = [
    "FABRIC_KEYS",
    "SCENE_KEYS",
    "MEASURED_KEY",
    "MAX_POINTS",
    "VALIDATION_COLUMNS",
    "Point",
    "MeasuredTable",
    "SweepFits",
    "SweepProgress",
    "expand",
    "resolve_point",
    "point_job",
    "loads_text",
    "measured_tests",
    "validate_point",
    "validation_headline",
    "run_point",
    "point_modules",
    "map_points",
    "cached_points",
    "forget_partial",
    "relaxed_pitches",
    "write_csv",
    "write_trends",
    "plot_params",
    "MET",
    "NOT_MET",
    "UNDETERMINED",
    "GoalSettings",
    "validation_goals",
    "goals_markdown",
    "held_fixed",
]
