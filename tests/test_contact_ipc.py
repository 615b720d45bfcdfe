"""Contact law ``ipc``: barrier contact through ipctk (derivatives, periodic weights, CCD, Hertz)."""

from __future__ import annotations

import attrs
import numpy as np
import pytest
import skfem
from contact_solid_helpers import hertz_supports, iso, join, nodes, quarter_cylinder_on_flat, solve, surface
from knitframe_contact.ipc import SolidIPC
from knitframe_contact.ipc_mesh import collision_mesh
from knitframe_linsolvers.direct import direct
from knitframe_solvers.volumetric_material import SolidForms
from knitframe_yarns.law import line_contact_approach

from knitframe.numerics.contact import SolidSurface
from knitframe.numerics.contact_search import SegmentTopology
from knitframe.numerics.mesh import surface_facets
from knitframe.numerics.newton import NewtonOptions, minimise
from knitframe.numerics.periodic import Lattice
from knitframe.plugins import get_registry


def test_ipc_is_registered_for_solids():
    law = get_registry()["contact_law"]["ipc"]()
    assert law.discretisation == "solid" and law.penalty(1.0, 0.1) == pytest.approx(100.0)


def _dhat(law: SolidIPC, surf: SolidSurface) -> float:
    return law.dhat * collision_mesh(surf).edge_length


@pytest.fixture(scope="module", params=[1, 2])
def cylinder(request):
    order = request.param
    mesh, body, arc, top = quarter_cylinder_on_flat(1.0, 0.01 if order == 1 else 0.02, 0.25, 0.05, order)
    return mesh, body, surface(mesh, body, arc, top)


def test_ipc_derivatives_match_finite_differences(cylinder):
    """Barrier gradient = FD of the energy, Hessian (unprojected) = FD of the gradient, on P1 and split P2
    facets."""
    mesh, body, surf = cylinder
    law = SolidIPC(psd=False)
    X = nodes(mesh)
    n = 3 * len(X)
    rng = np.random.default_rng(0)
    u = np.zeros(n)
    u[1::3] = 0.4 * _dhat(law, surf) * (body == 0)  # the cylinder hovers within the barrier's reach
    u += 1e-3 * _dhat(law, surf) * rng.normal(size=n)
    du = rng.normal(size=n) * np.repeat(body == 0, 3)

    def f(v, order):
        return law.evaluate(surf, X + v.reshape(-1, 3), None, order, stiffness=1e3, reach=0.1)

    E, g, H, info = f(u, 2)
    assert info["active"] > 0 and 0 < info["min_distance"] < _dhat(law, surf) and E > 0
    h = 1e-6 * _dhat(law, surf)  # the mollifier of near-parallel edge pairs is sharp: small steps
    fd_g = (f(u + h * du, 0)[0] - f(u - h * du, 0)[0]) / (2 * h)
    fd_H = (f(u + h * du, 1)[1] - f(u - h * du, 1)[1])[:n] / (2 * h)
    assert g[:n] @ du == pytest.approx(fd_g, rel=1e-6)
    assert np.linalg.norm(H[:n, :n] @ du - fd_H) < 1e-5 * np.linalg.norm(fd_H)


def test_ipc_projected_hessian_is_positive_semidefinite(cylinder):
    """With ``psd`` (the default) every pair's Hessian is clamped: the assembled contact Hessian has no
    negative eigenvalue."""
    mesh, body, surf = cylinder
    law = SolidIPC()
    X = nodes(mesh)
    u = np.zeros(3 * len(X))
    u[1::3] = 0.3 * _dhat(law, surf) * (body == 0)
    _, _, H, _ = law.evaluate(surf, X + u.reshape(-1, 3), None, 2, stiffness=1e3, reach=0.1)
    act = np.unique(H.nonzero()[0])
    ev = np.linalg.eigvalsh(H[act][:, act].toarray())
    assert ev.max() > 0 and ev.min() > -1e-10 * ev.max()
    # without the projection the same state has negative curvature (edge–edge and point–edge pairs)
    _, _, H0, _ = attrs.evolve(law, psd=False).evaluate(
        surf, X + u.reshape(-1, 3), None, 2, stiffness=1e3, reach=0.1
    )
    assert np.linalg.eigvalsh(H0[act][:, act].toarray()).min() < -1e-6 * ev.max()


