"""The limb a garment is designed on: closed cross-section loops at stations along its axis.

A :class:`Limb` is a structured quad grid on the limb's surface. Station ``i`` is a plane normal to
the (straight) axis at distance ``positions[i]`` (mm) from station 0; loop ``i`` is the limb's
cross-section in that plane, sampled at ``n_around`` points equally spaced by arc length. Station 0
is the distal end (wrist or ankle) and the axis runs distal → proximal. Every loop runs
counter-clockwise seen looking from station 0 towards the last station, and its point 0 lies on the
half-line from the section's area centroid along one common reference direction ``e1``
(perpendicular to the axis), so ``(i, j)`` is the same azimuth on every station.

Local section coordinates (used by every derived quantity): with ``d`` the axis direction and
``f1``, ``f2 = f1 × d`` an orthonormal pair perpendicular to it, a point ``p`` of loop ``i`` has
``X = (p - o)·f1``, ``Y = (p - o)·f2`` (``o`` = ``axis_origin``). Because ``f1 × f2 = -d``, the
loops are *positively* oriented (counter-clockwise) in (X, Y), and ``(p[i+1, j] - p[i, j]) ×
(p[i, j+1] - p[i, j])`` points out of the limb.

Each loop is represented by its periodic trigonometric interpolant (the unique trigonometric
polynomial of degree n/2 through its n points, from the FFT)::

    w(θ) = X(θ) + i Y(θ) = Σ_k c_k e^{ikθ},   c_k = (1/n) Σ_j w_j e^{-2πi jk/n},   θ ∈ [0, 2π)

which is exact for a circle and spectrally accurate for any smooth section. From it:

* circumference  C = ∮ |w'(θ)| dθ                           (periodic trapezoid rule on 8n points)
* area           A = ½ ∮ Im( conj(w) w' ) dθ                (Green's theorem)
* centroid       (X̄, Ȳ) = (1/A) ( ∮ ½X² dY , -∮ ½Y² dX )
* curvature      κ = Im( conj(w') w'' ) / |w'|³,  ρ = 1/κ    (on the low-pass filtered loop)

The inputs are a scan (:meth:`Limb.from_scan`: STL, OBJ, PLY and everything trimesh or meshio read),
clinical tape measurements (:meth:`Limb.from_measurements`) or the built-in :func:`example_arm`.
Units are mm throughout.
"""

from __future__ import annotations

import functools
import numbers
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import attrs
import numpy as np
from scipy import sparse, special
from scipy.interpolate import PchipInterpolator
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from knitframe.errors import ConfigError, DataError, GeometryError, KnitframeWarning

__all__ = [
    "Limb",
    "example_arm",
    "load_limb",
    "loop_curvature_radius",
    "ellipse_semi_axes",
    "EXAMPLE_ARM_MEASUREMENTS",
]

#: a scan shorter than this along its axis (in file units) is taken to be in metres (units="auto")
METRES_BELOW = 3.0
#: tubularity: the scan's length along its axis must be at least this many mean section diameters
MIN_LENGTH_OVER_DIAMETER = 1.5
#: tubularity: the thinnest/widest second-moment ratio of every section must be at least this
MIN_SECTION_ASPECT = 0.2
#: tubularity: the largest station circumference may be at most this many times the smallest
MAX_CIRCUMFERENCE_RATIO = 5.0
#: disconnected pieces with less than this fraction of the largest shell's area are scan debris
FRAGMENT_AREA_FRACTION = 0.01
#: transverse second moments closer than this (relative) make the scan "round": reference = world axis
ROUND_SPREAD = 0.05
_UPSAMPLE = 8


# ----------------------------------------------------------------------------------------------
# periodic trigonometric interpolation of loops
# ----------------------------------------------------------------------------------------------


def _wavenumbers(n: int) -> np.ndarray:
    """Integer wavenumbers of an n-point FFT, k = 0, 1, …, -1."""
    return np.rint(np.fft.fftfreq(n) * n).astype(np.int64)


def _trig_eval(coeffs: np.ndarray, m: int, order: int = 0) -> np.ndarray:
    """Evaluate the ``order``-th θ-derivative of the trigonometric interpolant on m equal steps.

    ``coeffs`` (..., n) are c_k = fft(w)/n. For even n the Nyquist coefficient is split evenly
    between k = ±n/2, which keeps the interpolant through the samples and makes it the
    minimum-oscillation one. ``m`` ≥ n. Returns (..., m) complex.
    """
    n = coeffs.shape[-1]
    k = _wavenumbers(n)
    c = np.array(coeffs, dtype=np.complex128, copy=True)
    padded = np.zeros(coeffs.shape[:-1] + (m,), dtype=np.complex128)
    if n % 2 == 0:
        nyq = n // 2
        half = c[..., nyq] / 2.0
        c[..., nyq] = 0.0
        padded[..., nyq % m] += half * (1j * nyq) ** order
        padded[..., (-nyq) % m] += half * (-1j * nyq) ** order
    padded[..., k % m] += c * (1j * k) ** order
    return np.fft.ifft(padded, axis=-1) * m


