"""Solid contact laws ``penalty`` (node-to-surface) and ``mortar`` (segment-to-segment): derivatives, Hertz,
patch test, images."""

from __future__ import annotations

import numpy as np
import pytest
import skfem
from contact_solid_helpers import (
    assert_derivatives,
    hertz_supports,
    image_blocks,
    iso,
    nodes,
    quarter_cylinder_on_flat,
    solve,
    stacked_blocks,
    surface,
)
from knitframe_contact.mortar import SolidMortar
from knitframe_contact.penalty import SolidPenalty
from knitframe_solvers.volumetric_material import SolidForms
from knitframe_yarns.law import line_contact_approach

from knitframe.geometry import Centerline, UnitCell
from knitframe.numerics.contact import (
    chain_facet_derivatives,
    facet_gap,
    nagata_facets,
    node_normals,
    p2_gap_derivatives,
    p2_shape,
    penalty_depth,
    penalty_terms,
    plane_gap,
    project_p2,
    select_pairs,
)
from knitframe.numerics.mesh import cell_mesh
from knitframe.plugins import get_registry


def test_laws_are_registered_for_solids():
    """Both laws are registered contact-law plugins for the solid discretisation."""
    kind = get_registry()["contact_law"]
    assert kind["penalty"] is SolidPenalty and kind["mortar"] is SolidMortar
    assert SolidPenalty.discretisation == SolidMortar.discretisation == "solid"


