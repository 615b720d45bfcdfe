"""A limb from a scan file: read, choose the shell, find the axis and units, slice, check, resample."""

from __future__ import annotations

import numbers
import warnings
from pathlib import Path

import numpy as np

from knitframe.errors import ConfigError, DataError, KnitframeWarning
from knitframe.garment.limb.checks import check_sections, check_tubular
from knitframe.garment.limb.measured import check_counts
from knitframe.garment.limb.reading import read_triangles
from knitframe.garment.limb.sections import perpendicular
from knitframe.garment.limb.shells import (
    Debris,
    canonical_sign,
    choose_shell,
    submesh,
    surface_moments,
)
from knitframe.garment.limb.slicing import Slicer, closed_loops, resample

__all__ = ["METRES_BELOW", "ROUND_SPREAD", "read_scan"]

#: a scan shorter than this along its axis (in file units) is taken to be in metres (units="auto")
METRES_BELOW = 3.0
#: transverse second moments closer than this (relative) make the scan "round": reference = world axis
ROUND_SPREAD = 0.05


_SCALES = {"auto": None, "mm": 1.0, "cm": 10.0, "m": 1000.0}


def _check_options(axis, trim, units) -> np.ndarray | None:
    """Refuse a bad ``trim`` or ``units``; the given ``axis`` as a unit vector, or None."""
    if isinstance(trim, bool) or not isinstance(trim, numbers.Real) or not 0.0 <= float(trim) < 0.5:
        raise ConfigError("trim", f"must be in [0, 0.5), got {trim!r}")
    if units not in _SCALES:
        raise ConfigError("units", f"must be one of {', '.join(_SCALES)}, got {units!r}")
    given_axis = None
    if axis is not None:
        given_axis = np.asarray(axis, dtype=np.float64).reshape(-1)
        if given_axis.size != 3 or not np.all(np.isfinite(given_axis)) or np.linalg.norm(given_axis) == 0.0:
            raise ConfigError("axis", f"must be a finite non-zero 3-vector, got {axis!r}")
        given_axis = given_axis / np.linalg.norm(given_axis)
    return given_axis


def _limb_shell(path: Path, label: str) -> tuple[np.ndarray, np.ndarray, list[str], Debris | None]:
    """Vertices (n, 3) and faces (k, 3) of the limb's shell, merged and cleaned, the notices, and the
    shells dropped as debris (their notice needs the units)."""
    import trimesh

    vertices, faces = read_triangles(path)
    tri = vertices[faces]
    nondegenerate = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) > 0.0
    mesh = trimesh.Trimesh(vertices, faces[nondegenerate], process=False)
    mesh.merge_vertices()
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces) == 0:
        raise DataError(label, "no triangles with a non-zero area")
    vertices = np.array(mesh.vertices, dtype=np.float64)
    faces = np.array(mesh.faces, dtype=np.int64)
    faces, notes, debris = choose_shell(vertices, faces, label)
    shell = submesh(vertices, faces)
    return np.array(shell.vertices, dtype=np.float64), np.array(shell.faces, dtype=np.int64), notes, debris


def _axis_and_reference(
    cov: np.ndarray, given_axis: np.ndarray | None, reference
) -> tuple[np.ndarray, np.ndarray]:
    """Axis direction d and reference direction e1 ⊥ d (see :meth:`Limb.from_scan` steps 3 and 6)."""
    if given_axis is None:
        d = canonical_sign(np.linalg.eigh(cov)[1][:, 2])
    else:
        d = given_axis
    if reference is None:
        proj = np.eye(3) - np.outer(d, d)
        lam, vec = np.linalg.eigh(proj @ cov @ proj)
        # a nearly round limb has no widest direction: take a fixed world direction instead
        e1 = vec[:, 2] if lam[2] - lam[1] > ROUND_SPREAD * lam[2] else perpendicular(d)
    else:
        e1 = np.asarray(reference, dtype=np.float64).reshape(-1)
        if e1.size != 3 or not np.all(np.isfinite(e1)) or not np.any(e1):
            raise ConfigError("reference", f"must be a finite non-zero 3-vector, got {reference!r}")
        e1 = e1 / np.linalg.norm(e1)
    e1 = e1 - (e1 @ d) * d
    if np.linalg.norm(e1) < 1e-3:  # within 0.06° of the axis: no azimuth
        raise ConfigError("reference", "must not be parallel to the axis")
    return d, canonical_sign(e1 / np.linalg.norm(e1))


