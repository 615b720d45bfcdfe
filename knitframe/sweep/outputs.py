"""The sweep's files: ``sweep.csv`` and ``validation.csv`` (:func:`write_csv`), ``trends.md``
(:func:`write_trends`) and ``params.png``, the paper's Fig. 4 (:func:`plot_params`).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["write_csv", "write_trends", "plot_params"]


def write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    """``rows`` as a CSV file, the first row's keys as the header; None and non-finite numbers are
    empty cells, other floats their ``repr`` (every digit)."""

    def cell(v: Any) -> Any:
        if v is None:
            return ""
        if isinstance(v, float):
            return repr(v) if math.isfinite(v) else ""
        return v

    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: cell(v) for k, v in r.items()})


def write_trends(
    output: Callable[[str], Path], rows: list[dict[str, Any]], param_keys: list[str], title: str
) -> dict[str, str]:
    """trends.md: the paper's four trends judged on the fits (:mod:`knitframe.sweep.trends`), when the model
    has a, b and θ (``param_keys``) and the points span stitch lengths, patterns and yarns, one fit
    each; ``output(name)`` gives the file's path (and records it). Returns ``{trend: verdict}``,
    empty when nothing was judged."""
    from knitframe.sweep.trends import spans_trends, trends, trends_markdown

    if not {"a", "b", "theta_deg"} <= set(param_keys) or not spans_trends(rows):
        return {}
    found = trends(rows)
    output("trends.md").write_text(
        trends_markdown(found, title=f"The paper's trends: {title}"), encoding="utf-8"
    )
    return {t.key: t.verdict for t in found}


# ------------------------------------------------------------------------------------------ Fig. 4
def plot_params(
    path: Path, rows: list[dict[str, Any]], model: Any, *, title: str = "", failed: int = 0
) -> None:
    """The paper's Fig. 4: each fitted parameter against stitch length (arc length when a point has no
    stitch length), one panel each; colour per pattern, marker per yarn, a line per pattern and yarn.
    An open marker is a parameter that ended at a bound of the model's box: the data do not determine it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from knitframe.fitting import params_to_json

    keys = list(params_to_json(model.param_names, [0.0] * len(model.param_names)))
    # a point compared with measured tests may be done without a fit (its fit failed): nothing to draw
    done = [r for r in rows if r["status"] == "done" and all(r[k] not in ("", None) for k in keys)]
    log = list(model.log_scale)
    by_sl = all(r["stitch_length"] not in (None, "") for r in done)
    xkey, xlabel = (
        ("stitch_length", "stitch length (machine setting)")
        if by_sl
        else ("arc_length_mm", "yarn per stitch, mm")
    )
    patterns = list(dict.fromkeys(r["pattern"] for r in done))
    yarns = list(dict.fromkeys(r["yarn"] for r in done))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    markers = ["o", "s", "^", "D", "v", "P", "X", "*", "<", ">"]
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for r in done:
        variant = json.dumps(
            [r["load"], r["max_strain"], r["steps"], r["effects"], r["solver"], r["solver_options"]]
        )
        groups.setdefault((r["pattern"], r["yarn"], variant), []).append(r)
    variants = list(dict.fromkeys(k[2] for k in groups))
    styles = ["-", "--", ":", "-."]
    fig, axes = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.9), dpi=110, squeeze=False)
    xs = sorted({float(r[xkey]) for r in done})
    for k, (key, ax) in enumerate(zip(keys, axes[0], strict=False)):
        for (pattern, yarn, variant), members in groups.items():
            members = sorted(members, key=lambda r: float(r[xkey]))
            x = [float(r[xkey]) for r in members]
            y = [float(r[key]) for r in members]
            color = colors[patterns.index(pattern) % len(colors)]
            marker = markers[yarns.index(yarn) % len(markers)]
            ax.plot(x, y, styles[variants.index(variant) % len(styles)], color=color, lw=1.3)
            free = [
                key in r["at_bound"].split() for r in members
            ]  # open: at a bound, not determined by the data
            for xi, yi, f in zip(x, y, free, strict=False):
                ax.plot([xi], [yi], ls="", marker=marker, ms=6, color=color, mfc="white" if f else color)
        if by_sl and len(xs) <= 12:
            ax.set_xticks(xs)
        name = key[:-4] if key.endswith("_deg") else key
        unit = ", °" if key.endswith("_deg") else (", N/mm" if name == "a" else "")
        ax.set_title(
            {"theta": "θ"}.get(name, name) + unit.replace(", ", " (").rstrip() + (")" if unit else "")
        )
        ax.set_xlabel(xlabel)
        if k < len(log) and log[k]:
            ax.set_yscale("log")
        ax.grid(alpha=0.3)
    handles = [Line2D([], [], color=colors[i % len(colors)], lw=2, label=p) for i, p in enumerate(patterns)]
    handles += [
        Line2D([], [], color="0.3", ls="", marker=markers[i % len(markers)], label=y)
        for i, y in enumerate(yarns)
    ]
    if any(r["at_bound"] for r in done):
        handles.append(Line2D([], [], color="0.3", ls="", marker="o", mfc="white", label="open: at a bound"))
    axes[0, -1].legend(handles=handles, fontsize=7, loc="best")
    note = f"; {failed} failed point{'s' if failed != 1 else ''} not shown" if failed else ""
    fig.suptitle((title or f"fitted {model.name} parameters") + note, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
