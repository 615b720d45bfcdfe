"""Slicing a scan: plane cuts of a shell, segments joined into loops, loops resampled by arc length."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from knitframe.errors import GeometryError
from knitframe.garment.limb.sections import UPSAMPLE, trig_eval, wavenumbers

__all__ = ["Slicer", "closed_loops", "resample"]


class Slicer:
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


def closed_loops(seg: np.ndarray, tol: float) -> tuple[list[np.ndarray], int]:
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


def resample(loop: np.ndarray, n: int) -> tuple[np.ndarray, float]:
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
    fine = UPSAMPLE * n
    w, dw = trig_eval(coeffs, fine, 0), trig_eval(coeffs, fine, 1)
    area = 0.5 * np.mean(np.imag(np.conj(w) * dw))
    cy = -np.mean(0.5 * w.imag**2 * dw.real) / area
    f = w.imag - cy
    change = np.flatnonzero(np.sign(f) != np.sign(np.roll(f, -1)))
    if change.size == 0:  # cannot happen for a closed curve around its centroid
        raise GeometryError("section loop does not cross its own centroid line")
    frac = f[change] / (f[change] - f[(change + 1) % fine])
    xcross = w.real[change] + frac * (w.real[(change + 1) % fine] - w.real[change])
    best = int(np.argmax(xcross))
    theta = 2.0 * np.pi * (change[best] + frac[best]) / fine
    k = wavenumbers(n)
    for _ in range(8):
        phase = coeffs * np.exp(1j * k * theta)
        value, slope = np.sum(phase).imag - cy, np.sum(1j * k * phase).imag
        if slope == 0.0:
            break
        theta -= value / slope
    points = np.fft.ifft(coeffs * np.exp(1j * k * theta)) * n
    return np.column_stack((points.real, points.imag)), perimeter
