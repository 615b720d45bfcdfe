"""The ladder's tables: ``ladder.csv`` (:data:`CSV_COLUMNS`) and the Markdown table ``ladder.md``."""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from knitframe.ladder.cost import format_duration, format_memory

CSV_COLUMNS = (
    "rung",
    "family",
    "solver",
    "options",
    "effects",
    "dofs",
    "increments",
    "status",
    "cached",
    "reference",
    "wall_time_s",
    "peak_rss_mb",
    "estimated_time_s",
    "estimated_rss_mb",
    "estimate_basis",
    "T1_end_N_per_mm",
    "T2_end_N_per_mm",
    "nrmse_vs_best",
    "nrmse_course_vs_best",
    "nrmse_wale_vs_best",
    "nrmse_vs_measured",
    "nrmse_course_vs_measured",
    "nrmse_wale_vs_measured",
    "fabric",
    "load",
    "notes",
)


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> None:
    """``ladder.csv``: one row per rung, :data:`CSV_COLUMNS`."""
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS)
        for row in rows:
            w.writerow([_cell(row.get(c)) for c in CSV_COLUMNS])


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (dict, list)):
        return json.dumps(value, sort_keys=True)
    return str(value)


def _pct(x: float | None) -> str:
    if x is None:
        return "–"
    return f"{100 * x:.0f} %" if abs(x) >= 10 else f"{100 * x:.3g} %"


def _tension(x: float) -> str:
    return "0" if abs(x) < 1e-9 else f"{x:.4g}"


def write_table(path: Path, rows: Sequence[Mapping[str, Any]], *, title: str, measured: Sequence[str]) -> str:
    """``ladder.md``: the Markdown table (returned as well)."""
    has_measured = bool(measured)
    head = (
        [
            "rung",
            "DOFs",
            "wall time",
            "peak memory",
            "estimated before",
            "T1, T2 at the end (N/mm)",
            "NRMSE vs best (course, wale)",
        ]
        + (["NRMSE vs measured"] if has_measured else [])
        + ["status"]
    )
    lines = [f"**{title}**", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in rows:
        ok = row.get("wall_time_s") is not None
        best = (
            "reference"
            if row.get("reference")
            else f"{_pct(row.get('nrmse_vs_best'))} ({_pct(row.get('nrmse_course_vs_best'))}, "
            f"{_pct(row.get('nrmse_wale_vs_best'))})"
            if row.get("nrmse_vs_best") is not None
            else "–"
        )
        est = (
            "–"
            if row.get("estimated_time_s") is None
            else (
                format_duration(row["estimated_time_s"])
                + (
                    ""
                    if row.get("estimated_rss_mb") is None
                    else f", {format_memory(row['estimated_rss_mb'])}"
                )
            )
        )
        ends = (
            "–"
            if row.get("T1_end_N_per_mm") is None
            else f"{_tension(row['T1_end_N_per_mm'])}, {_tension(row['T2_end_N_per_mm'])}"
        )
        status = row.get("status", "")
        if row.get("cached"):
            status += " (cached)"
        cells = [
            row["rung"],
            f"{row['dofs']:,}".replace(",", " ") if row.get("dofs") else "–",
            format_duration(row["wall_time_s"]) if ok else "–",
            format_memory(row["peak_rss_mb"]) if row.get("peak_rss_mb") else "–",
            est,
            ends,
            best,
        ]
        if has_measured:
            cells.append(_pct(row.get("nrmse_vs_measured")))
        cells.append(status.replace("|", "/"))
        lines.append("| " + " | ".join(cells) + " |")
    if has_measured:
        lines += ["", f"Measured: {', '.join(measured)} (points up to the path's largest stretch)."]
    text = "\n".join(lines) + "\n"
    path.write_text(text, encoding="utf-8")
    return text
