"""The validation goals of a sweep against measured tests (knitframe.sweep.goals), on hand-made rows."""

from __future__ import annotations

import csv
import io

import pytest

from knitframe.sweep.goals import MET, NOT_MET, UNDETERMINED, GoalSettings, goals_markdown, validation_goals


def row(yarn, pattern, direction, ratios, measured_10, lateral=(-0.10, -0.08), status="done"):
    r10, r20, r30 = ratios
    return {
        "yarn": yarn,
        "pattern": pattern,
        "direction": direction,
        "measured_status": status,
        "reason": "" if status == "done" else "mesh failed",
        "ratio_10": r10,
        "ratio_20": r20,
        "ratio_30": r30,
        "measured_10": measured_10,
        "lateral_at": 0.2,
        "lateral_simulated": lateral[0],
        "lateral_measured": lateral[1],
    }


def by_key(goals):
    return {g.key: g for g in goals}


def test_every_goal_met_when_the_simulation_is_the_test():
    rows = [
        row("a", "jersey", "course", (1.0, 1.1, 0.9), 0.01),
        row("a", "rib", "course", (1.2, 1.0, 1.0), 0.002),
        row("a", "seed", "course", (0.8, 0.9, None), 0.05),
    ]
    goals = by_key(validation_goals(rows))
    assert {k: g.verdict for k, g in goals.items()} == dict.fromkeys(
        ("median_ratio", "every_curve", "pattern_order", "lateral"), MET
    )
    assert goals["median_ratio"].summary == "median 1 over 8 ratios at 10/20/30 %"
    assert goals["pattern_order"].summary == "3 of 3 pattern pairs in the measured order"
    assert goals["pattern_order"].table[0][2:] == ("rib < jersey < seed", "rib < jersey < seed", "3 of 3")


def test_verdicts_and_counts():
    rows = [
        row("a", "jersey", "course", (1.0, 1.0, 1.0), 0.01),
        row("a", "rib", "course", (10.0, 10.0, 10.0), 0.002),
        row("b", "jersey", "wale", (0.1, 0.1, 0.1), 0.3, lateral=(-0.20, -0.05)),
        row("b", "garter", "wale", (0.1, 0.1, 0.1), 0.1),
    ]
    goals = by_key(validation_goals(rows))
    # 12 ratios: 0.1 x6, 1 x3, 10 x3; median (0.1 + 1)/2 = 0.55, not within 1.5x
    assert goals["median_ratio"].verdict == NOT_MET
    assert goals["median_ratio"].summary == "median 0.55 over 12 ratios at 10/20/30 %"
    assert [r[0] for r in goals["median_ratio"].table] == ["a", "b"]
    assert goals["every_curve"].verdict == NOT_MET
    assert goals["every_curve"].summary == "1 of 4 curves; ratios from 0.1 to 10"
    # a: rib 0.002 -> 0.02 simulated, jersey 0.01 -> 0.01: the pair is reversed; b keeps its order
    assert goals["pattern_order"].summary == "1 of 2 pattern pairs in the measured order"
    assert goals["pattern_order"].verdict == NOT_MET
    assert goals["lateral"].summary == "3 of 4 curves"
    md = goals_markdown(validation_goals(rows), title="t")
    assert "0 of 4 goals met." in md and "| b jersey wale | 0.2 | -0.200 | -0.050 | no |" in md


def test_thresholds_are_options():
    rows = [row("a", "jersey", "course", (2.0, 2.0, 2.0), 0.01, lateral=(-0.2, -0.1))]
    loose = by_key(validation_goals(rows, GoalSettings(median_within=2.5, lateral_within=0.15)))
    strict = by_key(validation_goals(rows))
    assert loose["median_ratio"].verdict == MET and strict["median_ratio"].verdict == NOT_MET
    assert loose["lateral"].verdict == MET and strict["lateral"].verdict == NOT_MET
    assert loose["pattern_order"].verdict == UNDETERMINED  # one pattern: nothing to order


def test_failed_curves_and_csv_strings_are_read():
    rows = [
        row("a", "jersey", "course", (1.0, 1.0, 1.0), 0.01),
        row("a", "garter", "course", ("", "", ""), "", status="failed"),
    ]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    read = list(csv.DictReader(io.StringIO(buf.getvalue())))
    goals = by_key(validation_goals(read))
    assert goals["median_ratio"].verdict == MET
    assert "a garter course: not simulated (mesh failed)" in goals["every_curve"].notes
    md = goals_markdown(list(goals.values()))
    assert md.count("a garter course: not simulated (mesh failed)") == 1  # once, for every goal
    assert "Left out of every goal:" in md


def test_no_curve_is_undetermined():
    goals = validation_goals([])
    assert [g.verdict for g in goals] == [UNDETERMINED] * 4


@pytest.mark.parametrize("field", ["median_within", "curve_within"])
def test_a_factor_below_one_is_refused(field):
    with pytest.raises(ValueError, match=field):
        GoalSettings(**{field: 0.5})
