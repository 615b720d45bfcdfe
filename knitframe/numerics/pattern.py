"""Sparse assembly into a cached CSR pattern.

A global matrix is a sum of parts, each a fixed list of (row, col) positions with values that change
from call to call (the element Hessians of a point map, a contact term of fixed pairs):

    A = Σ_p Σ_e  v_e · e_{r_e} e_{c_e}ᵀ

Building it from COO triplets each time (``scipy.sparse.csr_matrix((v, (r, c)))``) converts, sorts
the column indices of every row and sums duplicates at every call. Here the positions of a set of
parts are turned once into a CSR structure (``indptr``, ``indices``) and a scatter map ``slot``
(entry e → its place in ``data``); each call is then one accumulation,

    data = bincount(slot, v),

in the order the values are given. The structure of a set of parts is kept (the last few sets, so
that a line search that moves between two contact pairings does not rebuild it); a new set of
parts (contact pairs that changed) builds a new one.

The result equals scipy's to round-off: the same terms are summed, each position's in the order the
parts and their values are given (scipy sums them in the order of its unstable sort of each row). The
distinct positions of a new set of parts are found by marking an n × n grid where that is small (the
rod cell: n ≈ 300), else with ``np.unique``.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
import scipy.sparse as sp

__all__ = ["Patterned", "PatternCache"]

#: a dense n × n marking finds the distinct positions up to this many cells; np.unique beyond
DENSE_CELLS = 4_000_000


class Patterned(Protocol):
    """A part of a matrix whose positions do not change: :class:`~knitframe.numerics.periodic.PointMap`."""

    def hessian_pattern(self) -> tuple[np.ndarray, np.ndarray]: ...


class _Structure:
    """The CSR structure of a set of parts: ``slot`` gives each entry (the parts' positions, concatenated) its
    place in ``data``."""

    __slots__ = ("parts", "slot", "indptr", "indices", "nnz")

    def __init__(self, parts: Sequence[Any], lin: np.ndarray, n: int):
        self.parts = tuple(parts)  # held, so that the ids of the key are not reused while kept
        if n * n <= DENSE_CELLS:
            mark = np.zeros(n * n, dtype=bool)
            mark[lin] = True
            distinct = np.flatnonzero(mark)  # sorted row-major: CSR order
            where = np.empty(n * n, dtype=np.int64)
            where[distinct] = np.arange(len(distinct))
            slot = where[lin]
        else:
            distinct, slot = np.unique(lin, return_inverse=True)
        self.slot = slot
        self.nnz = len(distinct)
        r, c = np.divmod(distinct, n)
        dtype = np.int32 if max(n, self.nnz) < 2**31 - 1 else np.int64
        self.indices = c.astype(dtype)
        self.indptr = np.searchsorted(r, np.arange(n + 1)).astype(dtype)


class PatternCache:
    """CSR matrices (n, n) assembled from parts with fixed positions (see the module docstring).

    Parameters
    ----------
    n : int
        The matrix size.
    keep : int
        How many sets of parts keep their structure (least recently used dropped first).
    """

    def __init__(self, n: int, keep: int = 4):
        self.n = int(n)
        self.keep = int(keep)
        self._structures: OrderedDict[tuple[int, ...], _Structure] = OrderedDict()
        # each part's linear positions row·n + col, by id (the part is held with them)
        self._lin: OrderedDict[int, tuple[Any, np.ndarray]] = OrderedDict()
        #: structures built (a new set of parts) and matrices assembled, for tests and profiles
        self.builds = 0
        self.calls = 0

    def structure(self, parts: Sequence[Patterned]) -> _Structure:
        key = tuple(id(p) for p in parts)
        s = self._structures.get(key)
        if s is None:
            s = _Structure(parts, np.concatenate([self._positions(p) for p in parts]), self.n)
            self.builds += 1
            self._structures[key] = s
            while len(self._structures) > self.keep:
                self._structures.popitem(last=False)
        else:
            self._structures.move_to_end(key)
        return s

    def _positions(self, part: Patterned) -> np.ndarray:
        """row·n + col of a part's entries, computed once per part (the fixed terms' on the first call)."""
        hit = self._lin.get(id(part))
        if hit is not None and hit[0] is part:
            self._lin.move_to_end(id(part))
            return hit[1]
        rows, cols = part.hessian_pattern()
        lin = np.asarray(rows, np.int64) * self.n + np.asarray(cols, np.int64)
        self._lin[id(part)] = (part, lin)
        while len(self._lin) > 2 * self.keep:
            self._lin.popitem(last=False)
        return lin

    def matrix(self, parts: Sequence[Patterned], values: Sequence[np.ndarray]) -> sp.csr_matrix:
        """A = Σ over the parts of their values at their positions, as a CSR matrix with sorted indices.

        ``values[i]`` lists part i's values in the order of its ``hessian_pattern()``.
        """
        s = self.structure(parts)
        self.calls += 1
        v = np.concatenate(values) if len(values) > 1 else np.asarray(values[0], np.float64)
        if len(v) != len(s.slot):
            raise ValueError(f"PatternCache: {len(v)} values for {len(s.slot)} positions")
        data = np.bincount(s.slot, weights=v, minlength=s.nnz)
        A = sp.csr_matrix((data, s.indices, s.indptr), shape=(self.n, self.n), copy=False)
        A.has_sorted_indices = True
        A.has_canonical_format = True
        return A
