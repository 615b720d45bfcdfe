"""The paper's four trends, judged from a sweep's fitted hgo parameters.

du Pasquier et al. (2026) report, for the reduced model ψ = a/b·[exp(b(I4−1)²)−1] with a fibre at
θ:

1. ``stitch_b``: a shorter stitch gives a larger b;
2. ``pattern_theta``: the pattern moves θ;
3. ``yarn_ab``: the yarn moves a and b by more than 10×;
4. ``jersey_theta``: jersey's θ is near 45°.

:func:`trends` takes the rows of a sweep's ``sweep.csv`` (as :class:`csv.DictReader` gives them,
or the sweep stage's own rows) and returns one :class:`Trend` per claim: ``reproduced``, ``not
reproduced`` or ``undetermined``, with the numbers it was judged on. A parameter that ended at a
bound of the model's box (the ``at_bound`` column) is not determined by the simulated curves: it
is left out of the comparison, and the trend says so. :func:`trends_markdown` writes them as a
Markdown report (the sweep stage's ``trends.md``)::

    import csv
    from knitframe.sweep.trends import trends, trends_markdown
    rows = list(csv.DictReader(open("sweep-out/sweep.csv")))
    for t in trends(rows):
        print(t.key, t.verdict, t.summary)

The rules (every threshold is a keyword argument). A trend is undetermined when fewer than
``min_cases`` (2) of its comparisons, or fewer than ``min_determined`` (half) of them, have their
parameters determined; otherwise it is reproduced when at least ``share`` (3/4) of the determined
comparisons show it, and not reproduced when fewer do.

* ``stitch_b``: for each pattern and yarn, b at the shortest against b at the longest stitch
  length, where neither b is at a bound. A b at a bound still gives a side (at the lower bound the
  curve wants b no larger), and the summary counts the pairs where the bounds alone say smaller or
  larger; they do not enter the verdict.
* ``pattern_theta``: for each yarn and stitch length, the spread (max − min) of θ across the
  patterns; shown when at least ``theta_spread_deg`` (5°).
* ``yarn_ab``: for each pattern and stitch length, the largest over the smallest a (and b) across
  the yarns, above ``yarn_factor`` (10); reproduced when both a and b are, not reproduced if
  either is not. Groups with a bound are counted apart, as for ``stitch_b``.
* ``jersey_theta``: |θ − 45°| ≤ ``jersey_tol_deg`` (5°) for the jersey fits.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import attrs

__all__ = ["Trend", "trends", "trends_markdown", "verdicts_markdown", "spans_trends", "VERDICTS"]

REPRODUCED, NOT_REPRODUCED, UNDETERMINED = "reproduced", "not reproduced", "undetermined"
VERDICTS = (REPRODUCED, NOT_REPRODUCED, UNDETERMINED)


@attrs.frozen
class Trend:
    """One of the paper's trends, judged on a sweep."""

    #: stitch_b, pattern_theta, yarn_ab or jersey_theta
    key: str
    #: the paper's claim in words
    claim: str
    #: reproduced, not reproduced or undetermined
    verdict: str
    #: one line: the count the verdict rests on
    summary: str
    #: the headers of ``table``
    columns: tuple[str, ...]
    #: the numbers, one row per comparison (formatted)
    table: tuple[tuple[str, ...], ...]
    #: what was left out and why (fits at a bound, failed points)
    notes: tuple[str, ...] = ()


# ------------------------------------------------------------------------------------------ rows
@attrs.frozen
class _Fit:
    pattern: str
    yarn: str
    sl: float
    a: float | None
    b: float | None
    #: degrees
    theta: float | None
    bound: frozenset[str]

    @property
    def label(self) -> str:
        return f"{self.pattern} SL{self.sl:g} {self.yarn}"


def _num(value: Any) -> float | None:
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    x = float(value)
    return x if math.isfinite(x) else None


def _fits(rows: Iterable[Mapping[str, Any]]) -> tuple[list[_Fit], list[str]]:
    """The done rows with a stitch length, and a note per row left out."""
    fits, left = [], []
    seen: dict[tuple[str, str, float], str] = {}
    for r in rows:
        name = str(r.get("name") or r.get("index") or "?")
        if r.get("status", "done") != "done":
            reason = str(r.get("reason") or "no reason").split("; ")[0]
            shown = reason if len(reason) <= 160 else reason[:157] + "..."
            left.append(f"{name}: {r.get('status')} ({shown}), not used")
            continue
        sl = _num(r.get("stitch_length"))
        a, b, th = _num(r.get("a")), _num(r.get("b")), _num(r.get("theta_deg"))
        if sl is None or (a is None and b is None and th is None):
            left.append(
                f"{name}: " + ("no stitch length" if sl is None else "no fitted parameters") + ", not used"
            )
            continue
        key = (str(r["pattern"]), str(r["yarn"]), sl)
        if key in seen:
            raise ValueError(
                f"two rows for {key[0]} SL{sl:g} {key[1]} ({seen[key]} and {name}): the trends compare "
                "one fit per pattern, stitch length and yarn"
            )
        seen[key] = name
        fits.append(_Fit(key[0], key[1], sl, a, b, th, frozenset(str(r.get("at_bound") or "").split())))
    return fits, left