def _block_row(count: int, gap: float):
    """``count`` unit blocks along x, each 1 − gap wide, on a lattice L1 = (count, 0, 0): each block's
    right face is ``gap`` from the next block's (or the next image's) left face."""
    blocks = [
        skfem.MeshTet1.init_tensor(
            np.linspace(k, k + 1 - gap, 3), np.linspace(0, 0.6, 3), np.linspace(0, 0.5, 3)
        )
        for k in range(count)
    ]
    m, body = join(blocks, 1)
    X = m.p.T
    facets = surface_facets(m, m.boundary_facets())
    n = len(X)
    nb = count
    topo = SegmentTopology(body, np.zeros(n, np.int64), np.zeros(n), np.zeros(nb, np.int64), np.zeros(nb))
    lattice = Lattice([float(count), 0, 0], [0, 3.0, 0])
    return (
        X,
        body,
        SolidSurface.build(X, facets, np.arange(len(facets)), np.arange(len(facets)), topo, 1.0, lattice),
    )


def test_periodic_cell_counts_each_pair_once():
    """A cell of one block touching its own image carries half the energy (and macro reaction) of the
    two-block supercell in the same state: the pair weights count each periodic pair once."""
    law = SolidIPC(dhat=0.5)
    gap = 0.04
    X1, _, s1 = _block_row(1, gap)
    X2, body2, s2 = _block_row(2, gap)
    assert _dhat(law, s1) > gap
    h = np.array([-0.01, 0.0, 0.004, 0.0, 0.002, 0.0])  # F̄: compress along x, shear, lift
    rng = np.random.default_rng(3)
    u1 = 2e-3 * rng.normal(size=X1.shape)
    shift = Lattice.H(h) @ np.array([1.0, 0.0])  # the second block sits where the first one's image is
    u2 = np.concatenate([u1, u1 + shift])
    E1, g1, _, i1 = law.evaluate(s1, X1 + u1, h, 1, stiffness=100.0, reach=0.1)
    E2, g2, _, i2 = law.evaluate(s2, X2 + u2, h, 1, stiffness=100.0, reach=0.1)
    assert i1["active"] > 0 and E1 > 0
    assert E2 == pytest.approx(2 * E1, rel=1e-10)
    n1, n2 = 3 * len(X1), 3 * len(X2)
    # each block of the supercell feels the forces of the cell's block
    assert np.allclose(
        g2[:n1], g1[:n1], atol=1e-10 * np.abs(g1).max()
    )  # the first block's forces are the cell's
    assert np.allclose(g2[n1:n2], g1[:n1], atol=1e-10 * np.abs(g1).max())


def test_periodic_derivatives_in_the_macro_dofs():
    """Gradient and Hessian in h (the image shifts F̄·S_k) match central differences."""
    law = SolidIPC(dhat=0.5, psd=False)
    X, _, surf = _block_row(1, 0.04)
    h0 = np.array([-0.01, 0.0, 0.004, 0.0, 0.002, 0.0])
    E, g, H, info = law.evaluate(surf, X, h0, 2, stiffness=100.0, reach=0.1)
    assert info["active"] > 0
    n = 3 * len(X)
    dh = np.array([1.0, 0.3, -0.2, 0.5, 0.1, 0.0])
    eps = 1e-7
    Ep = law.evaluate(surf, X, h0 + eps * dh, 1, stiffness=100.0, reach=0.1)
    Em = law.evaluate(surf, X, h0 - eps * dh, 1, stiffness=100.0, reach=0.1)
    assert g[n:] @ dh == pytest.approx((Ep[0] - Em[0]) / (2 * eps), rel=1e-6)
    assert np.allclose(H[:, n:] @ dh, (Ep[1] - Em[1]) / (2 * eps), atol=1e-6 * np.abs(H).max())


@pytest.mark.parametrize("ccd", ["additive", pytest.param("tight-inclusion", marks=pytest.mark.slow)])
def test_step_limit_stops_a_step_before_the_surfaces_cross(ccd):
    """CCD: a step that would push a block through its image is cut to a crossing-free fraction."""
    law = SolidIPC(dhat=0.1, ccd=ccd)
    gap = 0.04
    X, _, surf = _block_row(1, gap)
    dx = np.zeros_like(X)
    dx[X[:, 0] > 0.5, 0] = 0.2  # the right face moves 0.2 towards an image 0.04 away
    a = law.step_limit(surf, X, np.zeros(6), dx, np.zeros(6), stiffness=100.0)
    assert 0.0 < a < gap / 0.2
    assert np.isfinite(law.evaluate(surf, X + a * dx, np.zeros(6), 0, stiffness=100.0, reach=0.1)[0])
    assert law.step_limit(surf, X, np.zeros(6), -dx, np.zeros(6), stiffness=100.0) == 1.0


