"""Solid yarn–yarn contact: the geometry and terms shared by the solid contact laws.

The contact surface of a tetrahedral mesh is made of linear triangles or quadratic (P2) facets.
A contact law finds candidate pairs with the surface's broad phase, picks one master element
per slave point, measures its signed gap with exact derivatives, and turns the gaps into
penalty (and friction) energy terms that are assembled over q = [u (3N), h (6)].

=====================  =======================================================================
module                 what it holds
=====================  =======================================================================
``surfaces``           :class:`SolidSurface` (facets, slave/master sets, areas, strand
                       topology, lattice) and its broad phase (:class:`Candidates`)
``gaps``               the plane gap of linear triangles with exact derivatives, barycentric
                       coordinates, point–triangle distances and bounds
``p2``                 quadratic facets: shape functions, the closest-point projection
                       (:func:`project_p2`, :class:`P2Projection`)
``p2_gaps``            the gap to a quadratic facet at its closest point, exact derivatives
``nagata``             nodal normals and Nagata patches that smooth linear master surfaces
``pairing``            the nearest opposing master element of each point (:func:`select_pairs`)
``penalty``            penalty energy ½ ε w ψ(⟨−g⟩) and its element derivatives
``friction``           lagged regularised Coulomb friction (:class:`FrictionState`,
                       :func:`friction_potential`, :func:`friction_terms`)
``assembly``           summing element terms and scattering them to the global gradient and
                       Hessian through the periodic point map
``evaluation``         the end of a law's evaluation: lagged friction, assembly and the
                       diagnostics (:func:`finish_evaluation`)
=====================  =======================================================================
"""

from knitframe.numerics.contact.assembly import assemble, combine
from knitframe.numerics.contact.evaluation import finish_evaluation
from knitframe.numerics.contact.friction import FrictionState, friction_potential, friction_terms
from knitframe.numerics.contact.gaps import barycentric, distance_bound, plane_gap, point_triangle_distance
from knitframe.numerics.contact.nagata import chain_facet_derivatives, nagata_facets, node_normals
from knitframe.numerics.contact.p2 import P2Projection, p2_coefficients, p2_shape, project_p2, rim_edges
from knitframe.numerics.contact.p2_gaps import facet_gap, p2_gap_derivatives
from knitframe.numerics.contact.pairing import OPPOSING, Selection, nearest, select_pairs
from knitframe.numerics.contact.penalty import penalty_depth, penalty_terms
from knitframe.numerics.contact.surfaces import Candidates, SolidSurface, bezier_points, facet_size

__all__ = [
    "plane_gap",
    "barycentric",
    "point_triangle_distance",
    "distance_bound",
    "nearest",
    "node_normals",
    "penalty_terms",
    "penalty_depth",
    "combine",
    "rim_edges",
    "assemble",
    "finish_evaluation",
    "SolidSurface",
    "Candidates",
    "bezier_points",
    "select_pairs",
    "Selection",
    "OPPOSING",
    "p2_shape",
    "p2_coefficients",
    "project_p2",
    "P2Projection",
    "facet_gap",
    "p2_gap_derivatives",
    "FrictionState",
    "friction_potential",
    "friction_terms",
    "facet_size",
    "nagata_facets",
    "chain_facet_derivatives",
]
