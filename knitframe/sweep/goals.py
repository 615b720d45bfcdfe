"""How a validation sweep meets its goals against measured tests.

A sweep whose points carry measured tests (``measured = {...}``) compares each simulated curve
with its test (:func:`knitframe.report.validate_uniaxial`, one row per curve of
``validation.csv``). :func:`validation_goals` judges the four goals of a validation run on those
rows:

1. ``median_ratio``: the median simulated/measured tension over every ratio at 10, 20 and 30 %
   strain is within ``median_within`` (1.5×) of 1. Also given per yarn.
2. ``every_curve``: every curve has all of its ratios within ``curve_within`` (3×) of 1.
3. ``pattern_order``: the simulated tension at 10 % strain puts the patterns of a yarn in the
   measured order, along the course and along the wale: every pair of patterns in the same order
   as measured.
4. ``lateral``: every curve's lateral strain (at 20 %, or the end of the shorter curve) is within
   ``lateral_within`` (0.05) of the measured one.

A curve that failed, or a ratio that one of the curves does not reach, is left out of the goal
and counted in its notes; a goal with nothing to judge is ``undetermined``.
:func:`goals_markdown` writes the verdicts as Markdown (the sweep stage's ``goals.md``), ending with
what the run held fixed (:func:`held_fixed`): the settings every point shares, the yarn records,
and whatever a point sets for itself, so that a reader sees at once whether anything was chosen
per fabric::

    import csv
    from knitframe.sweep.goals import validation_goals, goals_markdown
    rows = list(csv.DictReader(open("singal-validation-out/validation.csv")))
    for g in validation_goals(rows):
        print(g.key, g.verdict, g.summary)
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import attrs
import numpy as np

from knitframe import validators as v
from knitframe.sweep.trends import verdicts_markdown

__all__ = [
    "Goal",
    "GoalSettings",
    "validation_goals",
    "goals_markdown",
    "held_fixed",
    "MET",
    "NOT_MET",
    "UNDETERMINED",
]

MET, NOT_MET, UNDETERMINED = "met", "not met", "undetermined"
#: the strains of the tension ratios, in % (the columns ratio_10, ratio_20, ratio_30)
RATIO_AT = (10, 20, 30)


@attrs.frozen
class GoalSettings:
    """Schema of ``[sweep.goals]``: the thresholds of the validation goals."""

    #: the median simulated/measured tension must lie within this factor of 1
    median_within: float = attrs.field(default=1.5, validator=v.in_range(1.0, 100.0, lo_open=True))
    #: every curve's ratios must lie within this factor of 1
    curve_within: float = attrs.field(default=3.0, validator=v.in_range(1.0, 100.0, lo_open=True))
    #: the simulated lateral strain must lie within this of the measured one
    lateral_within: float = attrs.field(default=0.05, validator=v.in_range(0.0, 1.0, lo_open=True))


@attrs.frozen
class Goal:
    """One validation goal, judged on a sweep's curves."""

    #: median_ratio, every_curve, pattern_order or lateral
    key: str
    #: the goal in words
    claim: str
    #: met, not met or undetermined
    verdict: str
    #: one line: the numbers the verdict rests on
    summary: str
    #: the headers of ``table``
    columns: tuple[str, ...] = ()
    #: the numbers, one row per curve or group (formatted)
    table: tuple[tuple[str, ...], ...] = ()
    #: what was left out and why
    notes: tuple[str, ...] = ()


def _num(value: Any) -> float | None:
    """A float from a row's cell ('' and None are missing; NaN too)."""
    if value is None or value == "":
        return None
    x = float(value)
    return x if math.isfinite(x) else None


def _g(x: float | None) -> str:
    return "—" if x is None else f"{x:.2g}"


def _within(x: float, factor: float) -> bool:
    return 1.0 / factor <= x <= factor


def _curve(r: Mapping[str, Any]) -> str:
    return f"{r['yarn']} {r['pattern']} {r['direction']}"


