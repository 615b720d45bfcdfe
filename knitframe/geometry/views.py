"""Views of a cell for people: VTU files for ParaView, a three-view PNG and a plain-data summary.

:func:`write_vtu` writes the centerlines (polylines with tangents and normals) and the yarns'
tubes swept along their rotation-minimising frames (:func:`tube_surface`); :func:`plot_views`
draws a front, top and side view of a few tiled cells; :func:`summary` is the plain data of
``geometry.json``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from knitframe.geometry.bending import bending_wavenumber
from knitframe.geometry.cell import UnitCell
from knitframe.geometry.framing import Frames, frames

if TYPE_CHECKING:
    from knitframe.geometry.proximity import Clearance

__all__ = ["tube_surface", "write_vtu", "plot_views", "summary"]


def tube_surface(fr: Frames, radius: float, sides: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Points and quads of the tube of ``radius`` swept along one yarn's frames.

    Returns points ((n+1)·sides, 3) mm and quad cells (n·sides, 4), ring by ring.
    """
    phi = 2.0 * np.pi * np.arange(sides) / sides
    ring = (
        np.cos(phi)[None, :, None] * fr.normal[:, None, :]
        + np.sin(phi)[None, :, None] * fr.binormal[:, None, :]
    )
    pts = (fr.x[:, None, :] + radius * ring).reshape(-1, 3)
    i = np.arange(len(fr.t) - 1)[:, None]
    j = np.arange(sides)[None, :]
    jn = (j + 1) % sides
    quads = np.stack([i * sides + j, i * sides + jn, (i + 1) * sides + jn, (i + 1) * sides + j], axis=-1)
    return pts, quads.reshape(-1, 4)


def write_vtu(cell: UnitCell, out: str | Path, *, n: int = 256, sides: int = 16) -> list[Path]:
    """Write ``centerlines.vtu`` (polylines with tangents) and ``tubes.vtu`` (swept surfaces) to ``out``.

    Each yarn gets ``n`` segments; ``yarn`` point data numbers the yarns. Returns the paths.
    """
    import meshio

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fr = frames(cell, n)
    pts, lines, yid, tan, nrm = [], [], [], [], []
    tpts, tquads, tyid = [], [], []
    off = toff = 0
    for i, f in enumerate(fr):
        m = len(f.t)
        pts.append(f.x)
        lines.append(off + np.stack([np.arange(m - 1), np.arange(1, m)], axis=1))
        yid.append(np.full(m, i))
        tan.append(f.tangent)
        nrm.append(f.normal)
        off += m
        p, q = tube_surface(f, cell.radius, sides)
        tpts.append(p)
        tquads.append(q + toff)
        tyid.append(np.full(len(p), i))
        toff += len(p)
    paths = [out / "centerlines.vtu", out / "tubes.vtu"]
    meshio.write(
        paths[0],
        meshio.Mesh(
            np.vstack(pts),
            [("line", np.vstack(lines))],
            point_data={"yarn": np.concatenate(yid), "tangent": np.vstack(tan), "normal": np.vstack(nrm)},
        ),
    )
    meshio.write(
        paths[1],
        meshio.Mesh(
            np.vstack(tpts), [("quad", np.vstack(tquads))], point_data={"yarn": np.concatenate(tyid)}
        ),
    )
    return paths


