"""Branch-jump detection on the rod solver's load paths: free-side jumps, tension drops, where they happened.

Stiff yarns in tight cells are multistable, and a load path may snap from its branch of
equilibria to another. Under a uniaxial load the free side's stretch jumps (:func:`branch_jumps`,
cut back by the load path's ``follow_branch`` with :func:`is_jump`); and a tension falls while
its stretch grows (:func:`tension_drops`: both tensions with no free side, the loaded one of a
uniaxial path). :func:`locate_jumps` attaches where within a load step a kept snap happened,
and :func:`flag_jumps` turns all of them into the run's warnings.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["branch_jumps", "flag_jumps", "is_jump", "locate_jumps", "tension_drops"]

#: a load step's free stretch jumps when it changes by more than JUMP_RATIO × the loaded stretch's change
#: and JUMP_FLOOR
JUMP_RATIO, JUMP_FLOOR = 3.0, 0.02
#: with no free side, a step whose stretch grows while its tension falls by more than this fraction of
#: the tension before it, and by more than DROP_FLOOR × the path's largest |tension|, is a snap
DROP_FRACTION, DROP_FLOOR = 0.10, 0.01
#: with ``follow_branch`` an increment is cut back already when the free change passes CUT_RATIO × the
#: loaded one (and JUMP_FLOOR): a smooth path passes once the increment is small enough, a snap never does
CUT_RATIO = 1.0


def is_jump(d_load: Any, d_free: Any, ratio: float = JUMP_RATIO, floor: float = JUMP_FLOOR) -> Any:
    r"""Whether a free-stretch change is a jump.

    :math:`|\Delta\lambda_{free}| > \max(\mathrm{ratio}\,|\Delta\lambda_{load}|, \mathrm{floor})`.
    """
    return np.abs(d_free) > np.maximum(ratio * np.abs(d_load), floor)


def branch_jumps(
    rows: np.ndarray, load: Any, *, ratio: float = JUMP_RATIO, floor: float = JUMP_FLOOR
) -> list[dict[str, Any]]:
    r"""Load steps where the free side's stretch jumps: a snap to another equilibrium branch.

    ``rows`` holds (λ1, λ2, T1, T2) per converged load step, from the relaxed lattice (λ = 1).
    Under a uniaxial load a step k is a jump when the free stretch changes by more than ``ratio``
    times the loaded stretch's change and by more than ``floor``:
    :math:`|\Delta\lambda_{free}| > \max(\mathrm{ratio}\,|\Delta\lambda_{load}|, \mathrm{floor})`.
    A smooth lateral contraction stays well below that (knit Poisson ratios are of order one).
    Equibiaxial and general paths have no free side and are not checked here.
    """
    if getattr(load, "kind", None) != "uniaxial" or len(rows) == 0:
        return []
    k_load = 0 if load.direction == "course" else 1
    k_free = 1 - k_load
    lam = np.vstack([[1.0, 1.0], rows[:, :2]])
    d_load = np.abs(np.diff(lam[:, k_load]))
    d_free = np.diff(lam[:, k_free])
    out = []
    for k in np.flatnonzero(is_jump(d_load, d_free, ratio, floor)):
        out.append(
            {
                "step": int(k) + 1,
                "free": "wale" if k_free else "course",
                "from": float(lam[k, k_free]),
                "to": float(lam[k + 1, k_free]),
                "loaded_change": float(d_load[k]),
            }
        )
    return out


def tension_drops(
    rows: np.ndarray, load: Any, *, fraction: float = DROP_FRACTION, floor: float = DROP_FLOOR
) -> list[dict[str, Any]]:
    r"""Load steps of a path where a tension falls while its stretch grows.

    ``rows`` holds (λ1, λ2, T1, T2) per converged load step. Along a direction d whose stretch
    grows in step k (Δλ_d > 0), the step is a snap to another equilibrium state when its tension
    falls by more than ``fraction`` of the tension before it and by more than ``floor`` times
    the path's largest |T|:
    :math:`T_d^{k-1} - T_d^{k} > \max(\mathrm{fraction}\,|T_d^{k-1}|, \mathrm{floor}\,\max|T|)`.
    A cell that stays on one branch stiffens or softens smoothly under a growing stretch; its
    tension does not fall. Under a uniaxial load only the loaded direction is checked (the free
    side carries no tension; its jumps are :func:`branch_jumps`'): a pulled cell that sticks and
    then slips, say with friction, drops its tension this way with its free side moving less
    than a jump.
    """
    if len(rows) == 0:
        return []
    lam = np.vstack([[1.0, 1.0], rows[:, :2]])
    T = np.vstack([[0.0, 0.0], rows[:, 2:4]])
    scale = floor * float(np.max(np.abs(T)))
    out = []
    directions = ((0, "course"), (1, "wale"))
    if getattr(load, "kind", None) == "uniaxial":
        directions = directions[:1] if load.direction == "course" else directions[1:]
    for d, name in directions:
        grows = np.diff(lam[:, d]) > 0
        fall = T[:-1, d] - T[1:, d]
        for k in np.flatnonzero(grows & (fall > np.maximum(fraction * np.abs(T[:-1, d]), scale))):
            out.append(
                {
                    "step": int(k) + 1,
                    "direction": name,
                    "from": float(T[k, d]),
                    "to": float(T[k + 1, d]),
                    "kind": "tension drop",
                }
            )
    return sorted(out, key=lambda j: (j["step"], j["direction"]))


def locate_jumps(
    jumps: list[dict[str, Any]], snaps: list[dict[str, list[float]]], rows: np.ndarray, load: Any
) -> list[dict[str, Any]]:
    """The load steps' jumps with where each happened: ``at_loaded_stretch`` [λa, λb] of its snap.

    ``snaps`` are the jumps the load path kept (``follow_branch``), each with its loaded and
    free stretches before and after and ``how``: at the smallest increment, or after Newton
    failed at the fold where the followed branch ends. A snap inside load step k (its
    loaded stretch between those of rows k−1 and k) is attached to that step's jump, or is
    reported as the step's jump when the whole step's change stays under :func:`branch_jumps`'s
    threshold.
    """
    if not snaps:
        return jumps
    k_load = 0 if load.direction == "course" else 1
    ends = np.concatenate([[1.0], rows[:, k_load]])
    out = {j["step"]: dict(j) for j in jumps}
    for snap in snaps:
        lo, hi = snap["loaded"]
        step = int(np.clip(np.searchsorted(ends, 0.5 * (lo + hi)), 1, len(rows)))  # loaded stretch rises
        jump = out.setdefault(
            step,
            {
                "step": step,
                "free": "wale" if k_load == 0 else "course",
                "from": snap["free"][0],
                "to": snap["free"][1],
                "loaded_change": float(abs(ends[step] - ends[step - 1])),
            },
        )
        jump.update(at_loaded_stretch=[lo, hi], how=snap["how"])
    return [out[k] for k in sorted(out)]


def flag_jumps(
    rows: np.ndarray, load: Any, snaps: list[dict[str, list[float]]], warn: Callable[[str], None], where: str
) -> list[dict[str, Any]]:
    """The load path's jumps and tension drops, sorted by step, each also warned about.

    ``warn(message)`` is called once per tension drop and once per free-side jump (its messages
    begin with ``where``, the solver and fabric); see :func:`branch_jumps`,
    :func:`tension_drops` and :func:`locate_jumps` for ``rows``, ``load`` and ``snaps``.
    """
    jumps = locate_jumps(branch_jumps(rows, load), snaps, rows, load)
    drops = tension_drops(rows, load)
    for j in drops:
        warn(
            f"{where}: load step {j['step']}: the {j['direction']} tension fell {j['from']:.4g} -> "
            f"{j['to']:.4g} N/mm while its stretch grew: the cell lost its stiffness or snapped to another "
            "state there, so the curve from there is suspect"
        )
    jumps = sorted(jumps + drops, key=lambda j: j["step"])
    for j in (j for j in jumps if "free" in j):
        at = (
            ""
            if "at_loaded_stretch" not in j
            else " (between loaded stretch {:.4f} and {:.4f}, {})".format(*j["at_loaded_stretch"], j["how"])
        )
        warn(
            f"{where}: load step {j['step']} jumped to another equilibrium branch{at}: the free {j['free']} "
            f"stretch went {j['from']:.3f} -> {j['to']:.3f} while the loaded stretch changed by "
            f"{j['loaded_change']:.3f}; the curve after it is another state"
        )
    return jumps