def spans_trends(rows: Iterable[Mapping[str, Any]]) -> bool:
    """True when the done rows span at least 2 stitch lengths, 2 patterns and 2 yarns, one fit each."""
    try:
        fits, _ = _fits(rows)
    except ValueError:
        return False
    return all(len({getattr(f, k) for f in fits}) >= 2 for k in ("sl", "pattern", "yarn"))


def _g(x: float | None) -> str:
    return "" if x is None else f"{x:.3g}"


def _verdict(
    hits: int, cases: int, share: float, min_cases: int, total: int = 0, min_determined: float = 0.0
) -> str:
    """Reproduced when ``hits`` reach ``share`` of the determined ``cases``; undetermined when fewer than
    ``min_cases`` cases, or fewer than ``min_determined`` of all ``total`` comparisons, are determined."""
    if cases < max(min_cases, min_determined * total):
        return UNDETERMINED
    return REPRODUCED if hits >= share * cases else NOT_REPRODUCED


def _order(values: Iterable[Any]) -> list[Any]:
    return list(dict.fromkeys(values))


def _interval(f: _Fit, name: str) -> tuple[float, float] | None:
    """What a fit says of a positive parameter: ``(v, v)`` when determined; at a bound, only a side: at the
    lower bound the data want it no larger, ``(0, v)``, at the upper no smaller, ``(v, inf)`` (which bound:
    the nearer on a log scale, the box being [1e-4, 1e3] for hgo's b)."""
    v = getattr(f, name)
    if v is None or v <= 0:
        return None
    if name not in f.bound:
        return v, v
    return (0.0, v) if v < 1.0 else (v, math.inf)


def _cell(f: _Fit | None, name: str) -> str:
    if f is None:
        return ""
    return _g(getattr(f, name)) + (" (at bound)" if name in f.bound else "")


# ------------------------------------------------------------------------------------------ the trends
def _stitch_b(fits: list[_Fit], share: float, min_cases: int, min_determined: float) -> Trend:
    sls = sorted({f.sl for f in fits})
    short, long_ = sls[0], sls[-1]
    by = {(f.pattern, f.yarn, f.sl): f for f in fits}
    rows, notes = [], []
    hits = cases = 0
    one_sided = {"larger": 0, "smaller": 0, "unknown": 0}
    for pattern in _order(f.pattern for f in fits):
        for yarn in _order(f.yarn for f in fits):
            s, lo = by.get((pattern, yarn, short)), by.get((pattern, yarn, long_))
            if s is None or lo is None or s.b is None or lo.b is None:
                continue
            ratio = ""
            if "b" in s.bound or "b" in lo.bound:
                notes.append(
                    f"{pattern} {yarn}: b at a bound in "
                    + ", ".join(f.label for f in (s, lo) if "b" in f.bound)
                )
                (s_lo, s_hi), (l_lo, l_hi) = _interval(s, "b"), _interval(lo, "b")
                side = "larger" if s_lo > l_hi else "smaller" if s_hi < l_lo else "unknown"
                one_sided[side] += 1
                verdict = {
                    "larger": "left out (the bounds say: larger)",
                    "smaller": "left out (the bounds say: smaller)",
                    "unknown": "left out",
                }[side]
            else:
                cases += 1
                up = s.b > lo.b
                hits += up
                ratio = _g(s.b / lo.b)
                verdict = "larger at the shorter stitch" if up else "not larger"
            mid = [by.get((pattern, yarn, x)) for x in sls[1:-1]]
            rows.append(
                (pattern, yarn, _cell(s, "b"), *[_cell(m, "b") for m in mid], _cell(lo, "b"), ratio, verdict)
            )
    columns = ("pattern", "yarn", *[f"b SL{x:g}" for x in sls], f"b SL{short:g} / SL{long_:g}", "")
    verdict = _verdict(hits, cases, share, min_cases, len(rows), min_determined)
    left = len(rows) - cases
    summary = (
        f"b larger at SL{short:g} than at SL{long_:g} in {hits} of {cases} pattern-yarn pairs with b "
        f"determined at both; {left} of {len(rows)} pair(s) left out with b at a bound"
    )
    if left:
        summary += (
            f" (where a bound gives a side: b smaller at SL{short:g} in {one_sided['smaller']}, larger in "
            f"{one_sided['larger']}; {one_sided['unknown']} at the same bound at both)"
        )
    return Trend(
        "stitch_b", "a shorter stitch gives a larger b", verdict, summary, columns, tuple(rows), tuple(notes)
    )


