"""Writing Responses as CSV and plots (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

import csv
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from knitframe.curves import by_strain
from knitframe.records import Response

__all__ = [
    "write_responses_csv",
    "plot_responses",
    "curve",
    "band_legend",
    "compare",
    "plot_comparison",
    "validate_uniaxial",
    "plot_validation",
    "plot_sections",
]

CSV_COLUMNS = (
    "label",
    "load",
    "n_samples",
    "lambda1",
    "lambda2",
    "T1_N_per_mm",
    "T2_N_per_mm",
    "T1_sd",
    "T2_sd",
    "lambda1_sd",
    "lambda2_sd",
)


def write_responses_csv(path: Path, responses: Sequence[Response]) -> None:
    """One row per point of every Response; missing spreads are empty cells."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(CSV_COLUMNS)
        for r in responses:
            cols = [r.lambda1, r.lambda2, r.T1, r.T2, r.T1_sd, r.T2_sd, r.lambda1_sd, r.lambda2_sd]
            for i in range(len(r)):
                w.writerow(
                    [r.label, r.load, r.n_samples] + ["" if c is None else f"{c[i]:.10g}" for c in cols]
                )


def curve(r: Response) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray | None]]:
    """The tension curves worth plotting: ``(name, strain, tension, sd)`` per loaded direction."""
    d = r.loaded_direction
    out = []
    for k, (lam, T, sd) in enumerate(((r.lambda1, r.T1, r.T1_sd), (r.lambda2, r.T2, r.T2_sd))):
        if d is None or d == k:
            out.append(("course" if k == 0 else "wale", lam - 1.0, T, sd))
    return out


def band_legend(ax, banded: Sequence[Response]) -> None:
    """A legend entry for the shaded bands drawn around the curves of ``banded``: each is ± one
    standard deviation over the Response's repeats (``n_samples``), as its ``*_sd`` arrays are.
    Nothing when no band was drawn."""
    if not banded:
        return
    counts = sorted({r.n_samples for r in banded})
    if counts[0] < 2:
        over = " of the repeats"
    elif len(counts) == 1:
        over = f" over {counts[0]} repeats"
    else:
        over = " over each test's repeats (" + " or ".join(map(str, counts)) + ")"
    ax.fill_between([], [], [], color="0.5", alpha=0.3, lw=0, label=f"shaded: ± 1 standard deviation{over}")


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
    banded = []
    for i, r in enumerate(responses):
        c = colors[i % len(colors)]
        pred = model(r) if model is not None else None
        for name, strain, T, sd in curve(r):
            ls = "-" if name == "course" else "--"
            label = f"{r.label or r.load} ({name})"
            x, y = by_strain(strain, T)
            ax.plot(x, y, ls, color=c, lw=1.2, marker="." if len(r) < 40 else None, label=label)
            if sd is not None:
                _, lo, hi = by_strain(strain, T - sd, T + sd)
                ax.fill_between(x, lo, hi, color=c, alpha=0.2, lw=0)
                banded.append(r)
            if pred is not None:
                P = pred[0] if name == "course" else pred[1]
                ax.plot(x, by_strain(strain, P)[1], ls, color="k", lw=1.0, alpha=0.8)
    if model is not None:
        ax.plot([], [], "k-", lw=1.0, label="fitted model")
    band_legend(ax, banded)
    _finish_tension_plot(fig, ax, path, title)


#: strains at which simulated and measured tensions are compared
COMPARE_AT = (0.10, 0.20, 0.30)


def compare(simulated: Sequence[Response], measured: Sequence[Response]) -> dict[str, dict[str, float]]:
    """Ratio of simulated to measured tension at 10, 20 and 30 % strain, per load and direction.

    Only for the loads both have, at strains inside both curves. A simulated path starts from the
    relaxed cell at zero strain and zero tension. Keys: ``"uniaxial-course"`` (or
    ``"equibiaxial course"`` … for a load with two loaded directions), then ``"10 %"`` …
    """
    out: dict[str, dict[str, float]] = {}
    for sim in simulated:
        for mea in (m for m in measured if m.load == sim.load):
            for (name, es, Ts, _), (_, em, Tm, _) in zip(curve(sim), curve(mea), strict=False):
                key = sim.load if sim.loaded_direction is not None else f"{sim.load} {name}"
                es, Ts = from_origin(*by_strain(es, Ts))
                em, Tm = by_strain(em, Tm)
                row = {}
                for e in COMPARE_AT:
                    if max(em[0], 0.0) <= e <= min(es[-1], em[-1]):
                        ts = np.interp(e, es, Ts)
                        tm = np.interp(e, em, Tm)
                        if tm > 0:
                            row[f"{100 * e:.0f} %"] = float(ts / tm)
                if row:
                    out[key] = row
            break
    return out


