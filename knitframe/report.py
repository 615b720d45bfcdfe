"""Writing Responses as CSV and plots (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from knitframe.records import Response

__all__ = ["write_responses_csv", "plot_responses", "curve"]

CSV_COLUMNS = (
    "label", "load", "n_samples", "lambda1", "lambda2", "T1_N_per_mm", "T2_N_per_mm",
    "T1_sd", "T2_sd", "lambda1_sd", "lambda2_sd",
)


def write_responses_csv(path: Path, responses: Sequence[Response]) -> None:
    """One row per point of every Response; missing spreads are empty cells."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS)
        for r in responses:
            cols = [r.lambda1, r.lambda2, r.T1, r.T2, r.T1_sd, r.T2_sd, r.lambda1_sd, r.lambda2_sd]
            for i in range(len(r)):
                w.writerow([r.label, r.load, r.n_samples] + ["" if c is None else f"{c[i]:.10g}" for c in cols])


def curve(r: Response) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None]]:
    """The tension curves worth plotting: ``(name, strain, tension, sd)`` per loaded direction."""
    d = r.loaded_direction
    out = []
    for k, (lam, T, sd) in enumerate(((r.lambda1, r.T1, r.T1_sd), (r.lambda2, r.T2, r.T2_sd))):
        if d is None or d == k:
            out.append(("course" if k == 0 else "wale", lam - 1.0, T, sd))
    return out


def plot_responses(
    path: Path,
    responses: Sequence[Response],
    *,
    model: Callable[[Response], tuple[np.ndarray, np.ndarray]] | None = None,
    title: str = "",
) -> None:
    """Tension against strain in the loaded direction(s), with a ±1 sd band where known.

    ``model(response) -> (P1, P2)`` adds the model's prediction at the response's stretches.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=110)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, r in enumerate(responses):
        c = colors[i % len(colors)]
        pred = model(r) if model is not None else None
        for name, strain, T, sd in curve(r):
            ls = "-" if name == "course" else "--"
            label = f"{r.label or r.load} ({name})"
            order = np.argsort(strain)
            ax.plot(strain[order], T[order], ls, color=c, lw=1.2, marker="." if len(r) < 40 else None, label=label)
            if sd is not None:
                ax.fill_between(strain[order], (T - sd)[order], (T + sd)[order], color=c, alpha=0.2, lw=0)
            if pred is not None:
                P = pred[0] if name == "course" else pred[1]
                ax.plot(strain[order], np.asarray(P)[order], ls, color="k", lw=1.0, alpha=0.8)
    if model is not None:
        ax.plot([], [], "k-", lw=1.0, label="fitted model")
    ax.set_xlabel("engineering strain in the loaded direction, -")
    ax.set_ylabel("tension per unit width, N/mm")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