def _median_ratio(done: list[Mapping[str, Any]], s: GoalSettings) -> Goal:
    claim = f"the median simulated/measured tension is within {s.median_within:g}× of 1"
    by_yarn: dict[str, list[float]] = {}
    for r in done:
        by_yarn.setdefault(str(r["yarn"]), []).extend(
            x for x in (_num(r.get(f"ratio_{p}")) for p in RATIO_AT) if x is not None
        )
    every = [x for xs in by_yarn.values() for x in xs]
    if not every:
        return Goal("median_ratio", claim, UNDETERMINED, "no curve reaches 10 % strain")
    med = float(np.median(every))
    table = tuple(
        (
            yarn,
            f"{float(np.median(xs)):.2g}",
            str(len(xs)),
            "yes" if _within(float(np.median(xs)), s.median_within) else "no",
        )
        for yarn, xs in sorted(by_yarn.items())
        if xs
    )
    verdict = MET if _within(med, s.median_within) else NOT_MET
    summary = f"median {med:.2g} over {len(every)} ratios at {'/'.join(map(str, RATIO_AT))} %"
    return Goal("median_ratio", claim, verdict, summary, ("yarn", "median", "ratios", "within"), table)


def _every_curve(done: list[Mapping[str, Any]], s: GoalSettings) -> Goal:
    claim = f"every curve is within {s.curve_within:g}× of its test"
    rows, good, notes = [], 0, []
    for r in done:
        xs = [_num(r.get(f"ratio_{p}")) for p in RATIO_AT]
        have = [x for x in xs if x is not None]
        if not have:
            notes.append(f"{_curve(r)}: no ratio (a curve ends before 10 %)")
            continue
        ok = all(_within(x, s.curve_within) for x in have)
        good += ok
        rows.append((_curve(r), *(_g(x) for x in xs), "yes" if ok else "no"))
    if not rows:
        return Goal("every_curve", claim, UNDETERMINED, "no curve has a ratio", notes=tuple(notes))
    every = [x for r in done for x in (_num(r.get(f"ratio_{p}")) for p in RATIO_AT) if x is not None]
    summary = f"{good} of {len(rows)} curves; ratios from {min(every):.2g} to {max(every):.2g}"
    columns = ("curve", *(f"at {p} %" for p in RATIO_AT), "within")
    return Goal(
        "every_curve",
        claim,
        MET if good == len(rows) else NOT_MET,
        summary,
        columns,
        tuple(rows),
        tuple(notes),
    )


def _pattern_order(done: list[Mapping[str, Any]]) -> Goal:
    claim = (
        "the patterns come out in the measured order of stiffness (at 10 %), along the course and the wale"
    )
    groups: dict[tuple[str, str], list[tuple[str, float, float]]] = {}
    notes = []
    for r in done:
        ratio, measured = _num(r.get("ratio_10")), _num(r.get("measured_10"))
        if ratio is None or measured is None:
            notes.append(f"{_curve(r)}: no tension at 10 %")
            continue
        groups.setdefault((str(r["yarn"]), str(r["direction"])), []).append(
            (str(r["pattern"]), measured, ratio * measured)
        )
    rows, pairs, good = [], 0, 0
    for (yarn, direction), items in sorted(groups.items()):
        if len(items) < 2:
            continue
        n = ok = 0
        for (_, ma, sa), (_, mb, sb) in itertools.combinations(items, 2):
            n += 1
            ok += (ma - mb) * (sa - sb) > 0
        measured_order = " < ".join(p for p, _, _ in sorted(items, key=lambda t: t[1]))
        simulated_order = " < ".join(p for p, _, _ in sorted(items, key=lambda t: t[2]))
        rows.append((yarn, direction, measured_order, simulated_order, f"{ok} of {n}"))
        pairs += n
        good += ok
    if not rows:
        return Goal(
            "pattern_order",
            claim,
            UNDETERMINED,
            "no yarn has two patterns at 10 % in one direction",
            notes=tuple(notes),
        )
    summary = f"{good} of {pairs} pattern pairs in the measured order"
    columns = ("yarn", "pulled along", "measured, softest first", "simulated", "pairs in order")
    return Goal(
        "pattern_order", claim, MET if good == pairs else NOT_MET, summary, columns, tuple(rows), tuple(notes)
    )


def _lateral(done: list[Mapping[str, Any]], s: GoalSettings) -> Goal:
    claim = f"the lateral contraction is within {s.lateral_within:g} of the measured"
    rows, good, notes = [], 0, []
    for r in done:
        sim, mea, at = (
            _num(r.get("lateral_simulated")),
            _num(r.get("lateral_measured")),
            _num(r.get("lateral_at")),
        )
        if sim is None or mea is None:
            notes.append(f"{_curve(r)}: no lateral strain to compare")
            continue
        ok = abs(sim - mea) <= s.lateral_within
        good += ok
        rows.append((_curve(r), _g(at), f"{sim:.3f}", f"{mea:.3f}", "yes" if ok else "no"))
    if not rows:
        return Goal("lateral", claim, UNDETERMINED, "no curve has lateral strains", notes=tuple(notes))
    summary = f"{good} of {len(rows)} curves"
    columns = ("curve", "at strain", "simulated", "measured", "within")
    return Goal(
        "lateral", claim, MET if good == len(rows) else NOT_MET, summary, columns, tuple(rows), tuple(notes)
    )


