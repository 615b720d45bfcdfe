r"""Patchworks of fabric regions: parallel strips, series chains and grids of both.

Each region is a tension–stretch curve along the load, T(λ) in N/mm, non-decreasing: either a
measured/simulated :class:`~knitframe.records.Response` (interpolated piecewise-linearly, made
monotone) or a fitted reduced model (its uniaxial response with a free or a fixed lateral side).

* **Parallel** (strips side by side across the load, widths w_i): every strip has the common
  stretch λ, the force is ``F = Σ w_i T_i(λ)`` (N) and the mean tension ``F / Σ w_i``.
* **Series** (regions one after another along the load, lengths L_j): every region carries the
  same tension T, and the stretches partition the end displacement,
  ``Σ_j L_j (λ_j(T) − 1) = u``. The left side is increasing in T, so T is found by a bracketed,
  bisection-safeguarded Newton iteration with ``d/dT = Σ_j L_j / T_j'(λ_j)``, each λ_j(T) by
  inverting the region's curve (exactly for Responses; for models by a safeguarded Newton iteration
  bracketed by a tabulated curve).
  The displacement of each interface, ``Σ_{k≤j} L_k (λ_k − 1)``, is reported.
* **Grid** (rows across the load, columns along it): each row is a series chain of the same total
  length, the rows act in parallel. Rows do not exchange shear, so this is the classical
  series-parallel (Reuss-in-rows, Voigt-across) estimate, not a full-field solution.

Zero-tension plateaus (slack, e.g. the paper's hgo with free sides below 1/cos θ) are handled:
while the chain's total slack exceeds the end displacement the tension is zero and the
displacement is shared in proportion to each region's slack. Only tension is modelled
(strains >= 0).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any, Literal

import attrs
import numpy as np

from knitframe.errors import KnitframeWarning, NumericalError
from knitframe.fitting import FREE_MIN, FitResult, bracketed_newton, direction_index, free_side_zero_message
from knitframe.records import Provenance, Response

__all__ = ["ResponseCurve", "ModelCurve", "as_curve", "PatchworkResult", "parallel", "series", "grid"]

#: Tension (N/mm) treated as "just taut" when inverting a curve with a zero plateau.
TAUT = 1e-12


@attrs.frozen(eq=False)
class ResponseCurve:
    """A measured or simulated curve along one direction, monotone and piecewise linear.

    Points are sorted by stretch; the tension is made non-decreasing by a running maximum and
    clipped at 0; a curve that starts above λ = 1 gets the point (1, 0) in front. Beyond the
    last point the last segment is extended linearly (and flagged by :meth:`extrapolated`).
    """

    #: (n,) stretch, increasing
    lam: np.ndarray
    #: (n,) tension, non-decreasing, N/mm
    T: np.ndarray
    label: str = ""

    @classmethod
    def from_response(cls, r: Response, direction: str | int | None = None) -> ResponseCurve:
        """The loaded direction of a uniaxial test, or ``direction`` of any Response."""
        d = r.loaded_direction if direction is None else direction_index(direction)
        if d is None:
            raise ValueError(f"response '{r.label}' is {r.load}: say which direction to use")
        lam, T = (r.lambda1, r.lambda2)[d], (r.T1, r.T2)[d]
        o = np.argsort(lam, kind="stable")
        lam, T = lam[o], np.maximum.accumulate(np.maximum(T[o], 0.0))
        keep = np.r_[np.diff(lam) > 0, True]  # one point per stretch (the last, highest tension)
        lam, T = lam[keep], T[keep]
        if lam[0] > 1.0:
            lam, T = np.r_[1.0, lam], np.r_[0.0, T]
        if len(lam) < 2 or T[-1] <= 0:
            raise ValueError(
                f"response '{r.label}' needs at least two points and some tension to act as a region"
            )
        return cls(lam, T, r.label)

    def tension(self, lam: np.ndarray) -> np.ndarray:
        """T(λ), N/mm; linear beyond the last point."""
        lam = np.asarray(lam, dtype=np.float64)
        slope = (self.T[-1] - self.T[-2]) / (self.lam[-1] - self.lam[-2])
        return np.where(
            lam > self.lam[-1], self.T[-1] + slope * (lam - self.lam[-1]), np.interp(lam, self.lam, self.T)
        )

    def stretch(self, T: np.ndarray) -> np.ndarray:
        """λ(T), the inverse; on a plateau the largest stretch of the plateau (slack taken up)."""
        T = np.asarray(T, dtype=np.float64)
        keep = np.r_[self.T[1:] > self.T[:-1], True]  # last point of each run of equal tension
        Tk, lk = self.T[keep], self.lam[keep]
        if len(Tk) == 1:
            return np.full_like(T, lk[0])
        slope = (lk[-1] - lk[-2]) / (Tk[-1] - Tk[-2])
        return np.where(T > Tk[-1], lk[-1] + slope * (T - Tk[-1]), np.interp(T, Tk, lk))

    def slope(self, lam: np.ndarray) -> np.ndarray:
        """dT/dλ of the segment holding λ (the last segment beyond the end), N/mm."""
        seg = np.diff(self.T) / np.diff(self.lam)
        i = np.clip(
            np.searchsorted(self.lam, np.asarray(lam, dtype=np.float64), side="right") - 1, 0, len(seg) - 1
        )
        return seg[i]

    def extrapolated(self, lam: np.ndarray) -> np.ndarray:
        """True where λ lies beyond the measured range."""
        return np.asarray(lam) > self.lam[-1]


@attrs.frozen(eq=False)
class ModelCurve:
    """A reduced model loaded along ``direction`` with the other side free (P = 0) or fixed (λ = 1)."""

    model: Any
    params: np.ndarray
    direction: int = 0
    lateral: Literal["free", "fixed"] = "free"
    label: str = ""
    _table: dict = attrs.field(factory=dict, init=False, repr=False)  # tabulated curve, grown on demand

    def _state(self, lam: np.ndarray):
        """Free-side stretch (or 1) and tension at loaded stretch λ."""
        if self.lateral == "free":
            with (
                warnings.catch_warnings()
            ):  # tabulation and inversion probe stretches; grid() warns on the result
                warnings.simplefilter("ignore", KnitframeWarning)
                return self.model.solve_uniaxial(self.params, lam, self.direction)
        one = np.ones_like(lam)
        return one, self.model.stress(self.params, *((lam, one) if self.direction == 0 else (one, lam)))[
            self.direction
        ]

    def tension(self, lam: np.ndarray) -> np.ndarray:
        """Loaded tension at stretch λ, N/mm."""
        return self._state(np.atleast_1d(np.asarray(lam, dtype=np.float64)))[1]

    def slack_warning(self, top: float) -> str | None:
        """Why this region carries no tension up to loaded stretch ``top``, if its free side is why.

        Only models that do not predict the free side (``predicts_lateral = False``, the paper's hgo)
        have a free-side slack (``free_side_slack(params, direction)``) to blame; for others, and for a
        fixed lateral side, None.
        """
        if self.lateral != "free" or self.model.predicts_lateral:
            return None
        slack = self.model.free_side_slack(self.params, self.direction)
        if not 1.0 < top <= slack:
            return None
        where = f"patchwork region '{self.label}': " if self.label else "patchwork region: "
        return where + free_side_zero_message(self.model.name, top, slack, self.direction)

    def slope(self, lam: np.ndarray) -> np.ndarray:
        """dT/dλ along the load path: ∂P_l/∂λ_l, condensed by the free side (K_ll − K_lf²/K_ff) when it
        is free."""
        return self.tension_slope(lam)[1]

    def tension_slope(self, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tension and its slope along the load path from one free-side solve."""
        lam = np.atleast_1d(np.asarray(lam, dtype=np.float64))
        lf, T = self._state(lam)
        d = self.direction
        K11, K12, K22 = self.model.tangent(self.params, *((lam, lf) if d == 0 else (lf, lam)))
        Kll, Kff = (K11, K22) if d == 0 else (K22, K11)
        if self.lateral == "fixed":
            return T, Kll
        interior = (lf > FREE_MIN) & (Kff > 0)
        return T, Kll - np.where(interior, K12 * K12 / np.where(interior, Kff, 1.0), 0.0)

    def _grid(self, T_max: float) -> tuple[np.ndarray, np.ndarray]:
        """Stretch grid (and its running-maximum tension) reaching at least ``T_max``."""
        lam, T = self._table.get("lam"), self._table.get("T")
        top = 1.5
        while lam is None or T[-1] < T_max:
            if lam is not None:
                top = 1.0 + 2.0 * (lam[-1] - 1.0)
                if top > 1e3:
                    raise NumericalError(
                        f"region '{self.label}': tension {T_max:.4g} N/mm not reached up to stretch "
                        f"{lam[-1]:.4g}"
                    )
            lam = np.linspace(1.0, top, 257)
            T = np.maximum.accumulate(self.tension(lam))
        self._table.update(lam=lam, T=T)
        return lam, T

    def stretch(self, T: np.ndarray) -> np.ndarray:
        """λ(T): bracketed by the tabulated curve, then Newton on the exact tension (bisection-safeguarded).

        T below :data:`TAUT` gives the end of any slack (the smallest λ carrying TAUT).
        """
        T = np.maximum(np.atleast_1d(np.asarray(T, dtype=np.float64)), TAUT)
        lam, Tg = self._grid(float(T.max()))
        i = np.clip(np.searchsorted(Tg, T), 1, len(lam) - 1)
        lo, hi = lam[i - 1], lam[i]
        x0 = np.interp(T, Tg, lam)

        def fdf(x):
            t, k = self.tension_slope(x)
            return t - T, k

        return bracketed_newton(fdf, lo, hi, x0, xtol=1e-12, increasing=True)


def as_curve(source: Any, direction: str | int = "course", lateral: str = "free", label: str = ""):
    """A region curve from a Response, a fitted model (FitResult), a ``(model, params)`` pair or a curve
    (:class:`ResponseCurve`, :class:`ModelCurve`)."""
    if isinstance(source, (ResponseCurve, ModelCurve)):
        return source
    d = direction_index(direction)
    if isinstance(source, Response):
        return ResponseCurve.from_response(source, None if source.loaded_direction is not None else d)
    if lateral not in ("free", "fixed"):
        raise ValueError(f"lateral must be 'free' or 'fixed', got {lateral!r}")
    if isinstance(source, tuple) and len(source) == 2:
        model, params = source
    elif isinstance(source, FitResult):
        model, params = source.model, source.params
    else:
        raise TypeError(f"cannot make a patchwork region from {type(source).__name__}")
    return ModelCurve(model, np.asarray(params, dtype=np.float64), d, lateral, label or model.name)


@attrs.frozen(eq=False)
class PatchworkResult:
    """Response of a patchwork along the load; arrays have one row per load step."""

    #: (s,) engineering strain of the whole patchwork along the load, -
    strain: np.ndarray
    #: (s,) mean tension = force / total width, N/mm
    tension: np.ndarray
    #: (s,) total force, N
    force: np.ndarray
    #: (s, rows) tension carried by each row (series chain), N/mm
    row_tension: np.ndarray
    #: (s, rows, cols) stretch of every region along the load, -
    stretch: np.ndarray
    #: (s, rows, cols − 1) displacement of each interface from the fixed end, mm
    interface_displacement: np.ndarray
    #: (rows,) mm
    widths: np.ndarray
    #: (rows, cols) mm
    lengths: np.ndarray
    mode: str = "grid"

    def to_response(self, direction: str | int = "course", label: str = "") -> Response:
        """The patchwork as a uniaxial Response (lateral stretch not modelled: set to 1)."""
        d = direction_index(direction)
        lam = 1.0 + self.strain
        one, zero = np.ones_like(lam), np.zeros_like(lam)
        prov = Provenance(
            kind="model",
            source=f"patchwork ({self.mode}, {self.stretch.shape[1]}x{self.stretch.shape[2]})",
            extra={"transverse_measured": False},
        )
        if d == 0:
            return Response(
                lam,
                one,
                self.tension,
                zero,
                load="uniaxial-course",
                label=label or "patchwork",
                provenance=prov,
            )
        return Response(
            one, lam, zero, self.tension, load="uniaxial-wale", label=label or "patchwork", provenance=prov
        )


def _chain(curves: Sequence[Any], lengths: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Series chain: tension T (s,) and stretches (s, n) with Σ L_j (λ_j(T) − 1) = u."""

    def stretches(T):
        return np.stack([c.stretch(T) for c in curves], axis=-1)

    def gap(T, uu):
        return (stretches(T) - 1.0) @ lengths - uu

    def gap_newton(T, uu):
        lam = stretches(T)
        with np.errstate(divide="ignore"):
            dlam = 1.0 / np.stack([c.slope(lam[:, j]) for j, c in enumerate(curves)], axis=-1)
        return (lam - 1.0) @ lengths - uu, dlam @ lengths

    zero = np.zeros_like(u)
    lam0 = stretches(zero)  # end of each region's slack
    slack = (lam0 - 1.0) @ lengths
    taut = u > slack + 1e-12 * lengths.sum()
    T = np.zeros_like(u)
    lam = np.where(
        slack[:, None] > 0, 1.0 + (lam0 - 1.0) * (u / np.where(slack > 0, slack, 1.0))[:, None], 1.0
    )
    if taut.any():
        ut = u[taut]
        # every region at the mean stretch: the stiffest one's tension bounds the chain's from above
        mean = 1.0 + ut / lengths.sum()
        hi = np.max([c.tension(mean) for c in curves], axis=0) + TAUT
        for _ in range(100):  # safety net; the bound above already brackets the root
            short = gap(hi, ut) < 0
            if not short.any():
                break
            hi = np.where(short, 2.0 * hi, hi)
        else:
            raise NumericalError("series patchwork: no tension reaches the requested stretch")
        # the inner inversions hold λ to ~1e-12, so the tension is asked for to 1e-9 (relative)
        Tt = bracketed_newton(
            lambda x: gap_newton(x, ut),
            np.zeros_like(ut),
            hi,
            0.5 * hi,
            xtol=1e-9,
            xscale=1e3 * TAUT,
            increasing=True,
        )
        T[taut] = Tt
        lam[taut] = stretches(Tt)
    return T, lam


def grid(
    regions: Sequence[Sequence[Any]],
    widths: Sequence[float],
    lengths: Sequence[Sequence[float]],
    strain: np.ndarray,
    *,
    direction: str | int = "course",
    lateral: str = "free",
    mode: str = "grid",
) -> PatchworkResult:
    """Rows (across the load) acting in parallel, each a series chain of regions along the load.

    Parameters
    ----------
    regions : rows × cols of Responses, fitted models or curves (rows may differ in length)
    widths : (rows,) width of each row across the load, mm
    lengths : rows × cols length of each region along the load, mm; every row must sum to the same total
    strain : (s,) engineering strain of the whole patchwork, >= 0
    direction, lateral : used for model regions (see :class:`ModelCurve`)
    """
    strain = np.atleast_1d(np.asarray(strain, dtype=np.float64))
    if np.any(strain < 0) or not np.all(np.isfinite(strain)):
        raise ValueError("patchwork strains must be finite and >= 0 (tension only)")
    w = np.asarray(widths, dtype=np.float64)
    if len(regions) != len(w) or len(lengths) != len(w):
        raise ValueError(
            f"{len(regions)} rows of regions, {len(w)} widths and {len(lengths)} rows of lengths differ"
        )
    if np.any(w <= 0):
        raise ValueError("widths must be > 0")
    rows = [[as_curve(r, direction, lateral) for r in row] for row in regions]
    L = [np.asarray(ls, dtype=np.float64) for ls in lengths]
    for i, (row, ls) in enumerate(zip(rows, L, strict=False)):
        if len(row) != len(ls) or not row:
            raise ValueError(f"row {i}: {len(row)} regions but {len(ls)} lengths")
        if np.any(ls <= 0):
            raise ValueError(f"row {i}: lengths must be > 0")
    total = L[0].sum()
    for i, ls in enumerate(L):
        if not np.isclose(ls.sum(), total, rtol=1e-9):
            raise ValueError(
                f"row {i} is {ls.sum():g} mm long, row 0 is {total:g} mm: rows must have the same length"
            )
    ncol = max(len(r) for r in rows)
    s = len(strain)
    lam = np.full((s, len(rows), ncol), np.nan)
    disp = np.full((s, len(rows), max(ncol - 1, 0)), np.nan)
    Trow = np.empty((s, len(rows)))
    for i, (row, ls) in enumerate(zip(rows, L, strict=False)):
        T, lr = _chain(row, ls, strain * total)
        Trow[:, i] = T
        lam[:, i, : len(row)] = lr
        disp[:, i, : len(row) - 1] = np.cumsum((lr - 1.0) * ls, axis=1)[:, :-1]
    for i, row in enumerate(rows):  # a region that stays slack because of its free side says so
        for j, c in enumerate(row):
            msg = c.slack_warning(float(np.max(lam[:, i, j]))) if isinstance(c, ModelCurve) else None
            if msg:
                warnings.warn(msg, KnitframeWarning, stacklevel=2)
    force = Trow @ w
    Lpad = np.full((len(rows), ncol), np.nan)
    for i, ls in enumerate(L):
        Lpad[i, : len(ls)] = ls
    return PatchworkResult(strain, force / w.sum(), force, Trow, lam, disp, w, Lpad, mode)


def parallel(regions: Sequence[Any], widths: Sequence[float], strain: np.ndarray, **kw) -> PatchworkResult:
    """Strips side by side across the load: common stretch, width-weighted tension."""
    return grid([[r] for r in regions], widths, [[1.0]] * len(regions), strain, mode="parallel", **kw)


def series(
    regions: Sequence[Any], lengths: Sequence[float], strain: np.ndarray, *, width: float = 1.0, **kw
) -> PatchworkResult:
    """Regions one after another along the load: equal tension, partitioned strain."""
    return grid([list(regions)], [width], [list(lengths)], strain, mode="series", **kw)
