"""Periodic lattice, macro DOFs, point maps and the periodic transform."""

from __future__ import annotations

import numpy as np
import pytest

from knitframe.errors import GeometryError
from knitframe.numerics.periodic import N_MACRO, Lattice, PointMap, macro_index, periodic_transform

LAT = Lattice([2.0, 0.0, 0.0], [0.3, 1.5, 0.0])


def test_shift_is_F_times_reference_shift():
    """An image's current shift is F̄·(k1 L1 + k2 L2) for any macro state."""
    F = np.array([[1.2, 0.1, 0.0], [-0.05, 0.9, 0.0], [0.02, 0.03, 1.0]])
    h = Lattice.h_from_F(F)
    k = np.array([[1, 0], [0, -1], [1, 1], [-1, 2]])
    S = k[:, :1] * LAT.L1 + k[:, 1:] * LAT.L2
    assert np.allclose(LAT.shift(k, h), S @ F.T)
    assert np.allclose(Lattice.F(h), F)


def test_constraints_free_side():
    """A stretch given as None leaves its macro DOF free; the rest are prescribed to diag(λ1, λ2) − I."""
    pres, val = LAT.constraints(1.3, None)
    assert not pres[macro_index(1, 1)] and pres.sum() == N_MACRO - 1
    assert val[macro_index(0, 0)] == pytest.approx(0.3)


def test_lattice_rejects_out_of_plane_and_parallel_vectors():
    """Lattice vectors must lie in z = 0 and span the plane."""
    with pytest.raises(GeometryError):
        Lattice([1, 0, 0.1], [0, 1, 0])
    with pytest.raises(GeometryError):
        Lattice([1, 0, 0], [2, 0, 0])


def test_pointmap_gradient_and_hessian_are_the_chain_rule():
    """Scattered gradient and Hessian equal finite differences of a function of image points."""
    rng = np.random.default_rng(3)
    n = 5
    X = rng.standard_normal((n, 3))
    nodes = rng.integers(0, n, size=(7, 2))
    images = rng.integers(-1, 2, size=(7, 2, 2))
    pm = PointMap(n, nodes, images, LAT)

    def energy(q):
        p = pm.points(X + q[: 3 * n].reshape(-1, 3), q[3 * n :])
        e = p[:, 1] - p[:, 0]
        l2 = np.einsum("mi,mi->m", e, e)
        g = np.stack([-2 * e, 2 * e], axis=1) * l2[:, None, None] * 2
        H = np.zeros((7, 2, 3, 2, 3))
        blk = 4 * l2[:, None, None] * np.eye(3) + 8 * e[:, :, None] * e[:, None, :]
        H[:, 0, :, 0], H[:, 1, :, 1], H[:, 0, :, 1], H[:, 1, :, 0] = blk, blk, -blk, -blk
        return float(np.sum(l2**2)), pm.gradient(g), pm.hessian(H).toarray()

    q = 0.1 * rng.standard_normal(pm.n_dof)
    E, g, H = energy(q)
    eps = 1e-6
    for i in range(pm.n_dof):
        dq = np.zeros(pm.n_dof)
        dq[i] = eps
        Ep, gp, _ = energy(q + dq)
        Em, gm, _ = energy(q - dq)
        assert (Ep - Em) / (2 * eps) == pytest.approx(g[i], rel=1e-6, abs=1e-6)
        assert np.allclose((gp - gm) / (2 * eps), H[:, i], rtol=1e-5, atol=1e-5)


def test_periodic_transform_ties_slaves_to_masters_including_corners():
    """u(X + L) − u(X) = (F̄ − I)·L for every slave, also for a corner reached through two pairs."""
    # nodes: 0 master, 1 = 0 + L1, 2 = 0 + L2, 3 = 1 + L2 (corner), 4 interior
    X = np.array([[0, 0, 0], LAT.L1, LAT.L2, LAT.L1 + LAT.L2, [0.5, 0.5, 0.1]])
    T, ind = periodic_transform(
        5, slave=[1, 2, 3], master=[0, 0, 1], images=[[1, 0], [0, 1], [0, 1]], lattice=LAT
    )
    assert list(ind) == [0, 4]
    rng = np.random.default_rng(0)
    qt = rng.standard_normal(T.shape[1])
    u = (T @ qt).reshape(-1, 3)
    H = Lattice.H(qt[-N_MACRO:])
    for s, m in ((1, 0), (2, 0), (3, 0), (3, 1), (3, 2)):
        assert np.allclose(u[s] - u[m], H @ (X[s] - X[m])[:2])
