"""The ``[solver.newton]`` tables of the rod and volumetric solvers: their tuning knobs and presets.

A user should not need these: the defaults were measured on the standard cells (the
measurements are in docs/notes/2026-11-27-solver-defaults.md), and a named preset covers the
usual reasons to change them. ``newton = "robust"`` picks a preset; ``newton = { preset =
"robust", max_step = 0.1 }`` changes keys of one (:mod:`knitframe.numerics.settings`). The
presets' runs are in docs/notes/2026-11-27-newton-presets.md.
"""

from __future__ import annotations

from typing import ClassVar, Literal

import attrs

from knitframe import validators as v
from knitframe.numerics.settings import Preset

__all__ = ["RodNewton", "VolumetricNewton"]


@attrs.frozen
class RodNewton:
    """Newton and cut-back settings of the rod solver (``[solver.newton]``)."""

    presets: ClassVar[dict[str, Preset]] = {
        "robust": Preset(
            {"max_step": 0.1, "min_step_fraction": 1.0 / 256},
            "shorter Newton steps and load increments cut back four times further before the run "
            "gives up: for tight or unusual cells whose default run stops on a cut-back",
        ),
        "fast": Preset(
            {"min_step_fraction": 1.0 / 16},
            "a failing load path gives up after four halvings of its increment instead of six: for "
            "sweeps over many cells, where a failure is better reported soon than fought; a run that "
            "converges takes the same path as with the defaults (longer Newton steps were tried and "
            "reached another equilibrium state)",
        ),
    }

    #: how far one Newton step may move a node, as a fraction of the current contact distance (at
    #: least dk/2); smaller is slower but keeps contacts from being jumped over, -
    max_step: float = attrs.field(default=0.2, validator=v.positive)
    #: smallest load increment, as a fraction of a load step, before a failing run gives up, -
    min_step_fraction: float = attrs.field(default=1.0 / 64, validator=v.in_range(0.0, 1.0, lo_open=True))
    #: damping added to Newton while a yarn is not yet held by any contact (it would float freely), as a
    #: fraction of the stiffness, -
    stabilisation: float = attrs.field(default=1e-6, validator=v.non_negative)


@attrs.frozen
class VolumetricNewton:
    """Newton, contact-search and cut-back settings of the volumetric solver (``[solver.newton]``)."""

    presets: ClassVar[dict[str, Preset]] = {
        "robust": Preset(
            {"min_step_fraction": 1.0 / 256, "cap_shift": 4.0, "contact_search": "evaluation"},
            "load increments cut back four times further before the run gives up, an oversized Newton "
            "step damped instead of shortened whole, and a fresh contact search at every energy "
            "evaluation: for cells whose default run stops on a cut-back; slower per iteration",
        ),
        "fast": Preset(
            {"extrapolation": 8.0, "chord_after_full_steps": False},
            "Newton steps lengthened where the energy shows they were too short, and steps on a reused "
            "factorisation only after shortened steps: fewer linear solves on P1 cells, for quick looks; "
            "on fine P2 cells the longer steps slow the run (measured in docs/performance.md)",
        ),
    }

    #: how far one Newton step may move a node, in yarn radii (at most half of ``reach`` while the contact
    #: search runs once per iteration), -
    max_step: float = attrs.field(default=0.25, validator=v.positive)
    #: how far around each surface point contacts are looked for, in yarn radii, -
    reach: float = attrs.field(default=0.5, validator=v.positive)
    #: when the contact search runs: once per Newton iteration ("iteration", its pairs kept through the line
    #: search) or at every energy evaluation ("evaluation": safer, slower)
    contact_search: Literal["iteration", "evaluation"] = attrs.field(
        default="iteration", validator=v.one_of(("iteration", "evaluation"))
    )
    #: the stiffness matrix Newton uses: made positive at each material point ("projected"), the exact one
    #: ("exact"), or exact near the solution and projected where exact steps fail ("adaptive")
    tangent: Literal["adaptive", "exact", "projected"] = attrs.field(
        default="projected", validator=v.one_of(("adaptive", "exact", "projected"))
    )
    #: with tangent = "adaptive", start each load increment on the projected matrix
    start_projected: bool = attrs.field(default=False, validator=v.boolean)
    #: how the projected matrix is made positive: negative eigenvalues set to zero at each material point
    #: ("clamp"), made positive there ("abs"), or set to zero per element ("element", slower)
    eigenvalue_filter: Literal["clamp", "abs", "element"] = attrs.field(
        default="clamp", validator=v.one_of(("clamp", "abs", "element"))
    )
    #: also converged when the residual is at most this fraction of the average force the cell carries
    #: (0: off), -
    flux_tolerance: float = attrs.field(default=5e-3, validator=v.non_negative)
    #: the same fraction after 9 iterations (0: flux_tolerance throughout), -
    late_flux_tolerance: float = attrs.field(default=2e-2, validator=v.non_negative)
    #: ... provided the last Newton correction is at most this fraction of the increment's displacement, -
    correction_tolerance: float = attrs.field(default=1e-2, validator=v.positive)
    #: how much looser (residual, force and step tests) the intermediate pre-stress states are solved than
    #: the final ones, -
    path_tolerance_factor: float = attrs.field(default=10.0, validator=v.in_range(1.0, 1e6))
    #: how a load increment starts: the cell stretched with the load ("affine"), or also the yarns'
    #: movement extrapolated from the last two increments ("secant")
    predictor: Literal["affine", "secant"] = attrs.field(
        default="affine", validator=v.one_of(("affine", "secant"))
    )
    #: with barrier contact, reuse a factorised matrix for cheap extra steps while they pay (needs a
    #: linear solver that factorises)
    chord: bool = attrs.field(default=True, validator=v.boolean)
    #: with chord, such steps also after full Newton steps
    chord_after_full_steps: bool = attrs.field(default=True, validator=v.boolean)
    #: halve a Newton step that undoes the last one, when that lowers the energy (ends a back-and-forth
    #: at friction's stick-slip switch)
    halve_reversals: bool = attrs.field(default=True, validator=v.boolean)
    #: after a full Newton step, try one up to this many times longer when the energy says it was too short
    #: (1: off), -
    extrapolation: float = attrs.field(default=1.0, validator=v.in_range(1.0, 1e3))
    #: a Newton step longer than this × max_step is damped (a larger matrix shift) instead of shortened whole
    #: (0: off), -
    cap_shift: float = attrs.field(default=0.0, validator=v.non_negative)
    #: smallest load increment, as a fraction of a load step, before a failing run gives up, -
    min_step_fraction: float = attrs.field(default=1.0 / 64, validator=v.in_range(0.0, 1.0, lo_open=True))
    #: give up a load increment (and cut it back) when the residual has not improved in this many Newton
    #: iterations (0: only after max_iterations; never with barrier contact), -
    stall_iterations: int = attrs.field(default=10, validator=v.in_range(0, 10000))
    #: weak springs holding each node to where the increment started, keeping loose yarns in place, as a
    #: fraction of E_transverse / h², -
    stabilisation: float = attrs.field(default=1e-4, validator=v.in_range(0.0, 1.0))
    #: keep freed memory in the process for the run (fewer page faults and faster iterations; the process
    #: keeps its peak memory until it exits)
    retain_freed_memory: bool = attrs.field(default=True, validator=v.boolean)
