"""Total-Lagrangian hyperelastic solid on tetrahedra: energy, residual and tangent by batched einsum.

Kinematics: x = X + u, F = I + ∇u (3, 3, n_el, n_qp), with u interpolated by scikit-fem's P1 or P2
Lagrange basis (vector DOF ``3·node + i``). For a strain energy density Ψ(F) per reference volume
(MPa = N/mm²)::

    W(u)       = Σ_e Σ_q Ψ(F_eq) dV_eq                                   (N·mm)
    R_ai(u)    = Σ_q P_iJ ∂_J N_a dV                                      (N)
    K_aibk(u)  = Σ_q ∂_J N_a A_iJkL ∂_L N_b dV,  A = ∂P/∂F                (N/mm)

The kernels run over (element, quadrature point) at once with ``numpy.einsum`` on scikit-fem's
basis gradients, quadrature weights and DOF maps, in chunks of elements to bound memory, the
chunks on a pool of threads (numpy's kernels release the GIL; BLAS is held to one thread inside
them so the threads do not oversubscribe the cores). Each chunk's tangent entries are summed by
``np.bincount`` over the CSR entries that chunk touches (precomputed with the pattern), and the
chunks are added in their order, so the result does not depend on the thread count or timing.

Thermal pre-stress: an eigenstrain transverse to the fibre a (the centerline tangent), with the
multiplicative split F = Fe·Fθ and the yarn's stress-free radius s·r::

    Fθ = I + (s − 1) ∇o,      Jθ = det Fθ

where o(X) is the offset of the material point from its yarn's centerline, interpolated from
the nodes. On a rotation-minimising frame ∇o = (I − a⊗a) − c/(1 − c) a⊗a with c = κ·o (κ the
centerline's curvature vector), so Fθ = s (I − a⊗a) + (1 − s c)/(1 − c) a⊗a: a transverse
shrink by s plus the axial factor that keeps the undersized tube x = C + s·o exactly stress-free
(without it the fibres of a curved yarn would be strained by κ·o·(1 − s), large for a stiff
yarn in a tight loop). Using the interpolated offsets makes the undersized tube stress-free for
the discrete mesh too. Raising s from r_under/r to 1 grows an undersized yarn to its knitted
diameter dk at constant centerline length; at s = 1, Fθ = I. W = ∫ Jθ Ψ(Fe) dV,
P = Jθ Pe(Fe)·Fθ⁻ᵀ and A_iJkL = Jθ Ae_iMkN Fθ⁻¹_JM Fθ⁻¹_LN.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import attrs
import numpy as np
import scipy.sparse as sp
from threadpoolctl import ThreadpoolController

from knitframe.errors import NumericalError

__all__ = ["YarnLaw", "SolidForms", "fibre_at_quadrature", "psd_project"]

#: the BLAS libraries' thread controller, found once (:func:`_one_blas_thread`)
_BLAS: list[ThreadpoolController] = []


def _one_blas_thread():
    """Context holding BLAS to one thread, as ``knitframe.numerics.parallel.one_blas_thread`` but with the
    libraries looked up once: threadpoolctl's ``threadpool_limits`` walks every loaded shared library at
    each call (2-3 ms with gmsh, ipctk and MKL loaded, 1.5 s over the 600 evaluations of a P2 run). The
    element chunks call numpy's BLAS, loaded with numpy before the first lookup."""
    if not _BLAS:
        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1, user_api="blas")