def _scale_to_mm(length: float, units: str, label: str, notes: list[str]) -> float:
    """The factor to mm for a scan ``length`` long along its axis; a notice appended to ``notes``."""
    scale = _SCALES[units]
    if scale is None:
        scale = 1.0
        if length < METRES_BELOW:
            scale = 1000.0
            note = (
                f"converted from metres: {length:.4g} long along the axis (< {METRES_BELOW:g}), "
                "coordinates multiplied by 1000"
            )
            notes.append(note)
            # attributed to the caller of Limb.from_scan (this, read_scan, from_scan, caller)
            warnings.warn(f"{label}: {note}", KnitframeWarning, stacklevel=4)
    elif scale != 1.0:
        notes.append(f"converted from {units} to mm (x{scale:g})")
    return scale


def _cut(slicer: Slicer, center, f1, f2, length, trim, n_stations) -> tuple[np.ndarray, list[np.ndarray]]:
    """Station heights z (n_stations,) and each station's section segments (k, 2, 2) in (X, Y)."""
    zmin, zmax = float(slicer.hsorted[0]), float(slicer.hsorted[-1])
    inset = max(float(trim) * length, 1e-6 * length)
    z = slicer.off_vertices(np.linspace(zmin + inset, zmax - inset, n_stations))
    raw = []
    for zi in z:  # one vectorised cut per station
        seg = slicer.segments(float(zi)) - center
        raw.append(np.stack((seg @ f1, seg @ f2), axis=-1))
    return z, raw


def read_scan(path: Path, *, axis, n_stations, n_around, trim, units, name, reference) -> dict:
    """The fields of the :class:`~knitframe.garment.limb.Limb` a scan gives (see :meth:`Limb.from_scan`):
    name, sections (mm), axis origin and direction, source and notices."""
    label = str(path)
    check_counts(n_stations, n_around)
    given_axis = _check_options(axis, trim, units)
    vertices, faces, notes, debris = _limb_shell(path, label)

    _, center, cov = surface_moments(vertices, faces)
    d, e1 = _axis_and_reference(cov, given_axis, reference)

    heights = (vertices - center) @ d
    length = float(heights.max() - heights.min())
    scale = _scale_to_mm(length, units, label, notes)
    if debris is not None:
        notes.append(debris.note(scale))
    vertices = vertices * scale
    center = center * scale
    length *= scale

    slicer = Slicer(submesh(vertices, faces), center, d)
    f1 = e1
    f2 = np.cross(f1, d)
    tol = 1e-8 * float(np.ptp(vertices, axis=0).max())
    z, raw = _cut(slicer, center, f1, f2, length, trim, n_stations)
    sizes = np.array([np.linalg.norm(s[:, 1] - s[:, 0], axis=1).sum() for s in raw])

    if given_axis is None:
        k = max(1, n_stations // 10)
        if sizes[:k].mean() > sizes[-k:].mean() * (1.0 + 1e-9):
            d, f2, z = -d, -f2, -z[::-1]
            raw = [s * np.array([1.0, -1.0]) for s in raw[::-1]]
    positions = z - z[0]

    found = [closed_loops(s, tol) for s in raw]
    check_sections(label, found, positions)
    xy = np.empty((n_stations, n_around, 2))
    perimeter = np.empty(n_stations)
    for i, (loops, _) in enumerate(found):
        xy[i], perimeter[i] = resample(loops[0], n_around)
    check_tubular(label, length, perimeter, xy, positions)

    plane = center + np.outer(z, d)
    sections = plane[:, None, :] + xy[..., :1] * f1 + xy[..., 1:] * f2
    return {
        "name": path.stem if name is None else name,
        "sections": sections,
        "axis_origin": plane[0],
        "axis_direction": d,
        "source": f"scan: {path.name}",
        "notes": tuple(notes),
    }