def from_origin(strain: np.ndarray, tension: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A simulated load path with its start, the relaxed cell at zero strain and tension, put first."""
    if strain[0] > 0:
        return np.concatenate([[0.0], strain]), np.concatenate([[0.0], tension])
    return strain, tension


def plot_comparison(
    path: Path,
    simulated: Sequence[Response],
    measured: Sequence[Response],
    *,
    title: str = "",
    ratios: dict[str, dict[str, float]] | None = None,
) -> None:
    """Simulated curves (solid, from the relaxed cell at zero tension) over the measured ones of the
    same load (dashed, ±1 sd band), one colour per load and direction, with the tension ratios."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.8, 4.6), dpi=110)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    k = 0
    banded = []
    for sim in simulated:
        same = [m for m in measured if m.load == sim.load]
        for name, e, T, _ in curve(sim):
            c = colors[k % len(colors)]
            k += 1
            x, y = from_origin(*by_strain(e, T))
            ax.plot(x, y, "-", color=c, lw=1.6, marker=".", label=f"simulated {sim.load} ({name})")
            for m in same[:1]:
                for mname, em, Tm, sd in curve(m):
                    if mname != name:
                        continue
                    xm, ym = by_strain(em, Tm)
                    ax.plot(xm, ym, "--", color=c, lw=1.2, label=f"measured {m.label or m.load} ({name})")
                    if sd is not None:
                        _, lo, hi = by_strain(em, Tm - sd, Tm + sd)
                        ax.fill_between(xm, lo, hi, color=c, alpha=0.15, lw=0)
                        banded.append(m)
    band_legend(ax, banded)
    if ratios:
        text = "\n".join(
            f"{load}: " + ", ".join(f"{v:.2g}" for v in row.values()) + " at " + ", ".join(row)
            for load, row in ratios.items()
        )
        ax.text(
            0.98,
            0.02,
            "simulated / measured tension\n" + text,
            transform=ax.transAxes,
            ha="right",
            va="bottom",
            fontsize=7,
            bbox={"facecolor": "white", "alpha": 0.85, "lw": 0.5},
        )
    _finish_tension_plot(fig, ax, path, title)


def _finish_tension_plot(fig, ax, path: Path, title: str) -> None:
    """Axis labels, grid, legend and the file of a tension-against-strain plot."""
    import matplotlib.pyplot as plt

    ax.set_xlabel("engineering strain in the loaded direction, -")
    ax.set_ylabel("tension per unit width, N/mm")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# ------------------------------------------------------------------------- against measured tests
#: axial strain at which the lateral strains of a simulated and a measured uniaxial test are compared
LATERAL_AT = 0.20


def lateral(r: Response) -> tuple[np.ndarray, np.ndarray]:
    """``(axial strain, lateral strain)`` of a uniaxial Response, sorted by axial strain."""
    d = r.loaded_direction
    if d is None:
        raise ValueError(f"not a uniaxial test: {r.load}")
    axial, side = (r.lambda1, r.lambda2) if d == 0 else (r.lambda2, r.lambda1)
    return by_strain(axial - 1.0, side - 1.0)


#: a simulated uniaxial curve whose tension falls below −this × its largest |tension| is suspect, -
NEGATIVE_TENSION = 1e-3


def validate_uniaxial(
    simulated: Response, measured: Response, *, lateral_at: float = LATERAL_AT
) -> dict[str, float | None]:
    """How a simulated uniaxial test (free sides) agrees with the measured one of the same load.

    * ``nrmse``: sqrt(mean (T_sim − T_meas)²) / max T_meas over the measured points inside the
      simulated strain range, the simulated curve taken from the relaxed cell (zero strain, zero
      tension) and interpolated linearly at the measured strains (the fits' normalisation);
    * ``ratio_10``, ``ratio_20``, ``ratio_30``: simulated / measured tension at 10, 20, 30 % strain
      (:func:`compare`; None where either curve ends earlier);
    * ``lateral_at``: the axial strain where the lateral strains are compared, ``lateral_at`` or the
      end of the shorter curve; ``lateral_simulated`` and ``lateral_measured``: the lateral
      engineering strain there (negative: the side contracts);
    * ``simulated_to`` and ``measured_to``: the largest axial strain of each curve;
    * ``suspect``: None, or why the simulated curve is suspect: a pulled fabric that pushes back
      (a tension below −:data:`NEGATIVE_TENSION` × its largest |tension| at a positive strain).

    Raises ValueError when the loads differ or are not uniaxial.
    """
    if simulated.load != measured.load or simulated.loaded_direction is None:
        raise ValueError(
            f"compare two uniaxial tests of the same load, got {simulated.load} and {measured.load}"
        )
    ((_, es, Ts, _),) = curve(simulated)
    ((_, em, Tm, _),) = curve(measured)
    es, Ts = from_origin(*by_strain(es, Ts))
    em, Tm = by_strain(em, Tm)
    keep = (em >= 0.0) & (em <= es.max() + 1e-9)
    nrmse = None
    if keep.sum() >= 2 and np.abs(Tm[keep]).max() > 0:
        err = np.interp(em[keep], es, Ts) - Tm[keep]
        nrmse = float(np.sqrt(np.mean(err**2)) / np.abs(Tm[keep]).max())
    ratios = compare([simulated], [measured]).get(simulated.load, {})
    out: dict[str, float | None] = {
        "simulated_to": float(es.max()),
        "measured_to": float(em.max()),
        "nrmse": nrmse,
    }
    out.update({f"ratio_{100 * e:.0f}": ratios.get(f"{100 * e:.0f} %") for e in COMPARE_AT})
    pushes = np.flatnonzero((es > 0) & (Ts < -NEGATIVE_TENSION * np.abs(Ts).max(initial=0.0)))
    out["suspect"] = (
        f"negative tension {Ts[pushes[0]]:.3g} N/mm at {100 * es[pushes[0]]:.3g} % strain while pulled"
        if len(pushes)
        else None
    )
    ls_e, ls = lateral(simulated)
    ls_e, ls = from_origin(ls_e, ls)
    lm_e, lm = lateral(measured)
    at = min(lateral_at, float(ls_e.max()), float(lm_e.max()))
    ok = at > 0 and at >= max(float(lm_e.min()), 0.0)
    out.update(
        {
            "lateral_at": at if ok else None,
            "lateral_simulated": float(np.interp(at, ls_e, ls)) if ok else None,
            "lateral_measured": float(np.interp(at, lm_e, lm)) if ok else None,
        }
    )
    return out


def plot_validation(path: Path, panels: Sequence[dict], *, title: str = "", columns: int = 4) -> None:
    """A grid of panels, one per measured test: the simulated curve (solid, from the relaxed cell) over
    the measured one (dashed, ±1 sd band), with the NRMSE, the tension ratios at 10/20/30 % and the
    lateral strains. A panel is a dict with ``title``, ``measured`` (Response), ``simulated``
    (Response or None) and ``metrics`` (from :func:`validate_uniaxial`) or ``reason`` (why there is
    no simulated curve)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = max(len(panels), 1)
    cols = min(columns, n)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.9 * rows), dpi=100, squeeze=False)
    banded = []
    for ax, panel in zip(axes.flat, panels, strict=False):
        mea, sim, m = panel["measured"], panel.get("simulated"), panel.get("metrics")
        for _, e, T, sd in curve(mea):
            x, y = by_strain(e, T)
            ax.plot(x, y, "--", color="0.2", lw=1.2, label="measured")
            if sd is not None:
                _, lo, hi = by_strain(e, T - sd, T + sd)
                ax.fill_between(x, lo, hi, color="0.5", alpha=0.2, lw=0)
                banded.append(mea)
        if sim is not None:
            for _, e, T, _ in curve(sim):
                x, y = from_origin(*by_strain(e, T))
                ax.plot(x, y, "-", color="C3", lw=1.5, marker=".", ms=4, label="simulated")
        if m is not None:
            lines = [
                "NRMSE " + (f"{100 * m['nrmse']:.0f} %" if m.get("nrmse") is not None else "–"),
                "sim/meas "
                + "/".join(
                    "–" if m.get(f"ratio_{100 * e:.0f}") is None else f"{m[f'ratio_{100 * e:.0f}']:.2g}"
                    for e in COMPARE_AT
                )
                + " at "
                + "/".join(f"{100 * e:.0f}" for e in COMPARE_AT)
                + " %",
            ]
            if m.get("lateral_at") is not None:
                lines.append(
                    f"lateral at {100 * m['lateral_at']:.0f} %: {m['lateral_simulated']:+.3f} sim, "
                    f"{m['lateral_measured']:+.3f} meas"
                )
            if m.get("suspect"):
                lines.append(f"suspect: {m['suspect']}")
            ax.text(
                0.03,
                0.97,
                "\n".join(lines),
                transform=ax.transAxes,
                ha="left",
                va="top",
                fontsize=6.5,
                bbox={"facecolor": "white", "alpha": 0.85, "lw": 0.5},
            )
        else:
            import textwrap

            reason = textwrap.fill("no simulated curve: " + str(panel.get("reason") or "failed"), 44)
            ax.text(0.03, 0.97, reason, transform=ax.transAxes, ha="left", va="top", fontsize=6.5, color="C3")
        ax.set_title(panel["title"], fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(panels) :]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("strain in the pull, -", fontsize=7)
    for ax in axes[:, 0]:
        ax.set_ylabel("tension, N/mm", fontsize=7)
    if panels:
        band_legend(axes.flat[0], banded)
        axes.flat[0].legend(fontsize=6.5, loc="center left")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# ------------------------------------------------------------------------ how far the yarn is squeezed
def plot_sections(path: Path, responses: Sequence[Response], *, title: str = "") -> bool:
    """How far the yarn is squeezed across along the load path: the section ratio det F / |F a|
    (the yarn's cross-section over its knitted section) of every Response whose provenance carries
    it (the volumetric solver's ``section_ratio``): its volume-weighted median (solid) and 5 %
    quantile (dashed) against the loaded strain, the pre-stressed cell at 0, with the yarn's
    compaction limit J_min (dotted), below which the fibres would be packed past solid. Returns
    False, and writes nothing, when no Response has the section ratio."""
    have = [r for r in responses if r.provenance.extra.get("section_ratio")]
    if not have:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.8, 4.6), dpi=110)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, r in enumerate(have):
        c = colors[k % len(colors)]
        rows = r.provenance.extra["section_ratio"]
        d = r.loaded_direction or 0
        e, median, p05 = by_strain(
            np.array([(row["lambda1"], row["lambda2"])[d] - 1.0 for row in rows]),
            np.array([row["median"] for row in rows]),
            np.array([row["p05"] for row in rows]),
        )
        ax.plot(e, median, "-", marker=".", color=c, label=f"{r.label} {r.load}".strip())
        ax.plot(e, p05, "--", color=c, lw=1.0)
        limit = r.provenance.extra.get("compaction_limit")
        if limit is not None:
            ax.axhline(limit, color=c, ls=":", lw=1.0)
    ax.axhline(1.0, color="0.5", lw=0.6)
    ax.plot([], [], "-", color="0.3", label="median over the yarn")
    ax.plot([], [], "--", color="0.3", lw=1.0, label="5 % of the yarn below this")
    ax.plot([], [], ":", color="0.3", lw=1.0, label="compaction limit J_min")
    ax.set_xlabel("engineering strain in the loaded direction (0: the pre-stressed cell), -")
    ax.set_ylabel("section ratio det F / |F a|, -")
    ax.set_ylim(0.0, 1.1)
    ax.set_title(title or "how far the yarn is squeezed across (dotted: its compaction limit J_min)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower left", framealpha=0.9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return True
