"""The limb a garment is designed on: closed cross-section loops at stations along its axis.

A :class:`Limb` is a structured quad grid on the limb's surface. Station ``i`` is a plane normal to
the (straight) axis at distance ``positions[i]`` (mm) from station 0; loop ``i`` is the limb's
cross-section in that plane, sampled at ``n_around`` points equally spaced by arc length. Station 0
is the distal end (wrist or ankle) and the axis runs distal → proximal. Every loop runs
counter-clockwise seen looking from station 0 towards the last station, and its point 0 lies on the
half-line from the section's area centroid along one common reference direction ``e1``
(perpendicular to the axis), so ``(i, j)`` is the same azimuth on every station.

Local section coordinates (used by every derived quantity): with ``d`` the axis direction and
``f1``, ``f2 = f1 × d`` an orthonormal pair perpendicular to it, a point ``p`` of loop ``i`` has
``X = (p - o)·f1``, ``Y = (p - o)·f2`` (``o`` = ``axis_origin``). Because ``f1 × f2 = -d``, the
loops are *positively* oriented (counter-clockwise) in (X, Y), and ``(p[i+1, j] - p[i, j]) ×
(p[i, j+1] - p[i, j])`` points out of the limb.

Each loop is represented by its periodic trigonometric interpolant (the unique trigonometric
polynomial of degree n/2 through its n points, from the FFT)::

    w(θ) = X(θ) + i Y(θ) = Σ_k c_k e^{ikθ},   c_k = (1/n) Σ_j w_j e^{-2πi jk/n},   θ ∈ [0, 2π)

which is exact for a circle and spectrally accurate for any smooth section. From it:

* circumference  C = ∮ |w'(θ)| dθ                           (periodic trapezoid rule on 8n points)
* area           A = ½ ∮ Im( conj(w) w' ) dθ                (Green's theorem)
* centroid       (X̄, Ȳ) = (1/A) ( ∮ ½X² dY , -∮ ½Y² dX )
* curvature      κ = Im( conj(w') w'' ) / |w'|³,  ρ = 1/κ    (on the low-pass filtered loop)

The inputs are a scan (:meth:`Limb.from_scan`: STL, OBJ, PLY and everything trimesh or meshio read),
clinical tape measurements (:meth:`Limb.from_measurements`) or the built-in :func:`example_arm`.
Units are mm throughout.

Modules: :mod:`.sections` (one loop's interpolant, curvature, ellipses), :mod:`.record` (the
:class:`Limb`), :mod:`.measured` (tape measurements), :mod:`.examples` (the example arm and
:func:`load_limb`), and for scans :mod:`.reading` (files), :mod:`.shells` (which shell is the limb),
:mod:`.slicing` (plane cuts, loops, resampling), :mod:`.checks` (refusals) and :mod:`.scan` (the
steps of :meth:`Limb.from_scan`).
"""

from knitframe.garment.limb.examples import EXAMPLE_ARM_MEASUREMENTS, example_arm, load_limb
from knitframe.garment.limb.record import Limb
from knitframe.garment.limb.sections import ellipse_semi_axes, loop_curvature_radius

__all__ = [
    "Limb",
    "example_arm",
    "load_limb",
    "loop_curvature_radius",
    "ellipse_semi_axes",
    "EXAMPLE_ARM_MEASUREMENTS",
]