def test_plane_gap_derivatives():
    """The plane gap's gradient and Hessian equal central differences."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(6, 4, 3))
    g, dg, H = plane_gap(*X.transpose(1, 0, 2))
    eps = 1e-6
    for k in range(4):
        for i in range(3):
            Xp, Xm = X.copy(), X.copy()
            Xp[:, k, i] += eps
            Xm[:, k, i] -= eps
            gp, dgp, _ = plane_gap(*Xp.transpose(1, 0, 2))
            gm, dgm, _ = plane_gap(*Xm.transpose(1, 0, 2))
            assert np.allclose((gp - gm) / (2 * eps), dg[:, k, i], atol=1e-7)
            assert np.allclose((dgp - dgm) / (2 * eps), H[:, :, :, k, i], atol=1e-6)


def test_quadratic_facet_gap_derivatives():
    """The gap to a curved quadratic facet has the gradient n, −N_i n of its closest point and the exact
    Hessian."""
    rng = np.random.default_rng(1)
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    mids = 0.5 * (corners[[0, 1, 2]] + corners[[1, 2, 0]]) + np.array([0, 0, 0.05])
    Xf = np.tile(np.vstack([corners, mids]), (5, 1, 1)) + 0.01 * rng.normal(size=(5, 6, 3))
    p = np.array([0.25, 0.25, 0.02]) + 0.02 * rng.normal(size=(5, 3))
    p[0, 2] = -0.2  # deep below the facet: the curvature terms of the projection matter
    g, dg, Hg, _ = facet_gap(p, Xf, 2)
    assert np.all(project_p2(p, Xf).interior)
    eps = 1e-7
    for k in range(7):
        for i in range(3):
            pp, Xp = p.copy(), Xf.copy()
            pm, Xm = p.copy(), Xf.copy()
            if k == 0:
                pp[:, i] += eps
                pm[:, i] -= eps
            else:
                Xp[:, k - 1, i] += eps
                Xm[:, k - 1, i] -= eps
            fp, fm = facet_gap(pp, Xp, 1), facet_gap(pm, Xm, 1)
            assert np.allclose((fp[0] - fm[0]) / (2 * eps), dg[:, k, i], atol=1e-6)
            assert np.allclose((fp[1] - fm[1]) / (2 * eps), Hg[:, :, :, k, i], atol=1e-5)
    assert np.abs(Hg[0]).max() > 0.1  # the second derivative is not the zero of a flat facet


def test_quadratic_projection_finds_the_closest_point():
    """Projected Newton reaches the closest point of a curved facet inside, along an edge and at a corner."""
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    mids = 0.5 * (corners[[0, 1, 2]] + corners[[1, 2, 0]]) + np.array([0, 0, 0.1])
    Xf = np.tile(np.vstack([corners, mids]), (3, 1, 1))
    p = np.array(
        [[0.3, 0.2, 0.3], [0.5, -0.3, 0.1], [-0.2, -0.3, 0.0]]
    )  # inside, beyond edge 01, beyond corner 0
    pr = project_p2(p, Xf)
    grid = np.linspace(0, 1, 401)
    S, T = np.meshgrid(grid, grid)
    keep = S + T <= 1
    N, _ = p2_shape(np.column_stack([S[keep], T[keep]]))
    pts = N @ Xf[0]
    sampled = np.linalg.norm(pts[None] - p[:, None], axis=2).min(axis=1)
    assert np.all(pr.dist <= sampled + 1e-12)
    assert np.all(pr.dist > sampled - 1e-4)
    assert pr.interior.tolist() == [True, False, False]
    assert pr.xi[1, 1] == 0.0 and np.allclose(pr.xi[2], 0.0)


BOWED_PATCHES = {
    # a full Newton step from the corners' plane overshot to a rim minimum 0.037 mm away
    "overshoot": (
        [0.4407618642255221, 0.291526210328928, 0.1067607992832436],
        [
            [0.3731746766708867, 0.25803144511617837, 0.162663772120205],
            [0.4858454240960754, 0.2812460431411018, 0.08522744735096027],
            [0.41377076440576466, 0.3160315027017038, 0.11573131897514108],
            [0.42366621074882976, 0.2768208200886712, 0.12456078336076531],
            [0.42868746208262126, 0.3037119402294923, 0.11362306373601246],
            [0.3939669607668355, 0.2801387428976035, 0.1421454372121445],
        ],
        0.00279109,
    ),
    # from the plane projection Newton sat 12 iterations near 0.027 mm and returned an unconverged point
    "slow": (
        [-0.7267101481682067, 0.18192358125331393, 0.04938587579145677],
        [
            [-0.6527192980025082, 0.10605802392821007, 0.07153553938907382],
            [-0.7586507267611693, 0.13916489922601594, 0.07097893630598316],
            [-0.7373373928636375, 0.29506642144364725, 0.01651511338591843],
            [-0.724489851789253, 0.11913301731608467, 0.06587979642311893],
            [-0.7649106443636946, 0.24270276132316482, 0.0551749933033462],
            [-0.711304750786362, 0.1965917265616802, 0.0483297652335191],
        ],
        0.00675581,
    ),
    # the plane projection lies near edge t = 0 and the full step leaves the triangle: halving the chord
    # to the clipped step (not a descent direction) crept along for 25 iterations
    "clipped": (
        [1.2446381771308965, 0.2924632528020442, 0.059730367838484524],
        [
            [1.2660415848614008, 0.2859341479555903, 0.07645327847854691],
            [1.1783248232012102, 0.299838302465308, 0.027647157677238382],
            [1.2687122008215979, 0.32816601504678805, -0.08719551712814164],
            [1.2225360197656583, 0.29040233787463093, 0.049463619044287824],
            [1.2048882052149839, 0.30818322110005153, -0.0025670856434849287],
            [1.2382776399257813, 0.30205199435381724, 0.010189926541353374],
        ],
        0.00344649,
    ),
    # the plane projection lies in the basin of a rim minimum 0.0093 mm away; the closest point is inside
    # at 0.0034 mm (jersey at 23 %): only a start search over the triangle finds it
    "far_basin": (
        [1.29687973048491, 0.47618651566179127, 0.1947390264525694],
        [
            [1.3322934526825287, 0.39804303645191236, 0.14934596361681934],
            [1.3273166149881142, 0.5602977310306162, 0.13529362770756018],
            [1.2898930066731085, 0.4559453842197101, 0.2192933944462193],
            [1.3096604500099063, 0.49764080694227625, 0.16012699123129137],
            [1.2994641227708805, 0.5098075595659571, 0.17863451084030552],
            [1.2960738473463362, 0.4441382817324463, 0.20106323409328836],
        ],
        0.00343040,
    ),
}


@pytest.mark.parametrize("case", sorted(BOWED_PATCHES))
def test_quadratic_projection_finds_the_closest_point_on_bowed_patches(case):
    """Strongly bowed Nagata patches of a jersey cell at 20 % stretch, where the contact energy
    jumped (by 3e-7 to 1e-5 N·mm) within 1e-16 of a Newton step: the projection had returned a
    far or unconverged point, and the gap changed sign with it. The start is the closer of the plane
    projection and a 28-point lattice on the triangle, and steps that raise the distance are
    backtracked, each trial clipped to the triangle, so the closest point is found (dense sampling)
    and converged."""
    p, X, dist = BOWED_PATCHES[case]
    p, Xf = np.array([p]), np.array([X])
    pr = project_p2(p, Xf, iterations=16)
    grid = np.linspace(0, 1, 801)
    S, T = np.meshgrid(grid, grid)
    keep = S + T <= 1
    N, _ = p2_shape(np.column_stack([S[keep], T[keep]]))
    sampled = np.linalg.norm(N @ Xf[0] - p, axis=1).min()
    assert pr.interior[0]
    assert sampled - 1e-5 < pr.dist[0] <= sampled + 1e-12
    assert pr.dist[0] == pytest.approx(dist, rel=1e-5)


def test_rim_gap_sign_comes_from_the_edge_pseudo_normal():
    """A point beyond the ridge of a convex roof, in the tangent plane of one roof facet: measured to
    that facet, its closest point is on the ridge and p − x* lies in the facet's plane, so the sign
    of n·(p − x*) is round-off (it flipped the gap between ±distance in a jersey cell at 20 %). With
    the nodal normals interpolated to the closest point, the same vector from both facets, the point
    is outside from either side."""
    X = np.array([[0, 0, 0], [1, 0, 0], [0.5, -1, -0.3], [0.5, 1, -0.3]], float)
    tri = np.array([[1, 0, 2], [0, 1, 3]])
    nodal = node_normals(X, tri)

    def gap(p, k, corner_normals):
        c = X[tri[k]]
        Xe = np.vstack([c, 0.5 * (c[[0, 1, 2]] + c[[1, 2, 0]])])[None]
        return select_pairs(
            p, np.array([0]), np.array([k]), Xe, np.array([[0, 0, -1.0]]), 1.0, corner_normals=corner_normals
        ).g[0]

    for eps in (1e-9, -1e-9):  # just above and just below facet 0's tangent plane, far above facet 1
        p = np.array([[0.5, 0.5, 0.15 + eps]])
        assert gap(p, 0, nodal[tri[[0]]]) == pytest.approx(np.hypot(0.5, 0.15))
        assert gap(p, 1, nodal[tri[[1]]]) > 0
    assert gap(np.array([[0.5, 0.5, 0.15 - 1e-9]]), 0, None) < 0  # the facet's own normal: the wrong side


def prism(n_sides: int, R: float = 1.0, length: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A closed n-gon prism (nodes on a circle of radius R) split into outward-facing triangles."""
    phi = 2 * np.pi * np.arange(n_sides) / n_sides
    ring = np.column_stack([R * np.cos(phi), R * np.sin(phi), np.zeros(n_sides)])
    X = np.concatenate([ring, ring + [0.0, 0.0, length]])
    i = np.arange(n_sides)
    j = (i + 1) % n_sides
    tri = np.concatenate(
        [np.column_stack([i, j, j + n_sides]), np.column_stack([i, j + n_sides, i + n_sides])]
    )
    return X, tri


