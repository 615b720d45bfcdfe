"""The paper's per-element method (steps 5–7): limit switch, uniform-tension choice, region merging.

A heuristic on the 2-D element map (paper mode only), kept to compare with the exact assignment.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from knitframe.garment.tube import ElementGeometry


def _periodic_labels(fabric: np.ndarray) -> tuple[np.ndarray, int]:
    """Connected regions of equal fabric on the tube (4-neighbours, joined across the seam)."""
    labels = np.zeros(fabric.shape, dtype=np.int64)
    n = 0
    for f in np.unique(fabric):
        lab, k = ndimage.label(fabric == f)
        labels[lab > 0] = lab[lab > 0] + n
        n += k
    parent = np.arange(n + 1)

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    seam = fabric[:, 0] == fabric[:, -1]
    for a, b in zip(labels[seam, 0], labels[seam, -1], strict=False):
        ra, rb = root(int(a)), root(int(b))
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([root(i) for i in range(n + 1)])
    _, dense = np.unique(roots, return_inverse=True)
    return dense[labels], int(dense.max())


def _paper_method(
    objective,
    library,
    T1: np.ndarray,
    feasible: np.ndarray,
    geo: ElementGeometry,
    base: int,
    min_elements: int,
) -> tuple[np.ndarray, list[str]]:
    """The paper's per-element procedure (steps 5–7); returns the (R, A) assignment and notes."""
    F = T1.shape[0]
    fab = np.full(geo.shape, base)
    over = ~feasible[base]
    compliant = np.argmin(np.where(feasible, T1, np.inf), axis=0)  # the least tension that fits
    fab[over] = compliant[over]
    notes = [
        f"{int(over.sum())} of {over.size} elements over the limit of "
        f"{library.entries[base].name}: switched to the most compliant fabric that fits"
    ]
    # choose each element's fabric for the most uniform tension, to a fixed point
    for it in range(50):  # noqa: B007 (it counts the passes, reported below)
        current = np.take_along_axis(T1, fab[None], 0)[0]
        tau = float(np.sum(geo.area * current) / np.sum(geo.area))
        new = np.argmin(np.where(feasible, np.abs(T1 - tau), np.inf), axis=0)
        new = np.where(feasible[new, np.arange(geo.shape[0])[:, None], np.arange(geo.shape[1])], new, fab)
        if np.array_equal(new, fab):
            break
        fab = new
    notes.append(f"uniform-tension choice converged after {it + 1} passes")
    merged = 0
    while True:  # merge regions below the minimum size into the neighbour they share most boundary with
        labels, n = _periodic_labels(fab)
        sizes = np.bincount(labels.ravel(), minlength=n + 1)
        small = [k for k in range(1, n + 1) if sizes[k] < min_elements]
        if not small or n == 1:
            break
        k = min(small, key=lambda k: sizes[k])
        mask = labels == k
        ring = (
            np.roll(mask, 1, 1)
            | np.roll(mask, -1, 1)
            | np.vstack([mask[1:], mask[-1:] & False])
            | np.vstack([mask[:1] & False, mask[:-1]])
        ) & ~mask
        neighbours = fab[ring]
        if not len(neighbours):
            break
        fab[mask] = np.bincount(neighbours, minlength=F).argmax()
        merged += 1
    notes.append(f"{merged} regions below {min_elements} elements merged into their neighbours")
    return fab, notes
