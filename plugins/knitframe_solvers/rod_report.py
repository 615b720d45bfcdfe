"""What a rod run reports: its Response and provenance, the branch jumps and the shear of its sections.

The last phase of :class:`knitframe_solvers.rod_run.RodRun` (the run is described in
:mod:`knitframe_solvers.rod`) and the bookkeeping on the way: the largest shear angle of each load
step of a shear-deformable rod, kept in the checkpointed state so a resumed run judges its whole
path, and the warnings of a shear length above the stitch and of sections sheared past the rod's
small-angle law (:data:`SHEAR_RANGE_DEG`).
"""

from __future__ import annotations

import functools

import attrs
import numpy as np

from knitframe.records import Response
from knitframe.yarn import shear_length
from knitframe_solvers.rod_branches import flag_jumps

__all__ = ["RodReport", "SHEAR_RANGE_DEG"]

#: largest shear angle of a shear-deformable rod's sections before its curve is called suspect, degrees:
#: its shear energy 2 κGA l0 tan²(γ/2) departs from the linear law ½ κGA l0 γ² by 4.8 % at 30°
SHEAR_RANGE_DEG = 30.0


class RodReport:
    """The Response of a rod run and the shear bookkeeping of its load steps.

    A base of :class:`knitframe_solvers.rod_run.RodRun`, whose state these methods read (``state``,
    ``run``, ``model``, ``energy``, ``cell``, ``snaps``, ``segments``, …).
    """

    def warn_long_shear_length(self) -> None:
        """Say before work starts when a shear-deformable rod's yarn has a shear length above its stitch."""
        if self.model.directors is None:
            return
        ls, ell = shear_length(self.fabric.yarn), float(self.cell.arc_length_per_stitch)
        if ls > ell:
            self.run.warn(
                f'{self.run.where}: with shear = "resolved", the yarn\'s shear length {ls:.3g} mm is longer '
                f"than its stitch ({ell:.3g} mm): its sections hardly turn with the loops and shear beyond a "
                "rod's small-angle law, so the run may stall or its curve be suspect",
                stacklevel=4,
            )

    def record_shear(self, index: int, q: np.ndarray) -> None:
        """Keep load step ``index``'s largest shear angle in the checkpointed state, so a resumed run
        judges its whole path; index −1 (the relaxed lattice) begins a path. Only with directors."""
        if self.model.directors is None:
            return
        kept = self.state["shear_deg"][: max(index, 0)]
        self.state["shear_deg"] = kept + ([float(self.model.shear_angles(q).max())] if index >= 0 else [])

    def response(self) -> Response:
        """The Response, with the branch jumps flagged and the rod's provenance."""
        fabric, scene, model, cell, energy, state = (
            self.fabric,
            self.scene,
            self.model,
            self.cell,
            self.energy,
            self.state,
        )
        # warnings point where simulate was called, as the fallback's does
        warn = functools.partial(self.run.warn, stacklevel=5)
        jumps = flag_jumps(self.run.rows_array(), scene.load, self.snaps, warn, self.run.where)
        shear = self.max_shear_angle()
        if shear is not None and shear > SHEAR_RANGE_DEG:
            warn(
                f"{self.run.where}: the yarn sections shear by up to {shear:.0f}° (the rod's shear law holds "
                f"for small angles, up to about {SHEAR_RANGE_DEG:g}°); the curve is suspect"
            )
        size = (
            f"SL{fabric.stitch_length:g}"
            if fabric.stitch_length is not None
            else f"{fabric.arc_length:g} mm/stitch"
        )
        lat = self.lat
        return self.run.response(
            source=f"rod {fabric.pattern}",
            mesh=f"{model.n_nodes} nodes, {len(model.edges)} segments ({self.segments}/stitch)",
            label=f"rod {fabric.pattern} {size} {fabric.yarn.name}",
            extra={
                "EA_N": energy.EA,
                "EI_Nmm2": energy.EI,
                "k_line_N_per_mm2": energy.k_line,
                "dk_mm": cell.dk,
                "contact_distance_mm": self.dk_full,
                "L1_mm": lat.L1.tolist(),
                "L2_mm": lat.L2.tolist(),
                "effects": sorted(scene.effects),
                "options": attrs.asdict(self.solver),
                "prestress_start": state["start"],
                "relaxed_stretch": state["lam_ref"],
                "branch_jumps": jumps,
                "relaxed_energy_Nmm": state["relaxed_energy"],
                "starts": state["starts"],
                "start_chosen": state["start_chosen"],
                "shear_deformable": model.directors is not None,
                "kGA_N": energy.GA if model.directors is not None else None,
                # the knitted loop's Rayleigh wavenumber against the effective stiffness's 2π/ℓ
                "bending_wavenumber_per_mm": self.bending_wavenumber(),
                "effective_bending_wavenumber_per_mm": 2.0 * np.pi / float(cell.arc_length_per_stitch),
                "max_shear_angle_deg": shear,
                "max_shear_angle_by_step_deg": list(self.state["shear_deg"]) or None,
            },
        )

    def bending_wavenumber(self) -> float | None:
        """The knitted cell's Rayleigh wavenumber k_R (:func:`knitframe.geometry.bending_wavenumber`), 1/mm.

        None for a cell whose yarns are straight.
        """
        from knitframe.geometry import bending_wavenumber

        try:
            return float(bending_wavenumber(self.cell))
        except ValueError:
            return None

    def max_shear_angle(self) -> float | None:
        """The largest angle between a segment and its director over the load path's steps, degrees.

        None for a rod without directors. A resumed run includes the steps before the resume (they
        are in the checkpointed state).
        """
        angles = self.state["shear_deg"]
        if self.model.directors is None or not angles:
            return None
        return max(angles)