def test_nagata_patch_rebuilds_a_circle_and_keeps_a_plane():
    """Patches through nodal normals: an 11-gon's edges bow onto its circle, flat facets stay flat,
    X6 = A·x."""
    X, tri = prism(11)
    nrm = node_normals(X, tri)
    assert np.allclose(nrm[:, 2], 0.0) and np.allclose(np.linalg.norm(nrm[:, :2] - X[:, :2], axis=1), 0.0)
    X6, A = nagata_facets(X[tri], nrm[tri])
    mid = X6[:, 3:]
    ring_edges = np.abs(mid[..., 2] - np.round(mid[..., 2])) < 1e-12  # circumferential edges (z = 0 or 1)
    radius = np.linalg.norm(mid[..., :2], axis=-1)[ring_edges]
    chord = np.cos(np.pi / 11)
    assert np.all(np.abs(radius - 1.0) < 1e-3) and abs(chord - 1.0) > 0.04  # the flat chord misses by 4 %
    assert np.allclose(np.einsum("mkcij,mcj->mki", A, X[tri]), X6, atol=1e-14)
    assert np.allclose(A.sum(axis=2), np.eye(3))  # a translation (periodic image) carries over
    # the two facets sharing an edge build the same mid point: the patched surface is continuous
    edges = {}
    for f in range(len(tri)):
        for k, (a, b) in zip((3, 4, 5), ((0, 1), (1, 2), (2, 0))):
            key = tuple(sorted((tri[f, a], tri[f, b])))
            if key in edges:
                assert np.allclose(edges[key], X6[f, k], atol=1e-14)
            edges[key] = X6[f, k]
    flat = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    Xf, _ = nagata_facets(flat, np.tile([0.0, 0, 1], (1, 3, 1)))
    assert np.allclose(Xf[0, 3:], [[0.5, 0, 0], [0.5, 0.5, 0], [0, 0.5, 0]])


def test_nagata_gap_derivatives_through_the_corners():
    """The gap to a patch, chained to the triangle's corners for fixed normals, has the exact gradient and
    Hessian."""
    rng = np.random.default_rng(3)
    X, tri = prism(9)
    nrm = node_normals(X, tri)
    f = np.array([0, 4, 10, 13])
    Xt = X[tri[f]] + 0.01 * rng.normal(size=(4, 3, 3))
    nt = nrm[tri[f]]
    p = Xt.mean(axis=1) * [0.99, 0.99, 1.0] + 0.001 * rng.normal(size=(4, 3))

    def gap(p, Xt):
        X6, A = nagata_facets(Xt, nt)
        pr = project_p2(p, X6)
        dg, Hg = chain_facet_derivatives(*p2_gap_derivatives(pr, X6, None, 2), A)
        return pr.g, dg, Hg

    g, dg, Hg = gap(p, Xt)
    assert np.all(g < 0)  # inside the patched cylinder
    eps = 1e-6
    for k in range(4):
        for i in range(3):
            dp = np.zeros((4, 4, 3))
            dp[:, k, i] = eps
            gp, dgp, _ = gap(p + dp[:, 0], Xt + dp[:, 1:])
            gm, dgm, _ = gap(p - dp[:, 0], Xt - dp[:, 1:])
            assert np.allclose((gp - gm) / (2 * eps), dg[:, k, i], atol=1e-7)
            assert np.allclose((dgp - dgm) / (2 * eps), Hg[:, :, :, k, i], atol=1e-5)


