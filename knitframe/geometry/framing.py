"""Rotation-minimising frames along the yarns of a cell, closed periodically over each strand.

:func:`frames` gives every yarn a :class:`Frames` record (positions, unit tangents, normals and
binormals at evenly spaced parameters) by the double-reflection method, untwisted so that the
frame is continuous across every cell boundary. The tube writer and the volumetric mesher sweep
the yarn's cross-section along these frames.
"""

from __future__ import annotations

import attrs
import numpy as np

from knitframe.errors import NumericalError
from knitframe.geometry.cell import UnitCell, strands

__all__ = ["Frames", "frames"]


@attrs.frozen(eq=False)
class Frames:
    """Rotation-minimising frame along one yarn at ``n + 1`` parameters from t0 to t1 inclusive."""

    #: (n+1,)
    t: np.ndarray
    #: (n+1, 3) positions, mm
    x: np.ndarray
    #: (n+1, 3) unit tangents
    tangent: np.ndarray
    #: (n+1, 3) unit normals, ⟂ tangent
    normal: np.ndarray
    #: (n+1, 3) tangent x normal
    binormal: np.ndarray


def _householder(v: np.ndarray) -> np.ndarray:
    """(m, 3, 3) reflections I - 2 v vᵀ / (v·v); identity where v = 0."""
    c = np.einsum("ij,ij->i", v, v)
    safe = np.where(c > 0, c, 1.0)
    h = np.eye(3)[None] - 2.0 * v[:, :, None] * v[:, None, :] / safe[:, None, None]
    h[c <= 1e-300] = np.eye(3)
    return h


def _prefix_products(m: np.ndarray) -> np.ndarray:
    """Cumulative products P_k = M_k ... M_1 M_0 of (n, 3, 3) matrices by a log-depth scan."""
    p = m.copy()
    k = 1
    while k < len(p):
        p[k:] = p[k:] @ p[:-k]
        k *= 2
    return p


def frames(cell: UnitCell, n: int = 256) -> list[Frames]:
    """Rotation-minimising frames of every yarn, closed periodically over each strand.

    The double-reflection method (Wang, Jüttler, Zheng & Liu 2008, ACM TOG 27(1)) propagates a
    normal from sample to sample: with v1 = x_{i+1} - x_i, reflect r_i and T_i in the plane
    ⟂ v1 to get r_L, T_L; with v2 = T_{i+1} - T_L, reflect r_L in the plane ⟂ v2. After one trip
    round a strand the frame comes back turned by the strand's holonomy angle φ about the
    tangent; the frame is then untwisted by -φ s/Λ (s the arc coordinate along the strand of
    length Λ), so it is continuous across every cell boundary. Each yarn gets ``n`` intervals.

    Returns
    -------
    list of Frames
        One per yarn, in the order of ``cell.yarns``; frame ``[-1]`` of yarn ``i`` equals frame
        ``[0]`` of its paired yarn.
    """
    out: list[Frames | None] = [None] * len(cell.yarns)
    for strand in strands(cell):
        ts, xs, tans = [], [], []
        shift = np.zeros(3)
        for i in strand:
            t, x, tan = cell.yarns[i].sample(n + 1)
            ts.append(t)
            xs.append(x[:-1] + shift)
            tans.append(tan[:-1])
            shift = shift + cell.L1
        # closing sample: the strand's start one full strand further on
        _, x_first, tan_first = cell.yarns[strand[0]].sample(2)
        x = np.vstack(xs + [x_first[:1] + shift])
        tan = np.vstack(tans + [tan_first[:1]])
        v1 = x[1:] - x[:-1]
        h1 = _householder(v1)
        t_left = np.einsum("mij,mj->mi", h1, tan[:-1])
        h2 = _householder(tan[1:] - t_left)
        step = h2 @ h1  # rotation taking frame i to frame i+1
        r0 = _perpendicular(tan[0])
        rot = _prefix_products(step)
        r = np.vstack([r0, np.einsum("mij,j->mi", rot, r0)])
        # holonomy: angle from the propagated end normal back to r0 about the (common) tangent
        b0 = np.cross(tan[0], r0)
        phi = np.arctan2(r[-1] @ b0, r[-1] @ r0)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(v1, axis=1))])
        ang = -phi * s / s[-1]
        b = np.cross(tan, r)
        normal = np.cos(ang)[:, None] * r + np.sin(ang)[:, None] * b
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        binormal = np.cross(tan, normal)
        if not (np.all(np.isfinite(normal)) and np.all(np.isfinite(binormal))):
            raise NumericalError(f"frame of strand {strand} is not finite (degenerate tangent?)")
        for k, i in enumerate(strand):
            sl = slice(k * n, k * n + n + 1)
            back = k * cell.L1
            out[i] = Frames(ts[k], x[sl] - back, tan[sl], normal[sl], binormal[sl])
    return out  # type: ignore[return-value]


def _perpendicular(t: np.ndarray) -> np.ndarray:
    """A unit vector ⟂ t, chosen from the coordinate axis least aligned with t."""
    e = np.zeros(3)
    e[int(np.argmin(np.abs(t)))] = 1.0
    r = e - (e @ t) * t
    return r / np.linalg.norm(r)
