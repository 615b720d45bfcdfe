"""Swept tetrahedral tube meshes of yarn centerlines (knitframe.numerics.mesh)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from knitframe.errors import GeometryError
from knitframe.geometry import Centerline, UnitCell
from knitframe.numerics.mesh import cell_mesh, mesh_quality, section_mesh


def helix_cell(R: float = 2.0, c: float = 1.0, r: float = 0.3) -> UnitCell:
    """One helical turn, periodic along its axis (L1 = pitch), with a far wale image."""
    heli = Centerline(
        "helix",
        lambda t: np.stack([R * np.cos(t), R * np.sin(t), c * t], 1),
        lambda t: np.stack([-R * np.sin(t), R * np.cos(t), c + 0 * t], 1),
        0.0,
        2 * np.pi,
        np.array([0.0, 0.0, 2 * np.pi * c]),
    )
    return UnitCell(
        "helix", (heli,), heli.period, np.array([3 * R + 4 * r, 0, 0]), r, ((0, 0),), (("k",),), 1.0, 1.0, 1.0
    )


@pytest.fixture(scope="module", params=[1, 2])
def helix_mesh(request):
    return cell_mesh(helix_cell(), order=request.param)


def test_end_faces_match_node_for_node(helix_mesh):
    """The end face of a yarn coincides with its paired start face shifted by L1, node for node, to 1e-12."""
    ((end, start, shift),) = helix_mesh.end_pairs
    x = helix_mesh.nodes
    dist, idx = cKDTree(x[start] + shift).query(x[end])
    assert dist.max() < 1e-12
    assert np.array_equal(np.sort(idx), np.arange(start.size))
    sec = section_mesh(1 / 3)
    n_edges = np.unique(np.sort(sec.triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1), axis=0).shape[0]
    assert end.size == sec.points.shape[0] + (n_edges if helix_mesh.order == 2 else 0)


def test_no_hanging_faces(helix_mesh):
    """Every facet is shared by two tetrahedra except the lateral surface and the two end caps."""
    m = helix_mesh.mesh
    n_boundary = m.boundary_facets().size
    n_lateral = helix_mesh.surface.shape[0]
    n_cap = 2 * section_mesh(1 / 3).triangles.shape[0]
    assert n_boundary == n_lateral + n_cap
    # Euler characteristic of a solid cylinder: V - E + F - T = 1
    assert m.nvertices - m.nedges + m.nfacets - m.nelements == 1


def test_volume_and_quality(helix_mesh):
    """The mesh volume matches π r² L (P1: polygonal section, 2.5 %; P2: curved, 0.01 %) with sound
    elements."""
    q = mesh_quality(helix_mesh)
    tol = 0.025 if helix_mesh.order == 1 else 1e-4
    assert abs(q["volume_error"]) < tol
    assert q["min_dihedral_deg"] > 15.0 and q["max_dihedral_deg"] < 150.0
    assert q["max_aspect_ratio"] < 3.0
    assert q["min_jacobian_ratio"] > 0.5


def test_surface_is_outward_and_covers_the_tube(helix_mesh):
    """Lateral surface triangles point away from the centerline and their area approximates 2π r L."""
    x, tri = helix_mesh.nodes, helix_mesh.surface[:, :3]
    n = np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]])
    off = helix_mesh.node_offset[tri].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", n, off) > 0)
    area = 0.5 * np.linalg.norm(n, axis=1).sum()
    exact = 2 * np.pi * helix_mesh.radius * helix_mesh.lengths.sum()
    assert abs(area / exact - 1) < 0.02


def test_seed_controls_resolution():
    """Halving the seed multiplies the element count by about eight."""
    coarse = cell_mesh(helix_cell(), seed=0.6, check=False)
    fine = cell_mesh(helix_cell(), seed=0.3, check=False)
    assert 5.0 < fine.n_elements / coarse.n_elements < 12.0


def test_crossing_centerlines_are_refused():
    """Turns of a helix closer than one yarn radius raise GeometryError before meshing."""
    with pytest.raises(GeometryError, match="cross"):
        cell_mesh(helix_cell(R=2.0, c=0.03, r=0.3))


def test_folding_tube_is_refused():
    """A centerline bent tighter than the tube radius raises GeometryError."""
    with pytest.raises(GeometryError, match="bends"):
        cell_mesh(helix_cell(R=0.2, c=0.05, r=0.3))
