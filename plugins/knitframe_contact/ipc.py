"""Contact law ``ipc``: barrier contact of Incremental Potential Contact (Li et al. 2020) through ipctk.

The yarn surfaces (linear triangles; a quadratic facet is split into four through its edge
nodes) never interpenetrate: every pair of surface primitives closer than the activation
distance d̂ — point–triangle, edge–edge, edge–point, point–point, with the closest-point type
chosen by ipctk — carries the clamped log barrier::

    W = κ Σ_c m_c b(d_c),   b(d) = −(d − d̂)² ln(d / d̂)  for 0 < d < d̂,   0 for d ≥ d̂

(m_c: how many point–triangle or edge–edge pairs share the reduced pair c, as in IPC), which is
C² in the positions (edge–edge pairs near parallel are mollified) and grows without
bound as d → 0. There is no signed gap, no closest-point projection onto a curved facet and no
contact pairing to switch: W is a smooth function of the positions wherever it is finite, and
the line search keeps it finite by continuous collision detection (:meth:`SolidIPC.step_limit`:
the largest fraction of a Newton step along which no primitives cross). The Hessian of each
pair is projected to positive semi-definite (``psd``), as in IPC's projected Newton.

Periodic cell. The cell's surface and its periodic images (the shifts F̄·S_k of
:mod:`knitframe.numerics.periodic`, S_k = k1 L1 + k2 L2) form one collision mesh whose vertices are
(node, image) pairs; a tube's end nodes are their matched start nodes of the next image, so the
yarns run on across the seams without a cut. The energy of the cell counts each periodic class
of pairs once: a point–triangle pair is kept in the translate whose point lies in the central
image, an edge–edge pair in the translate where its edge of smaller class is owned by the
central image (:meth:`PeriodicCollisionMesh.candidates`); the filtering acts on the candidate
pairs, before ipctk reduces each to its distance type, so the count does not change where the
type does. Positions are
affine in q = [u (3N), h (6)], V = X + u + S_k + H·S_k, so the gradient and Hessian in q are
Pᵀ ∂W/∂V and Pᵀ ∂²W/∂V² P with the constant sparse P.

Stiffness: the solver's penalty ε (N/mm³, ``factor``·E/h as for ``penalty`` and ``mortar``) sets
κ so that the barrier's normal stiffness at d = d̂/2 of a vertex with the mean tributary area A
equals ε·A. Self-contact: a yarn meets its own other loops, but not its own material: vertices of one
strand copy closer than the surface's ``exclusion`` along it never form a pair
(:meth:`PeriodicCollisionMesh.own_material_filter`), as in the ``penalty`` and ``mortar`` laws.

Broad phase: a search's candidates are kept while no vertex has moved more than ``reuse``·d̂
since it (a Verlet list, exact: :meth:`SolidIPC._collisions`), so the line search's and chord
steps' evaluations near one iterate share one search and one filtering pass.

Friction (only with a ``friction_state``): IPC's lagged smooth Coulomb friction, with the normal
forces and tangent bases of the increment's start state and the slip u_T measured from it::

    D = μ Σ_c m_c λ_c f0(|u_T,c|),   f0′(y) = y(2 − y/ε_v)/ε_v  (y < ε_v),  1  (y ≥ ε_v)

ε_v = ``slip`` × the mean surface edge length.
"""

from __future__ import annotations

import functools
import itertools
import operator
from typing import Any, ClassVar

import attrs
import numpy as np
import scipy.sparse as sp

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.errors import NumericalError
from knitframe.numerics.periodic import N_MACRO, macro_index

#: halvings of a step whose collision check ran out of memory before the check gives up
CCD_HALVINGS = 6
#: staggered binnings of the own-material exclusion (pairs within (1 − 1/n) × exclusion along a strand excluded)
EXCLUSION_BINNINGS = 4

__all__ = ["SolidIPC", "PeriodicCollisionMesh"]