def test_smoothed_master_gap_does_not_jump_across_facet_edges():
    """A point sliding round inside a faceted cylinder: the flat-facet gap swings by the facets' sagitta and
    kinks at every edge; the gap to the Nagata patches stays within 0.1 % of the radius of the true one."""
    X, tri = prism(11, R=1.0, length=2.0)
    nrm = node_normals(X, tri)
    depth = 0.02
    phi = np.linspace(0.0, 4 * np.pi / 11, 241)
    pts = np.column_stack([(1 - depth) * np.cos(phi), (1 - depth) * np.sin(phi), np.full(phi.size, 1.0)])
    point = np.repeat(np.arange(len(pts)), len(tri))
    element = np.tile(np.arange(len(tri)), len(pts))
    inward = -pts / np.linalg.norm(pts, axis=1, keepdims=True)  # the slave surface faces the master
    flat = select_pairs(pts[point], point, element, X[tri][element], inward[point], 0.3)
    X6, _ = nagata_facets(X[tri], nrm[tri], blocks=False)
    smooth = select_pairs(pts[point], point, element, X6[element], inward[point], 0.3)
    assert len(flat.g) == len(smooth.g) == len(pts)
    assert np.ptp(flat.g) > 0.03  # the sagitta of the 11-gon, 4 % of R
    assert np.max(np.abs(smooth.g + depth)) < 1e-3
    assert np.max(np.abs(np.diff(smooth.g))) < 0.1 * np.max(np.abs(np.diff(flat.g)))


def test_folded_patch_is_not_a_penetration():
    """A point outside a strongly bowed patch, just beyond its rim: the patch's continuation folds over there
    (normal turned against the corners' plane) and reported a gap of −0.097 mm; it must not qualify.

    The numbers are a triangle, its nodal normals and a slave point taken from a jersey cell run where
    this spurious pair made the contact energy jump."""
    Xt = np.array(
        [
            [0.3970220578290573, 0.6172234515365792, 0.13746648774933495],
            [0.5186977355848384, 0.6063778531860873, 0.2561806073084894],
            [0.4765906506443856, 0.7049691798592989, 0.16747823843478618],
        ]
    )
    nt = np.array(
        [
            [-0.6368880963383645, 0.16845692981560978, 0.7523269339453378],
            [-0.17745334564439583, 0.5815138302562098, 0.7939470859826632],
            [-0.1618329135962339, 0.6359132682948969, 0.7546021622573423],
        ]
    )
    p = np.array([[0.4958636184723171, 0.6634617543482386, 0.33105287966188657]])
    ns = np.array([[0.01062752663991197, -0.00489598085137729, 0.00696698809696292]])
    X6, _ = nagata_facets(Xt[None], nt[None])
    flat = np.cross(Xt[1] - Xt[0], Xt[2] - Xt[0])
    assert np.dot(p[0] - Xt[0], flat) > 0  # outside: above the corners' plane
    ext = project_p2(p, X6, extend=True, start=project_p2(p, X6).xi)
    assert ext.interior[0] and ext.g[0] < -0.09 and np.dot(ext.n[0], flat) < 0  # the folded continuation
    chosen = select_pairs(p, np.zeros(1, np.int64), np.zeros(1, np.int64), X6, ns, 0.111)
    assert len(chosen.g) == 0 or chosen.g[0] > 0


def test_penalty_fades_out_continuously_at_the_reach():
    """ψ = d² below the band; across it the energy and force fall to zero at the reach (no jump when a pair
    enters the search), and the gradient and Hessian of the faded energy match central differences."""
    reach, band = 0.1, (0.05, 0.1)
    d = np.array([0.0, 0.02, 0.05, 0.075, 0.1 - 1e-12])
    psi, dpsi, _ = penalty_depth(-d, band)
    assert np.allclose(psi[:3], d[:3] ** 2) and np.allclose(dpsi[:3], 2 * d[:3])
    assert 0 < psi[3] < d[3] ** 2 and psi[4] < 1e-15 and abs(dpsi[4]) < 1e-9
    assert SolidMortar().band(reach) == (0.05, 0.1) and SolidMortar(fade=1.0).band(reach) is None
    rng = np.random.default_rng(5)
    X = np.array([[[0.07, 0.2, -0.06], [0, 0, 0], [1, 0, 0], [0, 1, 0]]]) + 1e-3 * rng.normal(size=(1, 4, 3))

    def f(v, order):
        x = v.reshape(1, 4, 3)
        g, dg, Hg = plane_gap(*x.transpose(1, 0, 2), order=max(order, 1))
        E, G, H = penalty_terms(g, dg, Hg if order == 2 else None, np.ones(1), 100.0, order, band)
        return E, None if G is None else G.ravel(), None if H is None else H.reshape(12, 12), {}

    v = X.ravel()
    assert f(v, 0)[0] > 0 and 0.05 < -plane_gap(*X.transpose(1, 0, 2), order=0)[0][0] < 0.1  # inside the band
    du = rng.normal(size=12)
    E, G, H, _ = f(v, 2)
    h = 1e-7
    assert abs(G @ du - (f(v + h * du, 0)[0] - f(v - h * du, 0)[0]) / (2 * h)) < 1e-6 * np.abs(G).sum()
    assert np.allclose(
        H @ du, (f(v + h * du, 1)[1] - f(v - h * du, 1)[1]) / (2 * h), atol=1e-5 * np.abs(H).max()
    )