def _pattern_theta(fits: list[_Fit], share: float, min_cases: int, spread_deg: float) -> Trend:
    rows, notes = [], []
    hits = cases = 0
    for yarn in _order(f.yarn for f in fits):
        for sl in sorted({f.sl for f in fits}):
            group = [f for f in fits if f.yarn == yarn and f.sl == sl]
            used = [f for f in group if f.theta is not None and "theta_deg" not in f.bound]
            notes += [f"{f.label}: θ at a bound, left out" for f in group if "theta_deg" in f.bound]
            if len(used) < 2:
                continue
            cases += 1
            ths = [f.theta for f in used]
            spread = max(ths) - min(ths)
            hits += spread >= spread_deg
            lo, hi = min(used, key=lambda f: f.theta), max(used, key=lambda f: f.theta)
            rows.append(
                (
                    yarn,
                    f"{sl:g}",
                    ", ".join(f"{f.pattern} {f.theta:.1f}" for f in used),
                    f"{spread:.1f}",
                    f"{lo.pattern} → {hi.pattern}",
                )
            )
    verdict = _verdict(hits, cases, share, min_cases)
    summary = f"θ spread across patterns ≥ {spread_deg:g}° in {hits} of {cases} yarn-stitch-length groups"
    return Trend(
        "pattern_theta",
        "the pattern moves θ",
        verdict,
        summary,
        ("yarn", "SL", "θ by pattern, °", "spread, °", "lowest → highest"),
        tuple(rows),
        tuple(notes),
    )


def _yarn_ab(fits: list[_Fit], share: float, min_cases: int, min_determined: float, factor: float) -> Trend:
    yarns = _order(f.yarn for f in fits)
    rows, notes = [], []
    hits = {"a": 0, "b": 0}
    cases = {"a": 0, "b": 0}
    total = {"a": 0, "b": 0}
    beyond = {"a": 0, "b": 0}  # left out, but the bounds alone put the spread above the factor
    for pattern in _order(f.pattern for f in fits):
        for sl in sorted({f.sl for f in fits}):
            group = {f.yarn: f for f in fits if f.pattern == pattern and f.sl == sl}
            if len(group) < 2:
                continue
            cells = []
            for p in ("a", "b"):
                spans = {y: _interval(f, p) for y, f in group.items()}
                if any(v is None for v in spans.values()):
                    cells += ["", ""]
                    continue
                total[p] += 1
                values = " / ".join(_cell(group[y], p) for y in yarns if y in group)
                bound = [f.label for f in group.values() if p in f.bound]
                if bound:  # a yarn's value is only a side: the spread across yarns is not known
                    notes.append(f"{pattern} SL{sl:g}: {p} at a bound in " + ", ".join(bound))
                    least = max(
                        lo / hi for y1, (lo, _) in spans.items() for y2, (_, hi) in spans.items() if y1 != y2
                    )
                    beyond[p] += least > factor
                    cells += [values, f"left out (bounds: > {least:.3g})" if least > 1.0 else "left out"]
                    continue
                vals = [lo for lo, _ in spans.values()]
                spread = max(vals) / min(vals)
                cases[p] += 1
                hits[p] += spread > factor
                cells += [values, f"{spread:.3g}"]
            rows.append((pattern, f"{sl:g}", *cells))
    verdicts = {
        p: _verdict(hits[p], cases[p], share, min_cases, total[p], min_determined) for p in ("a", "b")
    }
    if NOT_REPRODUCED in verdicts.values():
        verdict = NOT_REPRODUCED
    elif UNDETERMINED in verdicts.values():
        verdict = UNDETERMINED
    else:
        verdict = REPRODUCED
    parts = []
    for p in ("a", "b"):
        text = (
            f"{p} moves more than {factor:g}× across the yarns in {hits[p]} of {cases[p]} "
            f"pattern-stitch-length groups with {p} determined for every yarn, of {total[p]}"
        )
        if total[p] > cases[p]:
            others = total[p] - cases[p]
            text += f" (the bounds alone put it above {factor:g}× in {beyond[p]} of the {others} others)"
        parts.append(text + f": {verdicts[p]}")
    names = " / ".join(yarns)
    columns = ("pattern", "SL", f"a ({names}), N/mm", "a max/min", f"b ({names})", "b max/min")
    return Trend(
        "yarn_ab",
        f"the yarn moves a and b by more than {factor:g}×",
        verdict,
        "; ".join(parts),
        columns,
        tuple(rows),
        tuple(notes),
    )


