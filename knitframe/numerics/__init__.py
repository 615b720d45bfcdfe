"""Shared numerics that solver plugins build on: a public, documented subpackage.

=========================  ==================================================================
module                     what it holds
=========================  ==================================================================
``cellrun``                the unit-cell run skeleton (:class:`CellRun`): pre-stress and load
                           phases, checkpoints and resume, VTU files, truncate, the Response
``continuation``           load-path continuation with cut-back, and per-step checkpoints
``newton``                 Newton's method on an energy (:func:`minimise`), its options
``newton_options``         the records of Newton's method: its options, result and problem
``newton_driver``          the state and stages of one :func:`minimise` iteration
``newton_steps``           the line search, extrapolated, halved and chord steps of Newton
``settings``               a solver's ``[solver.newton]`` tuning table: presets and overrides
``stepfiles``              one VTU file per converged step and the ``.pvd`` that lists them
``periodic``               the periodic 2x2 cell's macro degrees of freedom and its tensions
``pattern``                sparse assembly into a cached CSR pattern (no COO → CSR per call)
``contact_search``         broad-phase search between yarn segments, with periodic images
``contact``                solid contact: surfaces, gaps, pairing, P2 projection, penalty and
                           friction terms, assembly (one module per concern)
``mesh``                   swept tetrahedral yarn tubes (gmsh) for the volumetric cell: the
                           section, the swept cell, facets, element quality
``memory``, ``parallel``   process memory and thread settings for the large solves
=========================  ==================================================================

Plugins import :mod:`knitframe` and these modules; nothing else of the core.
"""
