"""Volumetric tube meshes of yarn centerlines: swept cross-sections split into tetrahedra.

A yarn of radius r around a centerline C(s) (s = arc length) is meshed by sweeping one
triangulated unit disc (meshed once by gmsh, element size ``seed``·r) along C on a
rotation-minimising frame (N, B)::

    x(s, ξ, η) = C(s) + r (ξ N(s) + η B(s)),        (ξ, η) in the unit disc

Layers are equally spaced in arc length, about ``seed``·r apart. Each prism between two layers is
split into three tetrahedra by the *minimum vertex index* rule (every quadrilateral face is cut
by the diagonal through its smallest global vertex index), which makes neighbouring prisms agree
on their shared faces, so there are no hanging faces. Everything after the frame recursion is
vectorised over layers and elements.

Why a sweep and not gmsh's OCC pipe: the pipe along looping centerlines was slow and fragile, and a
sweep gives end faces that coincide node for node by construction when the frame's twist is
closed around each yarn cycle of the unit cell (end of yarn i continues as the start of yarn j
shifted by L1).

P2 meshes are isoparametric (``skfem.MeshTet2``): mid-edge nodes are placed on the exact swept
geometry (half-layer frames, mid-section points pushed onto the circle on the lateral surface),
so the tube surface is curved rather than polygonal.

=============  ===================================================================================
module         what it holds
=============  ===================================================================================
``section``    the unit-disc cross-section (:func:`section_mesh`) and arc-length sampling
``cell``       :func:`cell_mesh` and its :class:`CellMesh`: the sweep, step by step
``facets``     boundary facets as node arrays (:func:`surface_facets`), their sub-triangles
``quality``    :func:`mesh_quality`: angles, aspect ratio, Jacobians, volume
=============  ===================================================================================
"""

from knitframe.numerics.mesh.cell import CellMesh, cell_mesh
from knitframe.numerics.mesh.facets import split_facets, surface_facets
from knitframe.numerics.mesh.quality import mesh_quality
from knitframe.numerics.mesh.section import Section, arc_length_samples, section_mesh

__all__ = [
    "Section",
    "CellMesh",
    "section_mesh",
    "arc_length_samples",
    "cell_mesh",
    "mesh_quality",
    "surface_facets",
    "split_facets",
]