@pytest.fixture(scope="module", params=[1, 2])
def cylinder(request):
    order = request.param
    mesh, body, arc, top = quarter_cylinder_on_flat(1.0, 0.01 if order == 1 else 0.02, 0.25, 0.05, order)
    return mesh, body, surface(mesh, body, arc, top)


def pressed(cylinder, seed: int):
    """Nodes X, DOF count n, a random generator and the displacement u pressing the cylinder 0.01 into the
    flat."""
    mesh, body, surf = cylinder
    X = nodes(mesh)
    n = 3 * len(X)
    u = np.zeros(n)
    u[1::3] = -0.01 * (body == 0)
    return X, n, np.random.default_rng(seed), u


@pytest.mark.parametrize(
    "law",
    [SolidPenalty(), SolidMortar(), SolidPenalty(smoothing="none"), SolidMortar(smoothing="none")],
    ids=["penalty", "mortar", "penalty-flat", "mortar-flat"],
)
def test_contact_derivatives_match_finite_differences(cylinder, law):
    """Contact gradient = FD of the energy; Hessian = FD of the gradient (exact, on curved P2 facets too)."""
    mesh, body, surf = cylinder
    X, n, rng, u = pressed(cylinder, 0)
    u += 1e-4 * rng.normal(size=n)
    du = rng.normal(size=n) * np.repeat(body == 0, 3)

    def f(v, order):
        return law.evaluate(surf, X + v.reshape(-1, 3), None, order, stiffness=1e3, reach=0.1)

    info = assert_derivatives(f, u, du, n)
    assert info["active"] > 0


@pytest.mark.parametrize("law", [SolidPenalty(), SolidMortar()], ids=["penalty", "mortar"])
def test_hertz_cylinder_on_flat(cylinder, law):
    """The axis approach of an elastic cylinder pressed on a rigid flat matches Hertz line contact
    within 5 %."""
    mesh, body, surf = cylinder
    E, nu, R, t, d = 100.0, 0.3, 1.0, 0.05, 0.02
    forms = SolidForms(mesh, iso(E, nu), None)
    X, fixed, sym = hertz_supports(mesh, body)
    u = np.zeros((len(X), 3))
    u[body == 0, 1] = -d
    h_c = 0.01 if isinstance(mesh, skfem.MeshTet1) and not isinstance(mesh, skfem.MeshTet2) else 0.02
    u, info = solve(forms, law, surf, u.ravel(), ~fixed.ravel(), law.penalty(E / (1 - nu**2), h_c), reach=0.2)
    reaction = forms.residual(u).reshape(-1, 3)
    f = -2 * reaction[sym, 1].sum() / t  # line load on the whole cylinder, N/mm
    assert 2 * info["force"] / t == pytest.approx(f, rel=1e-6)
    assert d / line_contact_approach(np.array([f]), R, E, nu, rigid_partner=True)[0] == pytest.approx(
        1.0, abs=0.05
    )


