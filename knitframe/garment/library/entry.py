"""One candidate fabric: :class:`FabricEntry`, its fitted model, pitches and limits."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError
from knitframe.garment.library.checks import (
    GAUGE_KEYS,
    OPTIONAL_KEYS,
    REQUIRED_KEYS,
    check_entry,
    float_dict,
    float_or_keep,
    gauge_pitches,
    gauge_text,
    is_pitch_estimate,
    json_path,
    plain_dict,
    short_repr,
)

__all__ = ["FabricEntry"]


@attrs.frozen(hash=False)
class FabricEntry:
    """One candidate fabric for garment design.

    Construction checks every field (:meth:`from_json` names the JSON path of a bad one) and
    builds the homogenizer once; :meth:`tensions` reuses it and the parameter array.
    """

    #: unique in its library, e.g. "cotton-rib"
    name: str
    #: jersey | garter | rib | seed | a plugin pattern
    pattern: str
    #: yarn name
    yarn: str
    #: machine setting (e.g. 10, 11, 12), if known
    stitch_length: float | None = attrs.field(converter=float_or_keep)
    #: mm of yarn per stitch, if known
    arc_length: float | None = attrs.field(converter=float_or_keep)
    #: homogenizer plugin name ("hgo", "hgo2m")
    model: str
    #: as in a params.json: angles as "<name>_deg"
    params: dict[str, float] = attrs.field(converter=float_dict)
    #: relaxed stitch width along the course, mm per wale column
    course_pitch: float = attrs.field(converter=float_or_keep)
    #: relaxed stitch height along the wale, mm per course
    wale_pitch: float = attrs.field(converter=float_or_keep)
    #: N/mm: the largest course tension the fabric may carry
    max_tension: float = attrs.field(converter=float_or_keep)
    #: largest course stretch λ1, if known
    max_stretch: float | None = attrs.field(default=None, converter=float_or_keep)
    #: where the model and the limits came from
    source: str = ""
    #: where the pitches came from
    pitch_source: str = ""
    #: the homogenizer's options
    model_options: dict[str, Any] = attrs.field(factory=dict, converter=plain_dict)
    #: how it was fitted (nrmse, fitter, ...)
    fit: dict[str, Any] = attrs.field(factory=dict, converter=plain_dict)
    #: scatter of the course tests' repeats, if known: the median over stretch of the repeats'
    #: relative half-spread of course tension, max_k T_k − min_k T_k over 2 mean_k T_k (see
    #: :func:`knitframe.garment.library.builtin.tension_scatter`); a fraction (0.09 = ±9 %)
    tension_scatter: float | None = attrs.field(default=None, converter=float_or_keep)
    #: whether the pitches were measured (true) or estimated (false); None: not recorded (see
    #: :attr:`pitch_is_estimate`)
    pitch_measured: bool | None = None
    #: the knitter's gauge the pitches come from, if any: ``{"stitches_per_10cm": s,
    #: "courses_per_10cm": c}`` of a relaxed swatch; then course_pitch = 100/s, wale_pitch = 100/c
    gauge: dict[str, float] | None = attrs.field(default=None, converter=float_dict)
    _homogenizer: Any = attrs.field(init=False, default=None, eq=False, repr=False)
    _params_array: Any = attrs.field(init=False, default=None, eq=False, repr=False)

    def __attrs_post_init__(self) -> None:
        label = self.name if isinstance(self.name, str) and self.name else "?"
        model, arr = check_entry(attrs.asdict(self, recurse=False), f"entry '{label}'")
        arr.setflags(write=False)
        object.__setattr__(self, "_homogenizer", model)
        object.__setattr__(self, "_params_array", arr)

    def __hash__(self) -> int:  # equal entries have equal names and numbers; the dicts are left out
        return hash(
            (
                self.name,
                self.pattern,
                self.yarn,
                self.model,
                self.course_pitch,
                self.wale_pitch,
                self.max_tension,
            )
        )

    @property
    def homogenizer(self) -> Any:
        """The registered homogenizer instance (with ``model_options``)."""
        return self._homogenizer

    @property
    def pitch_is_estimate(self) -> bool:
        """True unless the pitches were measured: a ``gauge`` or ``pitch_measured`` true says so.

        When neither is recorded (a library.json written before they were), the ``pitch_source``
        decides: an estimate unless it says measured, given or gauge and nothing of an estimate
        ("estimat", "Munden", "not measured"); so the built-in library's Munden pitches are estimates.
        """
        return is_pitch_estimate(self.pitch_measured, self.gauge, self.pitch_source)

    def with_gauge(
        self, stitches_per_10cm: float, courses_per_10cm: float, *, path: str | None = None
    ) -> FabricEntry:
        """This entry with the pitches of a knitter's gauge: ``stitches_per_10cm`` stitches along the
        course and ``courses_per_10cm`` courses along the wale in 10 cm of relaxed fabric give
        course_pitch = 100/stitches and wale_pitch = 100/courses mm, measured.

        A number that is not finite and > 0 is refused in one line naming ``path``.stitches_per_10cm
        (or .courses_per_10cm); ``path`` defaults to ``entry '<name>'.gauge``.
        """
        where = path if path is not None else f"entry '{self.name}'.gauge"
        course_pitch, wale_pitch = gauge_pitches(stitches_per_10cm, courses_per_10cm, where)
        gauge = dict(zip(GAUGE_KEYS, (float(stitches_per_10cm), float(courses_per_10cm))))
        return attrs.evolve(
            self,
            course_pitch=course_pitch,
            wale_pitch=wale_pitch,
            gauge=gauge,
            pitch_measured=True,
            pitch_source=gauge_text(gauge),
        )

    @property
    def params_array(self) -> np.ndarray:
        """Parameters ordered as the model's ``param_names``, angles in radians (read-only)."""
        return self._params_array

    def tensions(self, lam1, lam2) -> tuple[np.ndarray, np.ndarray]:
        """Course and wale tensions ``(T1, T2)`` in N/mm of the fitted model at stretches λ1, λ2
        (broadcast arrays)."""
        T1, T2 = self._homogenizer.stress(self._params_array, lam1, lam2)
        return np.asarray(T1, dtype=np.float64), np.asarray(T2, dtype=np.float64)

    def uniaxial(self, lam, direction: str = "course") -> tuple[np.ndarray, np.ndarray]:
        """Free-sides uniaxial pull (as the tests): ``(lam_free, T_loaded)`` at loaded stretches ``lam``."""
        return self._homogenizer.solve_uniaxial(
            self._params_array, np.asarray(lam, dtype=np.float64), direction
        )

    def within_limits(self, lam1, T1) -> np.ndarray:
        """True where the course tension T1 <= max_tension and (if known) λ1 <= max_stretch; broadcast
        arrays."""
        lam1, T1 = np.broadcast_arrays(np.asarray(lam1, dtype=np.float64), np.asarray(T1, dtype=np.float64))
        ok = T1 <= self.max_tension
        if self.max_stretch is not None:
            ok = ok & (lam1 <= self.max_stretch)
        return np.asarray(ok, dtype=bool)

    def to_json(self) -> dict[str, Any]:
        """The entry as in library.json (every field, in a fixed order)."""
        return {
            "name": self.name,
            "pattern": self.pattern,
            "yarn": self.yarn,
            "stitch_length": self.stitch_length,
            "arc_length": self.arc_length,
            "model": self.model,
            "model_options": dict(self.model_options),
            "params": dict(self.params),
            "course_pitch": self.course_pitch,
            "wale_pitch": self.wale_pitch,
            "max_tension": self.max_tension,
            "max_stretch": self.max_stretch,
            "tension_scatter": self.tension_scatter,
            "source": self.source,
            "pitch_source": self.pitch_source,
            "pitch_measured": self.pitch_measured,
            "gauge": None if self.gauge is None else dict(self.gauge),
            "fit": dict(self.fit),
        }

    @classmethod
    def from_json(cls, data: Any, path: str = "entry", *, source: str | None = None) -> FabricEntry:
        """Check an entry as written in library.json (errors name ``path``) and build it."""
        if not isinstance(data, Mapping):
            raise ConfigError(path, f"expected a table (JSON object), got {short_repr(data)}", source=source)
        for key in REQUIRED_KEYS:
            if key not in data:
                raise ConfigError(json_path(path, key), "required key is missing", source=source)
        unknown = sorted(set(data) - set(REQUIRED_KEYS) - set(OPTIONAL_KEYS))
        if unknown:
            raise ConfigError(
                json_path(path, str(unknown[0])),
                f"unknown key; an entry has {', '.join(REQUIRED_KEYS + OPTIONAL_KEYS)}",
                source=source,
            )
        check_entry(data, path, source)
        values = {k: data.get(k) for k in REQUIRED_KEYS + OPTIONAL_KEYS if k in data}
        return cls(**values)
