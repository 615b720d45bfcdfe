"""What the volumetric solver no longer redoes outside the mechanics, and that its results did not move.

The Newton driver hands the linear solver the free block of the Hessian in the format it factorises
(:func:`knitframe.numerics.newton_driver.free_block`: CSR for PARDISO, CSC for SuperLU) instead of
CSR -> CSC -> CSR; the symmetry probe of the PARDISO path keeps its random vectors; the periodic
filter of the ``ipc`` law's broad-phase candidates reads each candidate's ids through the
properties' getters. None of them changes a floating-point operation of the mechanics: a small
volumetric cell gives the tensions of the code before them to the last digit.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import scipy.sparse as sp
from test_contact_ipc import _block_row

from knitframe.numerics.newton_driver import free_block, solver_format

#: tensions of the code before these changes (jersey cotton SL12, P1, seed r, equibiaxial 0 -> 5 % in one
#: step, all effects) in the deterministic run of :data:`DETERMINISTIC_RUN`, by linear-solver backend: the
#: cell's 2 589 free unknowns go to SuperLU under ``auto``, to PARDISO when asked for. PARDISO's since it
#: runs in MKL's reproducible mode (AUTO, a code path of its own: 0.07359260939766923, 0.05672359097157564
#: before, 4e-6 apart)
PINNED = {
    "pardiso": (0.07359230237791636, 0.05672361330530444),
    "auto": (0.07359081087017494, 0.05672378141595865),
}


def _matrix(n: int, density: float, seed: int, *, symmetric: bool = False) -> sp.csr_matrix:
    A = sp.random(n, n, density=density, format="csr", random_state=np.random.default_rng(seed))
    A = A + sp.diags(np.arange(1.0, n + 1.0))
    return sp.csr_matrix(A + A.T if symmetric else A)


def _same(A: sp.spmatrix, B: sp.spmatrix) -> bool:
    """Same format, shape and stored arrays, entry for entry and in the same order."""
    return (
        A.format == B.format
        and A.shape == B.shape
        and np.array_equal(A.indptr, B.indptr)
        and np.array_equal(A.indices, B.indices)
        and np.array_equal(A.data, B.data)
    )


@pytest.mark.parametrize("fmt", ["csr", "csc"])
@pytest.mark.parametrize("layout", ["sorted csr", "unsorted csr", "csc"])
def test_free_block_is_the_sliced_block_in_the_format_asked_for(fmt, layout):
    H = _matrix(60, 0.1, 1)
    free = np.random.default_rng(2).random(60) < 0.7
    before = H[free][:, free].tocsc()  # what the driver gave the solver before
    if fmt == "csr":
        before = sp.csr_matrix(before)  # what the PARDISO path converted it back to
    if layout == "unsorted csr":
        H = H.copy()
        for i in range(H.shape[0]):  # each row's entries reversed
            s = slice(H.indptr[i], H.indptr[i + 1])
            H.indices[s], H.data[s] = H.indices[s][::-1].copy(), H.data[s][::-1].copy()
        H.has_sorted_indices = False
    elif layout == "csc":
        H = H.tocsc()
    got = free_block(H, free, fmt)
    assert _same(got, before)
    assert np.array_equal(got.toarray(), H.toarray()[np.ix_(free, free)])
    if fmt == "csr":
        assert got.has_sorted_indices
    with pytest.raises(ValueError, match="format"):
        free_block(H, free, "coo")


def test_the_direct_solver_names_the_format_of_its_backend():
    from knitframe_linsolvers.direct import AUTO_PARDISO_SIZE, available, direct

    assert direct("superlu").matrix_format(10**6) == "csc"
    auto = direct("auto")
    assert solver_format(auto, 10) == "csc"
    assert solver_format(auto, AUTO_PARDISO_SIZE) == ("csr" if available("pardiso") else "csc")
    if available("pardiso"):
        assert direct("pardiso").matrix_format(10) == "csr"
    assert solver_format(lambda A, b: b, 10**6) == "csc"  # a plain function gets CSC, as before


@pytest.mark.parametrize("backend", ["superlu", "pardiso"])
def test_a_shifted_step_solves_the_same_system_in_either_format(backend):
    """The Levenberg shift added to the CSR block (PARDISO) is the shifted CSC block entry for entry."""
    from knitframe_linsolvers.direct import available, direct

    if not available(backend):
        pytest.skip(f"{backend} is not installed")
    H = _matrix(300, 0.02, 3, symmetric=True)
    free = np.ones(300, bool)
    free[::7] = False
    shifted = [
        (lambda B: B + sp.identity(B.shape[0], format=B.format) * 0.37)(free_block(H, free, f))
        for f in ("csr", "csc")
    ]
    assert _same(sp.csr_matrix(shifted[1]), shifted[0])
    b = np.linspace(-1.0, 1.0, int(free.sum()))
    solve = direct(backend)
    x = solve(shifted[0] if backend == "pardiso" else shifted[1], b)
    assert np.allclose(shifted[1] @ x, b, rtol=0, atol=1e-9)


def test_symmetry_probe_keeps_its_vectors_and_gives_the_two_products():
    from knitframe_linsolvers.direct import _probe_vectors, is_symmetric

    rng = np.random.default_rng(12345)
    x0, y0 = rng.standard_normal(500), rng.standard_normal(500)
    x, y, xy = _probe_vectors(500)
    assert np.array_equal(x, x0) and np.array_equal(y, y0)
    assert np.array_equal(xy[:, 0], x) and np.array_equal(xy[:, 1], y)
    assert not (x.flags.writeable or y.flags.writeable or xy.flags.writeable)
    assert _probe_vectors(500)[2] is xy
    A = _matrix(500, 0.02, 4)
    Axy = A @ xy
    assert np.array_equal(Axy[:, 0], A @ x) and np.array_equal(Axy[:, 1], A @ y)  # bit for bit
    S = _matrix(500, 0.02, 4, symmetric=True)
    assert is_symmetric(S) and is_symmetric(S.tocsc())
    assert not is_symmetric(A)


def test_collision_mesh_positions_are_the_lattice_shifts_of_the_nodes():
    """The kept reference shifts give the vertex positions and moves of Lattice.shift and .affine, bit for
    bit."""
    from knitframe_contact.ipc_mesh import collision_mesh

    _, _, surf = _block_row(2, 0.04)
    pcm = collision_mesh(surf)
    rng = np.random.default_rng(6)
    x = surf.X + 0.01 * rng.normal(size=surf.X.shape)
    h, dx, dh = 0.01 * rng.normal(size=6), 0.01 * rng.normal(size=surf.X.shape), 0.01 * rng.normal(size=6)
    lat = pcm.lattice
    S = lat.reference_shift(pcm.image)
    assert np.array_equal(pcm.positions(x, h), x[pcm.node] + lat.shift(pcm.image, h))
    assert np.array_equal(pcm.positions(x, None), x[pcm.node] + lat.shift(pcm.image, np.zeros(6)))
    assert np.array_equal(pcm.displacement(dx, dh), dx[pcm.node] + lat.affine(S, dh))


def test_periodic_candidates_are_those_of_the_attribute_filter():
    """The kept broad-phase candidates, in order, are those the filter by attribute access keeps."""
    import ipctk
    from knitframe_contact.ipc_mesh import collision_mesh

    _, _, surf = _block_row(2, 0.04)
    pcm = collision_mesh(surf)
    V = pcm.positions(surf.X + 0.01 * np.random.default_rng(5).normal(size=surf.X.shape), np.zeros(6))
    threads = ipctk.get_num_threads()
    ipctk.set_num_threads(1)  # the broad phase's order is that of its threads
    try:
        got = pcm.candidates(V, 0.3)
        cand = ipctk.Candidates()
        cand.build(pcm.mesh, V, 0.3)
    finally:
        ipctk.set_num_threads(threads)
    fv = [(c.face_id, c.vertex_id) for c in cand.fv_candidates]
    want_fv = [p for p in fv if p[1] < pcm.n_center]
    want_ee = []
    for c in cand.ee_candidates:
        a, b = c.edge0_id, c.edge1_id
        ca, cb = pcm.edge_class[a], pcm.edge_class[b]
        oa, ob = pcm.edge_owned[a], pcm.edge_owned[b]
        d = tuple(pcm.edge_image[b] - pcm.edge_image[a])
        if (
            (ca < cb and oa)
            or (ca > cb and ob)
            or (ca == cb and ((oa and d > (0, 0)) or (ob and d < (0, 0))))
        ):
            want_ee.append((a, b))
    assert 0 < len(want_fv) < len(fv) and want_ee
    assert [(c.face_id, c.vertex_id) for c in got.fv_candidates] == want_fv
    assert [(c.edge0_id, c.edge1_id) for c in got.ee_candidates] == want_ee


#: a volumetric run of the code before these changes made to repeat bit for bit, in a fresh interpreter
#: (PARDISO's handles and MKL's thread pool are process-wide state): BLAS and MKL (PARDISO's) on one thread,
#: and the Newton driver's choice between chord and Newton steps timed by the count of evaluations that run
#: used for its clock (1, 2, 20 for the energy, the gradient, the Hessian; nothing for the linear solves).
#: ipctk runs on one thread inside the ``ipc`` law, and the driver counts work instead of wall seconds, by
#: default now (tests/test_repeatable.py)
DETERMINISTIC_RUN = textwrap.dedent(
    """\
    import json, sys
    import knitframe.numerics.newton_driver as nd
    from knitframe import get_registry
    from knitframe.records import Fabric, LoadPath, Scene

    nd.WORK_COST.update({0: 1.0, 1: 2.0, 2: 20.0, "factorisation": 0.0, "solve": 0.0})
    reg = get_registry()
    solver = reg["solver"]["volumetric"](
        order=1, seed=1.0, linear_solver={"kind": "direct", "backend": sys.argv[1]}
    )
    r = solver.simulate(
        Fabric(pattern="jersey", yarn=reg["yarn"]["cotton"], stitch_length=12),
        Scene(
            load=LoadPath(kind="equibiaxial", max_strain=0.05, steps=1),
            effects=("large_deformation", "bending", "contact", "prestress", "friction", "self_contact"),
        ),
    )
    print(json.dumps([float(r.T1[-1]), float(r.T2[-1])]))
    """
)


@pytest.mark.parametrize("backend", ["pardiso", pytest.param("auto", marks=pytest.mark.slow)])
def test_small_cell_keeps_the_tensions_of_the_code_before(backend):
    """The tensions of a small cell are those of the code before, to the last digit (1e-12), in a run made
    repeatable (:data:`DETERMINISTIC_RUN`); PARDISO takes the Hessian's free block as CSR now, SuperLU as
    CSC."""
    pytest.importorskip("gmsh")
    pytest.importorskip("ipctk")
    from knitframe_linsolvers.direct import available

    if backend == "pardiso" and not available("pardiso"):
        pytest.skip("pypardiso is not installed")
    one = {k: "1" for k in ("MKL_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
    out = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", DETERMINISTIC_RUN, backend],
        capture_output=True,
        text=True,
        env={**os.environ, **one},
        timeout=600,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    T1, T2 = json.loads(out.stdout.strip().splitlines()[-1])
    assert T1 == pytest.approx(PINNED[backend][0], rel=1e-12, abs=0)
    assert T2 == pytest.approx(PINNED[backend][1], rel=1e-12, abs=0)
