"""The files of a design: ``design.json``, ``knit-map.csv``, ``knit-map.png``, ``pressure.png`` and
``design.vtu``."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from knitframe.garment.core import CLASSES, Design
from knitframe.interfaces import DesignObjective, declared

__all__ = ["write_design", "plot_knit_map", "plot_pressure", "write_knit_map", "station_table"]


def station_table(d: Design) -> str:
    """The stations as a text table: position, circumference, needles, fabric, pressure, target, the
    band under the limb tolerance, and whether the station meets the prescription."""
    rows = d.stations()
    x = 100 * d.safety.get("limb_tolerance", 0.03)
    head = (
        f"{'mm':>5} {'circ':>5} {'st.':>4} {'fabric':<18} {'mmHg':>5} {'target':>6} {f'±{x:g}% limb':>12}  ok"
    )
    out = [head]
    for r in rows:
        band = r["band_mmHg"]["circumference"]
        t = r["target_mmHg"]
        ok = "" if r["inside_tolerance"] is None else ("yes" if r["inside_tolerance"] else "NO")
        out.append(
            f"{r['position_mm']:5.0f} {r['circumference_mm']:5.0f} "
            f"{'' if r['needles'] is None else r['needles']:>4} {r['fabric'][:18]:<18} "
            f"{r['pressure_mmHg']['equivalent']:5.1f} {'' if t is None else f'{t:6.1f}':>6} "
            f"{band[0]:5.1f}–{band[1]:<6.1f}  {ok}"
        )
    return "\n".join(out)


def write_design(d: Design, folder: Path) -> list[str]:
    """Write every output of a design into ``folder``; returns the file names."""
    from knitframe.fitting import finite_json

    data, _ = finite_json(d.to_json())
    (folder / "design.json").write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    write_knit_map(d, folder / "knit-map.csv")
    plot_knit_map(d, folder / "knit-map.png")
    plot_pressure(d, folder / "pressure.png")
    d.limb.to_vtu(folder / "design.vtu", cell_data=_cell_fields(d))
    return ["design.json", "knit-map.csv", "knit-map.png", "pressure.png", "design.vtu"]


def _cell_fields(d: Design) -> dict[str, np.ndarray]:
    return {
        "fabric": d.fabric.ravel().astype(np.int64),
        "lambda1": d.lam1.ravel(),
        "lambda2": d.lam2.ravel(),
        "T1_N_per_mm": d.T1.ravel(),
        "T2_N_per_mm": d.T2.ravel(),
        "pressure_equivalent_mmHg": d.pressure_equivalent.ravel(),
        "pressure_local_mmHg": d.pressure_local.ravel(),
        "over_limit": d.over_limit.ravel().astype(np.int64),
    }


def write_knit_map(d: Design, path: Path) -> None:
    """One row per element: course and wale ranges, fabric, stretches, tensions and pressures."""
    R, A = d.fabric.shape
    first = np.concatenate([[0], np.cumsum(d.courses)]).astype(int)
    row_needles = d.row_needles if d.row_needles is not None else np.zeros(R, dtype=int)
    pe, pl = d.pressure_equivalent, d.pressure_local
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(
            [
                "row",
                "column",
                "course_start",
                "course_end",
                "wale_start",
                "wale_end",
                "needles",
                "position_mm",
                "fabric",
                "pattern",
                "yarn",
                "stitch_length",
                "lambda1",
                "lambda2",
                "T1_N_per_mm",
                "T2_N_per_mm",
                "pressure_equivalent_mmHg",
                "pressure_local_mmHg",
            ]
        )
        for i in range(R):
            for j in range(A):
                e = d.library.entries[int(d.fabric[i, j])]
                needles = int(row_needles[i])
                w0, w1 = ((j * needles) // A, ((j + 1) * needles) // A) if needles else ("", "")
                w.writerow(
                    [
                        i,
                        j,
                        first[i],
                        first[i + 1],
                        w0,
                        w1,
                        needles or "",
                        f"{d.geometry.z[i]:.3f}",
                        e.name,
                        e.pattern,
                        e.yarn,
                        "" if e.stitch_length is None else f"{e.stitch_length:g}",
                        f"{d.lam1[i, j]:.6g}",
                        f"{d.lam2[i, j]:.6g}",
                        f"{d.T1[i, j]:.6g}",
                        f"{d.T2[i, j]:.6g}",
                        f"{pe[i, j]:.4f}",
                        f"{pl[i, j]:.4f}",
                    ]
                )


def _colours(n: int):
    import matplotlib

    cmap = matplotlib.colormaps["tab10" if n <= 10 else "tab20"]
    return [cmap(k % cmap.N) for k in range(n)]


def _row_edges(d: Design) -> np.ndarray:
    """(R+1,) edges of the element rows along the limb, mm (the vertical axis of both pictures)."""
    g = d.geometry
    return np.concatenate([[g.z[0] - 0.5 * g.row_length[0]], g.z + 0.5 * g.row_length])


def _course_axis(ax, d: Design, edges: np.ndarray) -> None:
    """A secondary vertical axis in courses from the distal end, mapped from mm along the limb."""
    courses = np.concatenate([[0.0], np.cumsum(d.courses)])
    sec = ax.secondary_yaxis(
        "right",
        functions=(lambda mm: np.interp(mm, edges, courses), lambda c: np.interp(c, courses, edges)),
    )
    sec.set_ylabel("course, from the distal end")


def plot_knit_map(d: Design, path: Path) -> None:
    """The unrolled tube coloured by fabric, as a knitter's shaped chart: stitches across (the width of
    each row is its needle count, centred), mm along the limb up, courses on the right."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    R, A = d.fabric.shape
    used = sorted(set(int(f) for f in np.unique(d.fabric)))
    colours = _colours(len(d.library.entries))
    edges = _row_edges(d)
    width = d.row_needles.astype(float) if d.row_needles is not None else np.full(R, float(A))
    # one band of quads per row, with a zero-height band between rows, so rows can differ in width
    X = np.repeat(width[:, None] * (np.linspace(0.0, 1.0, A + 1)[None, :] - 0.5), 2, axis=0)
    Y = np.repeat(np.stack([edges[:-1], edges[1:]], axis=1).reshape(-1)[:, None], A + 1, axis=1)
    C = np.ma.masked_all((2 * R - 1, A))
    C[0::2] = d.fabric
    fig, ax = plt.subplots(figsize=(7.5, 8.5), layout="constrained")
    ax.pcolormesh(
        X, Y, C, cmap=ListedColormap(colours), vmin=-0.5, vmax=len(colours) - 0.5, edgecolors="none"
    )
    for r in d.regions():
        if r["rows"][0] > 0:
            ax.axhline(edges[r["rows"][0]], color="k", lw=0.6)
    if d.row_needles is not None:
        for sign in (-0.5, 0.5):
            ax.stairs(sign * width, edges, orientation="horizontal", color="k", lw=1.0, baseline=None)
    ax.set_xlabel("stitches across the tube (centred)" if d.row_needles is not None else "element column")
    ax.set_ylabel("position along the limb (mm), distal at 0")
    half = 0.55 * width.max()
    ax.set_xlim(-half, half)
    ax.set_ylim(edges[0], edges[-1])
    _course_axis(ax, d, edges)
    title = f"knit map: {len(d.regions())} regions, {int(d.courses.sum())} courses"
    if d.row_needles is not None:
        lo, hi = int(d.row_needles.min()), int(d.row_needles.max())
        title += f", {lo}–{hi} stitches per course" if lo != hi else f" × {lo} stitches"
    ax.set_title(title)
    ent = d.library.entries
    ax.legend(
        handles=[
            Patch(
                color=colours[f],
                label=f"{ent[f].name} ({ent[f].pattern}, {ent[f].yarn}"
                + (f", SL{ent[f].stitch_length:g}" if ent[f].stitch_length else "")
                + ")",
            )
            for f in used
        ],
        loc="upper center",
        bbox_to_anchor=(0.5, -0.07),
        ncol=2,
        fontsize=8,
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_pressure(d: Design, path: Path) -> None:
    """Left: the local pressure map on the unrolled tube. Right: the pressure along the limb with the
    RAL-GZ 387 class bands, the local min–max, the equivalent-radius pressure and the target."""
    import matplotlib.pyplot as plt

    g = d.geometry
    pe, pl = d.pressure_equivalent, d.pressure_local
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 6.5), layout="constrained", width_ratios=[1, 1.2])
    A = d.fabric.shape[1]
    edges = _row_edges(d)
    m = ax1.pcolormesh(np.arange(A + 1), edges, pl, cmap="viridis", shading="flat")
    fig.colorbar(m, ax=ax1, label="pressure, local radius (mmHg)")
    ax1.set_xlabel("element column around the limb")
    ax1.set_ylabel("position along the limb (mm)")
    ax1.set_title("interface pressure p = T/r (local curvature)")
    top = max(float(pl.max()), float(pe.max()), 50.0) * 1.08
    shades = ["#e8f4e8", "#d4ebd4", "#bfe0bf", "#a9d5a9"]
    for (name, lo, hi), colour in zip(CLASSES, shades, strict=False):
        ax2.axvspan(lo, min(hi, top), color=colour, zorder=0)
        ax2.text(0.5 * (lo + min(hi, top)), g.z[-1], f"class {name}", ha="center", va="top", fontsize=8)
    ax2.fill_betweenx(
        g.z,
        pl.min(axis=1),
        pl.max(axis=1),
        color="tab:orange",
        alpha=0.3,
        label="local radius: min–max around",
    )
    band = d.bands()["circumference"]
    x = 100 * d.safety.get("limb_tolerance", 0.03)
    ax2.fill_betweenx(
        g.z, band[:, 0], band[:, 1], color="tab:blue", alpha=0.18, label=f"equivalent, limb ±{x:g} %"
    )
    ax2.plot(pe.mean(axis=1), g.z, color="tab:blue", lw=2.4, zorder=3, label="equivalent radius C/2π")
    ax2.plot(
        pl.mean(axis=1),
        g.z,
        color="tab:red",
        lw=1.6,
        ls=(0, (2, 2)),
        zorder=4,
        label="local radius: mean around",
    )
    want = declared(d.objective, DesignObjective, "target")(g.position)
    if want is not None and np.ptp(want) > 0:  # a profile along the limb
        ax2.plot(want, g.z, "k--", lw=1.2, label="target")
    elif want is not None:  # one level
        ax2.axvline(float(want.flat[0]), color="k", ls="--", lw=1.2, label="target")
    ax2.set_xlim(0, top)
    ax2.set_ylim(edges[0], edges[-1])
    ax2.set_xlabel("pressure (mmHg)")
    ax2.set_ylabel("position along the limb (mm), distal at 0")
    ax2.set_title("pressure profile with RAL-GZ 387 classes")
    ax2.legend(loc="lower right", fontsize=8, framealpha=0.95)
    fig.savefig(path, dpi=110)
    plt.close(fig)