def _jersey_theta(fits: list[_Fit], share: float, min_cases: int, tol_deg: float) -> Trend:
    jersey = [f for f in fits if f.pattern == "jersey" and f.theta is not None]
    used = [f for f in jersey if "theta_deg" not in f.bound]
    notes = tuple(f"{f.label}: θ at a bound, left out" for f in jersey if "theta_deg" in f.bound)
    hits = sum(abs(f.theta - 45.0) <= tol_deg for f in used)
    rows = tuple(
        (
            f.yarn,
            f"{f.sl:g}",
            f"{f.theta:.1f}",
            f"{f.theta - 45.0:+.1f}",
            "yes" if abs(f.theta - 45.0) <= tol_deg else "no",
        )
        for f in used
    )
    verdict = _verdict(hits, len(used), share, 1)
    summary = f"jersey θ within {tol_deg:g}° of 45° in {hits} of {len(used)} fits"
    if used:
        ths = sorted(f.theta for f in used)
        summary += f" (θ {ths[0]:.1f}–{ths[-1]:.1f}°)"
    return Trend(
        "jersey_theta",
        "jersey θ is near 45°",
        verdict,
        summary,
        ("yarn", "SL", "θ, °", "θ − 45°", f"within {tol_deg:g}°"),
        rows,
        notes,
    )


def trends(
    rows: Iterable[Mapping[str, Any]],
    *,
    share: float = 0.75,
    min_cases: int = 2,
    min_determined: float = 0.5,
    theta_spread_deg: float = 5.0,
    yarn_factor: float = 10.0,
    jersey_tol_deg: float = 5.0,
) -> list[Trend]:
    """The paper's four trends judged on a sweep's rows (see the module's text for the rules).

    ``rows``: sweep.csv's rows (strings, as :class:`csv.DictReader` reads them) or the sweep stage's
    own; they need ``status``, ``pattern``, ``yarn``, ``stitch_length``, ``a``, ``b``, ``theta_deg``
    and ``at_bound``. Rows that failed, or have no stitch length, are left out (said in every
    trend's notes). Raises :class:`ValueError` for two rows of the same pattern, stitch length and
    yarn, or when the rows do not span 2 stitch lengths, 2 patterns and 2 yarns.
    """
    fits, left = _fits(rows)
    missing = [
        what
        for what, k in (("stitch lengths", "sl"), ("patterns", "pattern"), ("yarns", "yarn"))
        if len({getattr(f, k) for f in fits}) < 2
    ]
    if missing:
        raise ValueError("the trends need fitted fabrics at 2 or more " + ", ".join(missing))
    out = [
        _stitch_b(fits, share, min_cases, min_determined),
        _pattern_theta(fits, share, min_cases, theta_spread_deg),
        _yarn_ab(fits, share, min_cases, min_determined, yarn_factor),
        _jersey_theta(fits, share, min_cases, jersey_tol_deg),
    ]
    return [attrs.evolve(t, notes=t.notes + tuple(left)) for t in out]


def verdicts_markdown(found: Sequence[Any], *, title: str, noun: str, lead: Sequence[str] = ()) -> str:
    """Judged claims as Markdown: a verdict line per claim, then each claim's table and notes.

    ``found`` holds records with ``claim``, ``verdict``, ``summary``, ``columns``, ``table`` and
    ``notes`` (:class:`Trend`, :class:`knitframe.sweep.goals.Goal`); ``noun`` names them ("trend",
    "goal"); ``lead`` lines go between the title and the table. A note every claim has is written
    once, under "Left out of every <noun>".
    """
    lines = [f"# {title}", ""] + ([*lead, ""] if lead else [])
    lines += [f"| {noun} | verdict | on what |", "|---|---|---|"]
    lines += [f"| {t.claim} | **{t.verdict}** | {t.summary} |" for t in found]
    common = [n for n in (found[0].notes if found else ()) if all(n in t.notes for t in found)]
    if common:
        lines += ["", f"Left out of every {noun}:", ""] + [f"- {n}" for n in common]
    for t in found:
        lines += ["", f"## {t.claim}: {t.verdict}", "", t.summary + ".", ""]
        if t.table:
            lines += ["| " + " | ".join(t.columns) + " |", "|" + "---|" * len(t.columns)]
            lines += ["| " + " | ".join(row) + " |" for row in t.table]
        own = [n for n in t.notes if n not in common]
        if own:
            lines += ["", "Left out:", ""] + [f"- {n}" for n in own]
    return "\n".join(lines) + "\n"


def trends_markdown(found: Sequence[Trend], *, title: str = "The paper's trends") -> str:
    """The trends as Markdown: a verdict line per trend, then each trend's table and notes."""
    return verdicts_markdown(found, title=title, noun="trend")
