"""knitframe.sweep.trends: the paper's four trends judged on hand-made sweep rows whose verdicts are known."""

from __future__ import annotations

import csv
import io

import pytest

from knitframe.sweep.trends import spans_trends, trends, trends_markdown

PATTERNS = ("jersey", "garter", "rib", "seed")
SLS = (10, 11, 12)
YARNS = ("cotton", "nylon")
#: θ of each pattern, degrees: spread 20° across the patterns
THETA = {"jersey": 45.0, "garter": 30.0, "rib": 50.0, "seed": 38.0}


def rows_where(a=None, b=None, theta=None, at_bound=None, status=None):
    """24 sweep.csv rows as csv.DictReader gives them (strings). Each of a, b, theta, at_bound, status is
    a function of (pattern, stitch length, yarn); the defaults reproduce every trend: b falls with
    the stitch length, θ differs by pattern (jersey 45°), nylon's a is 20× and its b 15× cotton's."""
    a = a or (lambda p, sl, y: (0.02 if y == "cotton" else 0.4) * (13 - sl))
    b = b or (lambda p, sl, y: (0.5 if y == "cotton" else 7.5) * (13 - sl))
    theta = theta or (lambda p, sl, y: THETA[p] + 0.3 * (sl - 11))
    at_bound = at_bound or (lambda p, sl, y: "")
    status = status or (lambda p, sl, y: "done")
    rows = []
    for i, (p, sl, y) in enumerate((p, sl, y) for p in PATTERNS for sl in SLS for y in YARNS):
        done = status(p, sl, y) == "done"
        rows.append(
            {
                "index": i,
                "name": f"{p}-sl{sl}-{y}",
                "status": status(p, sl, y),
                "reason": "" if done else "Newton did not converge",
                "pattern": p,
                "yarn": y,
                "stitch_length": float(sl),
                "a": a(p, sl, y) if done else "",
                "b": b(p, sl, y) if done else "",
                "theta_deg": theta(p, sl, y) if done else "",
                "at_bound": at_bound(p, sl, y) if done else "",
                "nrmse": 0.01,
            }
        )
    text = io.StringIO()
    w = csv.DictWriter(text, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    return list(csv.DictReader(io.StringIO(text.getvalue())))


def verdicts(rows, **kw):
    return {t.key: t.verdict for t in trends(rows, **kw)}


def test_rows_made_to_show_every_trend_reproduce_every_trend():
    found = {t.key: t for t in trends(rows_where())}
    assert {k: t.verdict for k, t in found.items()} == {
        "stitch_b": "reproduced",
        "pattern_theta": "reproduced",
        "yarn_ab": "reproduced",
        "jersey_theta": "reproduced",
    }
    assert found["stitch_b"].summary.startswith("b larger at SL10 than at SL12 in 8 of 8")
    # the numbers: b of jersey cotton at SL10, 11, 12 and the SL10/SL12 ratio 3/1
    jersey_cotton = next(r for r in found["stitch_b"].table if r[:2] == ("jersey", "cotton"))
    assert jersey_cotton[2:6] == ("1.5", "1", "0.5", "3")
    assert "spread" in found["pattern_theta"].columns[3] and found["pattern_theta"].table[0][3] == "20.0"
    assert "in 6 of 6" in found["pattern_theta"].summary
    assert found["yarn_ab"].table[0][3] == "20" and found["yarn_ab"].table[0][5] == "15"
    assert "in 6 of 6 fits" in found["jersey_theta"].summary


def test_b_rising_with_stitch_length_is_not_reproduced():
    rows = rows_where(b=lambda p, sl, y: (0.5 if y == "cotton" else 7.5) * (sl - 9))
    found = {t.key: t for t in trends(rows)}
    assert found["stitch_b"].verdict == "not reproduced"
    assert "in 0 of 8" in found["stitch_b"].summary
    assert found["yarn_ab"].verdict == "reproduced"  # the other trends are untouched


def test_b_at_a_bound_is_left_out_and_said_so():
    # b at its lower bound at SL12 for every fabric but rib nylon: one pair is determined, fewer than 2
    bound = lambda p, sl, y: "b" if sl == 12 and (p, y) != ("rib", "nylon") else ""  # noqa: E731
    rows = rows_where(at_bound=bound, b=lambda p, sl, y: 1e-4 if bound(p, sl, y) else 2.0 * (13 - sl))
    found = {t.key: t for t in trends(rows)}
    assert found["stitch_b"].verdict == "undetermined"
    assert "in 1 of 1" in found["stitch_b"].summary and "7 of 8 pair(s) left out" in found["stitch_b"].summary
    # at the lower bound at SL12, b there is at most the bound: the bounds alone say larger at SL10
    assert "b smaller at SL10 in 0, larger in 7; 0 at the same bound" in found["stitch_b"].summary
    jersey_cotton = found["stitch_b"].table[0]
    assert jersey_cotton[5:] == ("", "left out (the bounds say: larger)")  # no ratio of a bound
    assert any("jersey cotton: b at a bound in jersey SL12 cotton" == n for n in found["stitch_b"].notes)
    assert "(at bound)" in found["stitch_b"].table[0][4]
    # the bound values would otherwise have "reproduced" the trend: they must not count
    assert (
        verdicts(rows_where(b=lambda p, sl, y: 1e-4 if bound(p, sl, y) else 2.0 * (13 - sl)))["stitch_b"]
        == "reproduced"
    )
    # b across the yarns cannot be judged where a yarn's b is at a bound; a still can
    assert "b at a bound" in " ".join(found["yarn_ab"].notes)
    sl12 = [r for r in found["yarn_ab"].table if r[1] == "12" and r[0] != "rib"]
    assert all(r[5].startswith("left out") for r in sl12) and all(r[3] == "20" for r in sl12)


def test_b_at_the_lower_bound_at_the_short_stitch_says_smaller_but_does_not_decide():
    """As in the rod sweep: b at its lower bound at SL10 for every fabric, determined at SL11 and SL12."""
    rows = rows_where(
        at_bound=lambda p, sl, y: "b" if sl == 10 else "",
        b=lambda p, sl, y: 1e-4 if sl == 10 else (0.05 if y == "cotton" else 0.8) * (sl - 10),
    )
    found = {t.key: t for t in trends(rows)}
    assert found["stitch_b"].verdict == "undetermined"
    assert "in 0 of 0" in found["stitch_b"].summary
    assert "b smaller at SL10 in 8, larger in 0" in found["stitch_b"].summary
    assert found["stitch_b"].table[0][-1] == "left out (the bounds say: smaller)"
    # across the yarns, b is determined at SL11 and SL12 only (8 of 12 groups): judged there
    assert "b moves more than 10× across the yarns in 8 of 8" in found["yarn_ab"].summary
    assert "in 0 of the 4 others" in found["yarn_ab"].summary  # both yarns at the same bound: no side
    assert found["yarn_ab"].verdict == "reproduced"


def test_a_trend_judged_on_too_few_determined_comparisons_is_undetermined():
    # b determined for both yarns only at SL12 of jersey and garter: 2 of 12 groups
    free = lambda p, sl, y: sl == 12 and p in ("jersey", "garter")  # noqa: E731
    rows = rows_where(
        at_bound=lambda p, sl, y: "" if free(p, sl, y) else "b",
        b=lambda p, sl, y: (0.5 if y == "cotton" else 7.5) if free(p, sl, y) else 1e-4,
    )
    found = {t.key: t for t in trends(rows)}
    assert (
        "b moves more than 10× across the yarns in 2 of 2 pattern-stitch-length groups with b determined for "
        "every yarn, of 12" in found["yarn_ab"].summary
    )
    assert found["yarn_ab"].verdict == "undetermined"
    assert verdicts(rows, min_determined=0.1)["yarn_ab"] == "reproduced"


def test_the_same_theta_for_every_pattern_is_not_reproduced():
    rows = rows_where(theta=lambda p, sl, y: 44.0 + 0.5 * PATTERNS.index(p))  # spread 1.5°
    v = verdicts(rows)
    assert v["pattern_theta"] == "not reproduced" and v["jersey_theta"] == "reproduced"
    assert verdicts(rows, theta_spread_deg=1.0)["pattern_theta"] == "reproduced"


def test_a_yarn_that_moves_a_but_not_b_tenfold_is_not_reproduced():
    rows = rows_where(b=lambda p, sl, y: (1.0 if y == "cotton" else 3.0) * (13 - sl))
    found = {t.key: t for t in trends(rows)}
    assert found["yarn_ab"].verdict == "not reproduced"
    assert "a moves more than 10× across the yarns in 12 of 12" in found["yarn_ab"].summary
    assert "b moves more than 10× across the yarns in 0 of 12" in found["yarn_ab"].summary
    # a softer second yarn moves a as much as a stiffer one: the factor is largest over smallest
    rows = rows_where(
        a=lambda p, sl, y: 1.0 if y == "cotton" else 0.05,
        b=lambda p, sl, y: (1.0 if y == "cotton" else 0.01) * (13 - sl),
    )
    assert verdicts(rows)["yarn_ab"] == "reproduced"


def test_jersey_theta_away_from_45_is_not_reproduced():
    rows = rows_where(theta=lambda p, sl, y: 62.0 if p == "jersey" else THETA[p])
    found = {t.key: t for t in trends(rows)}
    assert found["jersey_theta"].verdict == "not reproduced"
    assert found["jersey_theta"].summary == "jersey θ within 5° of 45° in 0 of 6 fits (θ 62.0–62.0°)"
    assert verdicts(rows, jersey_tol_deg=20.0)["jersey_theta"] == "reproduced"


def test_failed_points_are_left_out_and_named():
    rows = rows_where(status=lambda p, sl, y: "failed" if p == "jersey" else "done")
    found = {t.key: t for t in trends(rows)}
    assert found["jersey_theta"].verdict == "undetermined" and found["jersey_theta"].table == ()
    assert any(
        n.startswith("jersey-sl10-cotton: failed (Newton did not converge)") for n in found["stitch_b"].notes
    )
    assert found["stitch_b"].summary.startswith("b larger at SL10 than at SL12 in 6 of 6")


def test_spans_and_refusals():
    rows = rows_where()
    assert spans_trends(rows)
    one_yarn = [r for r in rows if r["yarn"] == "cotton"]
    assert not spans_trends(one_yarn)
    with pytest.raises(ValueError, match="2 or more yarns"):
        trends(one_yarn)
    assert not spans_trends(rows + rows[:1])
    with pytest.raises(ValueError, match="two rows for jersey SL10 cotton"):
        trends(rows + rows[:1])


def test_markdown_has_a_line_and_a_table_per_trend():
    text = trends_markdown(trends(rows_where(b=lambda p, sl, y: 1.0 * (sl - 9))), title="demo")
    assert text.startswith("# demo\n")
    assert "| a shorter stitch gives a larger b | **not reproduced** |" in text
    assert text.count("\n## ") == 4
    assert "| pattern | yarn | b SL10 | b SL11 | b SL12 | b SL10 / SL12 |  |" in text
    # a failed point is named once, above the trends, with the first clause of its reason
    rows = rows_where(status=lambda p, sl, y: "failed" if (p, sl, y) == ("seed", 10, "cotton") else "done")
    rows[18]["reason"] = "NumericalError: no convergence in 400 iterations; it 395: E=15.9; it 396: E=15.9"
    text = trends_markdown(trends(rows))
    assert text.count("seed-sl10-cotton: failed") == 1
    assert "- seed-sl10-cotton: failed (NumericalError: no convergence in 400 iterations), not used" in text


# --------------------------------------------------------------------------- the sweep stage's trends.md
class _Ctx:
    def __init__(self, folder):
        self.folder = folder

    def output(self, name):
        return self.folder / name


def _stage(tmp_path, grid):
    from knitframe.config import load_toml
    from knitframe.pipeline import Pipeline

    cfg = tmp_path / "sweep.toml"
    cfg.write_text(
        f'[sweep]\nname = "t"\ngrid = {grid}\n\n[sweep.solver]\nkind = "rod"\n\n[sweep.scene]\n'
        'effects = ["large_deformation", "bending", "contact", "prestress"]\n'
        'load = { kind = "equibiaxial", max_strain = 0.5, steps = 10 }\n'
    )
    (stage,) = Pipeline(load_toml(cfg), base_dir=tmp_path, source=str(cfg)).stages
    return stage


def test_the_sweep_stage_writes_trends_md_for_a_grid_that_spans_the_trends(tmp_path):
    stage = _stage(
        tmp_path,
        '{ pattern = ["jersey", "garter", "rib", "seed"], stitch_length = [10, 11, 12], '
        'yarn = ["cotton", "nylon"] }',
    )
    rows = rows_where(b=lambda p, sl, y: (0.5 if y == "cotton" else 7.5) * (sl - 9))
    assert stage._write_trends(_Ctx(tmp_path), rows) == {
        "stitch_b": "not reproduced",
        "pattern_theta": "reproduced",
        "yarn_ab": "reproduced",
        "jersey_theta": "reproduced",
    }
    text = (tmp_path / "trends.md").read_text(encoding="utf-8")
    assert (
        "| a shorter stitch gives a larger b | **not reproduced** | b larger at SL10 than at SL12 in 0 of 8"
        in text
    )
    assert "equibiaxial 0-50 % in 10 steps" in text.splitlines()[0]


def test_the_sweep_stage_writes_no_trends_md_for_one_yarn(tmp_path):
    stage = _stage(tmp_path, '{ pattern = ["jersey", "rib"], stitch_length = [11, 12], yarn = ["cotton"] }')
    rows = [
        r
        for r in rows_where()
        if r["yarn"] == "cotton" and r["pattern"] in ("jersey", "rib") and r["stitch_length"] != "10.0"
    ]
    assert stage._write_trends(_Ctx(tmp_path), rows) == {}
    assert not (tmp_path / "trends.md").exists()


def test_the_shipped_trends_config_is_the_24_fabric_rod_sweep_with_nothing_per_fabric():
    from pathlib import Path

    from knitframe.config import load_toml
    from knitframe.pipeline import Pipeline

    path = Path(__file__).resolve().parents[1] / "knitframe" / "examples" / "trends-rod.toml"
    (stage,) = Pipeline(load_toml(path), base_dir=path.parent, source=str(path)).stages
    assert len(stage.points) == 24
    assert {
        (p.stage.fabric.pattern, p.stage.fabric.stitch_length, p.stage.fabric.yarn.name) for p in stage.points
    } == {(p, float(sl), y) for p in PATTERNS for sl in SLS for y in YARNS}
    # one solver, scene and fit for every point: the jobs differ only in their fabric
    assert all(
        j["solver"] == stage.jobs[0]["solver"]
        and j["scenes"] == stage.jobs[0]["scenes"]
        and j["fit"] == stage.jobs[0]["fit"]
        for j in stage.jobs
    )
    assert stage.jobs[0]["solver"]["kind"] == "rod" and stage.jobs[0]["solver"]["starts"] == "auto"
    load = stage.jobs[0]["scenes"][0]["load"]
    assert (load["kind"], load["max_strain"], load["steps"]) == ("equibiaxial", 0.5, 10)
    assert stage.model_name == "hgo" and stage.fitter_name == "lbfgs"


def test_the_shipped_volumetric_trends_config_is_the_same_24_fabrics_on_the_p1_cell():
    from pathlib import Path

    from knitframe.config import load_toml
    from knitframe.pipeline import Pipeline

    path = Path(__file__).resolve().parents[1] / "knitframe" / "examples" / "trends-volumetric-p1.toml"
    (stage,) = Pipeline(load_toml(path), base_dir=path.parent, source=str(path)).stages
    assert {
        (p.stage.fabric.pattern, p.stage.fabric.stitch_length, p.stage.fabric.yarn.name) for p in stage.points
    } == {(p, float(sl), y) for p in PATTERNS for sl in SLS for y in YARNS}
    assert all(
        j["solver"] == stage.jobs[0]["solver"] and j["scenes"] == stage.jobs[0]["scenes"] for j in stage.jobs
    )
    solver = stage.jobs[0]["solver"]
    assert (solver["kind"], solver["order"], solver["seed"]) == ("volumetric", 1, 1.0)
    load = stage.jobs[0]["scenes"][0]["load"]
    assert (load["kind"], load["max_strain"], load["steps"]) == ("equibiaxial", 0.3, 6)


def test_a_sweep_run_writes_trends_md_and_its_verdicts(tmp_path, monkeypatch):
    """The whole stage (run, outputs, results) with the point function replaced by fits whose trends are
    known."""
    import numpy as np

    import knitframe.sweep.job as sweep
    from knitframe.pipeline import run
    from knitframe.records import Provenance, Response

    def fake_point(job):
        f = job["fabric"]
        sl, yarn = f["stitch_length"], f["yarn"]["name"]
        lam = np.linspace(1.05, 1.5, 10)
        r = Response(
            lambda1=lam, lambda2=lam, T1=lam - 1.0, T2=lam - 1.0, provenance=Provenance(kind="simulation")
        )
        # b larger at the shorter stitch, nylon's a 20x and b 15x cotton's, θ by pattern: every trend shown
        fit = {
            "model": "hgo",
            "a": (0.02 if yarn == "cotton" else 0.4) * (13 - sl),
            "b": (0.5 if yarn == "cotton" else 7.5) * (13 - sl),
            "theta_deg": THETA[f["pattern"]],
            "nrmse": {"overall": 0.01},
            "fitter": "lbfgs",
            "converged": True,
            "at_bound": [],
            "warnings": [],
        }
        return {
            "fit": fit,
            "responses": [r.to_dict()],
            "simulate_s": 0.0,
            "fit_s": 0.0,
            "wall_time_s": 0.0,
            "warnings": [],
            "host": "test",
        }

    monkeypatch.setattr(sweep, "run_point", fake_point)
    cfg = tmp_path / "sweep.toml"
    cfg.write_text(
        '[sweep]\nname = "t"\ngrid = { pattern = ["jersey", "garter", "rib", "seed"], '
        'stitch_length = [10, 11, 12], yarn = ["cotton", "nylon"] }\n\n[sweep.solver]\nkind = "rod"\n\n'
        '[sweep.scene]\neffects = ["large_deformation", "bending", "contact", "prestress"]\n'
        'load = { kind = "equibiaxial", max_strain = 0.5, steps = 10 }\n\n[executor]\nkind = "local"\n'
    )
    res = run(cfg, tmp_path / "out", no_cache=True, quiet=True)
    assert res.results["sweep"]["trends"] == {
        "stitch_b": "reproduced",
        "pattern_theta": "reproduced",
        "yarn_ab": "reproduced",
        "jersey_theta": "reproduced",
    }
    text = (tmp_path / "out" / "trends.md").read_text(encoding="utf-8")
    assert "b larger at SL10 than at SL12 in 8 of 8" in text
    assert "trends.md" in res.summary["outputs"]