@pytest.mark.parametrize(
    "order,law,tol",
    [
        (1, SolidMortar(quadrature=10), 0.005),
        (2, SolidMortar(quadrature=6), 0.03),
        (1, SolidPenalty(), None),
        (2, SolidPenalty(), None),
    ],
    ids=["mortar-P1", "mortar-P2", "penalty-P1", "penalty-P2"],
)
def test_contact_patch_test(order, law, tol):
    """Two blocks with non-matching meshes in confined compression: mortar transmits a uniform stress.

    Node-to-surface penalty balances the load globally but, as is known for single-pass
    node-to-surface contact, not pointwise; for it only the transmitted force is checked.
    """
    E, nu, strain = 100.0, 0.3, 0.02
    mesh, body, surf, n_lo = stacked_blocks(order)
    forms = SolidForms(mesh, iso(E, nu), None)
    X = nodes(mesh)
    fixed = np.zeros((len(X), 3), bool)
    fixed[np.isclose(X[:, 0], 0) | np.isclose(X[:, 0], 1), 0] = True
    fixed[np.isclose(X[:, 1], 0) | np.isclose(X[:, 1], 1), 1] = True
    fixed[np.isclose(X[:, 2], 0) | np.isclose(X[:, 2], 1), 2] = True
    u = np.zeros((len(X), 3))
    u[body == 1, 2] = -strain
    u, info = solve(forms, law, surf, u.ravel(), ~fixed.ravel(), law.penalty(E, 0.2), reach=0.1)
    szz = forms.stress(u)[2, 2]
    reaction = forms.residual(u).reshape(-1, 3)
    bottom = -reaction[np.isclose(X[:, 2], 0), 2].sum()
    assert info["force"] == pytest.approx(-bottom, rel=1e-4)  # contact force = support reaction
    assert -bottom == pytest.approx(-szz.mean(), rel=0.02)
    if tol is not None:
        assert np.ptp(szz) < tol * abs(szz.mean())
        p = info["pressure"][surf.slave_nodes]
        assert np.ptp(p) < 2 * tol * p.mean()


def test_contact_with_periodic_image_moves_with_macro_dofs():
    """A block overlapping its own image across the lattice feels contact whose h-derivatives match FD.

    The image is offset sideways so that no slave node projects onto a master edge (where the
    nearest-facet choice, and with it the Hessian, would be ambiguous).
    """
    X, surf, n = image_blocks()
    hdofs = np.zeros(6)
    for law in (SolidPenalty(), SolidMortar()):
        E, g, H, info = law.evaluate(surf, X, hdofs, 2, stiffness=100.0, reach=0.1)
        assert info["active"] > 0 and E > 0
        # stretching the lattice along x by more than the overlap separates the images
        assert law.evaluate(surf, X, np.array([0.05, 0, 0, 0, 0, 0]), 0, stiffness=100.0, reach=0.1)[0] == 0.0
        dh = np.array([1.0, 0.3, -0.2, 0.5, 0.1, 0.0])
        eps = 1e-7
        Ep = law.evaluate(surf, X, eps * dh, 1, stiffness=100.0, reach=0.1)
        Em = law.evaluate(surf, X, -eps * dh, 1, stiffness=100.0, reach=0.1)
        assert g[3 * n :] @ dh == pytest.approx((Ep[0] - Em[0]) / (2 * eps), rel=1e-6)
        assert np.allclose(H[:, 3 * n :] @ dh, (Ep[1] - Em[1]) / (2 * eps), atol=1e-6 * np.abs(H).max())


def helix_cell(c: float, r: float = 0.3) -> UnitCell:
    """Two helical turns (pitch 2πc) periodic along the axis z."""
    R = 1.0
    heli = Centerline(
        "helix",
        lambda t: np.stack([R * np.cos(t), R * np.sin(t), c * t], 1),
        lambda t: np.stack([-R * np.sin(t), R * np.cos(t), c + 0 * t], 1),
        0.0,
        4 * np.pi,
        [0.0, 0.0, 4 * np.pi * c],
    )
    return UnitCell("helix", (heli,), heli.period, [10.0, 0, 0], r, ((0, 0),), (("k",),), 1.0, 1.0, 1.0)


@pytest.mark.parametrize("law", [SolidPenalty(), SolidMortar()], ids=["penalty", "mortar"])
def test_self_contact_between_helix_turns_only(law):
    """A tube is never in contact with its own cross-section, but overlapping turns of a helix are."""
    from knitframe_solvers.volumetric_model import contact_surface

    for c, expect in ((0.2, False), (0.085, True)):  # pitch 1.26 mm (> 2r) and 0.53 mm (< 2r = 0.6)
        cm = cell_mesh(helix_cell(c), seed=0.6, check=False)
        surf = contact_surface(cm, None)
        E, _, _, info = law.evaluate(surf, cm.nodes, None, 0, stiffness=10.0, reach=0.2)
        assert (info["active"] > 0) == expect


