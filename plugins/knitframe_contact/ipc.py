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
yarns run on across the seams without a cut. The energy of the cell counts each periodic class of
pairs once: a point–triangle pair is kept in the translate whose point lies in the central image, an
edge–edge pair in the translate where its edge of smaller class is owned by the central image
(:meth:`knitframe_contact.ipc_mesh.PeriodicCollisionMesh.candidates`); the filtering acts on the
candidate pairs, before ipctk reduces each to its distance type, so the count does not change where
the type does. Positions are affine in q = [u (3N), h (6)], V = X + u + S_k + H·S_k, so the gradient
and Hessian in q are Pᵀ ∂W/∂V and Pᵀ ∂²W/∂V² P with the constant sparse P.

Stiffness: the solver's penalty ε (N/mm³, ``factor``·E/h as for ``penalty`` and ``mortar``) sets κ
so that the barrier's normal stiffness at d = d̂/2 of a vertex with the mean tributary area A equals
ε·A. Self-contact: a yarn meets its own other loops, but not its own material: vertices of one
strand copy closer than the surface's ``exclusion`` along it never form a pair
(:meth:`knitframe_contact.ipc_mesh.PeriodicCollisionMesh.own_material_filter`), as in the
``penalty`` and ``mortar`` laws.

Broad phase: a search's candidates are kept while no vertex has moved more than ``reuse``·d̂
since it (a Verlet list, exact: :meth:`SolidIPC._collisions`), so the line search's and chord
steps' evaluations near one iterate share one search and one filtering pass.

Friction (only with a ``friction_state``): IPC's lagged smooth Coulomb friction, with the normal
forces and tangent bases of the increment's start state and the slip u_T measured from it::

    D = μ Σ_c m_c λ_c f0(|u_T,c|),   f0′(y) = y(2 − y/ε_v)/ε_v  (y < ε_v),  1  (y ≥ ε_v)

ε_v = ``slip`` × the mean surface edge length.

Repeatability: the evaluations, the friction state and the CCD run ipctk on one thread
(:func:`knitframe_contact.ipc_mesh.one_thread`). On several, the broad phase's candidate order and
the sums over pairs follow how the work fell to the threads, and two runs of the same cell gave
tensions 4 % apart after two load steps; on one they repeat bit for bit.
"""

import functools
from typing import Any, ClassVar

import attrs
import numpy as np

from knitframe import hookimpl
from knitframe import validators as v
from knitframe.errors import NumericalError
from knitframe_contact.ipc_mesh import collision_mesh, ipctk_module, one_thread

#: halvings of a step whose collision check ran out of memory before the check gives up
CCD_HALVINGS = 6

__all__ = ["SolidIPC"]


def _on_one_thread(method):
    """The method with ipctk held to one thread while it runs (:func:`one_thread`: repeatable sums)."""

    @functools.wraps(method)
    def wrapped(*args, **kwargs):
        with one_thread():
            return method(*args, **kwargs)

    return wrapped


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
        "barrier contact (Incremental Potential Contact via ipctk): no interpenetration, "
        "CCD line search (solid)"
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
        """Penalty stiffness ε (N/mm³): ``stiffness``, else ``factor`` · E / h (converted to κ per
        surface)."""
        return float(self.stiffness) if self.stiffness is not None else self.factor * modulus / size

    def master_normals(self, surface, x: np.ndarray | None = None) -> None:
        """None: the barrier acts on the flat facets, no smoothed master surface."""
        return None

    def _setup(self, surface, stiffness: float):
        ipctk = ipctk_module()
        pcm = collision_mesh(surface)
        dhat = self.dhat * pcm.edge_length
        area = float(np.mean(surface.tributary[surface.tributary > 0]))
        # κ: normal stiffness of one point–plane pair at d̂/2 equal to ε·A
        k1 = _normal_stiffness(dhat)
        return pcm, dhat, ipctk.BarrierPotential(dhat, stiffness * area / k1)

    @_on_one_thread
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

        The narrow phase is ``ccd``. The IPC Toolkit's CCD can run out of memory on a long step with
        many near pairs (std::bad_alloc; ipc-toolkit issues #39 and #99: the broad phase's space-time
        boxes and the narrow phase's interval lists grow with the trajectory). Then the first half of
        the step is checked instead, α = ½·α(½ dx), down to ``CCD_HALVINGS`` halvings, a conservative
        bound; past that a NumericalError names the failure.
        """
        ipctk = ipctk_module()
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
        ipctk = ipctk_module()
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
        ipctk = ipctk_module()
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

    @_on_one_thread
    def friction_state(
        self, surface, x: np.ndarray, h: np.ndarray | None, *, stiffness: float, reach: float, **_: Any
    ) -> IPCFrictionState:
        """Tangential pairs of the converged state x (normal forces and tangent bases lagged from it)."""
        ipctk = ipctk_module()
        pcm, dhat, B = self._setup(surface, stiffness)
        V0 = pcm.positions(x, h)
        col = self._collisions(pcm, V0, dhat)
        tc = ipctk.TangentialCollisions()
        tc.build(pcm.mesh, V0, col, B, self.friction)
        return IPCFrictionState(tc, V0)

    @_on_one_thread
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
        ipctk = ipctk_module()
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
