"""Periodic unit cells: lattice, macro degrees of freedom, image shifts and reactions.

Shared by the unit-cell solvers (rod and volumetric). The macroscopic deformation gradient F̄
enters through six macro degrees of freedom ``h``: the in-plane columns of H = F̄ − I,

    h = [H_x1, H_x2, H_y1, H_y2, H_z1, H_z2],   H_ij = F̄_ij − δ_ij,  i ∈ {x, y, z}, j ∈ {1, 2}

where j indexes the reference in-plane axes x and y of the lattice (the lattice vectors L1, L2
lie in the z = 0 plane). A point of a periodic image k = (k1, k2) of node n sits at

    x = X_n + u_n + S_k + H · S_k,xy,      S_k = k1 L1 + k2 L2            (mm)

so u(X + L) − u(X) = (F̄ − I)·L for every lattice vector L: ABAQUS-style reference points whose
displacements are U_a = H·L_a. The reaction conjugate to ``h`` is A·P, with P the nominal
membrane stress (N/mm) and A = |L1 × L2| the reference cell area:

    ∂W/∂H_ij = A · P_ij,   course tension T1 = P_x1, wale tension T2 = P_y2.

Two equivalent ways of imposing periodicity are provided:

* :class:`PointMap` (rods, contact): each element point carries a node index and an integer
  image k; its coordinates depend on the node's displacement and on ``h`` with weights S_k.
  Element gradients and Hessians are scattered to global DOFs ``q = [u (3N), h (6)]``.
* :func:`periodic_transform` (meshes): slave nodes on the cell boundary are images of master
  nodes, ``u = T · q̃`` with ``q̃ = [u_independent, h]``; this is the sparse constraint
  ``u = T·ũ + (F̄ − I)·X`` written with the affine part folded into the slave rows (the
  fluctuation formulation adds :meth:`Lattice.affine` to every node instead).
"""

from __future__ import annotations

import attrs
import numpy as np
import scipy.sparse as sp

from knitframe.errors import GeometryError

__all__ = ["N_MACRO", "Lattice", "PointMap", "periodic_transform", "macro_index"]

#: number of macro degrees of freedom (in-plane columns of F̄ − I)
N_MACRO = 6


def macro_index(i: int, j: int) -> int:
    """Position of H_ij (spatial i ∈ {0, 1, 2}, reference in-plane axis j ∈ {0, 1}) in ``h``."""
    return 2 * i + j


def _vec3(v) -> np.ndarray:
    a = np.array(v, dtype=np.float64).reshape(3)
    a.setflags(write=False)
    return a


