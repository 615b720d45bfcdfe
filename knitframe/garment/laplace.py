r"""Laplace's law for a tensioned sleeve on a limb, and the pressure unit.

.. math:: p = \frac{T}{r}

with T the course (circumferential) tension per unit length (N/mm) and r the radius (mm), so p is in
MPa = N/mm² before it is converted to mmHg (1 mmHg = 133.322 Pa, 1 MPa = 7500.6 mmHg).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MMHG_PER_MPA", "laplace_mmhg"]

#: 1 MPa = 1e6 Pa = 7500.6 mmHg (1 mmHg = 133.322 Pa)
MMHG_PER_MPA = 1e6 / 133.322


def laplace_mmhg(tension, radius) -> np.ndarray:
    """Pressure (mmHg) of a course tension ``tension`` (N/mm) on a radius ``radius`` (mm), broadcast.

    An infinite radius (a flat or concave stretch of the section, which the fabric bridges) gives 0.
    """
    return np.asarray(tension, dtype=np.float64) / np.asarray(radius, dtype=np.float64) * MMHG_PER_MPA
