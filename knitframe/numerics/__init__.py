"""Shared numerics that solver plugins build on: a public, documented subpackage.

=========================  ==================================================================
module                     what it holds
=========================  ==================================================================
``newton``                 the Newton driver (:func:`minimise`), load-path continuation with
                           cut-back and per-step checkpoints
``newton_driver``          the state and stages of one :func:`minimise` iteration
``newton_steps``           the line search, extrapolated, halved and chord steps of Newton
``settings``               a solver's ``[solver.newton]`` tuning table: presets and overrides
``stepfiles``              one VTU file per converged step and the ``.pvd`` that lists them
``periodic``               the periodic 2x2 cell's macro degrees of freedom and its tensions
``contact_search``         broad-phase search between yarn segments, with periodic images
``contact``                solid contact: surfaces, gaps, pairing, P2 projection, penalty and
                           friction terms, assembly (one module per concern)
``mesh``                   swept tetrahedral yarn tubes (gmsh) for the volumetric cell
``memory``, ``parallel``   process memory and thread settings for the large solves
=========================  ==================================================================

Plugins import :mod:`knitframe` and these modules; nothing else of the core.
"""