def validation_goals(curves: Iterable[Mapping[str, Any]], settings: GoalSettings | None = None) -> list[Goal]:
    """The four goals judged on a validation sweep's curves: the rows of ``validation.csv`` (as
    :class:`csv.DictReader` gives them) or the sweep stage's own. Each row needs ``yarn``,
    ``pattern``, ``direction``, ``measured_status``, ``ratio_10/20/30``, ``measured_10`` (the
    measured tension at 10 %, N/mm) and the lateral strains."""
    s = settings or GoalSettings()
    rows = list(curves)
    done = [r for r in rows if r.get("measured_status") == "done"]
    failed = [
        f"{_curve(r)}: not simulated ({r.get('reason') or 'failed'})"
        for r in rows
        if r.get("measured_status") != "done"
    ]
    goals = [_median_ratio(done, s), _every_curve(done, s), _pattern_order(done), _lateral(done, s)]
    if failed:
        goals = [attrs.evolve(g, notes=(*failed, *g.notes)) for g in goals]
    return goals


def goals_markdown(
    found: Sequence[Goal], *, title: str = "Validation goals", fixed: Sequence[str] = ()
) -> str:
    """The goals as Markdown: how many are met, a verdict line per goal, then each goal's table and
    notes (:func:`knitframe.sweep.trends.verdicts_markdown`), and the lines of ``fixed``
    (:func:`held_fixed`) under "What was held fixed"."""
    met = sum(g.verdict == MET for g in found)
    text = verdicts_markdown(found, title=title, noun="goal", lead=[f"{met} of {len(found)} goals met."])
    if fixed:
        text += "\n".join(["", "## What was held fixed", "", *fixed]) + "\n"
    return text


def _inline(value: Any) -> str:
    """A config value as inline TOML."""
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{k} = {_inline(x)}" for k, x in value.items()) + " }"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_inline(x) for x in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    return repr(value) if isinstance(value, float) else str(value)


#: the keys of a validation point that name what is compared, not how it is simulated
OWN_KEYS = frozenset({"name", "pattern", "yarn", "measured"})


def held_fixed(
    *,
    common: Mapping[str, Mapping[str, Any]],
    points: Sequence[Mapping[str, Any]] = (),
    grid: Mapping[str, Sequence[Any]] | None = None,
    yarns: Sequence[str] = (),
    own_yarns: Sequence[str] = (),
) -> list[str]:
    """Markdown lines saying what a validation sweep held fixed and what it set per point.

    ``common`` maps a table name (``sweep.solver``) to the keys every point shares; ``points`` are
    the config's point tables and ``grid`` its grid, whose keys other than the pattern, the yarn,
    the measured tests and the name are set per point (listed with the point's name or index);
    ``yarns`` are the yarn records used, ``own_yarns`` those the config defines itself. The
    measured tests are only compared with, never fitted to, and the first line says so.
    """
    lines = [
        "Nothing in this run was fitted to the measured tests: they are read only to be compared with "
        "the simulations.",
        "",
    ]
    for table, keys in common.items():
        shown = ", ".join(f"{k} = {_inline(v)}" for k, v in keys.items()) or "nothing set"
        lines.append(f"- the same for every point, `[{table}]`: {shown}; the defaults otherwise")
    if yarns:
        own = set(own_yarns)
        lines.append(
            "- the same yarn record for every point of a yarn: "
            + ", ".join(f"`{y}`" + (" (this config's `[yarns]` table)" if y in own else "") for y in yarns)
            + " (`knitframe yarn NAME` shows each value and whether it is measured)"
        )
    per_point = []
    for i, point in enumerate(points):
        extra = {k: v for k, v in point.items() if k not in OWN_KEYS}
        if extra:
            label = point.get("name") or f"point {i}"
            per_point.append(f"  - {label}: " + ", ".join(f"{k} = {_inline(v)}" for k, v in extra.items()))
    varied = [k for k in (grid or {}) if k not in OWN_KEYS]
    if varied:
        per_point.append("  - varied over the grid: " + ", ".join(f"`{k}`" for k in varied))
    if per_point:
        lines += ["- set per point:", *per_point]
    else:
        lines.append("- set per point: nothing but its pattern, its yarn and its measured tests")
    return lines
