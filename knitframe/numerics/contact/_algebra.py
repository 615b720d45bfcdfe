"""Row-wise small-vector algebra shared by the solid-contact modules."""

from __future__ import annotations

import numpy as np


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products (m,) of two (m, k) arrays."""
    return np.einsum("ij,ij->i", a, b)