@pytest.mark.parametrize(
    "law",
    [SolidPenalty(), SolidMortar(), SolidMortar(smoothing="none")],
    ids=["penalty", "mortar", "mortar-flat"],
)
def test_held_candidates_reproduce_the_search_and_are_differentiable(cylinder, law):
    """Evaluated with the candidates of its own search, a state gives the same energy, gradient and
    Hessian; at a moved state they give those of a fresh search, and the gradient and Hessian are
    those of the energy (FD)."""
    mesh, body, surf = cylinder
    X, n, rng, u = pressed(cylinder, 1)
    E, g, H, info = law.evaluate(surf, X + u.reshape(-1, 3), None, 2, stiffness=1e3, reach=0.1)
    held = info["candidates"]
    assert info["active"] > 0 and len(held.point) > info["active"]
    E2, g2, H2, info2 = law.evaluate(
        surf, X + u.reshape(-1, 3), None, 2, stiffness=1e3, reach=0.1, candidates=held
    )
    assert (
        E2 == E and np.array_equal(g2, g) and abs(H2 - H).max() == 0.0 and info2["active"] == info["active"]
    )
    # a different state: sideways slide and a deeper press, evaluated on the held candidates
    v = u + 1e-4 * rng.normal(size=n) + np.tile([0.003, -0.002, 0.0], len(X)) * np.repeat(body == 0, 3)
    du = rng.normal(size=n) * np.repeat(body == 0, 3)
    fresh = law.evaluate(surf, X + v.reshape(-1, 3), None, 1, stiffness=1e3, reach=0.1)
    kept = law.evaluate(surf, X + v.reshape(-1, 3), None, 1, stiffness=1e3, reach=0.1, candidates=held)
    assert kept[0] == pytest.approx(fresh[0], rel=1e-12) and np.allclose(
        kept[1], fresh[1], rtol=1e-10, atol=1e-14
    )

    def f(w, order):
        return law.evaluate(
            surf, X + w.reshape(-1, 3), None, order, stiffness=1e3, reach=0.1, candidates=held
        )

    assert assert_derivatives(f, v, du, n)["active"] > 0
    # held candidates are all there is: those of a separated state see no contact at the pressed one
    apart = u.copy()
    apart[1::3] = 0.5 * (body == 0)
    none = law.evaluate(surf, X + apart.reshape(-1, 3), None, 0, stiffness=1e3, reach=0.1)[3]["candidates"]
    assert len(none.point) == 0
    assert (
        law.evaluate(surf, X + u.reshape(-1, 3), None, 1, stiffness=1e3, reach=0.1, candidates=none)[0] == 0.0
    )


def test_held_candidates_follow_the_macro_dofs():
    """Held candidates with a periodic image move with the lattice: at other macro DOFs the held
    energy equals a fresh search's, and separates to zero with it."""
    X, surf, n = image_blocks()
    for law in (SolidPenalty(), SolidMortar()):
        held = law.evaluate(surf, X, np.zeros(6), 2, stiffness=100.0, reach=0.1)[3]["candidates"]
        for hx in (0.002, 0.05):
            hd = np.array([hx, 0, 0, 0, 0, 0])
            fresh = law.evaluate(surf, X, hd, 1, stiffness=100.0, reach=0.1)
            kept = law.evaluate(surf, X, hd, 1, stiffness=100.0, reach=0.1, candidates=held)
            assert kept[0] == pytest.approx(fresh[0], rel=1e-12, abs=1e-300)
            assert np.allclose(kept[1], fresh[1], rtol=0, atol=1e-12 * max(np.abs(fresh[1]).max(), 1.0))
        assert kept[0] == 0.0


def _one_facet_gap(p, X6, order=2):
    """Gap of point p to the single quadratic facet X6 (6, 3) as the contact laws measure it, with
    derivatives."""
    sel = select_pairs(
        p[None],
        np.zeros(1, np.int64),
        np.zeros(1, np.int64),
        X6[None],
        -np.cross(X6[1] - X6[0], X6[2] - X6[0])[None],
        1.0,
    )
    dg, Hg = p2_gap_derivatives(sel.projection, X6[None], None, order)
    return sel.g[0], dg[0], None if Hg is None else Hg[0], sel.projection


@pytest.mark.parametrize(
    "p,where",
    [
        ([-0.05, 0.4, -0.03], "edge s = 0"),
        ([0.4, -0.1, 0.08], "edge t = 0"),
        ([0.6, 0.6, -0.05], "edge s + t = 1"),
        ([-0.05, -0.06, -0.02], "corner"),
        ([0.3, 0.3, -0.02], "inside"),
    ],
)
def test_gap_beyond_the_rim_is_the_signed_distance_with_exact_derivatives(p, where):
    """Closest point on a curved facet's edge or corner: g = ±|p − x*|, and its gradient and Hessian in the
    point and the six facet nodes match central differences (inside: the usual n·(p − x*))."""
    rng = np.random.default_rng(0)
    X6 = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.5, 0, 0.1], [0.5, 0.5, 0.15], [0, 0.5, 0.05]]
    ) + 0.02 * rng.normal(size=(6, 3))
    p = np.array(p, float)
    g, dg, Hg, pr = _one_facet_gap(p, X6)
    assert pr.interior[0] == (where == "inside")
    assert abs(abs(g) - np.linalg.norm(p - pr.x[0])) < 1e-12
    z, eps = np.vstack([p, X6]), 1e-6
    for k in range(7):
        for i in range(3):
            dz = np.zeros_like(z)
            dz[k, i] = eps
            gp, dgp, _, _ = _one_facet_gap(z[0] + dz[0], z[1:] + dz[1:])
            gm, dgm, _, _ = _one_facet_gap(z[0] - dz[0], z[1:] - dz[1:])
            assert abs((gp - gm) / (2 * eps) - dg[k, i]) < 1e-8
            assert np.abs((dgp - dgm) / (2 * eps) - Hg[:, :, k, i]).max() < 1e-7 * max(np.abs(Hg).max(), 1.0)