def plot_views(
    cell: UnitCell, path: str | Path, *, tiles: int = 2, n: int = 400, clearance: Clearance | None = None
) -> Path:
    """Three-view PNG (front x-y, top x-z, side y-z) of ``tiles`` x ``tiles`` copies of the cell.

    Yarns are drawn as segments of the knitted diameter's width, painted back to front and
    darker further back, so each view shows which yarn passes over which. Rows have their own
    colours. With the cell's ``clearance`` the places closer than dk are circled in red in every
    copy (the closest place when none is), and the legend below the views gives their count.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    colors = plt.get_cmap("tab10").colors
    segs, depth, col = {v: [] for v in range(3)}, {v: [] for v in range(3)}, []
    views = ((0, 1, 2), (0, 2, 1), (1, 2, 0))  # (horizontal, vertical, depth axis)
    for i, c in enumerate(cell.yarns):
        _, x, _ = c.sample(n)
        for k1 in range(tiles):
            for k2 in range(tiles):
                xs = x + k1 * cell.L1 + k2 * cell.L2
                for v, (hx, vy, dz) in enumerate(views):
                    p = xs[:, [hx, vy]]
                    segs[v].append(np.stack([p[:-1], p[1:]], axis=1))
                    depth[v].append(0.5 * (xs[:-1, dz] + xs[1:, dz]) * (1 if v != 1 else -1))
                col.append(np.repeat([colors[i % 10]], n - 1, axis=0))
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.2))
    labels = ("x (course), mm", "y (wale), mm", "z (thickness), mm")
    names = ("front (x-y)", "top (x-z)", "side (y-z)")
    allc = np.vstack(col)
    for v, ax in enumerate(axes):
        s = np.vstack(segs[v])
        order = np.argsort(np.concatenate(depth[v]), kind="stable")
        ax.set_aspect("equal")
        lo, hi = s.reshape(-1, 2).min(0) - cell.radius, s.reshape(-1, 2).max(0) + cell.radius
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        fig.canvas.draw()
        bbox = ax.get_window_extent()
        pts_per_mm = min(bbox.width / (hi[0] - lo[0]), bbox.height / (hi[1] - lo[1])) * 72.0 / fig.dpi
        dep = np.concatenate(depth[v])[order]
        shade = (0.55 + 0.45 * (dep - dep.min()) / max(float(np.ptp(dep)), 1e-300))[:, None]
        ax.add_collection(
            LineCollection(
                s[order], colors=allc[order] * shade, linewidths=cell.dk * pts_per_mm, capstyle="round"
            )
        )
        ax.set_xlabel(labels[views[v][0]])
        ax.set_ylabel(labels[views[v][1]])
        ax.set_title(names[v])
    fig.suptitle(
        f"{cell.pattern}: {cell.arc_length_per_stitch:.3g} mm/stitch, pitches {cell.course_pitch:.3g} x "
        f"{cell.wale_pitch:.3g} mm, dk {cell.dk:.3g} mm ({tiles}x{tiles} cells)"
    )
    if clearance is not None:
        _mark_close_places(fig, axes, views, cell, clearance, tiles)
        fig.tight_layout(rect=(0, 0.07, 1, 1))
    else:
        fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _mark_close_places(fig, axes, views, cell: UnitCell, clr: Clearance, tiles: int) -> None:
    """Red circles at the places closer than dk (the closest place when none is), in every copy of
    the cell and every view, with one legend entry below the views that counts them."""
    places = clr.overlaps or (clr.closest,)
    shifts = [k1 * cell.L1 + k2 * cell.L2 for k1 in range(tiles) for k2 in range(tiles)]
    pts = np.array([np.asarray(c.point) + s for c in places for s in shifts])
    for ax, (hx, vy, _) in zip(axes, views, strict=True):
        marks = ax.scatter(
            pts[:, hx], pts[:, vy], s=36, facecolors="none", edgecolors="red", linewidths=1.4, zorder=5
        )
    ratio = f"{clr.minimum:.3g} mm = {clr.minimum / clr.dk:.2g} dk"
    label = (
        f"{len(clr.overlaps)} places per cell where the yarn centerlines are closer than dk "
        f"({clr.dk:.3g} mm; the closest {ratio})"
        if clr.overlaps
        else f"no place closer than dk ({clr.dk:.3g} mm): the closest place, {ratio}"
    )
    fig.legend([marks], [label], loc="lower center", frameon=False, fontsize=10)


def summary(cell: UnitCell, clr: Clearance | None = None) -> dict[str, Any]:
    """Plain-data description of a cell (and its clearance) for ``geometry.json``."""
    lengths = [c.arc_length() for c in cell.yarns]
    out: dict[str, Any] = {
        "pattern": cell.pattern,
        "layout": [list(r) for r in cell.layout],
        "arc_length_per_stitch": cell.arc_length_per_stitch,
        "yarn_lengths": lengths,
        "course_pitch": cell.course_pitch,
        "wale_pitch": cell.wale_pitch,
        "L1": cell.L1.tolist(),
        "L2": cell.L2.tolist(),
        "dk": cell.dk,
        "end_pairs": [list(p) for p in cell.end_pairs],
        "shape": dict(cell.info),
    }
    k = bending_wavenumber(cell)
    #: the Rayleigh wavenumber of the curvature, 1/mm, and in waves per stitch (k ℓ / 2π)
    out["bending_wavenumber"] = k
    out["bending_waves_per_stitch"] = k * cell.arc_length_per_stitch / (2.0 * np.pi)
    if clr is not None:
        out["clearance"] = clr.to_dict()
    return out