def _inv_det(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse and determinant of (3, 3, ...) matrices by cofactors."""
    c = np.empty_like(F)
    c[0, 0] = F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]
    c[0, 1] = F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]
    c[0, 2] = F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]
    c[1, 0] = F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]
    c[1, 1] = F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]
    c[1, 2] = F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]
    c[2, 0] = F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]
    c[2, 1] = F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]
    c[2, 2] = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    J = F[0, 0] * c[0, 0] + F[0, 1] * c[1, 0] + F[0, 2] * c[2, 0]
    return c / np.where(J == 0, 1.0, J), J


@attrs.frozen
class YarnLaw:
    """A yarn model's solid law on skfem-shaped arrays: F (3, 3, n_el, n_qp), fibres a (3, n_el, n_qp).

    ``model.evaluate(F (..., 3, 3), fibre (..., 3)) -> (Ψ, P, A)`` is the vectorised law of a yarn
    model plugin (for example ``transverse_isotropic`` or ``isotropic``); this adapter moves the
    tensor axes to the front, as scikit-fem's forms expect, and returns Ψ = +inf for inverted
    states instead of raising, so line searches can back off.
    """

    #: yarn model plugin instance with ``evaluate`` (:class:`~knitframe.interfaces.YarnModel`)
    model: Any
    #: ``model.evaluate`` takes ``order``, as the YarnModel protocol declares; False for a model
    #: written before it did (it computes everything)
    takes_order: bool = True

    @classmethod
    def from_yarn(cls, yarn: Any, registry: Any = None) -> YarnLaw:
        """Law of the yarn model named by ``yarn.model``, parameterised by the Yarn record."""
        from knitframe import get_registry

        reg = registry or get_registry()
        return cls(reg["yarn_model"][yarn.model].from_yarn(yarn))

    def _evaluate(self, F: np.ndarray, a: np.ndarray, order: int = 2) -> tuple[np.ndarray, Any, Any]:
        Fm, am = np.moveaxis(F, (0, 1), (-2, -1)), np.moveaxis(a, 0, -1)
        if self.takes_order:
            W, P, A = self.model.evaluate(Fm, am, order=order)
        else:  # a yarn model without the ``order`` keyword computes everything
            W, P, A = self.model.evaluate(Fm, am)
        P = None if P is None or order < 1 else np.moveaxis(P, (-2, -1), (0, 1))
        A = None if A is None or order < 2 else np.moveaxis(A, (-4, -3, -2, -1), (0, 1, 2, 3))
        return W, P, A

    def energy(self, F: np.ndarray, a: np.ndarray) -> np.ndarray:
        """Ψ (n_el, n_qp), MPa; +inf everywhere if any point is inverted."""
        if np.any(~(_inv_det(F)[1] > 0)):
            return np.full(F.shape[2:], np.inf)
        return self._evaluate(F, a, 0)[0]

    def stress(self, F: np.ndarray, a: np.ndarray) -> np.ndarray:
        """First Piola-Kirchhoff stress P (3, 3, n_el, n_qp), MPa."""
        return self._evaluate(F, a, 1)[1]

    def tangent(self, F: np.ndarray, a: np.ndarray) -> np.ndarray:
        """A_iJkL = ∂P_iJ/∂F_kL (3, 3, 3, 3, n_el, n_qp), MPa."""
        return self._evaluate(F, a, 2)[2]

    def evaluate(self, F: np.ndarray, a: np.ndarray, order: int = 2) -> tuple[np.ndarray, Any, Any]:
        """(Ψ, P, A) at once (the yarn model computes them together); ``order`` < 2 skips A, < 1 skips P."""
        return self._evaluate(F, a, order)


def psd_project(A: np.ndarray, method: str = "clamp") -> np.ndarray:
    """Positive semi-definite part of the tangent A_iJkL (3, 3, 3, 3, ...) at every quadrature point.

    A is symmetric as a 9x9 matrix M_(iJ)(kL) (a hyperelastic tangent has major symmetry).
    With M = V diag(w) Vᵀ, the projection is M⁺ = V diag(max(w, 0)) Vᵀ, the closest PSD matrix in
    the Frobenius norm. Every element matrix K_e = Σ_q ∇Nᵀ A⁺ ∇N dV is then PSD as well: the
    projected Newton method of barrier contact (Li et al. 2020), here per quadrature point, where a
    9x9 eigenproblem replaces the element's 12x12 (P1) or 30x30 (P2) one. Compressive stress makes
    A indefinite (its geometric part is negative for rotations under compression; a compressed
    fibre of a 10⁴-anisotropic yarn makes it strongly so).

    ``method = "abs"`` takes M⁺ = V diag(|w|) Vᵀ instead (positive definite where M is regular): a
    negative-curvature mode keeps a stiffness of its own size rather than none, so a Newton step does
    not run far along it (the absolute-value eigenvalue filter of Chen et al., SIGGRAPH Asia 2024).
    """
    if method not in ("clamp", "abs"):
        raise ValueError(f"psd_project: method must be 'clamp' or 'abs', got {method!r}")
    M = _filter_eigenvalues(np.moveaxis(A.reshape(9, 9, -1), -1, 0), method)
    return np.moveaxis(M, 0, -1).reshape(A.shape)


def _filter_eigenvalues(M: np.ndarray, method: str = "clamp") -> np.ndarray:
    """Symmetric part of a stack of matrices M (p, n, n) rebuilt as V diag(f(w)) Vᵀ, f(w) = max(w, 0) or
    |w|."""
    M = 0.5 * (M + np.swapaxes(M, 1, 2))
    w, V = np.linalg.eigh(M)
    return np.einsum(
        "pij,pj,pkj->pik", V, np.abs(w) if method == "abs" else np.maximum(w, 0.0), V, optimize=True
    )


def psd_project_elements(Ke: np.ndarray) -> np.ndarray:
    """Positive semi-definite part of each element matrix Ke (n_el, n, 3, n, 3): V diag(max(w, 0)) Vᵀ of
    its (3n × 3n) eigen-decomposition (IPC's per-element projection; costlier than the per-point one, but
    it keeps what the other quadrature points of the element hold up)."""
    return _filter_eigenvalues(Ke.reshape(Ke.shape[0], Ke.shape[1] * Ke.shape[2], -1)).reshape(Ke.shape)


def fibre_at_quadrature(basis: Any, node_tangent: np.ndarray) -> np.ndarray:
    """Unit fibre directions a (3, n_el, n_qp): nodal tangents interpolated with the basis, normalised."""
    dofs = basis.element_dofs  # (n_local, n_el) node numbers for a scalar Lagrange basis
    vals = np.stack([np.asarray(phi[0]) for phi in basis.basis])  # (n_local, n_el, n_qp)
    a = np.einsum("leq,lei->ieq", vals, node_tangent[dofs])
    return a / np.linalg.norm(a, axis=0, keepdims=True)


def _eigen_transform(grad_offset: np.ndarray, s: float) -> tuple[np.ndarray, np.ndarray]:
    """Fθ⁻¹ (3, 3, n_el, n_qp) and Jθ (n_el, n_qp) of the pre-stress eigenstrain Fθ = I + (s − 1)∇o."""
    Ft = (s - 1.0) * grad_offset
    Ft[0, 0] += 1.0
    Ft[1, 1] += 1.0
    Ft[2, 2] += 1.0
    return _inv_det(Ft)


class SolidForms:
    """Energy, residual and tangent of a hyperelastic body on a scikit-fem tetrahedral mesh.

    Parameters
    ----------
    mesh : skfem.MeshTet1 or skfem.MeshTet2.
    law : a material with ``energy(F, a)``, ``stress(F, a)`` and ``evaluate(F, a, order)`` giving
        (Ψ, P, A) at once, e.g. :class:`YarnLaw`.
    node_tangent : (N, 3) fibre direction at each node (N = vertices for P1, vertices + edges
        for P2); None gives a fixed x fibre (only meaningful for isotropic laws).
    node_offset : (N, 3) offset of each node from its yarn's centerline (mm), for the pre-stress
        eigenstrain; None disables it (then s must stay 1).
    intorder : quadrature order (default 2: 4 points, like ABAQUS C3D10).
    chunk : elements per einsum batch.
    threads : threads the chunks run on (default: the CPUs this process may use, at most 8).
    """

    def __init__(
        self,
        mesh: Any,
        law: Any,
        node_tangent: np.ndarray | None = None,
        *,
        intorder: int = 2,
        chunk: int = 4096,
        node_offset: np.ndarray | None = None,
        threads: int | None = None,
    ):
        import skfem

        elem = skfem.ElementTetP2() if isinstance(mesh, skfem.MeshTet2) else skfem.ElementTetP1()
        self.mesh = mesh
        self.law = law
        self.basis = skfem.Basis(mesh, elem, intorder=intorder)
        self.grad = np.stack([phi[0].grad for phi in self.basis.basis])  # (nl, 3, n_el, n_qp)
        self.dx = np.asarray(self.basis.dx)  # (n_el, n_qp) mm³
        self.edofs = np.asarray(self.basis.element_dofs)  # (nl, n_el) node numbers
        self.n_nodes = int(self.basis.N)
        self.ndof = 3 * self.n_nodes
        if node_tangent is None:
            node_tangent = np.tile([1.0, 0.0, 0.0], (self.n_nodes, 1))
        self.fibre = fibre_at_quadrature(self.basis, np.asarray(node_tangent, dtype=np.float64))
        self.grad_offset = None  # ∇o at the quadrature points (3, 3, n_el, n_qp)
        if node_offset is not None:
            o = np.asarray(node_offset, dtype=np.float64)[self.edofs]  # (nl, n_el, 3)
            self.grad_offset = np.einsum("lei,lJeq->iJeq", o, self.grad)
        self.chunk = int(chunk)
        #: eigenvalue filter of the projected tangent: "clamp" or "abs" per point (:func:`psd_project`),
        #: "element" (:func:`psd_project_elements`)
        self.projection = "clamp"
        self.flux: np.ndarray | None = None  #: Σ_e |R_e| of the last evaluate(order >= 1), N
        nl, ne = self.edofs.shape
        self.vdofs = (3 * self.edofs[:, None, :] + np.arange(3)[None, :, None]).reshape(
            3 * nl, ne
        )  # (3nl, n_el)
        self._pattern: tuple[sp.csr_matrix, np.ndarray] | None = None
        self._scatter: dict[int, tuple[np.ndarray, np.ndarray]] | None = (
            None  # per chunk start: CSR entries touched, inverse map
        )
        if threads is None:
            threads = (
                len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
            )
        self.threads = max(1, min(int(threads), 8))
        self._pool: ThreadPoolExecutor | None = None

    # -- kinematics ------------------------------------------------------------------------------
    def deformation_gradient(self, u: np.ndarray, sl: slice = slice(None)) -> np.ndarray:
        """F = I + Σ_a u_a ⊗ ∇N_a, (3, 3, n_el, n_qp) for the elements ``sl``."""
        ue = u.reshape(-1, 3)[self.edofs[:, sl]]  # (nl, n_el, 3)
        F = np.einsum("lei,lJeq->iJeq", ue, self.grad[:, :, sl])
        F[0, 0] += 1.0
        F[1, 1] += 1.0
        F[2, 2] += 1.0
        return F

    def _chunks(self) -> list[slice]:
        """Slices of at most ``chunk`` elements, and 8 of them for meshes of 2 048 to 8 ``chunk`` elements
        (work for up to 8 threads); the slicing does not depend on ``threads``, so neither does the summation
        order."""
        ne = self.edofs.shape[1]
        size = max(1, min(self.chunk, max(256, -(-ne // 8))))
        return [slice(start, min(start + size, ne)) for start in range(0, ne, size)]

    def _map(self, fn: Callable[[slice], Any]) -> Iterator[Any]:
        """fn(chunk) for every chunk, in chunk order; on ``threads`` threads with BLAS held to one thread
        each.

        A chunk that raises re-raises here (the first in chunk order)."""
        chunks = self._chunks()
        if self.threads == 1 or len(chunks) == 1:
            yield from map(fn, chunks)
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=self.threads, thread_name_prefix="knitframe-solid")
        with _one_blas_thread():
            futures = [self._pool.submit(fn, sl) for sl in chunks]
            try:
                for f in futures:
                    yield f.result()
            finally:
                for f in futures:
                    f.cancel()

    def _check(self, F: np.ndarray, sl: slice) -> None:
        _, J = _inv_det(F)
        bad = ~(J > 0)
        if np.any(bad):
            e = int(np.flatnonzero(bad.any(axis=1))[0]) + (sl.start or 0)
            raise NumericalError(
                f"volumetric solid: {int(bad.sum())} quadrature points inverted "
                f"(det F = {float(J[bad].min()):.3g}), first in element {e}; the load step is too large or "
                "the mesh too coarse"
            )

    # -- forms -------------------------------------------------------------------------------------
    def energy(self, u: np.ndarray, s: float = 1.0) -> float:
        """Strain energy W = Σ Jθ Ψ(F Fθ⁻¹) dV, N·mm; +inf if any element is inverted."""

        def chunk(sl: slice) -> float:
            F = self.deformation_gradient(u, sl)
            a = self.fibre[:, sl]
            Jt = 1.0
            if s != 1.0:
                Ti, Jt = self._eigen(s, sl)
                F = np.einsum("iMeq,MJeq->iJeq", F, Ti)
            return float(np.sum(Jt * self.law.energy(F, a) * self.dx[sl]))

        return float(sum(self._map(chunk)))

    def _eigen(self, s: float, sl: slice) -> tuple[np.ndarray, np.ndarray]:
        if self.grad_offset is None:
            raise NumericalError(
                "volumetric solid: a pre-stress parameter s != 1 needs the nodes' centerline offsets"
            )
        return _eigen_transform(self.grad_offset[:, :, sl], s)

    def _stress(self, F: np.ndarray, a: np.ndarray, s: float, sl: slice) -> np.ndarray:
        if s == 1.0:
            return self.law.stress(F, a)
        Ti, Jt = self._eigen(s, sl)
        Fe = np.einsum("iMeq,MJeq->iJeq", F, Ti)
        return Jt * np.einsum("iMeq,JMeq->iJeq", self.law.stress(Fe, a), Ti)

    def residual(self, u: np.ndarray, s: float = 1.0) -> np.ndarray:
        """Internal force R = ∂W/∂u (3N,), N."""

        def chunk(sl: slice) -> np.ndarray:
            F = self.deformation_gradient(u, sl)
            self._check(F, sl)
            P = self._stress(F, self.fibre[:, sl], s, sl)
            Re = np.einsum("iJeq,lJeq,eq->lie", P, self.grad[:, :, sl], self.dx[sl])
            return np.bincount(
                self.vdofs[:, sl].ravel(), Re.reshape(-1, Re.shape[-1]).ravel(), minlength=self.ndof
            )

        out = np.zeros(self.ndof)
        for r in self._map(chunk):
            out += r
        return out

    def stress(self, u: np.ndarray, s: float = 1.0) -> np.ndarray:
        """First Piola-Kirchhoff stress at the quadrature points (3, 3, n_el, n_qp), MPa."""
        return np.concatenate(
            list(
                self._map(lambda sl: self._stress(self.deformation_gradient(u, sl), self.fibre[:, sl], s, sl))
            ),
            axis=2,
        )

    def pattern(self) -> tuple[sp.csr_matrix, np.ndarray]:
        """CSR sparsity pattern of the tangent and the map from element-matrix entries to its data."""
        if self._pattern is None:
            m, ne = self.vdofs.shape
            rows = np.broadcast_to(self.vdofs[:, None, :], (m, m, ne)).transpose(2, 0, 1).ravel()
            cols = np.broadcast_to(self.vdofs[None, :, :], (m, m, ne)).transpose(2, 0, 1).ravel()
            key = rows.astype(np.int64) * self.ndof + cols
            uniq, where = np.unique(key, return_inverse=True)
            K = sp.csr_matrix(
                (np.zeros(uniq.size), (uniq // self.ndof, uniq % self.ndof)), shape=(self.ndof, self.ndof)
            )
            K.sort_indices()
            # csr data order is row-major sorted keys, the same order as np.unique's
            self._pattern = (K, where.astype(np.int64 if uniq.size > 2**31 - 1 else np.int32))
        return self._pattern

    def scatter(self) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """Per chunk (by its first element), the CSR entries of the tangent its elements touch and the map of
        its element-matrix entries onto them: K.data[touched] += bincount(inverse, Ke.ravel()) sums one chunk
        (a bincount as long as the chunk's share of the pattern instead of the whole of it)."""
        if self._scatter is None:
            _, where = self.pattern()
            m2 = self.vdofs.shape[0] ** 2
            out = {}
            for sl in self._chunks():
                touched, inverse = np.unique(where[sl.start * m2 : sl.stop * m2], return_inverse=True)
                out[sl.start] = (touched, inverse.astype(np.int32))
            self._scatter = out
        return self._scatter

    def tangent(self, u: np.ndarray, s: float = 1.0) -> sp.csr_matrix:
        """Tangent stiffness K = ∂R/∂u (3N, 3N) as CSR, N/mm."""
        return self.evaluate(u, s, 2)[2]

    def evaluate(
        self, u: np.ndarray, s: float = 1.0, order: int = 2, *, project: bool = False
    ) -> tuple[float, np.ndarray | None, sp.csr_matrix | None]:
        """(W, R, K) in one pass over the elements: the law is evaluated once per chunk.

        ``order`` 0 gives W only (+inf for an inverted element), 1 adds R, 2 adds K. With
        ``project`` the tangent is the positive semi-definite projection of A at every quadrature
        point (:func:`psd_project`), so K is positive semi-definite (W and R are unchanged).

        With ``order >= 1`` the force flux ``self.flux`` (3N,) is kept as well: the sum over
        elements of the absolute element nodal forces, Σ_e |R_e,ai| (N). Unlike R it does not
        cancel at equilibrium, so it measures the force level that a residual is small against
        (the "time-averaged force" of implicit FE codes' convergence tests).
        """
        if order == 0:
            return self.energy(u, s), None, None
        K0 = self.pattern()[0] if order == 2 else None
        scatter = self.scatter() if order == 2 else None

        def chunk(sl: slice):
            F = self.deformation_gradient(u, sl)
            self._check(F, sl)
            a = self.fibre[:, sl]
            G = self.grad[:, :, sl]
            Jt, Ti = 1.0, None
            if s != 1.0:
                Ti, Jt = self._eigen(s, sl)
                F = np.einsum("iMeq,MJeq->iJeq", F, Ti)
            Psi, P, A = self.law.evaluate(F, a, order)
            W = float(np.sum(Jt * Psi * self.dx[sl]))
            if Ti is not None:
                P = Jt * np.einsum("iMeq,JMeq->iJeq", P, Ti)
            Re = np.einsum("iJeq,lJeq,eq->lie", P, G, self.dx[sl])
            dofs = self.vdofs[:, sl].ravel()
            R = np.bincount(dofs, Re.reshape(-1, Re.shape[-1]).ravel(), minlength=self.ndof)
            flux = np.bincount(dofs, np.abs(Re).reshape(-1, Re.shape[-1]).ravel(), minlength=self.ndof)
            Kc = None
            if order == 2:
                if Ti is not None:
                    A = Jt * np.einsum("iMkNeq,JMeq,LNeq->iJkLeq", A, Ti, Ti, optimize=True)
                if project and self.projection != "element":
                    A = psd_project(A, self.projection)
                T = np.einsum("aJeq,iJkLeq->aikLeq", G, A, optimize=True)
                Ke = np.einsum("aikLeq,bLeq,eq->eaibk", T, G, self.dx[sl], optimize=True)
                if project and self.projection == "element":
                    Ke = psd_project_elements(Ke)
                touched, inverse = scatter[sl.start]
                Kc = (touched, np.bincount(inverse, Ke.ravel(), minlength=touched.size))
            return W, R, flux, Kc

        data = np.zeros(K0.nnz) if order == 2 else None
        R = np.zeros(self.ndof)
        flux = np.zeros(self.ndof)
        W = 0.0
        for Wc, Rc, fc, Kc in self._map(chunk):  # summed in chunk order: deterministic
            W += Wc
            R += Rc
            flux += fc
            if Kc is not None:
                data[Kc[0]] += Kc[1]
        self.flux = flux
        K = None
        if order == 2:  # the pattern's index arrays are shared, not copied (270 MB on a P2 r/3 cell)
            K = sp.csr_matrix((data, K0.indices, K0.indptr), shape=K0.shape, copy=False)
            K.has_sorted_indices = True
        return W, R, K