def test_gap_is_continuous_where_the_nearest_facet_changes_over_a_corner():
    """A point passing over the apex of a six-facet cone: its nearest facet changes between facets that share
    only the apex. The gap is the distance to the cone (1-Lipschitz along the path), where the gap to the
    continuation of the facet that was nearest jumps when another facet's inside becomes nearest."""
    ring = np.array([[np.cos(a), np.sin(a), 0.0] for a in np.arange(6) * np.pi / 3])
    apex = np.array([0.0, 0.0, 0.3])
    tri = np.array([[apex, ring[k], ring[(k + 1) % 6]] for k in range(6)])
    X6 = np.concatenate([tri, 0.5 * (tri[:, [0, 1, 2]] + tri[:, [1, 2, 0]])], axis=1)  # flat quadratic facets
    s = np.linspace(-0.4, 0.4, 801)
    pts = np.column_stack([s, 0.13 + 0 * s, 0.42 + 0 * s])  # above the apex, off the cone's ridges
    point = np.repeat(np.arange(len(pts)), 6)
    element = np.tile(np.arange(6), len(pts))
    sel = select_pairs(
        pts[point], point, element, X6[element], np.tile([0.0, 0.0, -1.0], (len(point), 1)), 1.0
    )
    assert len(sel.g) == len(pts)
    chosen = element[sel.rows]
    assert (
        len(np.unique(chosen)) >= 3 and np.any(~sel.projection.interior) and np.any(sel.projection.interior)
    )
    assert np.max(np.abs(np.diff(sel.g))) <= np.diff(s)[0] * (1 + 1e-9)


def test_open_edges_of_the_master_surface():
    """An open face has its rim as open edges; a periodic cell's tube surface, its end nodes identified with
    the start nodes across the seam, has none."""
    from knitframe_solvers.volumetric_model import contact_surface

    _, surf, _ = image_blocks()
    m = surf.master
    assert 0 < surf.open_facet[m].sum() < surf.open_facet[m].size and not surf.open_facet[surf.slave].any()
    cm = cell_mesh(helix_cell(0.2), seed=0.6, check=False)
    assert contact_surface(cm, None).open_facet.sum() == 0


def test_nagata_normals_match_across_the_periodic_seam():
    """The end nodes of a periodic tube and the start nodes they stand for get one nodal normal from both
    fans of triangles, so the smoothed (Nagata) master surface has no step at the seam; from one fan
    each, the two sides' normals differed and the patches on either side of the seam did not meet."""
    from knitframe_solvers.volumetric_model import contact_surface

    cm = cell_mesh(helix_cell(0.2), seed=0.6, check=False)
    surf = contact_surface(cm, None)
    law = SolidMortar()
    tri = surf.triangles[surf.tri_master]
    end = np.concatenate([e for e, _, _ in cm.end_pairs])
    start = np.concatenate([s for _, s, _ in cm.end_pairs])
    x = cm.nodes + 0.01 * np.sin(7.0 * cm.nodes)  # a deformed state, so that the fans differ
    shift = x[start] - x[end]
    x[end] = x[start] - shift.mean(axis=0)  # the end nodes an image of the start nodes (a translation)
    one_sided = node_normals(x, tri)
    assert np.abs(one_sided[end] - one_sided[start]).max() > 1e-3
    n = law.master_normals(surf, x)
    assert np.allclose(n[end], n[start], atol=1e-14)
    on = np.linalg.norm(one_sided[end], axis=1) > 0  # the end faces' surface nodes (the rest are inside)
    assert on.sum() > 0 and np.allclose(np.linalg.norm(n[end[on]], axis=1), 1.0)


def test_a_flank_at_right_angles_stays_in_contact():
    """A slave point 0.01 inside a master facet whose own normal stands at right angles to the master's
    (the flank of a crossing yarn): it pairs with the same gap whether its normal leans 3° towards or away
    from the master's; only a normal within 60° of the master's (the back of the other body) is refused."""
    X6 = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.5, 0, 0], [0.5, 0.5, 0], [0, 0.5, 0]], float)[None]
    p = np.array([[0.3, 0.3, -0.01]])
    one = np.zeros(1, np.int64)
    gaps = []
    for angle in (93.0, 87.0, 65.0, 50.0):
        a = np.radians(angle)  # between the slave normal and the master normal +z
        ns = np.array([[np.sin(a), 0.0, np.cos(a)]])
        sel = select_pairs(p, one, one, X6, ns, 0.1)
        gaps.append(sel.g[0] if len(sel.g) else None)
    assert (
        gaps[0] == pytest.approx(-0.01)
        and gaps[1] == pytest.approx(-0.01)
        and gaps[2] == pytest.approx(-0.01)
    )
    assert gaps[3] is None