def _ipctk():
    try:
        import ipctk
    except ImportError as e:  # pragma: no cover - ipctk is a dependency
        raise NumericalError("contact law 'ipc' needs ipctk: pip install ipctk") from e
    return ipctk


class PeriodicCollisionMesh:
    """The cell's surface with its periodic images as one ipctk collision mesh.

    Vertices are (canonical node, image k) pairs, those of the central image first
    (``n_center``); ``node`` and ``image`` hold them. ``P`` maps q = [u (3N), h (6)] to the
    stacked vertex positions minus ``V_rest`` (mm).
    """

    def __init__(self, surface, ring: int = 2, margin: float = 0.35):
        ipctk = _ipctk()
        X = surface.X
        N = surface.n_nodes
        canon = np.arange(N) if surface.identify is None else np.asarray(surface.identify, np.int64)
        lat = surface.lattice
        tri = np.asarray(surface.triangles, np.int64)
        if lat is None:
            k_node = np.zeros((N, 2), np.int64)
            images = np.zeros((1, 2), np.int64)
        else:
            L = np.column_stack([lat.L1[:2], lat.L2[:2]])
            k_node = np.rint(np.linalg.solve(L, (X - X[canon])[:, :2].T).T).astype(np.int64)
            if np.abs(lat.reference_shift(k_node) - (X - X[canon])).max() > 1e-6 * (1.0 + np.abs(X).max()):
                raise NumericalError(
                    "ipc: an identified node is not a lattice image of the node it stands for"
                )
            used = np.unique(canon[tri])
            lo, hi = X[used].min(axis=0), X[used].max(axis=0)
            grow = margin * max(np.linalg.norm(lat.L1), np.linalg.norm(lat.L2))
            r = range(-ring, ring + 1)
            cand = np.array([(a, b) for a in r for b in r], np.int64)
            S = lat.reference_shift(cand)
            overlap = np.all(
                (lo[None, :2] + S[:, :2] <= hi[:2] + grow) & (hi[None, :2] + S[:, :2] >= lo[:2] - grow),
                axis=1,
            )
            images = cand[overlap]
            images = images[np.argsort(np.abs(images).sum(axis=1), kind="stable")]
        # every image's triangles, their corners mapped to (canonical node, image)
        c_all = np.broadcast_to(canon[tri][None], (len(images),) + tri.shape)
        k_all = images[:, None, None, :] + k_node[tri][None]
        span = int(np.abs(k_all).max(initial=0)) + 1
        width = 2 * span + 1
        key = (c_all * width + (k_all[..., 0] + span)) * width + (k_all[..., 1] + span)
        uniq, inv = np.unique(key.ravel(), return_inverse=True)
        node = uniq // (width * width)
        kk = np.column_stack([(uniq // width) % width - span, uniq % width - span])
        center = (kk[:, 0] == 0) & (kk[:, 1] == 0)
        faces = inv.reshape(-1, 3)
        if lat is not None:
            # image triangles far from the central image only cost time: keep those with a corner in
            # the central image or within the margin of its bounding box (reference positions)
            Vr = X[node] + lat.reference_shift(kk)
            lo, hi = Vr[center].min(axis=0) - grow, Vr[center].max(axis=0) + grow
            near = center | np.all((Vr >= lo) & (Vr <= hi), axis=1)
            faces = faces[near[faces].any(axis=1)]
        used = np.zeros(len(node), bool)
        used[faces.ravel()] = True
        used |= center
        order = np.flatnonzero(used)[np.argsort(~center[used], kind="stable")]  # central image first
        rank = np.full(len(node), -1, np.int64)
        rank[order] = np.arange(len(order))
        self.node = node[order]
        self.image = kk[order]
        self.n_center = int(center.sum())
        self.faces = rank[faces].astype(np.int32)
        shift = np.zeros((len(self.node), 3)) if lat is None else lat.reference_shift(self.image)
        self.V_rest = X[self.node] + shift
        self.n_nodes = N
        nv = len(self.node)
        rows = np.arange(3 * nv)
        cols = (3 * self.node[:, None] + np.arange(3)[None, :]).ravel()
        blocks = [sp.csr_matrix((np.ones(3 * nv), (rows, cols)), shape=(3 * nv, 3 * N + N_MACRO))]
        if lat is not None:
            S = lat.reference_shift(self.image)  # ∂V_i/∂H_ij = S_k,j
            r_, c_, d_ = [], [], []
            for i in range(3):
                for j in range(2):
                    r_.append(3 * np.arange(nv) + i)
                    c_.append(np.full(nv, 3 * N + macro_index(i, j)))
                    d_.append(S[:, j])
            blocks.append(
                sp.csr_matrix(
                    (np.concatenate(d_), (np.concatenate(r_), np.concatenate(c_))),
                    shape=(3 * nv, 3 * N + N_MACRO),
                )
            )
        self.P = sum(blocks[1:], blocks[0]).tocsr()
        self.PT = self.P.T.tocsr()
        self.lattice = lat
        edges = ipctk.edges(self.faces)
        self.mesh = ipctk.CollisionMesh(self.V_rest, edges, self.faces)
        self.mesh.can_collide = ipctk.make_static_obstacle_filter(self.n_center)
        own = self.own_material_filter(surface)
        if own is not None:
            self.mesh.can_collide = self.mesh.can_collide & own
        self.edges = np.asarray(self.mesh.edges)
        # each edge's periodic class (its two canonical nodes and their relative image) and owner: the
        # translate whose first end (the smaller canonical node) lies in the central image
        a, b = self.edges[:, 0], self.edges[:, 1]
        swap = (self.node[a] > self.node[b]) | ((self.node[a] == self.node[b]) & (b < a))
        first, second = np.where(swap, b, a), np.where(swap, a, b)
        rel = self.image[second] - self.image[first]
        w = 2 * int(np.abs(rel).max(initial=0)) + 1
        self.edge_class = (
            ((self.node[first] * N + self.node[second]) * w + rel[:, 0] + w // 2) * w + rel[:, 1] + w // 2
        )
        self.edge_image = self.image[first]
        self.edge_owned = np.all(self.image[first] == 0, axis=1)
        #: the last broad-phase search (positions, candidates, d̂, reuse reach) kept by SolidIPC._collisions, and
        #: how many searches ran
        self.held = None
        self.searches = 0
        # mean edge length of the cell's own surface (each triangle edge once per triangle), mm
        corners = X[tri]
        self.edge_length = float(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).mean())

    def own_material_filter(self, surface, n_bins: int = EXCLUSION_BINNINGS):
        """ipctk filter of the pairs of a yarn with its own material: vertices of one strand copy within
        the surface's ``exclusion`` along it never collide (None when nothing is excluded).

        A vertex (node n, image k) lies on strand copy (strand, k₂, base) at unrolled arc a
        (:meth:`knitframe.numerics.contact_search.SegmentTopology.unrolled`). ipctk filters by vertex patches
        (equivalence classes), so the exclusion is ``n_bins`` staggered binnings of a into bins of
        length ℓ = exclusion, offset by ℓ/n_bins: a pair is excluded when its two vertices share a bin
        in any binning. A pair |Δa| < (1 − 1/n_bins)·ℓ apart shares one (its interval holds at most
        n_bins − 1 bin boundaries, each of another binning); a pair ≥ ℓ apart shares none. So pairs
        within 0.75 × exclusion (n_bins = 4) are always excluded and pairs beyond it never, as the
        ``penalty`` and ``mortar`` laws exclude them: where a transversely soft tube is squashed, its
        surface folds onto itself, and barrier pairs between the folds (a tube's own material, not a
        contact) had stalled the Newton steps. ipctk keeps an edge–edge or face–vertex candidate when
        any of its vertex pairs may collide, so pairs straddling a bin are kept.
        """
        ipctk = _ipctk()
        topo, excl = surface.topology, float(surface.exclusion)
        if topo is None or not excl > 0.0:
            return None
        base, arc = topo.unrolled(self.node, self.image[:, 0])
        copy = np.column_stack([topo.strand[self.node], self.image[:, 1], base])
        if not np.isfinite(excl):  # no self-contact: a strand copy never meets itself
            _, pid = np.unique(copy, axis=0, return_inverse=True)
            return ipctk.make_vertex_patches_filter(pid.astype(np.int32).reshape(-1, 1))
        out = None
        for j in range(n_bins):
            bins = np.floor(arc / excl + j / n_bins).astype(np.int64)
            _, pid = np.unique(np.column_stack([copy, bins]), axis=0, return_inverse=True)
            f = ipctk.make_vertex_patches_filter(pid.astype(np.int32).reshape(-1, 1))
            out = f if out is None else out & f
        return out

    def positions(self, x: np.ndarray, h: np.ndarray | None) -> np.ndarray:
        """Vertex positions (nv, 3) for node positions x (N, 3) and macro DOFs h."""
        V = np.asarray(x)[self.node]
        if self.lattice is not None:
            V = V + self.lattice.shift(self.image, np.zeros(N_MACRO) if h is None else h)
        return np.asfortranarray(V)

    def displacement(self, dx: np.ndarray, dh: np.ndarray | None) -> np.ndarray:
        """Vertex displacements (nv, 3) for node displacements dx (N, 3) and a macro step dh."""
        dV = np.asarray(dx)[self.node]
        if self.lattice is not None and dh is not None:  # the images' shifts move by ΔH·S_k
            dV = dV + self.lattice.affine(self.lattice.reference_shift(self.image), dh)
        return dV

    def candidates(self, V: np.ndarray, inflation: float):
        """Broad-phase candidates within ``inflation`` of each other, one representative per periodic class.

        A point–triangle pair is kept when its point lies in the central image (each class of
        pairs has exactly one such translate). An edge–edge pair {e1, e2} is kept in the translate
        where the edge of the smaller canonical id (its end nodes and their relative image) is
        owned, i.e. has its first end node (the smaller canonical node) in the central image;
        between an edge and its own image, the translate whose second edge lies on the positive
        side. The energy then counts each periodic pair once, whatever the reduced pair type
        (point–edge, point–point) its distance takes: a weight per reduced pair would jump where
        the type switches.
        """
        ipctk = _ipctk()
        cand = ipctk.Candidates()
        cand.build(self.mesh, V, inflation)
        out = ipctk.Candidates()
        fv = cand.fv_candidates
        if len(fv):
            keep = np.flatnonzero(_ids(fv, "vertex_id")[:, 0] < self.n_center)
            out.fv_candidates = [fv[i] for i in keep]
        ee = cand.ee_candidates
        if len(ee):
            ids = _ids(ee, "edge0_id", "edge1_id")
            a, b = ids[:, 0], ids[:, 1]
            ca, cb = self.edge_class[a], self.edge_class[b]
            oa, ob = self.edge_owned[a], self.edge_owned[b]
            d = self.edge_image[b] - self.edge_image[a]
            pos = (d[:, 0] > 0) | ((d[:, 0] == 0) & (d[:, 1] > 0))
            neg = (d[:, 0] < 0) | ((d[:, 0] == 0) & (d[:, 1] < 0))
            keep = np.where(ca < cb, oa, np.where(ca > cb, ob, (oa & pos) | (ob & neg)))
            out.ee_candidates = [ee[i] for i in np.flatnonzero(keep)]
        if len(cand.ev_candidates) or len(
            cand.vv_candidates
        ):  # pragma: no cover - only for codimensional meshes
            raise NumericalError(
                "ipc: edge–vertex and vertex–vertex candidates (codimensional surfaces) are not supported"
            )
        return out


def _ids(objs: list, *names: str) -> np.ndarray:
    """(len(objs), len(names)) int64 array of the named integer attributes of ipctk candidates (no
    intermediate tuples: about 2.5 times faster than a list comprehension on 10⁵–10⁶ candidates)."""
    get = operator.attrgetter(*names)
    flat = get if len(names) > 1 else (lambda o: (get(o),))
    return np.fromiter(
        itertools.chain.from_iterable(map(flat, objs)), np.int64, len(names) * len(objs)
    ).reshape(-1, len(names))


_CACHE: dict[int, tuple[Any, PeriodicCollisionMesh]] = {}


def collision_mesh(surface) -> PeriodicCollisionMesh:
    """The (cached) periodic collision mesh of a solid contact surface."""
    hit = _CACHE.get(id(surface))
    if hit is not None and hit[0] is surface:
        return hit[1]
    pcm = PeriodicCollisionMesh(surface)
    if len(_CACHE) > 8:
        _CACHE.clear()
    _CACHE[id(surface)] = (surface, pcm)
    return pcm


@attrs.frozen
class IPCFrictionState:
    """Lagged friction of an increment: ipctk's tangential pairs at its start and the start positions."""

    collisions: Any
    V0: np.ndarray

    def __len__(self) -> int:
        return len(self.collisions)


@attrs.frozen
class SolidIPC:
    """Barrier contact (IPC, through ipctk) for solid meshes: intersection-free, smooth, with CCD."""

    name: ClassVar[str] = "ipc"
    description: ClassVar[str] = (
        "barrier contact (Incremental Potential Contact via ipctk): no interpenetration, CCD line search (solid)"
    )
    discretisation: ClassVar[str] = "solid"
    #: a barrier: infinite energy at touching surfaces, each step bounded by :meth:`step_limit`
    barrier: ClassVar[bool] = True
    #: evaluate keeps its own broad-phase candidates (a Verlet list), it takes none
    holds_candidates: ClassVar[bool] = False
    #: no load strain limit: no signed gap's pairing to switch
    finishes_strain: ClassVar[float | None] = None

    #: ε, N/mm³; default factor·E/h
    stiffness: float | None = attrs.field(default=None, validator=v.optional(v.positive))
    #: ε = factor · E / h when stiffness is not given, -
    factor: float = attrs.field(default=10.0, validator=v.positive)
    #: activation distance d̂ / mean surface edge length, -
    dhat: float = attrs.field(default=0.1, validator=v.in_range(1e-4, 1.0))
    #: Coulomb coefficient μ (used only with a friction state), -
    friction: float = attrs.field(default=0.3, validator=v.in_range(0.0, 10.0))
    #: friction regularisation ε_v / mean surface edge length, -
    slip: float = attrs.field(default=0.05, validator=v.positive)
    #: project each pair's Hessian to positive semi-definite (IPC's projected Newton)
    psd: bool = True
    #: broad-phase candidates are kept while no vertex has moved over reuse·d̂ since the search, which
    #: inflates each box by (½ + reuse)·d̂ (exact: a pair now within d̂ was then within d̂ + 2·reuse·d̂); 0
    #: searches at every evaluation, -
    reuse: float = attrs.field(default=0.5, validator=v.in_range(0.0, 10.0))
    #: narrow-phase CCD of the line search: "additive" (ACCD, Li et al. 2021: iterative, no interval lists;
    #: fast when pairs sit far inside d̂) or "tight-inclusion" (Wang et al. 2021: interval subdivision,
    #: ipctk's default; on the tight SL10 cell, 5e-8 mm gaps, one check took 60-70 s and 1.7 GB), -
    ccd: str = attrs.field(default="additive", validator=v.one_of(("additive", "tight-inclusion")))

    def penalty(self, modulus: float, size: float) -> float:
        """Penalty stiffness ε (N/mm³): ``stiffness``, else ``factor`` · E / h (converted to κ per surface)."""
        return float(self.stiffness) if self.stiffness is not None else self.factor * modulus / size

    def master_normals(self, surface, x: np.ndarray | None = None) -> None:
        """None: the barrier acts on the flat facets, no smoothed master surface."""
        return None

    def _setup(self, surface, stiffness: float):
        ipctk = _ipctk()
        pcm = collision_mesh(surface)
        dhat = self.dhat * pcm.edge_length
        area = float(np.mean(surface.tributary[surface.tributary > 0]))
        # κ: normal stiffness of one point–plane pair at d̂/2 equal to ε·A
        k1 = _normal_stiffness(dhat)
        return pcm, dhat, ipctk.BarrierPotential(dhat, stiffness * area / k1)

    def step_limit(
        self,
        surface,
        x: np.ndarray,
        h: np.ndarray | None,
        dx: np.ndarray,
        dh: np.ndarray | None,
        *,
        stiffness: float,
    ) -> float:
        """Largest α ∈ [0, 1] such that the straight path x + t·α·dx (t ∈ [0, 1]) has no crossing (CCD).

        The narrow phase is ``ccd``. The IPC Toolkit's CCD can run out of memory on a long step with many near pairs
        (std::bad_alloc; ipc-toolkit issues #39 and #99: the broad phase's space-time boxes and the
        narrow phase's interval lists grow with the trajectory). Then the first half of the step is
        checked instead, α = ½·α(½ dx), down to ``CCD_HALVINGS`` halvings, a conservative bound; past
        that a NumericalError names the failure.
        """
        ipctk = _ipctk()
        pcm, _, _ = self._setup(surface, stiffness)
        V0 = pcm.positions(x, h)
        D = pcm.displacement(dx, dh)
        scale = 1.0
        for _ in range(CCD_HALVINGS + 1):
            try:
                return scale * float(
                    ipctk.compute_collision_free_stepsize(
                        pcm.mesh, V0, np.asfortranarray(V0 + scale * D), narrow_phase_ccd=self._narrow_phase()
                    )
                )
            except MemoryError:
                scale *= 0.5
        raise NumericalError(
            f"ipc: the collision check of a step ran out of memory even for 1/{2**CCD_HALVINGS:d} "
            f"of it (largest node move {float(np.max(np.abs(D))):.3g} mm)"
        )

    def _narrow_phase(self):
        """ipctk's narrow-phase CCD of ``ccd``, each with ipctk's defaults (conservative rescaling 0.9 for
        ACCD, 0.8 for Tight Inclusion: the step stops at that fraction of the time of impact)."""
        ipctk = _ipctk()
        return ipctk.AdditiveCCD() if self.ccd == "additive" else ipctk.TightInclusionCCD()

    def _collisions(self, pcm, V, dhat):
        """ipctk's normal collisions of V: the pairs closer than d̂ among the broad-phase candidates.

        The candidates of a search at V_s with box inflation ρ = (½ + ``reuse``)·d̂ hold every pair
        closer than 2ρ at V_s (boxes inflated by ρ overlap when their primitives are closer than
        2ρ). Primitive distances are 1-Lipschitz in the largest vertex move δ = max_i |V_i − V_s,i|
        (each point of a primitive is a convex combination of its vertices), so while δ ≤ ``reuse``·d̂
        a pair now closer than d̂ was closer than d̂ + 2δ ≤ 2ρ at V_s and is among them: the set of
        collisions is exactly that of a fresh search (a Verlet list). The search, and the periodic
        filtering of its candidates in Python, then runs only when a vertex has moved further.
        """
        ipctk = _ipctk()
        held = pcm.held
        reach = self.reuse * dhat
        if (
            held is None
            or held[2] != dhat
            or held[3] != reach
            or held[0].shape != V.shape
            or float(np.max(np.einsum("ij,ij->i", V - held[0], V - held[0]), initial=0.0)) > reach * reach
        ):
            held = (np.array(V, copy=True), pcm.candidates(V, 0.5 * dhat + reach), dhat, reach)
            pcm.held = held
            pcm.searches += 1
        col = ipctk.NormalCollisions()
        col.build(held[1], pcm.mesh, V, dhat)
        return col

    def friction_state(
        self, surface, x: np.ndarray, h: np.ndarray | None, *, stiffness: float, reach: float, **_: Any
    ) -> IPCFrictionState:
        """Tangential pairs of the converged state x (normal forces and tangent bases lagged from it)."""
        ipctk = _ipctk()
        pcm, dhat, B = self._setup(surface, stiffness)
        V0 = pcm.positions(x, h)
        col = self._collisions(pcm, V0, dhat)
        tc = ipctk.TangentialCollisions()
        tc.build(pcm.mesh, V0, col, B, self.friction)
        return IPCFrictionState(tc, V0)

    def evaluate(
        self,
        surface,
        x: np.ndarray,
        h: np.ndarray | None,
        order: int,
        *,
        stiffness: float,
        reach: float,
        friction_state: IPCFrictionState | None = None,
        **_: Any,
    ) -> tuple[float, Any, Any, dict[str, Any]]:
        """Energy W (N·mm), gradient and Hessian in q = [u (3N), h (6)], and diagnostics.

        ``info``: ``active`` pairs within d̂, ``min_distance`` (mm), ``max_penetration`` (always 0:
        the barrier admits none), nodal ``pressure`` (|contact force| / tributary area, MPa) and
        ``force`` (sum of the pair force magnitudes, N).
        """
        ipctk = _ipctk()
        pcm, dhat, B = self._setup(surface, stiffness)
        V = pcm.positions(x, h)
        col = self._collisions(pcm, V, dhat)
        E = float(B(col, pcm.mesh, V))
        info: dict[str, Any] = {
            "active": len(col),
            "max_penetration": 0.0,
            "min_distance": float(np.sqrt(col.compute_minimum_distance(pcm.mesh, V))) if len(col) else dhat,
        }
        if not np.isfinite(E):
            return np.inf, None, None, {"diagnostic": "ipc: surfaces touch or cross", **info}
        fr = friction_state is not None and self.friction > 0 and len(friction_state)
        if fr:
            D = ipctk.FrictionPotential(self.slip * pcm.edge_length)
            U = np.asfortranarray(V - friction_state.V0)
            Ef = float(D(friction_state.collisions, pcm.mesh, U))
            E += Ef
            info["friction_energy"] = Ef
        if order == 0:
            return E, None, None, info
        gV = B.gradient(col, pcm.mesh, V)
        if fr:
            gV = gV + D.gradient(friction_state.collisions, pcm.mesh, U)
        G = pcm.PT @ gV
        f = np.linalg.norm(G[: 3 * pcm.n_nodes].reshape(-1, 3), axis=1)
        trib = surface.tributary
        info["pressure"] = np.where(trib > 0, f / np.where(trib > 0, trib, 1.0), 0.0)
        info["force"] = float(f.sum())
        Hm = None
        if order == 2:
            proj = ipctk.PSDProjectionMethod.CLAMP if self.psd else ipctk.PSDProjectionMethod.NONE
            HV = B.hessian(col, pcm.mesh, V, proj)
            if fr:
                HV = HV + D.hessian(friction_state.collisions, pcm.mesh, U, proj)
            Hm = (pcm.PT @ HV @ pcm.P).tocsr()
        return E, G, Hm, info


@functools.lru_cache(maxsize=64)
def _normal_stiffness(dhat: float) -> float:
    """d²W/dz² of one unit-stiffness point–triangle pair at distance d̂/2 (central differences)."""
    import ipctk

    B = ipctk.BarrierPotential(dhat, 1.0)

    def energy(z: float) -> float:
        V = np.array([[-1.0, -1.0, 0.0], [2.0, -1.0, 0.0], [-1.0, 2.0, 0.0], [0.0, 0.0, z]])
        m = ipctk.CollisionMesh(
            V, ipctk.edges(np.array([[0, 1, 2]], np.int32)), np.array([[0, 1, 2]], np.int32)
        )
        c = ipctk.NormalCollisions()
        c.build(m, V, dhat)
        return float(B(c, m, V))

    z, e = 0.5 * dhat, 1e-3 * dhat
    return (energy(z + e) - 2.0 * energy(z) + energy(z - e)) / e**2


@hookimpl
def register_contact_laws(register):
    register(SolidIPC)