@attrs.frozen(eq=False)
class Lattice:
    """The 2D lattice of a periodic cell: vectors L1 (course) and L2 (wale) in the z = 0 plane, mm."""

    L1: np.ndarray = attrs.field(converter=_vec3)
    L2: np.ndarray = attrs.field(converter=_vec3)

    def __attrs_post_init__(self) -> None:
        if abs(self.L1[2]) > 1e-12 or abs(self.L2[2]) > 1e-12:
            raise GeometryError(
                f"lattice vectors must lie in the z = 0 plane, got L1 = {self.L1}, L2 = {self.L2}"
            )
        if self.area <= 1e-12 * (np.linalg.norm(self.L1) * np.linalg.norm(self.L2) + 1e-300):
            raise GeometryError(f"lattice vectors are parallel: L1 = {self.L1}, L2 = {self.L2}")

    @property
    def area(self) -> float:
        """Reference cell area |L1 × L2|, mm²."""
        return float(abs(self.L1[0] * self.L2[1] - self.L1[1] * self.L2[0]))

    def reference_shift(self, k: np.ndarray) -> np.ndarray:
        """S_k = k1 L1 + k2 L2 for integer images ``k`` (..., 2); returns (..., 3) mm."""
        k = np.asarray(k, dtype=np.float64)
        return k[..., :1] * self.L1 + k[..., 1:2] * self.L2

    def shift(self, k: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Current image shift F̄·S_k = S_k + H·S_k,xy for images ``k`` (..., 2); (..., 3) mm."""
        S = self.reference_shift(k)
        return S + S[..., :2] @ self.H(h).T

    @staticmethod
    def H(h: np.ndarray) -> np.ndarray:
        """(3, 2) matrix H = F̄ − I (in-plane columns) from the macro DOFs ``h`` (6,)."""
        return np.asarray(h, dtype=np.float64).reshape(3, 2)

    @staticmethod
    def F(h: np.ndarray) -> np.ndarray:
        """(3, 3) macroscopic deformation gradient F̄ (the third column stays e_z)."""
        F = np.eye(3)
        F[:, :2] += np.asarray(h, dtype=np.float64).reshape(3, 2)
        return F

    @staticmethod
    def h_from_F(F: np.ndarray) -> np.ndarray:
        """Macro DOFs (6,) of a (3, 3) or (3, 2) deformation gradient."""
        F = np.asarray(F, dtype=np.float64)
        return (F[:, :2] - np.eye(3)[:, :2]).reshape(-1)

    def affine(self, X: np.ndarray, h: np.ndarray) -> np.ndarray:
        """Affine displacement (F̄ − I)·X of points X (n, 3), mm."""
        return np.asarray(X)[:, :2] @ self.H(h).T

    def nominal_stress(self, reaction: np.ndarray) -> np.ndarray:
        """(3, 2) nominal membrane stress P = (∂W/∂H) / A in N/mm from the macro reactions (6,) in N·mm."""
        return np.asarray(reaction, dtype=np.float64).reshape(3, 2) / self.area

    def tensions(self, reaction: np.ndarray) -> tuple[float, float]:
        """Course and wale tension per unit reference width (T1 = P_x1, T2 = P_y2), N/mm."""
        P = self.nominal_stress(reaction)
        return float(P[0, 0]), float(P[1, 1])

    def constraints(
        self, lam1: float | None, lam2: float | None, *, F: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Which macro DOFs are prescribed, and their values, for stretches λ1, λ2.

        F̄ = diag(λ1, λ2, 1); shear and out-of-plane components are held at zero, which also
        removes the rigid rotation of the lattice. A stretch given as None is free: its DOF
        is solved for, so its conjugate stress is zero (a free side). ``F`` (3, 3) prescribes
        every component instead (used for rotated or sheared states).

        Returns ``(prescribed (6,) bool, values (6,))``.
        """
        if F is not None:
            return np.ones(N_MACRO, bool), self.h_from_F(F)
        prescribed = np.ones(N_MACRO, bool)
        values = np.zeros(N_MACRO)
        for axis, lam in ((0, lam1), (1, lam2)):
            idx = macro_index(axis, axis)
            if lam is None:
                prescribed[idx] = False
            else:
                values[idx] = lam - 1.0
        return prescribed, values


def _n_dof(n_nodes: int) -> int:
    return 3 * n_nodes + N_MACRO


@attrs.frozen(eq=False)
class PointMap:
    """Element points (node + periodic image) → global DOFs ``q = [u (3 n_nodes), h (6)]``.

    ``nodes`` (m, k) and ``images`` (m, k, 2) describe m elements of k points each. Each point
    coordinate c depends on DOF ``3·node + c`` with weight 1 and, when the point is an image, on
    ``h`` entries H_c1, H_c2 with weights S_x, S_y of its reference shift. Gradients scatter with
    ``np.bincount`` and Hessians as COO triplets, with no Python loop over elements.
    """

    n_nodes: int
    nodes: np.ndarray
    images: np.ndarray
    lattice: Lattice | None = None
    #: (m, k, 3, s) global DOF of each slot
    dofs: np.ndarray = attrs.field(init=False)
    #: (m, k, 3, s) weights
    weights: np.ndarray = attrs.field(init=False)
    #: (m,) elements with a point at a non-zero image
    imaged: np.ndarray = attrs.field(init=False)
    _pattern: tuple | None = attrs.field(init=False, default=None, repr=False)
    _shift: np.ndarray | None = attrs.field(init=False, default=None, repr=False)
    _macro: np.ndarray | None = attrs.field(init=False, default=None, repr=False)

    def __attrs_post_init__(self) -> None:
        nodes = np.asarray(self.nodes, dtype=np.int64)
        m, k = nodes.shape
        images = np.zeros((m, k, 2), np.int64) if self.images is None else np.asarray(self.images, np.int64)
        c = np.arange(3)
        node_dof = 3 * nodes[:, :, None] + c  # (m, k, 3)
        periodic = self.lattice is not None and np.any(images != 0)
        if not periodic:
            dofs = node_dof[..., None]
            w = np.ones(dofs.shape)
        else:
            S = self.lattice.reference_shift(images)  # (m, k, 3)
            macro = 3 * self.n_nodes + 2 * c[None, None, :, None] + np.arange(2)  # (1, 1, 3, 2)
            dofs = np.concatenate([node_dof[..., None], np.broadcast_to(macro, (m, k, 3, 2))], axis=-1)
            w = np.concatenate(
                [np.ones((m, k, 3, 1)), np.broadcast_to(S[:, :, None, :2], (m, k, 3, 2))], axis=-1
            )
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "images", images)
        object.__setattr__(self, "dofs", dofs)
        object.__setattr__(self, "weights", w)
        object.__setattr__(
            self, "imaged", np.any(images != 0, axis=(1, 2)) if periodic else np.zeros(m, bool)
        )
        object.__setattr__(self, "_shift", self.lattice.reference_shift(images) if periodic else None)

    @property
    def n_dof(self) -> int:
        return _n_dof(self.n_nodes)

    def points(self, x: np.ndarray, h: np.ndarray | None = None) -> np.ndarray:
        """Current positions (m, k, 3) of the element points from node positions x (n, 3)."""
        p = x[self.nodes]
        S = self._shift  # the reference image shifts S_k, fixed for the map; None when none is non-zero
        if S is None:
            return p
        if h is None:
            return p + S
        return p + (S + S[..., :2] @ self.lattice.H(h).T)  # F̄·S_k (Lattice.shift)

    def gradient(self, g: np.ndarray) -> np.ndarray:
        """Global gradient (n_dof,) from element point gradients g (m, k, 3)."""
        vals = self.weights * g[..., None]
        return np.bincount(self.dofs.reshape(-1), vals.reshape(-1), minlength=self.n_dof)

    def hessian_pattern(self) -> tuple[np.ndarray, np.ndarray]:
        """(rows, cols) of :meth:`hessian_values`, the same for every call: computed once per map."""
        if self._pattern is None:
            m, k = self.nodes.shape
            n3 = 3 * k
            nd = self.dofs[..., 0].reshape(m, n3)
            rows = [np.broadcast_to(nd[:, :, None], (m, n3, n3)).reshape(-1)]
            cols = [np.broadcast_to(nd[:, None, :], (m, n3, n3)).reshape(-1)]
            if np.any(self.imaged):
                macro = 3 * self.n_nodes + np.arange(N_MACRO)
                nds = nd[self.imaged]
                shape = (len(nds), n3, N_MACRO)
                node = np.broadcast_to(nds[:, :, None], shape).reshape(-1)
                mac = np.broadcast_to(macro[None, None, :], shape).reshape(-1)
                rows += [node, mac, np.repeat(macro, N_MACRO)]
                cols += [mac, node, np.tile(macro, N_MACRO)]
            object.__setattr__(self, "_pattern", (np.concatenate(rows), np.concatenate(cols)))
        return self._pattern

    def hessian_values(self, H: np.ndarray) -> np.ndarray:
        """Values of Jᵀ·H·J for element Hessians H (m, k, 3, k, 3), in the order of :meth:`hessian_pattern`.

        With J = [I | M] (node part, macro part M (3k, 6) of the image shifts), the blocks are
        H (node–node), H·M and Mᵀ·H = (H·M)ᵀ (node–macro; every element Hessian is symmetric) and
        Σ Mᵀ·H·M (macro–macro); the macro blocks are formed only for elements that have a point at a
        non-zero image.
        """
        m, k = self.nodes.shape
        n3 = 3 * k
        Hl = H.reshape(m, n3, n3)
        sel = self.imaged
        if not np.any(sel):
            return Hl.reshape(-1)
        Hs = Hl[sel]
        M = self._macro_weights()
        HM = Hs @ M  # (m_s, 3k, 6); Mᵀ·H = (H·M)ᵀ, H being symmetric
        MHM = M.reshape(-1, N_MACRO).T @ HM.reshape(-1, N_MACRO)  # Σ_m M_mᵀ·H_m·M_m
        return np.concatenate([Hl.reshape(-1), HM.reshape(-1), HM.reshape(-1), MHM.reshape(-1)])

    def _macro_weights(self) -> np.ndarray:
        """M (m_s, 3k, 6) of the imaged elements: ∂(point coordinates)/∂h, fixed for the map."""
        if self._macro is None:
            m, k = self.nodes.shape
            n3 = 3 * k
            sel = self.imaged
            S = self.weights[sel][..., 1:].reshape(int(sel.sum()), n3, 2)
            M = np.zeros((len(S), n3, N_MACRO))
            for c in range(3):
                M[:, c::3, 2 * c : 2 * c + 2] = S[:, c::3, :]
            object.__setattr__(self, "_macro", M)
        return self._macro

    def hessian_coo(self, H: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """COO triplets (rows, cols, vals) of Jᵀ·H·J for element Hessians H (m, k, 3, k, 3)."""
        rows, cols = self.hessian_pattern()
        return rows, cols, self.hessian_values(H)

    def hessian(self, H: np.ndarray) -> sp.csr_matrix:
        """Global sparse Hessian (n_dof, n_dof) from element Hessians H (m, k, 3, k, 3)."""
        r, c, v = self.hessian_coo(H)
        return sp.csr_matrix((v, (r, c)), shape=(self.n_dof, self.n_dof))


def periodic_transform(
    n_nodes: int, slave: np.ndarray, master: np.ndarray, images: np.ndarray, lattice: Lattice
) -> tuple[sp.csr_matrix, np.ndarray]:
    """Sparse T with ``u = T · [u_independent (3 n_ind), h (6)]`` for a mesh with periodic node pairs.

    Node ``slave[p]`` is the image ``images[p]`` (k1, k2) of node ``master[p]``:
    X_slave = X_master + k1 L1 + k2 L2, and u_slave = u_master + H·S_xy, i.e.
    u(X + L) − u(X) = (F̄ − I)·L. Chains (a slave whose master is itself a slave, as at cell
    corners) are resolved to the independent node.

    Returns
    -------
    T : csr_matrix (3 n_nodes, 3 n_ind + 6)
    independent : (n_ind,) node numbers of the independent nodes, in column order
    """
    slave = np.asarray(slave, np.int64)
    master = np.asarray(master, np.int64).copy()
    images = np.asarray(images, np.int64).copy()
    parent = np.arange(n_nodes)
    img = np.zeros((n_nodes, 2), np.int64)
    parent[slave] = master
    img[slave] = images
    for _ in range(4):  # corners chain at most twice in 2D
        nxt = parent[parent]
        if np.array_equal(nxt, parent):
            break
        img = img + img[parent]
        parent = nxt
    if not np.array_equal(parent[parent], parent):
        raise GeometryError("periodic node pairs form a cycle")
    independent = np.flatnonzero(parent == np.arange(n_nodes))
    col_of = -np.ones(n_nodes, np.int64)
    col_of[independent] = np.arange(len(independent))
    pm = PointMap(len(independent), col_of[parent][:, None], img[:, None, :], lattice)
    n_cols = 3 * len(independent) + N_MACRO
    rows = np.broadcast_to(
        (3 * np.arange(n_nodes)[:, None, None] + np.arange(3)[None, :, None]), pm.dofs[:, 0].shape
    )
    T = sp.csr_matrix(
        (pm.weights[:, 0].reshape(-1), (rows.reshape(-1), pm.dofs[:, 0].reshape(-1))),
        shape=(3 * n_nodes, n_cols),
    )
    T.eliminate_zeros()
    return T, independent