def test_step_limit_checks_half_steps_when_the_ccd_runs_out_of_memory(monkeypatch):
    """The IPC Toolkit's CCD can throw std::bad_alloc (MemoryError) on a long step: the bound is then that of
    the step's first half (scaled), still crossing-free; a step that fails at every length gives a one-line
    NumericalError."""
    import ipctk
    from knitframe_contact import ipc

    from knitframe.errors import NumericalError

    law = SolidIPC(dhat=0.1)
    X, _, surf = _block_row(1, 0.04)
    dx = np.zeros_like(X)
    dx[X[:, 0] > 0.5, 0] = 0.2
    exact = law.step_limit(surf, X, np.zeros(6), dx, np.zeros(6), stiffness=100.0)
    real = ipctk.compute_collision_free_stepsize
    longest = float(np.abs(dx).max())

    def short_only(mesh, V0, V1, **kw):
        if float(np.abs(V1 - V0).max()) > 0.3 * longest:  # "out of memory" on the full and half step
            raise MemoryError("std::bad_alloc")
        return real(mesh, V0, V1, **kw)

    monkeypatch.setattr(ipctk, "compute_collision_free_stepsize", short_only)
    a = law.step_limit(surf, X, np.zeros(6), dx, np.zeros(6), stiffness=100.0)
    assert a == pytest.approx(min(exact, 0.25), rel=0.05)  # the quarter step, within the CCD's own margin
    assert np.isfinite(law.evaluate(surf, X + a * dx, np.zeros(6), 0, stiffness=100.0, reach=0.1)[0])

    def never(mesh, V0, V1, **kw):
        raise MemoryError("std::bad_alloc")

    monkeypatch.setattr(ipctk, "compute_collision_free_stepsize", never)
    with pytest.raises(NumericalError, match=f"1/{2**ipc.CCD_HALVINGS}") as err:
        law.step_limit(surf, X, np.zeros(6), dx, np.zeros(6), stiffness=100.0)
    assert "\n" not in str(err.value)


HERTZ = {"E": 100.0, "nu": 0.3, "R": 1.0, "t": 0.05, "d": 0.02}


def _hertz_h(mesh) -> float:
    return 0.01 if isinstance(mesh, skfem.MeshTet1) and not isinstance(mesh, skfem.MeshTet2) else 0.02


def pressed_with_the_barrier(cylinder) -> tuple[float, dict]:
    """The quarter cylinder pushed d onto the rigid flat through ``ipc``: (line load N/mm, contact info)."""
    mesh, body, surf = cylinder
    E, nu, t, d = HERTZ["E"], HERTZ["nu"], HERTZ["t"], HERTZ["d"]
    law = SolidIPC(dhat=0.003)  # d̂ ≈ 2e-4 R: the barrier's layer is 1 % of the indentation
    forms = SolidForms(mesh, iso(E, nu), None)
    X, fixed, sym = hertz_supports(mesh, body)
    free = ~fixed.ravel()
    k = law.penalty(E / (1 - nu**2), _hertz_h(mesh))
    n = forms.ndof

    def fun(u, order):
        Em = forms.energy(u)
        if not np.isfinite(Em):
            return np.inf, None, None, {}
        Ec, gc, Hc, info = law.evaluate(surf, X + u.reshape(-1, 3), None, order, stiffness=k, reach=0.1)
        if order == 0 or not np.isfinite(Ec):
            return Em + Ec, None, None, info
        g = forms.residual(u) + gc[:n]
        return Em + Ec, g, (forms.tangent(u) + Hc[:n, :n]) if order == 2 else None, info

    def limit(u, du):
        return law.step_limit(surf, X + u.reshape(-1, 3), None, du.reshape(-1, 3), None, stiffness=k)

    lift = 0.5 * _dhat(law, surf)  # start apart: the barrier admits no touching state
    u = np.zeros((len(X), 3))
    u[body == 0, 1] = lift
    u = u.ravel()
    for step in np.linspace(lift, -d, 5)[1:]:
        u[3 * np.flatnonzero(sym) + 1] = step
        res = minimise(
            fun,
            u,
            free,
            solve=direct(),
            step_limit=limit,
            options=NewtonOptions(atol=1e-9, rtol=1e-9, max_iter=200, xtol=1e-13),
        )
        u = res.x
    reaction = forms.residual(u).reshape(-1, 3)
    return -2 * reaction[sym, 1].sum() / t, fun(u, 1)[3]  # line load on the whole cylinder, N/mm


