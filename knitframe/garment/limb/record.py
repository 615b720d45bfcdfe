"""The :class:`Limb` record: closed cross-section loops at stations along a straight axis (mm)."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.errors import GeometryError
from knitframe.garment.limb.measured import measured_sections
from knitframe.garment.limb.sections import UPSAMPLE, loop_curvature_radius, perpendicular, trig_eval

__all__ = ["Limb"]


def _frozen_array(value: Any) -> np.ndarray:
    arr = np.array(value, dtype=np.float64, copy=True)
    arr.setflags(write=False)
    return arr


def _unit_vector(value: Any) -> np.ndarray:
    arr = np.array(value, dtype=np.float64, copy=True).reshape(-1)
    norm = float(np.linalg.norm(arr)) if arr.size == 3 and np.all(np.isfinite(arr)) else 0.0
    if norm == 0.0:
        raise GeometryError(f"Limb.axis_direction: must be a finite non-zero 3-vector, got {value!r}")
    arr = arr / norm
    arr.setflags(write=False)
    return arr


@attrs.frozen(eq=False)
class Limb:
    """A limb surface sampled as closed cross-section loops at stations along its axis (mm).

    ``sections`` (n_stations, n_around, 3), float64, mm: loop i lies in the plane normal to the
    axis at station i; its n_around points are equally spaced by arc length, ordered
    counter-clockwise seen looking from the first (distal: wrist/ankle) station towards the last,
    and point 0 of every loop lies at the same azimuth (on the half-line from the section's
    centroid along a common reference direction), so (i, j) form a structured quad grid.
    ``axis_origin`` (3,) is the axis point at station 0 and ``axis_direction`` (3,) the unit
    vector distal → proximal. ``source`` says where the limb came from and ``notes`` holds
    one-line notices (unit conversion, shell choice).

    The constructor checks the contract: finite coordinates, at least 2 stations and 8 points per
    loop, every loop in its station plane (to 1e-6 of the limb's size), stations strictly
    increasing along the axis, and every loop counter-clockwise as above.
    """

    name: str
    sections: np.ndarray = attrs.field(converter=_frozen_array)
    axis_origin: np.ndarray = attrs.field(converter=_frozen_array)
    axis_direction: np.ndarray = attrs.field(converter=_unit_vector)
    source: str = ""
    notes: tuple[str, ...] = attrs.field(default=(), converter=tuple)

    def __attrs_post_init__(self) -> None:
        s = self.sections
        where = f"Limb '{self.name}'"
        if s.ndim != 3 or s.shape[2] != 3 or s.shape[0] < 2 or s.shape[1] < 8:
            raise GeometryError(f"{where}: sections must be (n_stations>=2, n_around>=8, 3), got {s.shape}")
        if not np.all(np.isfinite(s)):
            raise GeometryError(f"{where}: sections contain non-finite coordinates")
        if self.axis_origin.shape != (3,) or not np.all(np.isfinite(self.axis_origin)):
            raise GeometryError(f"{where}: axis_origin must be a finite 3-vector")
        height = np.einsum("ijk,k->ij", s - self.axis_origin, self.axis_direction)
        size = float(np.ptp(s.reshape(-1, 3), axis=0).max())
        tilt = np.ptp(height, axis=1)
        if np.any(tilt > 1e-6 * size):
            i = int(np.argmax(tilt))
            raise GeometryError(
                f"{where}: loop {i} is not in a plane normal to the axis (spread {tilt[i]:.3g} mm along it)"
            )
        pos = height.mean(axis=1)
        if np.any(np.diff(pos) <= 0.0):
            i = int(np.argmax(np.diff(pos) <= 0.0))
            raise GeometryError(
                f"{where}: stations must be strictly increasing along axis_direction "
                f"(station {i + 1} is not beyond station {i})"
            )
        area = self._area_raw()
        if np.any(area <= 0.0):
            i = int(np.argmax(area <= 0.0))
            raise GeometryError(
                f"{where}: loop {i} runs clockwise seen from station 0 towards the last; "
                "loops must run counter-clockwise"
            )

    def __repr__(self) -> str:
        n, m, _ = self.sections.shape
        return (
            f"Limb(name={self.name!r}, {n} stations x {m} around, length "
            f"{self.positions[-1]:.1f} mm, source={self.source!r})"
        )

    # -- local coordinates --------------------------------------------------------------------
    @functools.cached_property
    def section_frame(self) -> tuple[np.ndarray, np.ndarray]:
        """(f1, f2): orthonormal in-plane axes with f2 = f1 × d, so f1 × f2 = -d.

        Loops are counter-clockwise in (X, Y) = ((p - o)·f1, (p - o)·f2). Any f1 ⊥ d would do;
        this one is the world axis least aligned with d, made orthogonal to it.
        """
        d = self.axis_direction
        f1 = perpendicular(d)
        return f1, np.cross(f1, d)

    @functools.cached_property
    def local_xy(self) -> np.ndarray:
        """(n_stations, n_around, 2) section coordinates (X, Y) in :attr:`section_frame`, mm."""
        f1, f2 = self.section_frame
        rel = self.sections - self.axis_origin
        return np.stack((rel @ f1, rel @ f2), axis=-1)

    @functools.cached_property
    def _coeffs(self) -> np.ndarray:
        xy = self.local_xy
        return np.fft.fft(xy[..., 0] + 1j * xy[..., 1], axis=1) / xy.shape[1]

    @functools.cached_property
    def _fine(self) -> tuple[np.ndarray, np.ndarray]:
        """The trigonometric interpolant w and w' on 8·n_around equal steps of θ."""
        m = UPSAMPLE * self.n_around
        return trig_eval(self._coeffs, m, 0), trig_eval(self._coeffs, m, 1)

    def _area_raw(self) -> np.ndarray:
        w, dw = self._fine
        return 0.5 * 2.0 * np.pi * np.mean(np.imag(np.conj(w) * dw), axis=1)

    # -- derived quantities -------------------------------------------------------------------
    @property
    def n_stations(self) -> int:
        """Number of stations (cross-section loops)."""
        return int(self.sections.shape[0])

    @property
    def n_around(self) -> int:
        """Number of points on each loop."""
        return int(self.sections.shape[1])

    @functools.cached_property
    def positions(self) -> np.ndarray:
        """(n_stations,) distance of each station along the axis from station 0, mm (increasing)."""
        h = np.einsum("ijk,k->i", self.sections - self.axis_origin, self.axis_direction) / self.n_around
        return h - h[0]

    @functools.cached_property
    def circumference(self) -> np.ndarray:
        """(n_stations,) perimeter of each closed loop, mm: C = ∮|w'(θ)| dθ of the loop's interpolant.

        Exact for a circle; for a polygon of n points on a smooth curve it is spectrally accurate,
        where the chord sum would be short by about (π²/6n²)·C (0.04 % at n = 64).
        """
        _, dw = self._fine
        return 2.0 * np.pi * np.mean(np.abs(dw), axis=1)

    @functools.cached_property
    def polygon_perimeter(self) -> np.ndarray:
        """(n_stations,) sum of the chords between consecutive points of each loop, mm."""
        s = self.sections
        return np.linalg.norm(np.roll(s, -1, axis=1) - s, axis=2).sum(axis=1)

    @functools.cached_property
    def area(self) -> np.ndarray:
        """(n_stations,) area enclosed by each loop, mm²: A = ½∮ Im(conj(w) w') dθ."""
        return self._area_raw()

    @functools.cached_property
    def centroid(self) -> np.ndarray:
        """(n_stations, 3) area centroid of each section, mm.

        X̄ = (1/A)∮ ½X² dY,  Ȳ = -(1/A)∮ ½Y² dX, evaluated on the loop's interpolant, then placed
        in the station plane: o + positions·d + X̄ f1 + Ȳ f2.
        """
        w, dw = self._fine
        x, y, dx, dy = w.real, w.imag, dw.real, dw.imag
        a = self.area
        cx = 2.0 * np.pi * np.mean(0.5 * x * x * dy, axis=1) / a
        cy = -2.0 * np.pi * np.mean(0.5 * y * y * dx, axis=1) / a
        f1, f2 = self.section_frame
        plane = self.axis_origin + np.outer(self.positions, self.axis_direction)
        return plane + np.outer(cx, f1) + np.outer(cy, f2)

    @functools.cached_property
    def equivalent_radius(self) -> np.ndarray:
        """(n_stations,) radius of the circle with the same circumference, C / 2π, mm."""
        return self.circumference / (2.0 * np.pi)

    @functools.cached_property
    def curvature_radius(self) -> np.ndarray:
        """(n_stations, n_around) signed local radius of curvature of each section, mm.

        Positive where convex, negative where concave, +inf where straight; computed by
        :func:`loop_curvature_radius` (Fourier-smoothed loop, each loop cut where its spectrum
        sinks into its noise floor).
        Laplace: the local pressure of a tension T (N/mm) is T/ρ.
        """
        return self.curvature_radius_smoothed()

    def curvature_radius_smoothed(self, max_harmonic: int | None = None) -> np.ndarray:
        """:attr:`curvature_radius` with a chosen harmonic cut-off K (see :func:`loop_curvature_radius`)."""
        return loop_curvature_radius(self.local_xy, max_harmonic)

    @functools.cached_property
    def named_stations(self) -> dict[str, int]:
        """{"distal": 0, "largest": argmax circumference, "top": n_stations - 1}."""
        return {"distal": 0, "largest": int(np.argmax(self.circumference)), "top": self.n_stations - 1}

    # -- output -------------------------------------------------------------------------------
    def quads(self) -> np.ndarray:
        """((n_stations-1)·n_around, 4) point indices of the surface quads, outward normals.

        Quad ``i*n_around + j`` joins points (i, j), (i+1, j), (i+1, j+1), (i, j+1) (j periodic);
        the point index of (i, j) is ``i*n_around + j``.
        """
        n, m = self.n_stations, self.n_around
        i, j = np.meshgrid(np.arange(n - 1), np.arange(m), indexing="ij")
        jn = (j + 1) % m
        q = np.stack((i * m + j, (i + 1) * m + j, (i + 1) * m + jn, i * m + jn), axis=-1)
        return q.reshape(-1, 4)

    def to_vtu(
        self,
        path: str | Path,
        cell_data: dict[str, np.ndarray] | None = None,
        point_data: dict[str, np.ndarray] | None = None,
    ) -> None:
        """Write the quad surface to a VTU file (meshio): points = sections, cells = :meth:`quads`.

        ``cell_data`` maps names to per-quad arrays of first dimension (n_stations-1)·n_around in
        the order of :meth:`quads`, or shaped (n_stations-1, n_around); ``point_data`` to
        per-point arrays of first dimension n_stations·n_around (point (i, j) at row
        i*n_around + j), or shaped (n_stations, n_around, …). Shapes are checked before anything
        is written.
        """
        import meshio

        quads = self.quads()
        cd = {}
        for key, value in (cell_data or {}).items():
            arr = np.asarray(value)
            if arr.ndim == 2 and arr.shape[:2] == (self.n_stations - 1, self.n_around):
                arr = arr.reshape(len(quads))
            if arr.shape[0] != len(quads):
                raise ValueError(
                    f"cell_data['{key}']: needs {len(quads)} rows (one per quad), got {arr.shape}"
                )
            cd[key] = [arr]
        pd = {}
        for key, value in (point_data or {}).items():
            arr = np.asarray(value)
            npts = self.n_stations * self.n_around
            if arr.ndim >= 2 and arr.shape[:2] == (self.n_stations, self.n_around):
                arr = arr.reshape((npts,) + arr.shape[2:])
            if arr.shape[0] != npts:
                raise ValueError(f"point_data['{key}']: needs {npts} rows (one per point), got {arr.shape}")
            pd[key] = arr
        mesh = meshio.Mesh(self.sections.reshape(-1, 3), [("quad", quads)], point_data=pd, cell_data=cd)
        meshio.write(str(path), mesh, file_format="vtu")

    # -- constructors -------------------------------------------------------------------------
    @classmethod
    def from_measurements(
        cls,
        positions_mm: Sequence[float],
        circumferences_mm: Sequence[float],
        *,
        ellipticity: float | Sequence[float] = 1.0,
        n_stations: int = 41,
        n_around: int = 64,
        name: str = "limb",
    ) -> Limb:
        """A limb from tape measurements: circumferences (mm) at distances (mm) from the wrist/ankle.

        Sections are ellipses with minor/major ratio k (``ellipticity``, in (0, 1], one value or one
        per measurement) whose perimeter is exactly the circumference C (semi-axes from
        :func:`ellipse_semi_axes`, exact elliptic integral), major axis along the reference
        direction f1 = +x, centred on a straight axis along +z through the origin. C and k are
        interpolated between measurements by monotone cubics (PCHIP: no overshoot, so no bulge
        between two measurements that a tape would not have found).

        Stations are ``n_stations`` equally spaced from the first to the last measurement, except
        that the station nearest each measurement is moved onto it, so every measurement is
        reproduced exactly at a station (two measurements closer than the spacing are refused).
        Station 0 is the first measurement; ``positions`` count from it.
        """
        sections, d, notes = measured_sections(
            positions_mm, circumferences_mm, ellipticity, n_stations, n_around
        )
        return cls(
            name=name,
            sections=sections,
            axis_origin=np.zeros(3),
            axis_direction=d,
            source="measurements",
            notes=notes,
        )

    @classmethod
    def from_scan(
        cls,
        path: str | Path,
        *,
        axis: Sequence[float] | None = None,
        n_stations: int = 41,
        n_around: int = 64,
        trim: float = 0.05,
        units: str = "auto",
        name: str | None = None,
        reference: Sequence[float] | None = None,
    ) -> Limb:
        """A limb from a surface scan (STL, OBJ, PLY, or anything trimesh or meshio reads).

        1. Read the triangles (``trimesh.load(force="mesh")`` for STL, OBJ, PLY, OFF, glTF, 3MF…,
           meshio for its formats, each the other's fallback); refuse an empty or unreadable
           file, one without triangles, or one with non-finite coordinates. Duplicate vertices
           are merged and zero-area triangles dropped.
        2. Split into connected shells. Shells tiny next to the largest are debris, dropped with
           one notice: under 1 % of its area, under 50 triangles (and 0.5 % of its count), or
           under a twentieth of its length across (:mod:`~knitframe.garment.limb.shells`). If
           the largest shell encloses every other one (skin around bones: each other shell's
           sampled vertices lie inside its cross-section at their height) it is chosen with a
           notice; shells side by side are refused as ambiguous.
        3. Axis: the eigenvector of the largest eigenvalue of the shell's surface covariance
           (exact second moments of the triangles, ∫xxᵀdA = Σ A/12 (ssᵀ + aaᵀ + bbᵀ + ccᵀ),
           s = a + b + c), through its area centroid, or ``axis`` if given (then taken as the
           distal → proximal direction, as is). Otherwise it is oriented so that the end with the
           smaller mean cross-section length (the last/first 10 % of the stations) comes first.
        4. Units: ``"auto"`` takes a scan shorter than 3 along the axis to be in metres and
           multiplies it by 1000, with a notice and a :class:`KnitframeWarning`; ``"mm"``, ``"cm"``
           or ``"m"`` force the scale.
        5. ``n_stations`` planes equally spaced between the ends trimmed by ``trim``·length (a
           plane within 1e-7·length of a vertex is moved off it by a few 1e-7·length, so
           ``positions`` are equal steps to that precision). Each plane is cut with trimesh
           (``trimesh.intersections.mesh_plane``); the segments are joined into loops; a section
           that is not one closed loop is refused naming the station.
        6. Each loop is resampled by arc length to ``n_around`` points, counter-clockwise seen from
           the distal end: the points are the loop's exact Fourier series in arc length truncated
           to |k| < n_around/2 (an anti-aliased resampling: facets shorter than about
           2C/n_around are smoothed rather than folded into the shape, so the points lie on the
           smooth curve through the facets, within their sagitta of the mesh), point 0 where the
           half-line from the section's centroid along the reference direction e1 crosses it (the
           outermost crossing). e1 is ``reference`` projected
           perpendicular to the axis, by default the scan's second principal axis (its widest
           transverse direction), signed so its largest component is positive; if the two
           transverse second moments are within 5 % (a nearly round limb, whose widest direction
           is noise) it is the world axis least aligned with the limb axis, made perpendicular.
        7. Tubularity: refused if the length is under 1.5 mean section diameters (C/π), a section's
           second-moment aspect (√(λmin/λmax)) is under 0.2, or the circumferences vary more than
           5× along the axis.
        """
        from knitframe.garment.limb.scan import read_scan

        return cls(
            **read_scan(
                Path(path),
                axis=axis,
                n_stations=n_stations,
                n_around=n_around,
                trim=trim,
                units=units,
                name=name,
                reference=reference,
            )
        )
