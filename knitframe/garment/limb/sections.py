"""The geometry of one cross-section loop: its periodic trigonometric interpolant, curvature, ellipses.

Each loop is represented by its periodic trigonometric interpolant (the unique trigonometric
polynomial of degree n/2 through its n points, from the FFT)::

    w(θ) = X(θ) + i Y(θ) = Σ_k c_k e^{ikθ},   c_k = (1/n) Σ_j w_j e^{-2πi jk/n},   θ ∈ [0, 2π)

The curvature κ = Im( conj(w') w'' ) / |w'|³ is taken on the low-pass filtered loop.
"""

from __future__ import annotations

import numpy as np
from scipy import special

__all__ = [
    "UPSAMPLE",
    "wavenumbers",
    "trig_eval",
    "loop_curvature_radius",
    "ellipse_semi_axes",
    "ellipse_points",
    "perpendicular",
]

UPSAMPLE = 8


def wavenumbers(n: int) -> np.ndarray:
    """Integer wavenumbers of an n-point FFT, k = 0, 1, …, -1."""
    return np.rint(np.fft.fftfreq(n) * n).astype(np.int64)


def trig_eval(coeffs: np.ndarray, m: int, order: int = 0) -> np.ndarray:
    """Evaluate the ``order``-th θ-derivative of the trigonometric interpolant on m equal steps.

    ``coeffs`` (..., n) are c_k = fft(w)/n. For even n the Nyquist coefficient is split evenly
    between k = ±n/2, which keeps the interpolant through the samples and makes it the
    minimum-oscillation one. ``m`` ≥ n. Returns (..., m) complex.
    """
    n = coeffs.shape[-1]
    k = wavenumbers(n)
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
    k = np.abs(wavenumbers(n)).astype(np.float64)
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
        absk = np.abs(wavenumbers(n))
        c = c * (absk <= cut[..., None])
        if n % 2 == 0:
            c[..., n // 2] = 0.0
    else:
        kmax = int(max_harmonic)
        if not 1 <= kmax <= n // 2:
            raise ValueError(f"max_harmonic must be in [1, {n // 2}], got {max_harmonic}")
        c = c * _lowpass(n, kmax)
    d1 = trig_eval(c, n, 1)
    d2 = trig_eval(c, n, 2)
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


def ellipse_points(a: float, b: float, n: int) -> np.ndarray:
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


def perpendicular(d: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to unit d: the world axis least aligned with d, made orthogonal."""
    axis = np.zeros(3)
    axis[int(np.argmin(np.abs(d)))] = 1.0
    v = axis - (axis @ d) * d
    return v / np.linalg.norm(v)
