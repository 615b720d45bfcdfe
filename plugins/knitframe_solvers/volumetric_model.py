"""The volumetric solver's discrete problem: the periodic solid cell's energy, its contact surface, its VTU.

:class:`VolumetricModel` is ``model(q, order) -> (E, g, H, info)`` over the independent
displacements and the macro DOFs of the periodic cell (see :mod:`knitframe_solvers.volumetric`);
:func:`contact_surface` builds the two-pass solid contact surface of a cell mesh with the yarns'
strand bookkeeping; :func:`write_solid_vtu` writes a deformed state with its stresses.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from knitframe.errors import NumericalError
from knitframe.numerics.contact import SolidSurface
from knitframe.numerics.contact_search import SegmentTopology
from knitframe.numerics.periodic import N_MACRO, Lattice
from knitframe_solvers.volumetric_material import SolidForms

__all__ = ["VolumetricModel", "contact_surface", "write_solid_vtu", "section_ratio", "section_summary"]


def contact_surface(cm: Any, lattice: Lattice | None, exclusion: float | None = None) -> SolidSurface:
    """Two-pass contact surface of a cell mesh: every lateral facet is both slave and master.

    Nodes get the strand bookkeeping of their yarn (position in its strand, arc unrolled along
    the strand), so pairs closer than ``exclusion`` (default π·dk) along one strand copy — a
    tube's own cross-section — are not contacts.
    """
    n_y = len(cm.names)
    nxt = {int(cm.node_body[end[0]]): int(cm.node_body[start[0]]) for end, start, _ in cm.end_pairs}
    periodic = len(nxt) == n_y
    st, seen = [], set()
    for i in range(n_y):  # strands: cycles of the end pairs (a handful of yarns)
        if i in seen:
            continue
        cyc = [i]
        while periodic and nxt[cyc[-1]] != i:
            cyc.append(nxt[cyc[-1]])
        seen.update(cyc)
        st.append(cyc)
    strand_of, pos, offset = np.zeros(n_y, np.int64), np.zeros(n_y, np.int64), np.zeros(n_y)
    cycle, length = np.zeros(len(st), np.int64), np.zeros(len(st))
    for k, cyc in enumerate(st):
        acc = 0.0
        for p, i in enumerate(cyc):
            strand_of[i], pos[i], offset[i] = k, p, acc
            acc += cm.lengths[i]
        cycle[k], length[k] = (len(cyc) if periodic else 0), acc
    b = cm.node_body
    topo = SegmentTopology(strand_of[b], pos[b], offset[b] + cm.node_arc, cycle, length)
    excl = np.pi * 2.0 * cm.radius if exclusion is None else float(exclusion)
    all_f = np.arange(len(cm.surface))
    # the tubes' end nodes stand for their matched start nodes: the seams are continued by the images
    identify = np.arange(cm.n_nodes)
    for end, start, _ in cm.end_pairs:
        identify[end] = start
    return SolidSurface.build(cm.nodes, cm.surface, all_f, all_f, topo, excl, lattice, identify)


def section_ratio(forms: SolidForms, u: np.ndarray, F: np.ndarray | None = None) -> np.ndarray:
    """The yarn's cross-section area over its knitted area, det F / |F a| (n_el, n_qp), at displacement u.

    The compaction the yarn model's barrier limits (at s = 1, where the pre-stress leaves F = Fe).
    """
    F = forms.deformation_gradient(u) if F is None else F
    J = np.linalg.det(np.moveaxis(F, (0, 1), (-2, -1)))
    Fa = np.einsum("iJeq,Jeq->ieq", F, forms.fibre)
    return J / np.linalg.norm(Fa, axis=0)


def section_summary(forms: SolidForms, u: np.ndarray) -> dict[str, float]:
    """The section ratio det F / |F a| over the yarn's volume at displacement u: its volume-weighted
    median and 5 % quantile (the ratio below which 5 % of the yarn lies) and its smallest value at a
    quadrature point."""
    x = section_ratio(forms, u).ravel()
    order = np.argsort(x)
    x, w = x[order], forms.dx.ravel()[order]
    cdf = (np.cumsum(w) - 0.5 * w) / w.sum()
    return {
        "median": float(np.interp(0.5, cdf, x)),
        "p05": float(np.interp(0.05, cdf, x)),
        "min": float(x[0]),
    }


def write_solid_vtu(path: Path, forms: SolidForms, u: np.ndarray, s: float, pressure: np.ndarray) -> Path:
    """VTU of the deformed solid: displacement and contact pressure (points), max principal stress
    and cross-section ratio (cells).

    The maximum principal Cauchy stress σ = J⁻¹ P Fᵀ (MPa) is averaged over each element's
    quadrature points. The cross-section ratio J_T = J/√I4 = det F / |F a| is the area of the
    yarn's cross-section over its knitted area (fibre a): how far the yarn is squeezed across
    (the smallest over the element's quadrature points). P2 meshes are written as VTK quadratic
    tetrahedra (same node order as scikit-fem's P2 element).
    """
    import meshio

    mesh = forms.mesh
    X = (mesh.doflocs if forms.edofs.shape[0] == 10 else mesh.p).T
    F = forms.deformation_gradient(u)
    P = forms.stress(u, s)
    J = np.linalg.det(np.moveaxis(F, (0, 1), (-2, -1)))
    sigma = np.einsum("iJeq,kJeq->ikeq", P, F) / J
    w = forms.dx / forms.dx.sum(axis=1, keepdims=True)
    sig_e = np.einsum("ikeq,eq->eik", sigma, w)
    smax = np.linalg.eigvalsh(0.5 * (sig_e + np.swapaxes(sig_e, 1, 2)))[:, -1]
    cross = section_ratio(forms, u, F).min(axis=1)
    cell_type = "tetra10" if forms.edofs.shape[0] == 10 else "tetra"
    out = meshio.Mesh(
        X,
        [(cell_type, forms.edofs.T)],
        point_data={"displacement": u.reshape(-1, 3), "contact_pressure": pressure},
        cell_data={
            "max_principal_stress": [smax],
            "cross_section_ratio": [cross],
            "yarn": [np.asarray(getattr(forms, "element_body", np.zeros(len(smax))))],
        },
    )
    out.write(str(path))
    return Path(path)


class VolumetricModel:
    """The discrete problem: ``model(q, order) -> (E, g, H, info)`` over q = [u_independent, h].

    E is the strain energy of the yarns at the current pre-stress parameter ``s`` plus the
    contact energy plus a weak foundation ½ c |u − u₀|² on the increment from the start u₀ of the
    current load increment (the stabilisation of ABAQUS's *STATIC, STABILIZE: it holds the rigid
    modes of yarns that no contact holds yet; its share of the energy is reported). g and H are
    pulled back to q through the periodic map u = T q. Wall time is accumulated per part in
    ``timings`` (material assembly, contact, transforms).

    Contact search (``hold_candidates``): a Hessian evaluation (order 2, one per Newton iterate)
    runs the broad-phase contact search and keeps its candidate master elements; energy and
    gradient evaluations (order 0 and 1: the line search between two iterates) choose each
    point's pair among them (the laws' ``candidates``), which saves the KD-tree search there. The
    gap is the same function as with a fresh search, as the step cannot bring a pair from out of
    the reach into contact. Implicit FE codes likewise search contact once per iteration.
    """

    def __init__(
        self, cell, cm, forms, lattice, T, independent, law, surface, stiffness, reach, t_mesh, damping=0.0
    ):
        self.cell, self.cm, self.forms, self.lattice = cell, cm, forms, lattice
        self.T, self.independent = T, independent
        self.law, self.surface, self.stiffness, self.reach = law, surface, stiffness, reach
        n = 3 * cm.n_nodes
        # q → [u (3N), h (6)] for the contact terms, which also depend on h through the images
        self.Q = sp.vstack(
            [T, sp.hstack([sp.csr_matrix((N_MACRO, T.shape[1] - N_MACRO)), sp.identity(N_MACRO)])]
        ).tocsr()
        self.QT = self.Q.T.tocsr()
        self.TT = T.T.tocsr()
        self.n = n
        self.s = 1.0
        self.L_max = float(max(np.linalg.norm(lattice.L1), np.linalg.norm(lattice.L2)))
        self.X_ind = cm.nodes[independent]
        self.damping = float(damping)
        self.u0 = np.zeros(n)
        self._pull_back = (
            None  # (K's indptr and indices, M, K's diagonal positions, H's indices, indptr, shape)
        )
        self.timings = {
            "mesh": t_mesh,
            "material": 0.0,
            "contact": 0.0,
            "transform": 0.0,
            "linear_solve": 0.0,
        }
        self.friction = False  # lagged Coulomb friction (scene effect "friction")
        self.friction_state = None
        self.normals = None  # nodal normals of the smoothed P1 master surface, frozen per increment (anchor)
        self.hold_candidates = (
            False  # broad-phase contact search at order-2 evaluations only, held for order 0 and 1
        )
        self.held = None
        self.barrier = (
            False  # a barrier contact law: the line search is bounded by continuous collision detection
        )
        self.evaluations = {"energy": 0, "gradient": 0, "hessian": 0, "linear_solves": 0}

    def pull_back(self, K: sp.csr_matrix) -> sp.csr_matrix:
        """Tᵀ (K + c I) T (c the foundation's ``damping``) for a K on the material's fixed pattern.

        Each entry of H = Tᵀ K T is Σ T_ia K_ij T_jb over the entries of K, linear in K's data: with the
        pattern fixed, H.data = M·(K.data + c·[diagonal entries]) with a constant sparse M (built once,
        about one entry per entry of K since most rows of T hold a single 1). A sparse matrix–vector
        product instead of two sparse matrix products per Hessian (0.1 s against 0.4–1.4 s at P2 r/3).
        A K on another pattern gets its own map, built again.
        """
        cached = self._pull_back
        # the same pattern: the same index arrays, or equal ones (scipy may copy them when it builds K)
        same = cached is not None and (
            cached[0] is K.indptr
            and cached[1] is K.indices
            or (
                cached[0].shape == K.indptr.shape
                and cached[1].shape == K.indices.shape
                and np.array_equal(cached[0], K.indptr)
                and np.array_equal(cached[1], K.indices)
            )
        )
        if not same:
            if not K.has_sorted_indices:
                K.sort_indices()
            cached = self._pull_back = (K.indptr, K.indices, *_pull_back_map(K, self.T))
        _, _, M, diag, indices, indptr, shape = cached
        v = K.data
        if self.damping != 0.0:
            v = v.copy()
            v[diag] += self.damping
        H = sp.csr_matrix((M @ v, indices, indptr), shape=shape, copy=False)
        H.has_sorted_indices = True
        return H

    def counters(self) -> dict[str, float]:
        """Wall time so far per part (``material_s``, ``contact_s``, ``transform_s``, ``linear_solve_s``) and
        the numbers of evaluations and linear solves (``n_energy``, ``n_gradient``, ``n_hessian``,
        ``n_linear_solves``)."""
        out = {f"{k}_s": v for k, v in self.timings.items() if k != "mesh"}
        out.update({f"n_{k}": float(n) for k, n in self.evaluations.items()})
        return out

    def shrunk(self, s0: float) -> np.ndarray:
        """q of the yarns shrunk across the fibre to s0·r: u = (s0 − 1)·(transverse offset)."""
        q = np.zeros(self.T.shape[1])
        u = (s0 - 1.0) * self.cm.node_offset[self.independent]
        q[: 3 * len(self.independent)] = u.ravel()
        return q

    def grow(self, q0: np.ndarray, s_from: float, s_to: float) -> np.ndarray:
        """Pre-stress predictor from q0 (radius factor s_from) to the stress-free radius s_to·r; sets ``s``.

        The free growth of the tubes, q0 + shrunk(s_to) − shrunk(s_from), exact away from contacts;
        with a barrier law only 0.9 of the crossing-free fraction of it (CCD), as a barrier admits
        no crossing.
        """
        step = self.crossing_free(q0, self.shrunk(s_to) - self.shrunk(s_from))
        self.s = s_to
        return q0 + step

    def crossing_free(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """A predictor's move dq from q as a barrier admits it: 0.9 of its crossing-free fraction (CCD); as is
        without a barrier law."""
        return dq * (0.9 * self.step_limit(q, dq)) if self.barrier else dq

    def anchor(self, q0: np.ndarray) -> None:
        """Start a load increment at q0: the foundation pulls towards this state, and with friction the
        contact pairs of q0 (normal forces, master points) are frozen for the increment's slip."""
        self.u0 = self.T @ q0
        self.friction_state = None
        self.held = None
        x = self.cm.nodes + self.u0.reshape(-1, 3)
        # no contact, or a law without a smoothed master surface: no frozen normals
        self.normals = None if self.law is None else self.law.master_normals(self.surface, x)
        if self.friction:
            self.friction_state = self.law.friction_state(
                self.surface, x, q0[-N_MACRO:], stiffness=self.stiffness, reach=self.reach, **self._normals()
            )

    def step_limit(self, q: np.ndarray, dq: np.ndarray) -> float:
        """Largest fraction α ≤ 1 of the step dq from q along which no yarn surfaces cross (the law's CCD)."""
        t0 = time.perf_counter()
        x = self.cm.nodes + (self.T @ q).reshape(-1, 3)
        dx = (self.T @ dq).reshape(-1, 3)
        try:
            return self.law.step_limit(
                self.surface, x, q[-N_MACRO:], dx, dq[-N_MACRO:], stiffness=self.stiffness
            )
        finally:
            self.timings["contact"] += time.perf_counter() - t0

    def _normals(self) -> dict[str, np.ndarray]:
        return {} if self.normals is None else {"normals": self.normals}

    def force_flux(self, gc: np.ndarray | None) -> float:
        """Average nodal force flux q̃ (N) of the last gradient evaluation.

        q̃ = mean over the loaded nodes of |f_a|, f_a = Σ_e |R_e,a| + |g_contact,a| (3-vectors of
        absolute element and contact nodal forces): the force level through the mesh, which does
        not cancel at equilibrium. ABAQUS tests residuals against 0.005 of its time average.
        """
        f = np.zeros(self.n) if self.forms.flux is None else self.forms.flux.copy()
        if gc is not None:
            f += np.abs(np.asarray(gc)[: self.n])
        node = np.linalg.norm(f.reshape(-1, 3), axis=1)
        loaded = node[node > 0]
        return float(loaded.mean()) if loaded.size else 0.0

    def __call__(self, q: np.ndarray, order: int, projected: bool = False) -> tuple[float, Any, Any, dict]:
        """(E, g, H, info) at q; ``projected``: the solid's tangent PSD-projected per quadrature point."""
        self.evaluations[("energy", "gradient", "hessian")[order]] += 1
        t0 = time.perf_counter()
        u = self.T @ q
        h = q[-N_MACRO:]
        self.timings["transform"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        try:
            E, R, K = self.forms.evaluate(u, self.s, order, project=projected)
        except NumericalError as e:  # an inverted element: inadmissible, the line search backs off
            self.timings["material"] += time.perf_counter() - t0
            return np.inf, None, None, {"diagnostic": str(e)}
        if not np.isfinite(E):
            self.timings["material"] += time.perf_counter() - t0
            return np.inf, None, None, {"diagnostic": "an element is inverted (det F <= 0)"}
        self.timings["material"] += time.perf_counter() - t0
        info: dict[str, Any] = {"active": 0, "max_penetration": 0.0}
        gc = Hc = None
        if self.law is not None:
            t0 = time.perf_counter()
            x = self.cm.nodes + u.reshape(-1, 3)
            kw = {"friction_state": self.friction_state} if self.friction_state is not None else {}
            kw.update(self._normals())
            if self.hold_candidates and order < 2 and self.held is not None:
                kw["candidates"] = self.held
            Ec, gc, Hc, info = self.law.evaluate(
                self.surface, x, h, order, stiffness=self.stiffness, reach=self.reach, **kw
            )
            if self.hold_candidates and order == 2:
                self.held = info.get("candidates")
            info.pop("candidates", None)
            E += Ec
            self.timings["contact"] += time.perf_counter() - t0
        du = u - self.u0
        E_stab = 0.5 * self.damping * float(du @ du)
        E += E_stab
        info["stabilisation_energy"] = E_stab
        if order == 0:
            return E, None, None, info
        info["flux"] = self.force_flux(gc)
        t0 = time.perf_counter()
        g = self.TT @ (R + self.damping * du)
        if gc is not None:
            g = g + self.QT @ gc
        H = None
        if order == 2:
            H = self.pull_back(K)
            if Hc is not None and Hc.nnz:
                Hq = self.QT @ Hc @ self.Q
                # sorted rows: scipy then merges the two canonical matrices (the same sums) into a sorted H,
                # which the Newton driver slices into the solver's CSR without a round trip through CSC
                Hq.sort_indices()
                H = H + Hq
            H = H.tocsr()
        self.timings["transform"] += time.perf_counter() - t0
        if not np.all(np.isfinite(g)):
            raise NumericalError("volumetric: non-finite residual")
        return E, g, H, info


def _pull_back_map(K: sp.csr_matrix, T: sp.csr_matrix):
    """M with (Tᵀ K T).data = M @ K.data for every K on K's pattern, the positions of K's diagonal, and the
    pattern (indices, indptr, shape) of Tᵀ K T in sorted CSR order."""
    T = sp.csr_matrix(T)
    nk = K.nnz
    I = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
    J = K.indices.astype(np.int64)
    cnt = np.diff(T.indptr)

    def expand(p, rows):  # every (entry p, T's entry in row rows[p]): p repeated, T's column and value
        c = cnt[rows]
        pe = np.repeat(p, c)
        start = np.repeat(T.indptr[rows], c)
        k = np.arange(pe.size) - np.repeat(np.cumsum(c) - c, c)
        return pe, T.indices[start + k].astype(np.int64), T.data[start + k]

    p1, a, ta = expand(np.arange(nk), I)
    p2, b, tb = expand(np.arange(p1.size), J[p1])
    p, a, w = p1[p2], a[p2], ta[p2] * tb
    n = T.shape[1]
    key, row = np.unique(a * n + b, return_inverse=True)  # row-major sorted: CSR order
    M = sp.csr_matrix((w, (row, p)), shape=(key.size, nk))
    rows_h = key // n
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows_h, minlength=n))])
    idx = np.int32 if max(n, key.size) < 2**31 else np.int64
    diag = np.flatnonzero(I == J)
    return M, diag, (key % n).astype(idx), indptr.astype(idx), (n, n)
