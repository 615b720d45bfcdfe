"""The end of a solid contact law's ``evaluate``: lagged friction, assembly and the diagnostics.

Both solid laws (``penalty``, ``mortar``) finish an evaluation alike: when a ``friction_state``
is given and the law has friction, the lagged regularised Coulomb friction D of its frozen pairs
is added (:func:`~knitframe.numerics.contact.friction_terms`), E = W + D; the element terms are
assembled over q = [u (3N), h (6)] (:func:`~knitframe.numerics.contact.assemble`); and the
diagnostics every solver reads are reported with them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from knitframe.numerics.contact.assembly import assemble
from knitframe.numerics.contact.friction import FrictionState, friction_terms
from knitframe.numerics.contact.surfaces import Candidates, SolidSurface

__all__ = ["finish_evaluation"]

#: an element term (nodes (m, k), images (m, k, 2), grad (m, k, 3), hess (m, k, 3, k, 3))
Term = tuple[np.ndarray, np.ndarray, Any, Any]


def finish_evaluation(
    surface: SolidSurface,
    x: np.ndarray,
    h: np.ndarray | None,
    order: int,
    E: float,
    term: Term,
    *,
    friction: float,
    slip: float,
    friction_state: FrictionState | None,
    g: np.ndarray,
    pressure: np.ndarray,
    force: float,
    candidates: Candidates,
    merge: Callable[[list[Term]], list[Term]] | None = None,
) -> tuple[float, Any, Any, dict[str, Any]]:
    """(E, gradient, Hessian, info) of a solid contact law from its penalty energy ``E`` and element
    ``term``.

    With a non-empty ``friction_state`` and ``friction`` μ > 0 the friction energy and its term
    (on the state's nodes and images) are added, and ``info`` starts from the friction's
    diagnostics with ``friction_energy``. ``merge``, when given, turns the terms (the penalty's,
    then the friction's) into the ones assembled (``mortar`` sums those of one slave facet on one
    master element). ``info`` reports ``active`` (the number of gaps ``g``), ``max_penetration``
    (mm), the nodal ``pressure`` (MPa), the total normal ``force`` (N) and the ``candidates``
    the pairs came from.
    """
    terms = [term]
    info: dict[str, Any] = {}
    if friction_state is not None and friction > 0 and len(friction_state):
        Ef, gf, Hf, info = friction_terms(friction_state, x, h, surface.lattice, friction, slip, order)
        E += Ef
        info["friction_energy"] = Ef
        terms.append((friction_state.nodes, friction_state.images, gf, Hf))
    if merge is not None:
        terms = merge(terms)
    E, G, H = assemble(surface.n_nodes, surface.lattice, E, terms, order)
    info.update(
        {
            "active": int(g.size),
            "max_penetration": float(-g.min()) if g.size else 0.0,
            "pressure": pressure,
            "force": force,
            "candidates": candidates,
        }
    )
    return E, G, H, info