def test_hertz_cylinder_on_flat_with_the_barrier(cylinder):
    """An elastic cylinder pushed onto a rigid flat through the barrier: axis approach within 5 % of Hertz."""
    f, info = pressed_with_the_barrier(cylinder)
    assert info["min_distance"] > 0
    ratio = (
        HERTZ["d"]
        / line_contact_approach(np.array([f]), HERTZ["R"], HERTZ["E"], HERTZ["nu"], rigid_partner=True)[0]
    )
    assert ratio == pytest.approx(1.0, abs=0.05)


@pytest.mark.parametrize("kind", ["penalty", "mortar"])
def test_penalty_and_mortar_carry_the_load_of_ipc(cylinder, kind):
    """The same small cell, the quarter cylinder pressed 2 % of its radius onto the flat: ``penalty`` and
    ``mortar`` carry the line load of ``ipc`` within 5 % (each also within 5 % of Hertz)."""
    mesh, body, surf = cylinder
    E, nu = HERTZ["E"], HERTZ["nu"]
    law = get_registry()["contact_law"][kind]()
    forms = SolidForms(mesh, iso(E, nu), None)
    X, fixed, sym = hertz_supports(mesh, body)
    u = np.zeros((len(X), 3))
    u[body == 0, 1] = -HERTZ["d"]
    u, _ = solve(
        forms, law, surf, u.ravel(), ~fixed.ravel(), law.penalty(E / (1 - nu**2), _hertz_h(mesh)), reach=0.2
    )
    f = -2 * forms.residual(u).reshape(-1, 3)[sym, 1].sum() / HERTZ["t"]
    f_ipc, _ = pressed_with_the_barrier(cylinder)
    assert f / f_ipc == pytest.approx(1.0, abs=0.05)


def test_energy_stays_continuous_where_the_pair_types_switch():
    """Sliding a block along its image's face: the points cross the image's facet edges (point–triangle
    pairs become point–edge pairs and back) and the energy follows its gradient without a jump."""
    law = SolidIPC(dhat=0.5)
    X, _, surf = _block_row(1, 0.1)
    h = np.zeros(6)
    assert 0.1 < _dhat(law, surf)
    right = X[:, 0] > 0.5
    slide = np.zeros_like(X)
    slide[right] = [0.0, 0.37, 0.11]  # the right half shears along the face, over several facet edges
    s = np.linspace(0.0, 1.0, 401)
    E, dE = [], []
    for t in s:
        e, g, _, info = law.evaluate(surf, X + t * slide, h, 1, stiffness=100.0, reach=0.1)
        E.append(e)
        dE.append(g[: 3 * len(X)] @ slide.ravel())
        assert info["active"] > 0
    E, dE = np.array(E), np.array(dE)
    # over every pair of samples the energy changes by the integral of its derivative (Simpson); the
    # mollifier of the initially parallel edges leaves a smooth but sharp residue (2e-3 of the largest
    # change here, falling under refinement), a weight per reduced pair type made the energy jump by
    # up to 13 times the largest change
    ds = s[1] - s[0]
    jump = np.abs(E[2::2] - E[:-2:2] - ds / 3 * (dE[:-2:2] + 4 * dE[1:-1:2] + dE[2::2]))
    assert jump.max() < 1e-2 * np.abs(E[2::2] - E[:-2:2]).max()


def _facing_blocks(arc_b: float, strand_b: int, exclusion: float):
    """Two blocks 0.02 apart across z = 0.5 (no lattice); block 1's nodes at arc ``arc_b`` on strand
    ``strand_b``."""
    lower = skfem.MeshTet1.init_tensor(np.linspace(0, 1, 4), np.linspace(0, 1, 4), np.linspace(0, 0.49, 3))
    upper = skfem.MeshTet1.init_tensor(np.linspace(0, 1, 3), np.linspace(0, 1, 3), np.linspace(0.51, 1.0, 3))
    m, body = join([lower, upper], 1)
    facets = surface_facets(m, m.boundary_facets())
    n = len(body)
    strand = np.where(body == 1, strand_b, 0)
    topo = SegmentTopology(
        strand, np.zeros(n, np.int64), np.where(body == 1, arc_b, 0.0), np.zeros(2, np.int64), np.zeros(2)
    )
    return m.p.T, SolidSurface.build(
        m.p.T, facets, np.arange(len(facets)), np.arange(len(facets)), topo, exclusion
    )


