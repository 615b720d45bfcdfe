"""The ladder's figures: ``ladder.png`` (wall time against error, the Pareto front) and
``curves.png`` (every rung's curves over the measured ones).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from knitframe.ladder.compare import loaded_directions
from knitframe.records import Response


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_pareto(path: Path, rows: Sequence[Mapping[str, Any]], *, title: str) -> None:
    """``ladder.png``: wall time against error, log axes, each rung labelled, the Pareto front dashed.

    Error against the best rung (filled), and against the measurement (open) when there is one,
    in % as in the ladder's tables; the front is drawn on the measured errors when there are any.
    """
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.0, 4.8), dpi=110)
    series = [("nrmse_vs_best", "vs best rung", "o", "C0", True)]
    if any(r.get("nrmse_vs_measured") is not None for r in rows):
        series.append(("nrmse_vs_measured", "vs measured", "s", "C3", False))
    front_key = series[-1][0]
    plotted = 0
    for key, label, marker, color, filled in series:
        pts = [
            (r["wall_time_s"], 100 * r[key], r["rung"])
            for r in rows
            if r.get("wall_time_s") and r.get(key) is not None and r[key] > 0
        ]
        if not pts:
            continue
        plotted += len(pts)
        ax.scatter(
            [p[0] for p in pts],
            [p[1] for p in pts],
            marker=marker,
            s=42,
            label=label,
            zorder=3,
            facecolors=color if filled else "none",
            edgecolors=color,
        )
        for x, y, name in pts:
            ax.annotate(name, (x, y), textcoords="offset points", xytext=(5, 4), fontsize=7.5, color=color)
        if key == front_key:
            _draw_front(ax, pts, color)
    if plotted:
        from matplotlib.ticker import LogFormatter

        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(LogFormatter())  # 0.01, 1, 100: plain percentages
        ax.yaxis.set_minor_formatter(LogFormatter(labelOnlyBase=False))
        ax.legend(fontsize=8, loc="best")
    else:
        ax.text(
            0.5,
            0.5,
            "only one rung finished: nothing to compare",
            ha="center",
            va="center",
            transform=ax.transAxes,
        )
    _mark_reference(ax, rows, plotted)
    ax.set_xlabel("wall time of the rung, s")
    ax.set_ylabel("NRMSE of tension, %")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.25)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _draw_front(ax: Any, pts: list[tuple[float, float, str]], color: str) -> None:
    """The Pareto front of ``(time, error, rung)`` points, dashed: the rungs no faster rung beats."""
    pts.sort()
    front, low = [], math.inf
    for x, y, _ in pts:
        if y < low:
            front.append((x, y))
            low = y
    if len(front) > 1:
        ax.step(
            [p[0] for p in front],
            [p[1] for p in front],
            where="post",
            ls="--",
            lw=1,
            color=color,
            alpha=0.6,
            label="Pareto front",
        )


def _mark_reference(ax: Any, rows: Sequence[Mapping[str, Any]], plotted: int) -> None:
    """The best rung, which has no error against itself: a vertical line at its time."""
    ref = next((r for r in rows if r.get("reference")), None)
    if ref is not None and ref.get("wall_time_s"):
        ax.axvline(ref["wall_time_s"], color="C0", ls=":", lw=1.2)
        ax.annotate(
            f"{ref['rung']} (best rung)",
            (ref["wall_time_s"], 0.03),
            xycoords=("data", "axes fraction"),
            rotation=90,
            ha="right",
            va="bottom",
            fontsize=7.5,
            color="C0",
            xytext=(-3, 0),
            textcoords="offset points",
        )
        if not plotted:
            ax.set_xscale("log")


def plot_curves(
    path: Path,
    curves: Mapping[str, Response],
    measured: Sequence[Response],
    *,
    title: str,
    load: str,
    reference: str | None = None,
) -> None:
    """``curves.png``: every rung's tension curves over the measured ones.

    Equibiaxial and general loads: course and wale tension; uniaxial: the loaded tension and the
    free side's lateral strain. The best rung's curve is drawn thicker; the tension axis is
    logarithmic when the curves' last tensions differ more than tenfold.
    """
    plt = _plt()
    dirs = loaded_directions(load)
    panels = (
        [("course", 0, "T"), ("wale", 1, "T")]
        if len(dirs) == 2
        else [("course" if dirs[0] == 0 else "wale", dirs[0], "T"), ("lateral", dirs[0], "lateral")]
    )
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.2), dpi=110)

    def xy(r: Response, d: int, what: str):
        lam = r.lambda1 if d == 0 else r.lambda2
        if what == "lateral":
            return 100 * (lam - 1), 100 * ((r.lambda2 if d == 0 else r.lambda1) - 1)
        return 100 * (lam - 1), r.T1 if d == 0 else r.T2

    for ax, (name, d, what) in zip(axes, panels, strict=False):
        for m in measured:
            x, y = xy(m, d, what)
            sd = (
                (m.T1_sd if d == 0 else m.T2_sd)
                if what == "T"
                else (m.lambda2_sd if d == 0 else m.lambda1_sd)
            )
            ax.plot(x, y, "k.", ms=4, label=f"measured: {m.label}")
            if sd is not None:
                scale = 1.0 if what == "T" else 100.0
                ax.fill_between(x, y - scale * sd, y + scale * sd, color="k", alpha=0.12, lw=0)
        ends, low = [], np.inf
        for i, (rung, r) in enumerate(curves.items()):
            x, y = xy(r, d, what)
            best = rung == reference
            ax.plot(
                x,
                y,
                "-",
                marker=".",
                ms=3,
                lw=2.6 if best else 1.3,
                color=f"C{i % 10}",
                label=f"{rung} (best rung)" if best else rung,
                zorder=2 if best else 3,
            )
            ends.append(float(y[-1]))
            low = min(low, float(np.min(y[y > 0], initial=np.inf)))
        if what == "T" and ends and min(ends) > 0 and max(ends) > 10 * min(ends):
            ax.set_yscale("log")
            ax.set_ylim(bottom=0.5 * low)  # the rungs' range: a measured point near zero strain is below it
        strain = "course" if d == 0 else "wale"
        ax.set_xlabel(f"{strain} strain, %")
        ax.set_ylabel(f"{name} tension, N/mm" if what == "T" else "lateral strain (free side), %")
        ax.grid(True, alpha=0.25)
    axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
