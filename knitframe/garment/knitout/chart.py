"""The stitch chart of a program: every course × needle by carrier and plain/reverse, and band details."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from knitframe.garment.knitout.machine import Plan
from knitframe.garment.knitout.writer import FIRST_NEEDLE, front_bed, front_layer


def transfers_before(p: Plan) -> np.ndarray:
    """(C,) loops transferred between beds before each course (the cast-on puts course 0's loops in place)."""
    front = front_bed(p)
    out = np.zeros(p.kmap.courses, dtype=int)
    out[1:] = (front[1:] != front[:-1]).sum(axis=1)
    return out


def _carrier_colours(p: Plan) -> dict[int, tuple[float, float, float]]:
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return {c: cmap((c - 1) % 10)[:3] for c in p.carriers.values()}


def plot_chart(p: Plan, path: str | Path) -> None:
    """The stitch chart of the program, as a technician reads it.

    Top: every course (up from the cast-on) × every needle, coloured by carrier, light where the
    stitch is plain seen from outside the tube (knitted on its layer's home bed) and dark where it
    is reverse (a purl, knitted on the other bed); each band's fabric, pattern, carrier and stitch
    number; the loops transferred before each course. Bottom: the first courses of each band at
    needle scale, each cell marked with the bed (F/B) that knits it.
    """
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    km = p.kmap
    N, C = km.needles, km.courses
    front = front_bed(p)
    colours = _carrier_colours(p)
    carriers = sorted(colours)
    band_of = np.repeat(np.arange(len(km.bands)), [b.courses for b in km.bands])
    cidx = np.array([carriers.index(c) for c in p.band_carriers])[band_of]  # (C,) carrier index per course
    reverse = front ^ front_layer(N)[None, :]
    code = 2 * cidx[:, None] + reverse.astype(int)  # light (plain) or dark (reverse) of the carrier colour
    palette = []
    for c in carriers:
        rgb = np.array(colours[c])
        palette += [tuple(0.45 * rgb + 0.55), tuple(0.75 * rgb)]
    detail = list(dict.fromkeys(range(len(km.bands))))[:6]
    fig = plt.figure(figsize=(12, 11), layout="constrained")
    grid = fig.add_gridspec(2, max(len(detail), 1), height_ratios=[3.2, 1])
    ax = fig.add_subplot(grid[0, :])
    needles = np.arange(FIRST_NEEDLE, FIRST_NEEDLE + N + 1) - 0.5
    ax.pcolormesh(
        needles, np.arange(C + 1), code, cmap=ListedColormap(palette), vmin=-0.5, vmax=len(palette) - 0.5
    )
    _transfers_and_bands(ax, p)
    ax.set_xlim(needles[0], needles[-1])
    ax.set_ylim(0, C)
    ax.set_xlabel(
        f"needle (front layer on {FIRST_NEEDLE + N - 1}, {FIRST_NEEDLE + N - 3}, …; back layer on the others)"
    )
    ax.set_ylabel("course, up from the cast-on (wrist)")
    fig.suptitle(
        f"{p.spec.machine}, gauge {p.spec.gauge} (knitted at half gauge), width {p.spec.bed_width}: a tube "
        f"of {N} stitches × {C} courses; cast-on below course 0, bind-off above course {C - 1}",
        fontsize=10,
    )
    _legend(ax, p, carriers, palette)
    _band_details(fig, grid, p, detail, front, reverse, colours)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _transfers_and_bands(ax, p: Plan) -> None:
    """The transfers before each course beside the chart, and each band's line and label."""
    km = p.kmap
    C = km.courses
    xfer = transfers_before(p)
    ax2 = ax.inset_axes((1.01, 0.0, 0.06, 1.0), sharey=ax)
    ax2.barh(np.arange(C) + 0.5, xfer, height=1.0, color="0.35")
    ax2.set_xlabel("xfers", fontsize=8)
    ax2.tick_params(labelleft=False, labelsize=7)
    nb = len(km.bands)
    for k, b in enumerate(km.bands):  # labels spread evenly on the right, each pointing at its band
        ax.axhline(b.start, color="k", lw=0.8)
        sl = "no stitch length (default)" if b.stitch_length is None else f"stitch length {b.stitch_length:g}"
        ax.annotate(
            f"courses {b.start}–{b.end}: {b.fabric}\n{b.pattern}, {b.yarn}, carrier {p.band_carriers[k]}\n"
            f"{sl} → x-stitch-number {p.stitch_numbers[k]}",
            xy=(1.07, (b.start + b.end) / 2 / C),
            xycoords="axes fraction",
            xytext=(1.12, (k + 0.5) / nb),
            textcoords="axes fraction",
            va="center",
            fontsize=7.5,
            arrowprops={"arrowstyle": "-", "lw": 0.6, "color": "0.4"},
        )


def _legend(ax, p: Plan, carriers: list[int], palette: list) -> None:
    """Below the chart: each carrier's plain and reverse colour."""
    from matplotlib.patches import Patch

    ax.legend(
        handles=[
            h
            for c in carriers
            for h in (
                Patch(color=palette[2 * carriers.index(c)], label=f"carrier {c} ({_yarn_of(p, c)}): plain"),
                Patch(color=palette[2 * carriers.index(c) + 1], label=f"carrier {c}: reverse (purl)"),
            )
        ],
        loc="upper center",
        bbox_to_anchor=(0.5, -0.06),
        ncol=min(4, 2 * len(carriers)),
        fontsize=8,
    )


def _band_details(fig, grid, p: Plan, detail, front: np.ndarray, reverse: np.ndarray, colours) -> None:
    """The first courses of each band at needle scale, each cell marked with the bed (F/B) that knits it."""
    from matplotlib.colors import ListedColormap

    km = p.kmap
    N = km.needles
    rows, cols = 4, min(N, 12)
    for i, k in enumerate(detail):
        b = km.bands[k]
        axd = fig.add_subplot(grid[1, i])
        sub = front[b.start : b.start + min(rows, b.courses), N - cols :]
        img = reverse[b.start : b.start + len(sub), N - cols :].astype(float)
        rgb = np.array(colours[p.band_carriers[k]])
        axd.imshow(
            img,
            cmap=ListedColormap([tuple(0.45 * rgb + 0.55), tuple(0.75 * rgb)]),
            vmin=0,
            vmax=1,
            origin="lower",
            aspect="auto",
            extent=(FIRST_NEEDLE + N - cols - 0.5, FIRST_NEEDLE + N - 0.5, b.start, b.start + len(sub)),
        )
        for r in range(len(sub)):
            for j in range(cols):
                axd.text(
                    FIRST_NEEDLE + N - cols + j,
                    b.start + r + 0.5,
                    "F" if sub[r, j] else "B",
                    ha="center",
                    va="center",
                    fontsize=7,
                )
        axd.set_title(f"{b.pattern} ({b.yarn})", fontsize=8)
        axd.set_yticks(b.start + np.arange(len(sub)) + 0.5, [str(b.start + r) for r in range(len(sub))])
        axd.set_xlabel("needle; F/B: the bed that knits", fontsize=7)
        axd.tick_params(labelsize=6)
        if i == 0:
            axd.set_ylabel("course", fontsize=7)


def _yarn_of(p: Plan, carrier: int) -> str:
    return next(y for y, c in p.carriers.items() if c == carrier)
