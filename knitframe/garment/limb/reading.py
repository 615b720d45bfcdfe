"""Reading a scan file: its vertices and triangles, with trimesh or meshio, or a one-line refusal."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from knitframe.errors import DataError

__all__ = ["read_triangles"]


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return (text[0][:160] if text else "") or type(exc).__name__


def read_triangles(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) float64 and triangles (k, 3) int64 of a mesh file, or a one-line DataError."""
    label = str(path)
    if not path.exists():
        raise DataError(label, "no such file")
    if path.is_dir():
        raise DataError(label, "is a folder, not a mesh file")
    if path.stat().st_size == 0:
        raise DataError(label, "empty file (0 bytes)")
    import trimesh

    suffix = path.suffix.lower() or "(no extension)"

    def with_trimesh() -> tuple[np.ndarray, np.ndarray]:
        loaded = trimesh.load(str(path), force="mesh", process=False)
        return (
            np.asarray(loaded.vertices, dtype=np.float64).reshape(-1, 3),
            np.asarray(loaded.faces, dtype=np.int64).reshape(-1, 3),
        )

    readers = [with_trimesh, lambda: _read_with_meshio(path)]
    if suffix.lstrip(".") not in _TRIMESH_NATIVE:
        readers.reverse()  # meshio formats: read them with meshio itself
    try:
        vertices, faces = readers[0]()
    except Exception as exc:  # any reader failure becomes one line naming the file
        try:
            vertices, faces = readers[1]()
        except Exception:
            # a missing optional decoder is how trimesh fails on bytes that are not text: no detail
            detail = "" if isinstance(exc, ImportError) else f": {_one_line(exc)}"
            raise DataError(label, f"not a readable mesh ({suffix} file){detail}") from None
    if len(faces) == 0:
        points = _count_points(path)
        if points:
            raise DataError(
                label,
                f"no triangles: {points} points but no faces (a point cloud?); a surface mesh is needed",
            )
        raise DataError(label, f"no mesh data found (unreadable, or not a {suffix} file)")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise DataError(label, f"face indices out of range (0..{len(vertices) - 1})")
    bad = ~np.all(np.isfinite(vertices), axis=1)
    if bad.any():
        raise DataError(
            label, f"{int(bad.sum())} of {len(vertices)} vertices have non-finite coordinates (NaN or inf)"
        )
    return vertices, faces


#: formats trimesh reads itself (others go to meshio first)
_TRIMESH_NATIVE = frozenset({"stl", "obj", "ply", "off", "glb", "gltf", "3mf", "dae", "zae", "xaml", "3dxml"})


def _read_with_meshio(path: Path) -> tuple[np.ndarray, np.ndarray]:
    import meshio

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # meshio probing bytes that are not its format
        m = meshio.read(str(path))
    pts = np.asarray(m.points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError("points are not 2D or 3D")
    if pts.shape[1] == 2:
        pts = np.column_stack((pts, np.zeros(len(pts))))
    tris = [np.asarray(c.data, dtype=np.int64) for c in m.cells if c.type == "triangle"]
    for c in m.cells:
        if c.type == "quad":
            q = np.asarray(c.data, dtype=np.int64)
            tris += [q[:, [0, 1, 2]], q[:, [0, 2, 3]]]
    faces = np.concatenate(tris) if tris else np.zeros((0, 3), dtype=np.int64)
    return pts, faces


def _count_points(path: Path) -> int:
    """How many points a file holds when it has no faces (0 if it cannot be read at all)."""
    import meshio
    import trimesh

    def with_trimesh() -> int:
        return int(len(getattr(trimesh.load(str(path), process=False), "vertices", ())))

    def with_meshio() -> int:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return int(len(meshio.read(str(path)).points))

    readers = [with_trimesh, with_meshio]
    if path.suffix.lower().lstrip(".") not in _TRIMESH_NATIVE:
        readers.reverse()
    for reader in readers:
        try:
            return reader()
        except Exception:
            continue
    return 0
