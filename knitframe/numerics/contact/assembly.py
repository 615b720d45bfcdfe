"""Assembly of contact element terms into the global gradient and Hessian over q = [u (3N), h (6)].

Element gradients and Hessians are scattered to q with
:class:`knitframe.numerics.periodic.PointMap`; :func:`combine` first sums the terms of rows that
share their nodes and images.
"""

from __future__ import annotations

import numpy as np

from knitframe.numerics.periodic import Lattice, PointMap

__all__ = ["combine", "assemble"]


def combine(
    key: np.ndarray, grad: list[np.ndarray] | None, hess: list[np.ndarray] | None
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Sum the element terms of rows that share ``key`` (same nodes and images) before scattering.

    ``grad`` and ``hess`` are lists of arrays whose rows, one after the other, match ``key``
    (None for none). Returns the first row of each group (to pick its nodes and images) and the
    summed gradients and Hessians; fewer, larger elements make a smaller sparse assembly. The
    sums are sparse (groups × rows) 0/1 matrix products: one pass over the element arrays.
    """
    import scipy.sparse as sp

    _, first, inv = np.unique(key, return_index=True, return_inverse=True)

    def total(parts):
        if parts is None:
            return None
        out, off = np.zeros((len(first), int(np.prod(parts[0].shape[1:])))), 0
        for a in parts:
            m = len(a)
            if m:
                A = sp.csr_matrix((np.ones(m), (inv[off : off + m], np.arange(m))), shape=(len(first), m))
                out = out + A @ a.reshape(m, -1)
            off += m
        return out.reshape((len(first),) + parts[0].shape[1:])

    return first, total(grad), total(hess)


def assemble(
    n_nodes: int,
    lattice: Lattice | None,
    E: float,
    terms: list[tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]],
    order: int,
):
    """Global (E, gradient (n_dof,), Hessian CSR) of element terms ``(nodes, images, grad, hess)``.

    Each term has m elements of k points: nodes (m, k), images (m, k, 2), grad (m, k, 3) and
    hess (m, k, 3, k, 3). The gradient is scattered through :class:`knitframe.numerics.periodic.PointMap`
    (u_a and, at a periodic image, h through the reference shift S of the point: p = x + F̄·S).
    The Hessian is assembled in 3×3 node blocks: an element with a point at an image gets the
    six macro DOFs h as two more "nodes" (n_nodes, n_nodes + 1, matching the DOF order
    q = [u (3N), h (6)]), with the blocks Jᵀ H J of J = [I | M], M (3k, 6) the image weights;
    the blocks of all terms are summed by (row, column) node and converted to CSR once.
    """
    import scipy.sparse as sp

    n = 3 * n_nodes + 6
    if order == 0:
        return E, None, None
    G = np.zeros(n)
    blocks: list[tuple[np.ndarray, np.ndarray]] = []
    for nodes, images, grad, hess in terms:
        if len(nodes) == 0:
            continue
        pm = PointMap(n_nodes, nodes, images, lattice)
        G += pm.gradient(grad)
        if order < 2:
            continue
        m, k = nodes.shape
        sel = pm.imaged
        plain = ~sel
        blocks.append((pm.nodes[plain], hess[plain]))
        if np.any(sel):
            ms, k3 = int(sel.sum()), 3 * k
            Hl = hess[sel].reshape(ms, k3, k3)
            S = pm.weights[sel][..., 1:].reshape(ms, k3, 2)
            M = np.zeros((ms, k3, 6))
            for c in range(3):
                M[:, c::3, 2 * c : 2 * c + 2] = S[:, c::3, :]
            HM = Hl @ M
            Hx = np.empty((ms, k3 + 6, k3 + 6))
            Hx[:, :k3, :k3] = Hl
            Hx[:, :k3, k3:] = HM
            Hx[:, k3:, :k3] = HM.transpose(0, 2, 1)
            Hx[:, k3:, k3:] = M.transpose(0, 2, 1) @ HM
            nx = np.column_stack([pm.nodes[sel], np.full(ms, n_nodes), np.full(ms, n_nodes + 1)])
            blocks.append((nx, Hx.reshape(ms, k + 2, 3, k + 2, 3)))
    if order == 1:
        return E, G, None
    nb = n_nodes + 2
    rows, cols, data = [], [], []
    for nodes, hess in blocks:
        m, k = nodes.shape
        rows.append(np.broadcast_to(nodes[:, :, None], (m, k, k)).ravel())
        cols.append(np.broadcast_to(nodes[:, None, :], (m, k, k)).ravel())
        data.append(hess.transpose(0, 1, 3, 2, 4).reshape(-1, 3, 3))
    if not rows:
        return E, G, sp.csr_matrix((n, n))
    key = np.concatenate(rows) * nb + np.concatenate(cols)
    data = np.concatenate(data)
    srt = np.argsort(key, kind="stable")
    key = key[srt]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    vals = np.add.reduceat(data[srt], start, axis=0)
    ukey = key[start]
    indptr = np.zeros(nb + 1, np.int64)
    np.cumsum(np.bincount(ukey // nb, minlength=nb), out=indptr[1:])
    H = sp.bsr_matrix((vals, ukey % nb, indptr), shape=(n, n)).tocsr()
    return E, G, H
