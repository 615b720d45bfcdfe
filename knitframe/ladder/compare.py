"""The rungs compared: tension errors (NRMSE) of one curve against another and the measured
points within a simulated path.
"""

from __future__ import annotations

import numpy as np

from knitframe.records import Response


def loaded_directions(load: str) -> tuple[int, ...]:
    """Indices (0 course, 1 wale) of the directions a load kind pulls on."""
    return {"uniaxial-course": (0,), "uniaxial-wale": (1,)}.get(load, (0, 1))


def tension_errors(ref: Response, r: Response) -> dict[str, float | None]:
    """NRMSE of ``r``'s course and wale tension against ``ref``, and overall.

    The normalisation is :func:`knitframe.curves.nrmse_between`'s (the reference's largest
    tension), so with both directions loaded ``overall`` is ``nrmse_between(ref, r)``. Under a
    uniaxial load the free direction carries no tension in either curve: it is left out (None),
    and ``overall`` is the loaded direction's.
    """
    from knitframe.curves import nrmse_between

    dirs = loaded_directions(ref.load)
    scale = max(np.abs(ref.T1).max(), np.abs(ref.T2).max())
    out: dict[str, float | None] = {"course": None, "wale": None}
    for d, name in ((0, "course"), (1, "wale")):
        if d in dirs:
            lam_ref, T_ref = (ref.lambda1, ref.T1) if d == 0 else (ref.lambda2, ref.T2)
            lam, T = (r.lambda1, r.T1) if d == 0 else (r.lambda2, r.T2)
            o = np.argsort(lam)
            out[name] = float(np.sqrt(np.mean((np.interp(lam_ref, lam[o], T[o]) - T_ref) ** 2)) / scale)
    out["overall"] = nrmse_between(ref, r) if len(dirs) == 2 else out["course" if dirs == (0,) else "wale"]
    return out


def within_range(measured: Response, top: float) -> Response | None:
    """The measured points up to the simulated path's largest stretch ``top`` (None if fewer than 2)."""
    d = loaded_directions(measured.load)
    lam = (
        measured.lambda1
        if d == (0,)
        else measured.lambda2
        if d == (1,)
        else np.maximum(measured.lambda1, measured.lambda2)
    )
    keep = lam <= top + 1e-9
    if keep.sum() < 2:
        return None
    arrays = {k: getattr(measured, k)[keep] for k in Response._ARRAYS if getattr(measured, k) is not None}
    return measured.evolve(**arrays)
