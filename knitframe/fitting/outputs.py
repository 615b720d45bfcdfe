"""What a fit writes and draws: the model's predicted curves along a Response's path, the fit
figure and the fit's output files (params.json and fit.png).
"""

from __future__ import annotations

import json
import textwrap
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from knitframe.errors import KnitframeWarning
from knitframe.fitting.free_side import _pair
from knitframe.fitting.result import FitResult
from knitframe.records import Provenance, Response


def predict(result: FitResult, response: Response) -> Response:
    """The fitted model's Response at a measured Response's loaded stretches.

    Uniaxial tests: a lateral model solves its free side; otherwise the measured free-side
    stretch is used (as in the fit). Other loads: both stretches are imposed.
    """
    d = response.loaded_direction
    lam1, lam2 = response.lambda1, response.lambda2
    if d is not None and result.model.predicts_lateral:
        lam_load = (lam1, lam2)[d]
        lf, _ = result.solve_uniaxial(lam_load, d)
        lam1, lam2 = _pair(d, lam_load, lf)
    P1, P2 = result.stress(lam1, lam2)
    if d is not None:  # the free side carries no load by definition of the test
        P1, P2 = (P1, np.zeros_like(P2)) if d == 0 else (np.zeros_like(P1), P2)
    return Response(
        lam1,
        lam2,
        P1,
        P2,
        load=response.load,
        label=f"{response.label} ({result.model.name})",
        provenance=Provenance(kind="model", source=result.model.name, notes=f"fitted by {result.fitter}"),
    )


def plot_fit(path: Path, result: FitResult, responses: Sequence[Response], *, title: str = "") -> None:
    """Data (±1 sd band) against the fitted model; a second panel shows the transverse strain of
    the free side of the uniaxial tests, measured (±1 sd band) and, for a model that predicts it,
    the model's."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from knitframe.report import band_legend, curve

    uni = [r for r in responses if r.loaded_direction is not None]
    lateral = result.model.predicts_lateral
    fig, axes = plt.subplots(1, 2 if uni else 1, figsize=(11 if uni else 6.4, 4.4), dpi=110, squeeze=False)
    ax, colors = axes[0, 0], plt.rcParams["axes.prop_cycle"].by_key()["color"]
    banded: dict[str, list[Response]] = {"tension": [], "lateral": []}
    for i, r in enumerate(responses):
        c = colors[i % len(colors)]
        pred = predict(result, r)
        for (name, strain, T, sd), (_, _, P, _) in zip(curve(r), curve(pred), strict=False):
            ls = "-" if name == "course" else "--"
            o = np.argsort(strain)
            ax.plot(strain[o], T[o], ls, color=c, lw=1.2, alpha=0.9, label=f"{r.label or r.load} ({name})")
            if sd is not None:
                ax.fill_between(strain[o], (T - sd)[o], (T + sd)[o], color=c, alpha=0.2, lw=0)
                banded["tension"].append(r)
            ax.plot(strain[o], P[o], ls, color="k", lw=1.0)
        d = r.loaded_direction
        if d is not None:
            bx = axes[0, 1]
            strain = (r.lambda1, r.lambda2)[d] - 1
            lat = (r.lambda1, r.lambda2)[1 - d] - 1
            sd = (r.lambda1_sd, r.lambda2_sd)[1 - d]
            o = np.argsort(strain)
            ls = "-" if d == 0 else "--"
            pulled = "course" if d == 0 else "wale"
            bx.plot(
                strain[o],
                lat[o],
                ls,
                color=c,
                lw=1.2,
                label=f"{r.label or r.load} (pulled along the {pulled})",
            )
            if sd is not None:
                bx.fill_between(strain[o], (lat - sd)[o], (lat + sd)[o], color=c, alpha=0.2, lw=0)
                banded["lateral"].append(r)
            if lateral:
                plat = (pred.lambda1, pred.lambda2)[1 - d] - 1
                bx.plot(strain[o], plat[o], ls, color="k", lw=1.0)
    ax.plot([], [], "k-", lw=1.0, label=f"fitted {result.model.name}")
    band_legend(ax, banded["tension"])
    ax.set_xlabel("engineering strain in the loaded direction, -")
    ax.set_ylabel("tension per unit width, N/mm")
    ax.set_title(title or result.headline(), fontsize=8)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    if uni:
        bx = axes[0, 1]
        if lateral:
            bx.plot([], [], "k-", lw=1.0, label=f"fitted {result.model.name}")
        band_legend(bx, banded["lateral"])
        bx.set_xlabel("engineering strain in the loaded direction, -")
        bx.set_ylabel("transverse strain of the free side, -")
        bx.set_title(
            "transverse strain of the free side: measured"
            + (
                f" and fitted {result.model.name}"
                if lateral
                else f" ({result.model.name} does not predict it)"
            ),
            fontsize=8,
        )
        bx.grid(alpha=0.3)
        bx.legend(fontsize=7, loc="best")
    notes = result.to_json()["warnings"]
    if notes:  # suspect results say so on the figure, in red below the axes
        text = "\n".join(textwrap.fill(f"warning: {w}", 150 if uni else 95) for w in notes)
        rows = text.count("\n") + 1
        fig.set_size_inches(fig.get_figwidth(), fig.get_figheight() + 0.16 * rows)
        fig.text(0.01, 0.01, text, color="red", fontsize=7, va="bottom", ha="left")
        fig.tight_layout(rect=(0, (0.16 * rows + 0.05) / fig.get_figheight(), 1, 1))
    else:
        fig.tight_layout()
    fig.savefig(path, metadata={"Description": " | ".join(notes) or "no warnings"})
    plt.close(fig)


def write_fit_outputs(
    result: FitResult, responses: Sequence[Response], params_path: Path, plot_path: Path
) -> None:
    """Write ``params.json`` (parameters, θ in degrees, NRMSE, metadata, warnings) and the fit plot.

    The JSON is strict: NaN and Infinity cannot be written (see :meth:`FitResult.to_json`); a
    result that needed cleaning says so by a :class:`~knitframe.errors.KnitframeWarning`.
    """
    data = result.to_json()
    if data.get("non_finite"):
        warnings.warn(f"{Path(params_path).name}: {data['warnings'][-1]}", KnitframeWarning, stacklevel=2)
    Path(params_path).write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")
    plot_fit(Path(plot_path), result, responses)