@pytest.mark.parametrize(
    ("arc_b", "strand_b", "exclusion", "pairs"),
    [
        (0.5, 0, 1.0, False),  # one strand, 0.5 apart along it: the yarn's own material
        (1.5, 0, 1.0, True),  # one strand, beyond the exclusion: self-contact
        (0.5, 1, 1.0, True),  # two strands: contact whatever their arcs
        (
            1.5,
            0,
            np.inf,
            False,
        ),  # no self-contact (scene without "self_contact"): a strand never meets itself
    ],
)
def test_pairs_of_a_yarn_with_its_own_material_are_excluded(arc_b, strand_b, exclusion, pairs):
    """Surfaces 0.02 apart, within d̂: barrier pairs form unless both lie on one strand copy within its
    exclusion."""
    law = SolidIPC(dhat=0.5)
    X, surf = _facing_blocks(arc_b, strand_b, exclusion)
    assert _dhat(law, surf) > 0.02
    E, _, _, info = law.evaluate(surf, X, None, 1, stiffness=100.0, reach=0.1)
    assert (info["active"] > 0) == pairs
    assert (E > 0) == pairs


def test_own_material_filter_excludes_within_three_quarters_of_the_exclusion_and_never_beyond_it():
    """The staggered binnings: every vertex pair of one strand copy closer than 0.75 × exclusion along it is
    refused, every pair at least the exclusion apart (or on another strand) is allowed."""
    rng = np.random.default_rng(5)
    n = 400
    X = np.column_stack([rng.uniform(0, 1, n), rng.uniform(0, 1, n), np.zeros(n)])
    tri = np.arange(n - n % 3).reshape(-1, 3)
    strand = rng.integers(0, 2, n)
    arc = rng.uniform(0, 10.0, n)
    topo = SegmentTopology(strand, np.zeros(n, np.int64), arc, np.zeros(2, np.int64), np.zeros(2))
    surf = SolidSurface.build(X, tri, np.arange(len(tri)), np.arange(len(tri)), topo, 1.3)
    pcm = collision_mesh(surf)
    f = pcm.own_material_filter(surf)
    i, j = rng.integers(0, len(pcm.node), (2, 20000))
    i, j = np.minimum(i, j), np.maximum(i, j)
    keep = i < j
    i, j = i[keep], j[keep]
    allowed = np.array([f(int(a), int(b)) for a, b in zip(i, j)])
    a, b = pcm.node[i], pcm.node[j]
    same = strand[a] == strand[b]
    d = np.abs(arc[a] - arc[b])
    assert not allowed[same & (d < 0.75 * 1.3)].any()
    assert allowed[~same | (d >= 1.3)].all()
    assert (~allowed[same & (d >= 0.75 * 1.3) & (d < 1.3)]).any()  # some between: the binnings' slack


def test_held_candidates_give_the_collisions_of_a_fresh_search(cylinder):
    """A search's candidates are reused while no vertex has moved over ``reuse``·d̂ since it: the pairs,
    energy and gradient are those of a search at every evaluation (``reuse = 0``), and a move past the
    reach searches again."""
    mesh, body, surf = cylinder
    held, fresh = SolidIPC(), SolidIPC(reuse=0.0)
    dhat = _dhat(held, surf)
    X = nodes(mesh)
    u = np.zeros((len(X), 3))
    u[:, 1] = 0.45 * dhat * (body == 0)
    pcm = collision_mesh(surf)
    pcm.held = None
    rng = np.random.default_rng(3)
    searches = []
    for m in (0.0, 0.2, 0.35, 0.49, 0.3, 1.5, 1.6):  # each vertex of the lifted body moves at most m·d̂ from u
        du = rng.uniform(-1.0, 1.0, size=(len(X), 3)) * (body == 0)[:, None] / np.sqrt(3.0)
        x = X + u + m * dhat * du
        before = pcm.searches
        E1, g1, _, i1 = held.evaluate(surf, x, None, 1, stiffness=1e3, reach=0.1)
        searches.append(pcm.searches - before)
        kept = pcm.held
        E0, g0, _, i0 = fresh.evaluate(surf, x, None, 1, stiffness=1e3, reach=0.1)
        pcm.held = kept  # the fresh law's own search replaced the held candidates
        assert i1["active"] == i0["active"] > 0
        assert E1 == pytest.approx(E0, rel=1e-12)
        assert np.abs(g1 - g0).max() <= 1e-12 * np.abs(g0).max()
    # searched at the first state; the moves within d̂/2 of it reuse its candidates; 1.5 d̂ searches again,
    # and 1.6 d̂ (another random move, over d̂/2 from the 1.5 state) once more
    assert searches == [1, 0, 0, 0, 0, 1, 1]