def _lowpass(n: int, max_harmonic: int) -> np.ndarray:
    """Spectral filter σ_k: 1 for |k| ≤ K, ½(1 + cos(π(|k|-K)/K)) for K < |k| < 2K, 0 beyond.

    The Nyquist mode (even n) is always removed: its derivative is not defined by the samples.
    """
    k = np.abs(_wavenumbers(n)).astype(np.float64)
    kk = float(max_harmonic)
    sigma = np.where(k <= kk, 1.0, 0.5 * (1.0 + np.cos(np.pi * np.clip((k - kk) / kk, 0.0, 1.0))))
    if n % 2 == 0:
        sigma[n // 2] = 0.0
    return sigma


def _adaptive_cutoff(coeffs: np.ndarray) -> np.ndarray:
    """Per-loop harmonic cut-off K from the loop's own spectrum: coeffs (..., n) -> (...,) int.

    The power of harmonic k is P_k = |c_k|² + |c_-k|², and its envelope P̃_k = max(P_k, …,
    P_k+3) (symmetric sections have gaps: a centred ellipse has only odd k, a square only
    k ≡ 1 mod 4). The noise floor N is the median of P_k over the upper half of the resolved
    band (n/4 ≤ k < n/2), where a smooth limb section has almost no signal. K is the last k of
    the low band whose envelope stays above 16 N (pure noise, χ² with 2 degrees of freedom,
    exceeds 16 times its mean with probability e⁻¹⁶), at least min(4, n/4). So a clean section
    keeps nearly all its harmonics, a noisy one is cut where its signal sinks into the noise, and
    an isolated high harmonic (the facets of a coarse polygonal mesh, aliased by the sampling)
    is not taken for shape.
    """
    n = coeffs.shape[-1]
    half = (n - 1) // 2 if n % 2 else n // 2 - 1  # highest k with both ±k resolved
    k = np.arange(1, half + 1)
    power = np.abs(coeffs[..., k]) ** 2 + np.abs(coeffs[..., -k]) ** 2
    noise = np.median(power[..., k >= max(n // 4, 1)], axis=-1, keepdims=True)
    padded = np.concatenate((power, np.zeros(power.shape[:-1] + (3,))), axis=-1)
    envelope = np.max(np.stack([padded[..., i : i + half] for i in range(4)]), axis=0)
    below = envelope <= 16.0 * noise
    cut = np.where(below.any(axis=-1), np.argmax(below, axis=-1), half)
    return np.maximum(cut, min(4, n // 4))


def loop_curvature_radius(loops_xy: np.ndarray, max_harmonic: int | None = None) -> np.ndarray:
    """Signed radius of curvature ρ (mm) at every point of closed, counter-clockwise 2D loops.

    ``loops_xy`` is (..., n, 2): n points per loop, equally spaced by arc length, ordered
    counter-clockwise (positive signed area). The loop is written as w(θ) = Σ c_k e^{ikθ} (its
    FFT), low-pass filtered, and differentiated spectrally::

        κ = Im( conj(w') w'' ) / |w'|³          ρ = 1/κ

    ρ > 0 where the section is convex, ρ < 0 where it is concave and +inf where it is straight
    (|κ|·C/2π < 1e-9, C the loop's length). The filter matters because the second derivative
    amplifies noise of harmonic k by k². By default (``max_harmonic=None``) each loop keeps the
    harmonics up to its own cut-off from :func:`_adaptive_cutoff` (signal above 16× the noise floor
    of its upper spectrum), so a circle of radius R gives R to rounding, an ellipse matches
    ρ = (a² sin²t + b² cos²t)^{3/2}/(ab), and a noisy scan is smoothed where its spectrum is
    flat. With ``max_harmonic=K`` every loop keeps |k| ≤ K and a cosine taper removes K < |k| < 2K
    (:func:`_lowpass`): a fixed smoothing over about C/(2πK) of arc length.
    """
    pts = np.asarray(loops_xy, dtype=np.float64)
    if pts.ndim < 2 or pts.shape[-1] != 2 or pts.shape[-2] < 8:
        raise ValueError(f"loops_xy must be (..., n>=8, 2), got {pts.shape}")
    n = pts.shape[-2]
    w = pts[..., 0] + 1j * pts[..., 1]
    c = np.fft.fft(w, axis=-1) / n
    if max_harmonic is None:
        cut = _adaptive_cutoff(c)
        absk = np.abs(_wavenumbers(n))
        c = c * (absk <= cut[..., None])
        if n % 2 == 0:
            c[..., n // 2] = 0.0
    else:
        kmax = int(max_harmonic)
        if not 1 <= kmax <= n // 2:
            raise ValueError(f"max_harmonic must be in [1, {n // 2}], got {max_harmonic}")
        c = c * _lowpass(n, kmax)
    d1 = _trig_eval(c, n, 1)
    d2 = _trig_eval(c, n, 2)
    speed = np.abs(d1)
    kappa = np.imag(np.conj(d1) * d2) / speed**3
    length = 2.0 * np.pi * speed.mean(axis=-1, keepdims=True)
    straight = np.abs(kappa) * length / (2.0 * np.pi) < 1e-9
    rho = np.full(kappa.shape, np.inf)
    np.divide(1.0, kappa, out=rho, where=~straight)
    return rho


def ellipse_semi_axes(circumference: np.ndarray, ratio: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Semi-axes (a, b) of the ellipse of perimeter C and minor/major ratio k = b/a (mm).

    Exact: C = 4 a E(m), m = 1 - k², with E the complete elliptic integral of the second kind
    (``scipy.special.ellipe``); so a = C / (4 E(1 - k²)), b = k a. k = 1 gives a = C/2π.
    """
    c = np.asarray(circumference, dtype=np.float64)
    k = np.asarray(ratio, dtype=np.float64)
    a = c / (4.0 * special.ellipe(1.0 - k**2))
    return a, k * a


def _ellipse_points(a: float, b: float, n: int) -> np.ndarray:
    """n points (n, 2) on the ellipse (a cos t, b sin t), equally spaced by arc length from t = 0.

    Arc length s(t) = ∫₀ᵗ √(a² sin²τ + b² cos²τ) dτ = a [E(t + π/2 | m) - E(m)], m = 1 - (b/a)²
    (``scipy.special.ellipeinc``); s(t_j) = j C/n is solved by Newton's method (ds/dt ≥ b > 0).
    """
    m = 1.0 - (b / a) ** 2
    perim = 4.0 * a * special.ellipe(m)
    target = perim * np.arange(n) / n
    t = 2.0 * np.pi * np.arange(n) / n
    e0 = special.ellipe(m)
    for _ in range(50):
        s = a * (special.ellipeinc(t + np.pi / 2.0, m) - e0)
        step = (s - target) / (a * np.sqrt(1.0 - m * np.cos(t) ** 2))
        t = t - step
        if np.max(np.abs(step)) < 1e-15:
            break
    return np.column_stack((a * np.cos(t), b * np.sin(t)))


# ----------------------------------------------------------------------------------------------
# the record
# ----------------------------------------------------------------------------------------------


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


def _perpendicular(d: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to unit d: the world axis least aligned with d, made orthogonal."""
    axis = np.zeros(3)
    axis[int(np.argmin(np.abs(d)))] = 1.0
    v = axis - (axis @ d) * d
    return v / np.linalg.norm(v)


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
        f1 = _perpendicular(d)
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
        m = _UPSAMPLE * self.n_around
        return _trig_eval(self._coeffs, m, 0), _trig_eval(self._coeffs, m, 1)

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
        pos = np.asarray(positions_mm, dtype=np.float64).reshape(-1)
        circ = np.asarray(circumferences_mm, dtype=np.float64).reshape(-1)
        _check_counts(n_stations, n_around)
        if pos.size < 2:
            raise ConfigError("positions_mm", f"needs at least 2 measurements, got {pos.size}")
        if circ.size != pos.size:
            raise ConfigError(
                "circumferences_mm", f"needs one value per position ({pos.size}), got {circ.size}"
            )
        for key, arr in (("positions_mm", pos), ("circumferences_mm", circ)):
            if not np.all(np.isfinite(arr)):
                raise ConfigError(key, "must be finite numbers")
        if np.any(np.diff(pos) <= 0.0):
            i = int(np.argmax(np.diff(pos) <= 0.0))
            raise ConfigError(
                "positions_mm", f"must be strictly increasing, got {pos[i]:g} then {pos[i + 1]:g}"
            )
        if np.any(circ <= 0.0):
            i = int(np.argmax(circ <= 0.0))
            raise ConfigError("circumferences_mm", f"must be > 0, got {circ[i]:g} at {pos[i]:g} mm")
        ell = np.asarray(ellipticity, dtype=np.float64).reshape(-1)
        if ell.size not in (1, pos.size):
            raise ConfigError(
                "ellipticity", f"needs one value or one per position ({pos.size}), got {ell.size}"
            )
        if not np.all(np.isfinite(ell)) or np.any(ell <= 0.0) or np.any(ell > 1.0):
            raise ConfigError("ellipticity", f"minor/major ratio must be in (0, 1], got {ell.tolist()}")
        if n_stations < pos.size:
            raise ConfigError(
                "n_stations", f"must be at least the number of measurements ({pos.size}), got {n_stations}"
            )

        grid = np.linspace(pos[0], pos[-1], n_stations)
        spacing = (pos[-1] - pos[0]) / (n_stations - 1)
        idx = np.rint((pos - pos[0]) / spacing).astype(np.int64)
        if np.any(np.diff(idx) == 0):
            i = int(np.argmax(np.diff(idx) == 0))
            raise ConfigError(
                "positions_mm",
                f"measurements at {pos[i]:g} and {pos[i + 1]:g} mm are closer than the "
                f"station spacing {spacing:.3g} mm; use more stations (n_stations)",
            )
        grid[idx] = pos
        c_st = PchipInterpolator(pos, circ)(grid)
        c_st[idx] = circ
        k_st = (
            np.full(n_stations, ell[0])
            if ell.size == 1
            else np.clip(PchipInterpolator(pos, ell)(grid), 1e-6, 1.0)
        )
        if ell.size > 1:
            k_st[idx] = ell
        a, b = ellipse_semi_axes(c_st, k_st)
        z = grid - pos[0]
        d = np.array([0.0, 0.0, 1.0])
        f1 = _perpendicular(d)  # +x
        f2 = np.cross(f1, d)  # -y: loops counter-clockwise seen along +z
        sections = np.empty((n_stations, n_around, 3))
        for i in range(n_stations):  # one vectorised ellipse per station
            xy = _ellipse_points(float(a[i]), float(b[i]), n_around)
            sections[i] = z[i] * d + np.outer(xy[:, 0], f1) + np.outer(xy[:, 1], f2)
        notes = []
        if pos[0] != 0.0:
            notes.append(f"station 0 is the first measurement, {pos[0]:g} mm from the wrist/ankle")
        return cls(
            name=name,
            sections=sections,
            axis_origin=np.zeros(3),
            axis_direction=d,
            source="measurements",
            notes=tuple(notes),
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
        2. Split into connected shells. Pieces under 1 % of the largest shell's area are debris
           (ignored, with a notice). If the largest shell encloses every other one (skin around
           bones: each other shell's sampled vertices lie inside its cross-section at their
           height) it is chosen with a notice; shells side by side are refused as ambiguous.
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
        return _scan_to_limb(
            Path(path),
            axis=axis,
            n_stations=n_stations,
            n_around=n_around,
            trim=trim,
            units=units,
            name=name,
            reference=reference,
        )


def _check_counts(n_stations: int, n_around: int) -> None:
    if isinstance(n_stations, bool) or not isinstance(n_stations, (int, np.integer)) or n_stations < 2:
        raise ConfigError("n_stations", f"must be an integer >= 2, got {n_stations!r}")
    if isinstance(n_around, bool) or not isinstance(n_around, (int, np.integer)) or n_around < 8:
        raise ConfigError("n_around", f"must be an integer >= 8, got {n_around!r}")


# ----------------------------------------------------------------------------------------------
# the example arm
# ----------------------------------------------------------------------------------------------

#: (distance from the wrist mm, circumference mm, minor/major ratio) of the built-in arm
EXAMPLE_ARM_MEASUREMENTS = (
    (0.0, 160.0, 0.70),  # wrist
    (90.0, 205.0, 0.78),  # lower forearm
    (190.0, 250.0, 0.85),  # largest forearm
    (270.0, 245.0, 0.90),  # elbow
    (420.0, 315.0, 0.95),  # upper arm
)


def example_arm(n_stations: int = 41, n_around: int = 64) -> Limb:
    """A built-in parametric adult arm, wrist (station 0) to upper arm, from typical circumferences.

    ============================  ===========  ===============  ===================
    position                      from wrist   circumference    minor/major ratio
    ============================  ===========  ===============  ===================
    wrist                         0 mm         160 mm           0.70
    lower forearm                 90 mm        205 mm           0.78
    largest forearm               190 mm       250 mm           0.85
    elbow                         270 mm       245 mm           0.90
    upper arm                     420 mm       315 mm           0.95
    ============================  ===========  ===============  ===================

    Source: typical adult values and the standard measuring positions of compression-garment
    fitting: the wrist about 15–17 cm around, the upper arm 26–34 cm and about twice the wrist
    (here 315/160 = 1.97), measured at the wrist, the largest forearm, the elbow and the upper arm.
    The positions, the lower-forearm value and the ratios (a flattened wrist rounding towards the
    upper arm; slightly elliptical forearm) are illustrative round numbers for an adult arm, not
    one measured person. Built by :meth:`Limb.from_measurements` (exact elliptic perimeters,
    PCHIP between the measurements), straight axis along +z.
    """
    pos, circ, ratio = (np.array(col) for col in zip(*EXAMPLE_ARM_MEASUREMENTS))
    limb = Limb.from_measurements(
        pos, circ, ellipticity=ratio, n_stations=n_stations, n_around=n_around, name="example arm"
    )
    return attrs.evolve(limb, source="example")


def load_limb(path_or_spec: Any, **kwargs: Any) -> Limb:
    """A limb from a scan file path, ``"example"``, a measurement mapping or a :class:`Limb`.

    A mapping needs ``positions_mm`` and ``circumferences_mm`` and may hold ``ellipticity``,
    ``n_stations``, ``n_around`` and ``name`` (passed to :meth:`Limb.from_measurements`); keyword
    arguments go to the chosen constructor.
    """
    if isinstance(path_or_spec, Limb):
        return path_or_spec
    if isinstance(path_or_spec, str) and path_or_spec == "example":
        return example_arm(**kwargs)
    if isinstance(path_or_spec, Mapping):
        spec = dict(path_or_spec)
        missing = [k for k in ("positions_mm", "circumferences_mm") if k not in spec]
        if missing:
            raise ConfigError("limb", f"a measurement table needs {', '.join(missing)}")
        allowed = {"positions_mm", "circumferences_mm", "ellipticity", "n_stations", "n_around", "name"}
        unknown = sorted(set(spec) - allowed)
        if unknown:
            raise ConfigError(f"limb.{unknown[0]}", f"unknown key; allowed: {', '.join(sorted(allowed))}")
        pos = spec.pop("positions_mm")
        circ = spec.pop("circumferences_mm")
        return Limb.from_measurements(pos, circ, **{**spec, **kwargs})
    if isinstance(path_or_spec, (str, Path)):
        return Limb.from_scan(path_or_spec, **kwargs)
    raise ConfigError(
        "limb", f"expected a scan file, 'example' or a measurement table, got {type(path_or_spec).__name__}"
    )


# ----------------------------------------------------------------------------------------------
# scans
# ----------------------------------------------------------------------------------------------


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return (text[0][:160] if text else "") or type(exc).__name__


def _read_triangles(path: Path) -> tuple[np.ndarray, np.ndarray]:
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


def _surface_moments(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Area, area centroid (3,) and covariance (3, 3) of a triangulated surface (exact).

    For a triangle (a, b, c) of area A: ∫x dA = A s/3 and ∫xxᵀ dA = A/12 (ssᵀ + aaᵀ + bbᵀ + ccᵀ),
    s = a + b + c. Coordinates are taken relative to the vertex mean for conditioning.
    """
    shift = vertices.mean(axis=0)
    tri = vertices[faces] - shift
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    total = float(area.sum())
    s = tri.sum(axis=1)
    centroid = (area @ s) / (3.0 * total)
    second = (np.einsum("f,fi,fj->ij", area, s, s) + np.einsum("f,fvi,fvj->ij", area, tri, tri)) / (
        12.0 * total
    )
    cov = second - np.outer(centroid, centroid)
    return total, centroid + shift, cov


def _canonical_sign(v: np.ndarray) -> np.ndarray:
    """v or -v, whichever has its largest-magnitude component positive."""
    return v if v[int(np.argmax(np.abs(v)))] >= 0.0 else -v


def _components(faces: np.ndarray, n_vertices: int) -> tuple[int, np.ndarray]:
    """Connected shells: (count, shell label of each face), via the vertex graph of the edges."""
    e = np.concatenate((faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]))
    g = sparse.coo_matrix(
        (np.ones(len(e), dtype=np.int8), (e[:, 0], e[:, 1])), shape=(n_vertices, n_vertices)
    )
    count, labels = csgraph.connected_components(g, directed=False)
    used, face_label = np.unique(labels[faces[:, 0]], return_inverse=True)
    return len(used), face_label.reshape(-1)


def _submesh(vertices: np.ndarray, faces: np.ndarray) -> Any:
    """A trimesh.Trimesh of only the vertices these faces use."""
    import trimesh

    used, inverse = np.unique(faces, return_inverse=True)
    return trimesh.Trimesh(vertices[used], inverse.reshape(faces.shape), process=False)


class _Slicer:
    """Cuts one triangulated shell by planes normal to a direction, with trimesh's mesh_plane."""

    def __init__(self, mesh: Any, origin: np.ndarray, direction: np.ndarray):
        # mesh_plane reads only .vertices and .faces; plain arrays skip trimesh's per-access hashing
        self.mesh = SimpleNamespace(vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces))
        self.origin = origin
        self.d = direction
        self.h = (np.asarray(mesh.vertices) - origin) @ direction  # vertex heights
        fh = self.h[np.asarray(mesh.faces)]
        self.fmin, self.fmax = fh.min(axis=1), fh.max(axis=1)
        self.hsorted = np.sort(self.h)
        self.length = float(self.hsorted[-1] - self.hsorted[0])
        self.step = max(1e-7 * self.length, 1e-7)

    def off_vertices(self, z: np.ndarray) -> np.ndarray:
        """Heights z moved off any vertex (degenerate cuts) by steps of 2.5e-7·length towards the middle."""
        z = np.array(z, dtype=np.float64)
        inward = np.where(z < 0.5 * (self.hsorted[0] + self.hsorted[-1]), 1.0, -1.0)
        for _ in range(50):
            i = np.clip(np.searchsorted(self.hsorted, z), 1, len(self.hsorted) - 1)
            gap = np.minimum(np.abs(self.hsorted[i] - z), np.abs(self.hsorted[i - 1] - z))
            close = gap < self.step
            if not close.any():
                break
            z[close] += 2.5 * self.step * inward[close]
        return z

    def segments(self, z: float) -> np.ndarray:
        """(k, 2, 3) segments of the section at height z (relative to origin along d)."""
        from trimesh.intersections import mesh_plane

        local = np.flatnonzero((self.fmin < z) & (self.fmax > z))
        if local.size == 0:
            return np.zeros((0, 2, 3))
        lines = mesh_plane(
            self.mesh,
            plane_normal=self.d,
            plane_origin=self.origin + z * self.d,
            local_faces=local,
            cached_dots=self.h - z,
        )
        return np.asarray(lines, dtype=np.float64).reshape(-1, 2, 3)


def _closed_loops(seg: np.ndarray, tol: float) -> tuple[list[np.ndarray], int]:
    """Join 2D segments (k, 2, 2) into loops: (closed loops as ordered (K, 2) arrays, open pieces).

    Endpoints are merged on a grid of size ``tol`` and then, for endpoints left dangling (a
    near-duplicate split by a grid line), within 4·tol; duplicate edges are dropped. A connected
    piece whose every node has two neighbours is a closed loop, ordered by a depth-first walk;
    any other piece (open ends, branches) is counted as open.
    """
    if len(seg) == 0:
        return [], 0
    seg = seg[np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) > tol]
    if len(seg) == 0:
        return [], 0
    pts = seg.reshape(-1, 2)
    q = np.floor((pts - pts.min(axis=0)) / tol).astype(np.int64)
    key = q[:, 0] * (int(q[:, 1].max()) + 1) + q[:, 1]
    _, node = np.unique(key, return_inverse=True)
    node = node.reshape(-1)
    n = int(node.max()) + 1
    xy = np.empty((n, 2))
    xy[node] = pts

    def edges_of(lab: np.ndarray) -> np.ndarray:
        e = np.sort(lab.reshape(-1, 2), axis=1)
        e = e[e[:, 0] != e[:, 1]]
        key = np.unique(e[:, 0] * np.int64(len(lab)) + e[:, 1])
        return np.column_stack((key // len(lab), key % len(lab)))

    edges = edges_of(node)
    deg = np.bincount(edges.ravel(), minlength=n)
    loose = np.flatnonzero(deg == 1)
    if loose.size >= 2:
        pairs = cKDTree(xy[loose]).query_pairs(4.0 * tol, output_type="ndarray")
        if len(pairs):
            g = sparse.coo_matrix(
                (np.ones(len(pairs)), (loose[pairs[:, 0]], loose[pairs[:, 1]])), shape=(n, n)
            )
            _, merged = csgraph.connected_components(g, directed=False)
            node = merged[node]
            edges = edges_of(node)
            n = int(merged.max()) + 1
            xy2 = np.empty((n, 2))
            xy2[merged] = xy
            xy = xy2
            deg = np.bincount(edges.ravel(), minlength=n)
    if len(edges) == 0:
        return [], 0
    g = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n)).tocsr()
    _, comp = csgraph.connected_components(g, directed=False)
    in_graph = deg > 0
    bad = np.bincount(comp, weights=(deg != 2) & in_graph, minlength=comp.max() + 1) > 0
    present = np.bincount(comp, weights=in_graph, minlength=comp.max() + 1) > 0
    loops = []
    for c in np.flatnonzero(present & ~bad):
        start = int(np.flatnonzero((comp == c) & in_graph)[0])
        order = csgraph.depth_first_order(g, start, directed=False, return_predecessors=False)
        loop = xy[order]
        if np.linalg.norm(np.roll(loop, -1, axis=0) - loop, axis=1).sum() > 100.0 * tol:
            loops.append(loop)
    return loops, int(np.count_nonzero(present & bad))


def _polygon_area_centroid(p: np.ndarray) -> tuple[float, np.ndarray]:
    """Signed area (> 0 counter-clockwise) and area centroid of a closed polygon (K, 2)."""
    x, y = p[:, 0], p[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area = 0.5 * cross.sum()
    cx = ((x + xn) * cross).sum() / (6.0 * area)
    cy = ((y + yn) * cross).sum() / (6.0 * area)
    return float(area), np.array([cx, cy])


def _polygon_fourier(loop: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """Exact Fourier coefficients, |k| < n/2, of a closed polygon parameterised by arc length.

    With s_j the arc length at vertex j, P the perimeter, ω = 2πk/P and Δt_j the change of the unit
    tangent at vertex j (w'' = Σ Δt_j δ(s - s_j)), integrating by parts twice gives::

        c_k = (1/P) ∫ w(s) e^{-iωs} ds = -(1/(P ω²)) Σ_j Δt_j e^{-iω s_j}      (k ≠ 0)
        c_0 = (1/P) Σ_edges ℓ_e · midpoint_e

    Returns the coefficients in FFT order (length n; Nyquist zero) of w(θ), θ = 2πs/P, and P.
    """
    w = loop[:, 0] + 1j * loop[:, 1]
    edge = np.roll(w, -1) - w
    ell = np.abs(edge)
    perimeter = float(ell.sum())
    tangent = edge / ell
    s_vertex = np.concatenate(([0.0], np.cumsum(ell)[:-1]))
    jump = tangent - np.roll(tangent, 1)
    top = n // 2 - 1 if n % 2 == 0 else (n - 1) // 2
    k = np.arange(1, top + 1)
    # e^{-iω_k s_j} = z_j^k with z_j = e^{-2πi s_j/P}: powers by a running product (k ≤ n/2)
    powers = np.cumprod(np.broadcast_to(np.exp(-2j * np.pi * s_vertex / perimeter), (top, len(w))), axis=0)
    scale = -perimeter / (2.0 * np.pi * k) ** 2  # -1/(P ω²)
    coeffs = np.zeros(n, dtype=np.complex128)
    coeffs[k] = scale * np.einsum("kj,j->k", powers, jump)
    coeffs[-k] = scale * np.conj(np.einsum("kj,j->k", powers, np.conj(jump)))
    coeffs[0] = np.sum(ell * (w + 0.5 * edge)) / perimeter
    return coeffs, perimeter


def _resample(loop: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """n points on a closed polygon's band-limited curve, counter-clockwise, point 0 on the +x ray.

    The polygon (K, 2) is oriented counter-clockwise and replaced by its Fourier series in arc
    length truncated to |k| < n/2 (:func:`_polygon_fourier`): an anti-aliased resampling, so the
    facets of a coarse mesh are smoothed instead of folding into the low harmonics that the
    curvature uses. The points are the curve at θ* + 2πj/n (equal steps of the polygon's arc
    length), where θ* is the outermost crossing of the horizontal line through the curve's area
    centroid on its +x side (secant/Newton on Im w(θ) = ȳ). Returns the points (n, 2) and the
    polygon's perimeter.
    """
    if _polygon_area_centroid(loop)[0] < 0.0:
        loop = loop[::-1]
    coeffs, perimeter = _polygon_fourier(loop, n)
    fine = _UPSAMPLE * n
    w, dw = _trig_eval(coeffs, fine, 0), _trig_eval(coeffs, fine, 1)
    area = 0.5 * np.mean(np.imag(np.conj(w) * dw))
    cx = np.mean(0.5 * w.real**2 * dw.imag) / area
    cy = -np.mean(0.5 * w.imag**2 * dw.real) / area
    f = w.imag - cy
    change = np.flatnonzero(np.sign(f) != np.sign(np.roll(f, -1)))
    if change.size == 0:  # cannot happen for a closed curve around its centroid
        raise GeometryError("section loop does not cross its own centroid line")
    frac = f[change] / (f[change] - f[(change + 1) % fine])
    xcross = w.real[change] + frac * (w.real[(change + 1) % fine] - w.real[change])
    best = int(np.argmax(xcross))
    theta = 2.0 * np.pi * (change[best] + frac[best]) / fine
    k = _wavenumbers(n)
    for _ in range(8):
        phase = coeffs * np.exp(1j * k * theta)
        value, slope = np.sum(phase).imag - cy, np.sum(1j * k * phase).imag
        if slope == 0.0:
            break
        theta -= value / slope
    points = np.fft.ifft(coeffs * np.exp(1j * k * theta)) * n
    return np.column_stack((points.real, points.imag)), perimeter


def _choose_shell(vertices: np.ndarray, faces: np.ndarray, label: str) -> tuple[np.ndarray, list[str]]:
    """Faces of the limb's shell, and notices. See :meth:`Limb.from_scan` step 2."""
    count, face_label = _components(faces, len(vertices))
    if count == 1:
        return faces, []
    tri = vertices[faces]
    areas = np.bincount(
        face_label,
        weights=0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1),
        minlength=count,
    )
    order = np.argsort(-areas)
    main = int(order[0])
    fragments = [int(s) for s in order[1:] if areas[s] < FRAGMENT_AREA_FRACTION * areas[main]]
    others = [int(s) for s in order[1:] if areas[s] >= FRAGMENT_AREA_FRACTION * areas[main]]
    main_faces = faces[face_label == main]
    notes = []
    if others:
        outer = _submesh(vertices, main_faces)
        _, center, cov = _surface_moments(vertices, main_faces)
        d = np.linalg.eigh(cov)[1][:, 2]
        slicer = _Slicer(outer, center, d)
        f1 = _perpendicular(d)
        f2 = np.cross(f1, d)
        outside = 0
        for s in others:
            idx = np.unique(faces[face_label == s])
            sample = vertices[idx[np.unique(np.linspace(0, len(idx) - 1, 24).astype(np.int64))]]
            h = (vertices[idx] - center) @ d
            sample = np.vstack((sample, vertices[idx[[np.argmin(h), np.argmax(h)]]]))
            if not all(_inside_section(slicer, f1, f2, p) for p in sample):
                outside += 1
        if outside:
            raise DataError(
                label,
                f"{len(others) + 1} separate shells side by side ({outside} not inside the "
                "largest): ambiguous which is the limb (two limbs?); crop the scan to one limb",
            )
        inner = len(others)
        notes.append(
            f"outer shell of {inner + 1} chosen; {inner} inner shell{'s' if inner > 1 else ''} ignored"
        )
    if fragments:
        k = len(fragments)
        notes.append(
            f"{k} small disconnected fragment{'s' if k > 1 else ''} (each under "
            f"{FRAGMENT_AREA_FRACTION:.0%} of the limb's area) ignored"
        )
    return main_faces, notes


def _inside_section(slicer: _Slicer, f1: np.ndarray, f2: np.ndarray, p: np.ndarray) -> bool:
    """Whether point p lies inside the shell's cross-section through it (even–odd ray test)."""
    z = float((p - slicer.origin) @ slicer.d)
    if not slicer.hsorted[0] < z < slicer.hsorted[-1]:
        return False
    seg = slicer.segments(float(slicer.off_vertices(np.array([z]))[0])) - slicer.origin
    a = np.stack((seg[:, 0] @ f1, seg[:, 0] @ f2), axis=1)
    b = np.stack((seg[:, 1] @ f1, seg[:, 1] @ f2), axis=1)
    q = np.array([(p - slicer.origin) @ f1, (p - slicer.origin) @ f2])
    cross = (a[:, 1] > q[1]) != (b[:, 1] > q[1])
    dy = np.where(cross, b[:, 1] - a[:, 1], 1.0)
    xi = a[:, 0] + (q[1] - a[:, 1]) / dy * (b[:, 0] - a[:, 0])
    return bool(np.count_nonzero(cross & (xi > q[0])) % 2 == 1)


def _scan_to_limb(path: Path, *, axis, n_stations, n_around, trim, units, name, reference) -> Limb:
    import trimesh

    label = str(path)
    _check_counts(n_stations, n_around)
    if isinstance(trim, bool) or not isinstance(trim, numbers.Real) or not 0.0 <= float(trim) < 0.5:
        raise ConfigError("trim", f"must be in [0, 0.5), got {trim!r}")
    scales = {"auto": None, "mm": 1.0, "cm": 10.0, "m": 1000.0}
    if units not in scales:
        raise ConfigError("units", f"must be one of {', '.join(scales)}, got {units!r}")
    given_axis = None
    if axis is not None:
        given_axis = np.asarray(axis, dtype=np.float64).reshape(-1)
        if given_axis.size != 3 or not np.all(np.isfinite(given_axis)) or np.linalg.norm(given_axis) == 0.0:
            raise ConfigError("axis", f"must be a finite non-zero 3-vector, got {axis!r}")
        given_axis = given_axis / np.linalg.norm(given_axis)

    vertices, faces = _read_triangles(path)
    tri = vertices[faces]
    nondegenerate = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) > 0.0
    mesh = trimesh.Trimesh(vertices, faces[nondegenerate], process=False)
    mesh.merge_vertices()
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces) == 0:
        raise DataError(label, "no triangles with a non-zero area")
    vertices = np.array(mesh.vertices, dtype=np.float64)
    faces = np.array(mesh.faces, dtype=np.int64)
    faces, notes = _choose_shell(vertices, faces, label)
    shell = _submesh(vertices, faces)
    vertices = np.array(shell.vertices, dtype=np.float64)
    faces = np.array(shell.faces, dtype=np.int64)

    _, center, cov = _surface_moments(vertices, faces)
    if given_axis is None:
        d = _canonical_sign(np.linalg.eigh(cov)[1][:, 2])
    else:
        d = given_axis
    if reference is None:
        proj = np.eye(3) - np.outer(d, d)
        lam, vec = np.linalg.eigh(proj @ cov @ proj)
        # a nearly round limb has no widest direction: take a fixed world direction instead
        e1 = vec[:, 2] if lam[2] - lam[1] > ROUND_SPREAD * lam[2] else _perpendicular(d)
    else:
        e1 = np.asarray(reference, dtype=np.float64).reshape(-1)
        if e1.size != 3 or not np.all(np.isfinite(e1)) or not np.any(e1):
            raise ConfigError("reference", f"must be a finite non-zero 3-vector, got {reference!r}")
        e1 = e1 / np.linalg.norm(e1)
    e1 = e1 - (e1 @ d) * d
    if np.linalg.norm(e1) < 1e-3:  # within 0.06° of the axis: no azimuth
        raise ConfigError("reference", "must not be parallel to the axis")
    e1 = _canonical_sign(e1 / np.linalg.norm(e1))

    heights = (vertices - center) @ d
    length = float(heights.max() - heights.min())
    scale = scales[units]
    if scale is None:
        scale = 1.0
        if length < METRES_BELOW:
            scale = 1000.0
            note = (
                f"converted from metres: {length:.4g} long along the axis (< {METRES_BELOW:g}), "
                "coordinates multiplied by 1000"
            )
            notes.append(note)
            warnings.warn(f"{label}: {note}", KnitframeWarning, stacklevel=3)
    elif scale != 1.0:
        notes.append(f"converted from {units} to mm (x{scale:g})")
    vertices = vertices * scale
    center = center * scale
    length *= scale

    slicer = _Slicer(_submesh(vertices, faces), center, d)
    zmin, zmax = float(slicer.hsorted[0]), float(slicer.hsorted[-1])
    inset = max(float(trim) * length, 1e-6 * length)
    z = slicer.off_vertices(np.linspace(zmin + inset, zmax - inset, n_stations))
    f1 = e1
    f2 = np.cross(f1, d)
    tol = 1e-8 * float(np.ptp(vertices, axis=0).max())
    raw = []
    for zi in z:  # one vectorised cut per station
        seg = slicer.segments(float(zi)) - center
        raw.append(np.stack((seg @ f1, seg @ f2), axis=-1))
    sizes = np.array([np.linalg.norm(s[:, 1] - s[:, 0], axis=1).sum() for s in raw])

    if given_axis is None:
        k = max(1, n_stations // 10)
        if sizes[:k].mean() > sizes[-k:].mean() * (1.0 + 1e-9):
            d, f2, z = -d, -f2, -z[::-1]
            raw = [s * np.array([1.0, -1.0]) for s in raw[::-1]]
    positions = z - z[0]

    found = [_closed_loops(s, tol) for s in raw]
    if not any(loops for loops, _ in found):
        raise DataError(
            label, "not tubular along its axis: no cross-section is a closed loop (an open sheet or plate?)"
        )
    problems = []
    for i, (loops, n_open) in enumerate(found):
        where = f"station {i} at {positions[i]:.1f} mm"
        if n_open:
            problems.append(
                f"{where}: section is not closed ({n_open} open piece{'s' if n_open > 1 else ''}: "
                "a hole or tear in the scan)"
            )
        elif len(loops) == 0:
            problems.append(f"{where}: section is empty (a gap in the scan)")
        elif len(loops) > 1:
            problems.append(f"{where}: section has {len(loops)} loops")
    if problems:
        more = f" ({len(problems) - 1} more stations too)" if len(problems) > 1 else ""
        raise DataError(label, problems[0] + more)

    xy = np.empty((n_stations, n_around, 2))
    perimeter = np.empty(n_stations)
    for i, (loops, _) in enumerate(found):
        xy[i], perimeter[i] = _resample(loops[0], n_around)

    diameter = float(np.mean(perimeter)) / np.pi
    if length < MIN_LENGTH_OVER_DIAMETER * diameter:
        raise DataError(
            label,
            f"not tubular along its axis: {length:.1f} mm long, only {length / diameter:.2f} "
            f"times its mean diameter {diameter:.1f} mm (needs {MIN_LENGTH_OVER_DIAMETER:g}; "
            "a sphere or box?)",
        )
    centred = xy - xy.mean(axis=1, keepdims=True)
    lam = np.linalg.eigvalsh(np.einsum("sni,snj->sij", centred, centred) / n_around)
    aspect = np.sqrt(np.clip(lam[:, 0], 0.0, None) / lam[:, 1])
    if aspect.min() < MIN_SECTION_ASPECT:
        i = int(np.argmin(aspect))
        raise DataError(
            label,
            f"not tubular along its axis: station {i} at {positions[i]:.1f} mm is flat "
            f"(thickness/width {aspect[i]:.2f} < {MIN_SECTION_ASPECT:g}; a plate?)",
        )
    ratio = perimeter.max() / perimeter.min()
    if ratio > MAX_CIRCUMFERENCE_RATIO:
        raise DataError(
            label,
            f"not tubular along its axis: cross-section length varies {ratio:.1f} times "
            f"(over {MAX_CIRCUMFERENCE_RATIO:g}; a cone to a point or a blob?)",
        )

    plane = center + np.outer(z, d)
    sections = plane[:, None, :] + xy[..., :1] * f1 + xy[..., 1:] * f2
    return Limb(
        name=path.stem if name is None else name,
        sections=sections,
        axis_origin=plane[0],
        axis_direction=d,
        source=f"scan: {path.name}",
        notes=tuple(notes),
    )
