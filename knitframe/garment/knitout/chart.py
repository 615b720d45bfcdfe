"""The stitch chart of a program: every course's stitches on their needles, by carrier and plain/reverse,
the tube's width course by course with its shaping, and band details."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from knitframe.garment.knitout.machine import Plan
from knitframe.garment.knitout.writer import FIRST_NEEDLE, front_bed, transfers_before

#: at most this many fabrics get a detail panel under the chart
DETAILS = 6


def _carrier_colours(p: Plan) -> dict[int, tuple[float, float, float]]:
    import matplotlib

    cmap = matplotlib.colormaps["tab10"]
    return {c: cmap((c - 1) % 10)[:3] for c in p.carriers.values()}


def _shades(rgb) -> tuple[tuple, tuple]:
    """The light (plain) and dark (reverse) shade of a carrier colour."""
    rgb = np.array(rgb)
    return tuple(0.45 * rgb + 0.55), tuple(0.75 * rgb)


def plot_chart(p: Plan, path: str | Path) -> None:
    """Draw :func:`chart_figure` into ``path`` (a PNG)."""
    import matplotlib.pyplot as plt

    fig = chart_figure(p)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def chart_figure(p: Plan):
    """The stitch chart of the program, as a knitter reads a shaped chart.

    Top: courses up (from the cast-on), needles across; each course's stitches on their needles,
    coloured by carrier, light where the stitch is plain seen from outside the tube (knitted on its
    layer's home bed) and dark where it is reverse (a purl, knitted on the other bed). The outline
    follows the stitches of each course; a shaping course is marked at the edge it changes (▲ an
    increase, ▼ a decrease). Beside it, the stitches of every course and the ``xfer`` instructions
    before it, and each band's fabric, pattern, carrier and stitch number. Bottom: the first courses
    of each fabric's first band at needle scale, each cell marked with the bed (F/B) that knits it.
    """
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    km, lay = p.kmap, p.layout
    W, C = lay.width, km.courses
    front = front_bed(p)
    mask = lay.mask()
    colours = _carrier_colours(p)
    carriers = sorted(colours)
    band_of = np.repeat(np.arange(len(km.bands)), [b.courses for b in km.bands])
    cidx = np.array([carriers.index(c) for c in p.band_carriers])[band_of]  # (C,) carrier index per course
    reverse = (front ^ lay.front()[None, :]) & mask
    code = np.ma.masked_array(2 * cidx[:, None] + reverse.astype(int), ~mask)
    palette = [s for c in carriers for s in _shades(colours[c])]
    first: dict[tuple, int] = {}
    for k, b in enumerate(km.bands):
        first.setdefault((b.fabric, b.pattern, b.yarn), k)
    detail = list(first.values())[:DETAILS]  # the first band of each fabric
    fig = plt.figure(figsize=(13, 11), layout="constrained")
    top, bottom = fig.add_gridspec(2, 1, height_ratios=[3.2, 1])
    cells = top.subgridspec(1, 4, width_ratios=[10, 1.0, 0.8, 3.6], wspace=0.01)
    ax = fig.add_subplot(cells[0])
    needles = np.arange(FIRST_NEEDLE, FIRST_NEEDLE + W + 1) - 0.5
    ax.pcolormesh(
        needles, np.arange(C + 1), code, cmap=ListedColormap(palette), vmin=-0.5, vmax=len(palette) - 0.5
    )
    _outline(ax, p)
    _beside(fig, [ax, *(fig.add_subplot(cells[i], sharey=ax) for i in (1, 2))], fig.add_subplot(cells[3]), p)
    ax.set_xlim(needles[0] - 1, needles[-1] + 1)  # room for the shaping marks
    first, last = FIRST_NEEDLE, FIRST_NEEDLE + W - 1
    ax.set_xticks([t for t in _ticks(10).tick_values(first, last) if first <= t <= last])
    ax.set_ylim(0, C)
    parity = "odd" if (FIRST_NEEDLE + lay.right[0]) % 2 else "even"
    ax.set_xlabel(f"needle (front layer on the {parity} needles, back layer on the others; one stitch each)")
    ax.set_ylabel("course, up from the cast-on (wrist)")
    fig.suptitle(
        f"{p.spec.machine}, gauge {p.spec.gauge} (knitted at half gauge), width {p.spec.bed_width}: "
        f"{km.description}\ncast-on below course 0, bind-off above course {C - 1}",
        fontsize=10,
    )
    _legend(ax, p, carriers, palette)
    _band_details(fig, bottom.subgridspec(1, max(len(detail), 1)), p, detail, front, reverse, colours)
    return fig


def _outline(ax, p: Plan) -> None:
    """The tube's edges course by course, and a mark at the edge each shaping course changes."""
    lay = p.layout
    C = lay.courses
    y = np.arange(C + 1)
    for edge, out in ((lay.left, -0.5), (lay.right, 0.5)):
        x = FIRST_NEEDLE + np.array(edge) + out
        ax.stairs(x, y, orientation="horizontal", baseline=None, color="k", lw=1.0)
    for c in p.kmap.shaping_courses:
        grew = lay.needles(c) > lay.needles(c - 1)
        for edge, out in ((lay.left, -1), (lay.right, 1)):
            if edge[c] != edge[c - 1]:
                ax.plot(
                    FIRST_NEEDLE + edge[c] + out,
                    c + 0.5,
                    marker="^" if grew else "v",
                    color="#1a7f37" if grew else "#b3261e",
                    markersize=5,
                    clip_on=False,
                )


def _beside(fig, axes, labels, p: Plan) -> None:
    """Beside the chart (``axes``: it, then the two panels): the stitches of every course and the transfers
    before it; each band's line, and its label in ``labels`` (spread evenly, pointing at its band)."""
    from matplotlib.patches import ConnectionPatch

    ax, ax1, ax2 = axes
    km = p.kmap
    C = km.courses
    counts = np.array(km.course_needles)
    ax1.stairs(counts, np.arange(C + 1), orientation="horizontal", baseline=None, color="k")
    lo, hi = int(counts.min()), int(counts.max())
    pad = max(2, (hi - lo) // 2)  # the two ticks well inside the panel
    ax1.set_xlim(lo - pad, hi + pad)
    ax1.set_xticks(sorted({lo, hi}))
    ax1.set_xlabel("stitches", fontsize=8)
    xfer = transfers_before(p)
    ax2.barh(np.arange(C) + 0.5, xfer, height=1.0, color="0.35")
    ax2.set_xlim(0, max(1, int(xfer.max())) * 1.3)
    ax2.set_xticks(sorted({0, int(xfer.max())}))
    ax2.set_xlabel("xfers", fontsize=8)
    for a in (ax1, ax2):
        a.tick_params(labelleft=False, labelsize=7)
    labels.set_axis_off()
    labels.set_ylim(0, 1)
    nb = len(km.bands)
    size = 7.5 if nb <= 12 else 6
    for k, b in enumerate(km.bands):
        for a in axes:
            a.axhline(b.start, color="k", lw=0.8)
        sl = "no stitch length (default)" if b.stitch_length is None else f"stitch length {b.stitch_length:g}"
        n = counts[b.start : b.end]
        width = f"{n[0]} stitches" if n.min() == n.max() else f"{n[0]}→{n[-1]} stitches"
        y = (k + 0.5) / nb
        labels.text(
            0.1,
            y,
            f"courses {b.start}–{b.end}: {b.fabric}\n{b.pattern}, {b.yarn}, carrier {p.band_carriers[k]}, "
            f"{width}\n{sl} → x-stitch-number {p.stitch_numbers[k]}",
            va="center",
            fontsize=size,
        )
        fig.add_artist(
            ConnectionPatch(
                (0.08, y),
                (1.0, (b.start + b.end) / 2),
                coordsA=labels.transAxes,
                coordsB=ax2.get_yaxis_transform(),
                lw=0.6,
                color="0.4",
            )
        )


def _legend(ax, p: Plan, carriers: list[int], palette: list) -> None:
    """Below the chart: each carrier's plain and reverse colour, and the shaping marks."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = [
        h
        for c in carriers
        for h in (
            Patch(color=palette[2 * carriers.index(c)], label=f"carrier {c} ({_yarn_of(p, c)}): plain"),
            Patch(color=palette[2 * carriers.index(c) + 1], label=f"carrier {c}: reverse (purl)"),
        )
    ]
    if p.kmap.shaped:
        handles += [
            Line2D([], [], ls="", marker="^", color="#1a7f37", label="increase at this edge"),
            Line2D([], [], ls="", marker="v", color="#b3261e", label="decrease at this edge"),
        ]
    ax.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.06),
        ncol=min(4, len(handles)),
        fontsize=8,
    )


def _band_details(fig, grid, p: Plan, detail, front: np.ndarray, reverse: np.ndarray, colours) -> None:
    """The first courses of each band at needle scale (the right edge of the tube), each cell marked with
    the bed (F/B) that knits it; one label for the row of panels."""
    from matplotlib.colors import ListedColormap

    km, lay = p.kmap, p.layout
    mask = lay.mask()
    rows = 4
    cols = min(12, min(km.course_needles))
    for i, k in enumerate(detail):
        b = km.bands[k]
        shown = range(b.start, b.start + min(rows, b.courses))
        right = max(lay.right[c] for c in shown)
        span = slice(right + 1 - cols, right + 1)
        sub = front[shown.start : shown.stop, span]
        here = mask[shown.start : shown.stop, span]
        img = np.ma.masked_array(reverse[shown.start : shown.stop, span].astype(float), ~here)
        axd = fig.add_subplot(grid[i])
        axd.imshow(
            img,
            cmap=ListedColormap(_shades(colours[p.band_carriers[k]])),
            vmin=0,
            vmax=1,
            origin="lower",
            aspect="auto",
            extent=(
                FIRST_NEEDLE + right - cols + 0.5,
                FIRST_NEEDLE + right + 0.5,
                b.start,
                b.start + len(sub),
            ),
        )
        for r, j in zip(*np.nonzero(here), strict=True):
            axd.text(
                FIRST_NEEDLE + right + 1 - cols + j,
                b.start + r + 0.5,
                "F" if sub[r, j] else "B",
                ha="center",
                va="center",
                fontsize=6.5,
            )
        axd.set_title(f"{b.pattern} ({b.yarn})", fontsize=8)
        axd.set_yticks(b.start + np.arange(len(sub)) + 0.5, [str(c) for c in shown])
        axd.xaxis.set_major_locator(_ticks(3))
        axd.tick_params(labelsize=6)
        if i == 0:
            axd.set_ylabel("course", fontsize=7)
    if detail:
        fig.supxlabel(
            f"the first courses of each fabric's first band at the tube's right edge: needle; F/B, the bed "
            f"that knits each stitch (at most {DETAILS} fabrics)",
            fontsize=8,
        )


def _ticks(n: int):
    from matplotlib.ticker import MaxNLocator

    return MaxNLocator(nbins=n, integer=True)


def _yarn_of(p: Plan, carrier: int) -> str:
    return next(y for y, c in p.carriers.items() if c == carrier)
