r"""Fabric library for garment design: candidate fabrics with a fitted reduced model, pitches and limits.

A :class:`FabricEntry` is one fabric a garment region can be made of: its pattern and yarn, the
reduced model fitted to it (a homogenizer plugin and its parameters, as in a ``params.json``),
its relaxed stitch pitches (how many stitches make a given circumference) and the limits it may
be used up to. :meth:`FabricEntry.tensions` gives the model's course and wale tensions
``(T1, T2)`` in N/mm at stretches ``(λ1, λ2)``. A :class:`FabricLibrary` is a named tuple of
entries with unique names, read from and written to ``library.json``.

``library.json`` (format 1)::

    {
      "knitframe_library": 1,                  # format version
      "name": "singal2024",
      "source": "where the library came from",
      "entries": [
        {
          "name": "cotton-rib",                # unique in the library
          "pattern": "rib",                    # a registered pattern plugin (jersey, garter, rib, seed, ...)
          "yarn": "pearl-cotton",              # yarn name (free text; need not be in the yarn library)
          "stitch_length": null,               # machine setting, if known
          "arc_length": null,                  # mm of yarn per stitch, if known
          "model": "hgo2m",                    # registered homogenizer plugin
          "model_options": {"compression_fibre": false},   # the homogenizer's options (optional)
          "params": {"mu1": ..., ...},         # the model's param_names; angles as "<name>_deg", degrees
          "course_pitch": 2.82,                # relaxed stitch width along the course, mm per wale column
          "wale_pitch": 2.128,                 # relaxed stitch height along the wale, mm per course
          "max_tension": 0.2996,               # N/mm, largest course tension the fabric may carry
          "max_stretch": 3.031,                # largest course stretch λ1 it may take, or null
          "source": "...",                     # where the model and the limits came from
          "pitch_source": "...",               # where the pitches came from
          "fit": {"nrmse": {...}, ...}         # how the model was fitted (optional; copied from params.json)
        }
      ]
    }

Loading checks every field and names the JSON path of the first bad one in one line
(``library.entries[3].params.a: must be in [1e-06, 100] (the bounds of model 'hgo'), got -1``):
unknown model or pattern, missing or extra parameters, parameters outside the model's own
``bounds()`` (θ compared in degrees, as written), non-finite numbers, pitches and limits <= 0
(max_stretch <= 1), duplicate names, an empty library, unknown keys.

Built-in library (:func:`builtin_library`, ``data/library-singal2024.json``)
-------------------------------------------------------------------------------
One entry per yarn and pattern of the uniaxial tests of Singal et al. 2024 (Nat Commun 15:2622;
data: sabetta/stitch-by-stitch, MIT licence, Copyright (c) 2023 sabetta; copied with their
attribution to ``data/singal2024/``): pearl cotton 3/2 and acrylic worsted, each in jersey
(their "stockinette"), garter, rib and seed, 8 entries. Each entry is knitframe's own fit of the
course (x) and wale (y) tests of that fabric jointly (mean of the repeats, reader
``singal2024``), with:

* model ``hgo2m`` (course and wale fibres plus an orthotropic membrane). The specimens' sides
  were free, and ``hgo2m`` solves its free side from zero lateral tension, so it fits the
  tension (overall NRMSE 0.3–1.2 %) *and* predicts the measured lateral contraction
  (transverse NRMSE 3.7–10.3 %). The paper's ``hgo`` fits the tension only when the measured
  lateral stretch is imposed (0.7–2.2 % with ``knitframe fit``), and in that state puts 31–148 %
  of the peak measured tension on the side that was free: its parameters are not a consistent
  state of the fabric and would mispredict the biaxial load of a sleeve on a limb (see
  docs/validation.md, "Reduced models against Singal et al. 2024").
* fitter ``lbfgs`` with 16 starts from 256 screened points (:data:`BUILTIN_FITTER`). The default
  4 starts from 64 end in a degenerate membrane (μ and K of 1e-6 to 1e-5 N/mm, next to their
  1e-6 lower bound) with 2–3× the tension NRMSE for cotton jersey, cotton seed and acrylic
  garter; 16 from 256 and 32 from 1024 give the same minimum for all eight. No parameter is at
  a bound (the smallest, cotton rib's a1 = 4.8e-5 N/mm, is 48× its lower bound).
* pitches from Munden's plain-knit relations, course pitch ℓ/Kw and wale pitch ℓ/Kc with
  Kc = 5.3, Kw = 4.0 (:data:`knitframe.geometry.MUNDEN_KC`, ``MUNDEN_KW``, mid-range), for an
  *estimated* loop length ℓ = 11.28 mm for both yarns: the data give no stitch counts.
  11.28 mm is the stitch length of Singal et al.'s own simulation of their acrylic stockinette
  (sabetta/stitch-by-stitch, code/fabric_simulations/stockinetteconfig.dat), so it is the best
  available figure for the acrylic, and the project's existing estimate for the pearl cotton
  (knitframe/examples/example.toml). The relations are for plain knit; rib (which relaxes
  narrower) and garter (shorter) get the same pitches and should be measured.
* limits: ``max_tension`` = the peak tension measured in the fabric's course (x) tests over all
  repeats (the data's loading branch ends at peak force, so it is the end of the measured range,
  not a proven breaking strength); ``max_stretch`` = 1 + the largest course strain measured there.

Rebuild it (about 40 s on one core) and compare or replace the shipped file::

    knitframe library build-builtin --out builtin-out
    cp builtin-out/library.json knitframe/garment/data/library-singal2024.json

``builtin-out/fits/`` then also holds each fabric's ``params.json`` and ``fit.png``. The
test ``test_builtin_rebuild_reproduces_shipped`` (marked slow) checks that a rebuild reproduces
the shipped parameters.

Your own library: fit your tests with ``knitframe fit DATA... --model hgo2m --out FIT`` (one fit
per fabric), then ``knitframe library build FIT1/params.json FIT2/params.json --out LIB
--pattern ... --yarn ... --max-tension ...`` (:meth:`FabricLibrary.from_fits`);
``knitframe library show LIB/library.json`` prints it.

Units: mm, N/mm; angles in degrees in files, radians in code.
"""

from __future__ import annotations

import functools
import json
import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.errors import ConfigError, KnitframeWarning

__all__ = [
    "FabricEntry",
    "FabricLibrary",
    "builtin_library",
    "build_builtin",
    "LIBRARY_FORMAT",
    "BUILTIN_FILE",
    "BUILTIN_FITTER",
    "BUILTIN_MODEL",
    "BUILTIN_LOOP_LENGTH",
    "DATA_DIR",
]

#: version written as ``knitframe_library`` and the only one :meth:`FabricLibrary.from_json` reads
LIBRARY_FORMAT = 1
#: package data of the built-in library
DATA_DIR = Path(__file__).with_name("data")
BUILTIN_FILE = DATA_DIR / "library-singal2024.json"
#: the Singal et al. 2024 CSV files the built-in library is fitted to
BUILTIN_DATA = DATA_DIR / "singal2024"
#: model and fitter of the built-in fits
BUILTIN_MODEL = "hgo2m"
BUILTIN_FITTER = {"kind": "lbfgs", "starts": 16, "screen": 256}
#: estimated loop length (mm of yarn per stitch) of both yarns of the built-in library; see the module docstring
BUILTIN_LOOP_LENGTH = 11.28
#: yarn in the file names -> (yarn name in the library, description, how the loop length was estimated)
BUILTIN_YARNS = {
    "cotton": (
        "pearl-cotton",
        "pearl cotton 3/2",
        "the project's estimate for this yarn (knitframe/examples/example.toml), taken from Singal et al.'s "
        "simulation of their acrylic stockinette; not measured",
    ),
    "acrylic": (
        "acrylic",
        "acrylic worsted (Brava, 100% acrylic)",
        "stitch length of Singal et al.'s own simulation of this acrylic in stockinette (sabetta/stitch-by-stitch, "
        "stockinetteconfig.dat); not measured",
    ),
}
#: pattern in the file names -> knitframe pattern
BUILTIN_PATTERNS = {"stockinette": "jersey", "garter": "garter", "rib": "rib", "seed": "seed"}

_REQUIRED = ("name", "pattern", "yarn", "model", "params", "course_pitch", "wale_pitch", "max_tension")
_OPTIONAL = ("stitch_length", "arc_length", "max_stretch", "source", "pitch_source", "model_options", "fit")
#: model -> fibre angles shown by ``knitframe library show`` when the model fixes them
_FIXED_ANGLES = {"hgo2m": "0/90"}


# ----------------------------------------------------------------------------------------- checks
def _at(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def _fmt(x: Any) -> str:
    if isinstance(x, float) and math.isfinite(x) and x.is_integer() and abs(x) < 1e15:
        return str(int(x))
    return repr(x)


def _shown(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def _is_number(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))


def _number(
    value: Any, path: str, *, above: float = 0.0, optional: bool = False, source: str | None = None
) -> float | None:
    """A finite number > ``above`` (None allowed if ``optional``), else a one-line ConfigError at ``path``."""
    if value is None and optional:
        return None
    if not _is_number(value):
        raise ConfigError(
            path, f"expected a number{' or null' if optional else ''}, got {_shown(value)}", source=source
        )
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(path, f"must be finite, got {_shown(value)}", source=source)
    if not v > above:
        raise ConfigError(path, f"must be > {_fmt(float(above))}, got {_fmt(v)}", source=source)
    return v


def _string(value: Any, path: str, *, empty: bool = False, source: str | None = None) -> str:
    if not isinstance(value, str):
        raise ConfigError(path, f"expected a string, got {_shown(value)}", source=source)
    if not empty and not value.strip():
        raise ConfigError(path, "must not be empty", source=source)
    if "\n" in value or "\r" in value:
        raise ConfigError(path, "must be one line", source=source)
    return value


def _registry():
    from knitframe.plugins import get_registry

    return get_registry()


def _homogenizer(model: Any, options: Any, path: str, source: str | None = None) -> Any:
    """The registered homogenizer ``model`` built with ``options``; errors name ``path``.model / .model_options."""
    from knitframe.config import instantiate
    from knitframe.errors import UnknownPluginError

    name = _string(model, _at(path, "model"), source=source)
    kind = _registry()["homogenizer"]
    try:
        kind.entry(name)
    except UnknownPluginError as e:
        raise ConfigError(_at(path, "model"), str(e), source=source) from None
    if not isinstance(options, Mapping):
        raise ConfigError(
            _at(path, "model_options"), f"expected a table of options, got {_shown(options)}", source=source
        )
    if "kind" in options:
        raise ConfigError(
            _at(path, "model_options.kind"), "not an option; the model is named by 'model'", source=source
        )
    return instantiate(
        _registry(), "homogenizer", {"kind": name, **options}, _at(path, "model_options"), source=source
    )


def _check_pattern(pattern: Any, path: str, source: str | None = None) -> str:
    from knitframe.errors import UnknownPluginError

    name = _string(pattern, path, source=source)
    try:
        _registry()["pattern"].entry(name)
    except UnknownPluginError as e:
        raise ConfigError(path, str(e), source=source) from None
    return name


def _params(model: Any, params: Any, path: str, source: str | None = None) -> np.ndarray:
    """The parameter array (radians inside) of ``params`` as written in a params.json, inside ``model.bounds()``."""
    from knitframe.fitting import params_from_json, params_to_json

    if not isinstance(params, Mapping):
        raise ConfigError(path, f"expected a table of parameters, got {_shown(params)}", source=source)
    names = tuple(model.param_names)
    for key, v in params.items():  # a non-number anywhere is named before a missing key
        if not _is_number(v) or not math.isfinite(float(v)):
            raise ConfigError(
                _at(path, str(key)), f"expected a finite number, got {_shown(v)}", source=source
            )
    try:
        arr = params_from_json(names, dict(params), path)
    except ConfigError as e:
        raise ConfigError(e.path, e.problem, source=source) from None
    bounds = getattr(model, "bounds", None)
    if bounds is not None:
        lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds())
        slack = 1e-9 * np.maximum(np.abs(lo), np.abs(hi))  # a fit that stopped on a bound is on it
        shown, low, high = (params_to_json(names, x) for x in (arr, lo, hi))
        for i, key in enumerate(shown):
            if not lo[i] - slack[i] <= arr[i] <= hi[i] + slack[i]:
                raise ConfigError(
                    _at(path, key),
                    f"must be in [{_fmt(low[key])}, {_fmt(high[key])}] (the bounds of "
                    f"model '{model.name}'), got {_fmt(shown[key])}",
                    source=source,
                )
    return arr


def _check_entry(values: Mapping[str, Any], path: str, source: str | None = None) -> tuple[Any, np.ndarray]:
    """Check every field of an entry (as in library.json); returns the homogenizer and the parameter array."""
    from knitframe.fitting import finite_json

    _string(values.get("name"), _at(path, "name"), source=source)
    _check_pattern(values.get("pattern"), _at(path, "pattern"), source)
    _string(values.get("yarn"), _at(path, "yarn"), source=source)
    for key in ("stitch_length", "arc_length"):
        _number(values.get(key), _at(path, key), optional=True, source=source)
    model = _homogenizer(values.get("model"), values.get("model_options", {}), path, source)
    arr = _params(model, values.get("params"), _at(path, "params"), source)
    for key in ("course_pitch", "wale_pitch", "max_tension"):
        _number(values.get(key), _at(path, key), source=source)
    _number(values.get("max_stretch"), _at(path, "max_stretch"), above=1.0, optional=True, source=source)
    for key in ("source", "pitch_source"):
        _string(values.get(key, ""), _at(path, key), empty=True, source=source)
    fit = values.get("fit", {})
    if not isinstance(fit, Mapping):
        raise ConfigError(_at(path, "fit"), f"expected a table, got {_shown(fit)}", source=source)
    _, bad = finite_json(dict(fit))
    if bad:
        raise ConfigError(_at(_at(path, "fit"), bad[0]), "must be finite", source=source)
    return model, arr


def _float_or_keep(value: Any) -> Any:
    return float(value) if _is_number(value) else value


def _float_dict(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _float_or_keep(v) for k, v in value.items()}
    return value


def _plain_dict(value: Any) -> Any:
    return dict(value) if isinstance(value, Mapping) else value


# ----------------------------------------------------------------------------------------- entry
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
    stitch_length: float | None = attrs.field(converter=_float_or_keep)
    #: mm of yarn per stitch, if known
    arc_length: float | None = attrs.field(converter=_float_or_keep)
    #: homogenizer plugin name ("hgo", "hgo2m")
    model: str
    #: as in a params.json: angles as "<name>_deg"
    params: dict[str, float] = attrs.field(converter=_float_dict)
    #: relaxed stitch width along the course, mm per wale column
    course_pitch: float = attrs.field(converter=_float_or_keep)
    #: relaxed stitch height along the wale, mm per course
    wale_pitch: float = attrs.field(converter=_float_or_keep)
    #: N/mm: the largest course tension the fabric may carry
    max_tension: float = attrs.field(converter=_float_or_keep)
    #: largest course stretch λ1, if known
    max_stretch: float | None = attrs.field(default=None, converter=_float_or_keep)
    #: where the model and the limits came from
    source: str = ""
    #: where the pitches came from
    pitch_source: str = ""
    #: the homogenizer's options
    model_options: dict[str, Any] = attrs.field(factory=dict, converter=_plain_dict)
    #: how it was fitted (nrmse, fitter, ...)
    fit: dict[str, Any] = attrs.field(factory=dict, converter=_plain_dict)
    _homogenizer: Any = attrs.field(init=False, default=None, eq=False, repr=False)
    _params_array: Any = attrs.field(init=False, default=None, eq=False, repr=False)

    def __attrs_post_init__(self) -> None:
        label = self.name if isinstance(self.name, str) and self.name else "?"
        model, arr = _check_entry(attrs.asdict(self, recurse=False), f"entry '{label}'")
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
    def params_array(self) -> np.ndarray:
        """Parameters ordered as the model's ``param_names``, angles in radians (read-only)."""
        return self._params_array

    def tensions(self, lam1, lam2) -> tuple[np.ndarray, np.ndarray]:
        """Course and wale tensions ``(T1, T2)`` in N/mm of the fitted model at stretches λ1, λ2 (broadcast arrays)."""
        T1, T2 = self._homogenizer.stress(self._params_array, lam1, lam2)
        return np.asarray(T1, dtype=np.float64), np.asarray(T2, dtype=np.float64)

    def uniaxial(self, lam, direction: str = "course") -> tuple[np.ndarray, np.ndarray]:
        """Free-sides uniaxial pull (as the tests): ``(lam_free, T_loaded)`` at loaded stretches ``lam``."""
        return self._homogenizer.solve_uniaxial(
            self._params_array, np.asarray(lam, dtype=np.float64), direction
        )

    def within_limits(self, lam1, T1) -> np.ndarray:
        """True where the course tension T1 <= max_tension and (if known) λ1 <= max_stretch; broadcast arrays."""
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
            "source": self.source,
            "pitch_source": self.pitch_source,
            "fit": dict(self.fit),
        }

    @classmethod
    def from_json(cls, data: Any, path: str = "entry", *, source: str | None = None) -> FabricEntry:
        """Check an entry as written in library.json (errors name ``path``) and build it."""
        if not isinstance(data, Mapping):
            raise ConfigError(path, f"expected a table (JSON object), got {_shown(data)}", source=source)
        for key in _REQUIRED:
            if key not in data:
                raise ConfigError(_at(path, key), "required key is missing", source=source)
        unknown = sorted(set(data) - set(_REQUIRED) - set(_OPTIONAL))
        if unknown:
            raise ConfigError(
                _at(path, str(unknown[0])),
                f"unknown key; an entry has {', '.join(_REQUIRED + _OPTIONAL)}",
                source=source,
            )
        _check_entry(data, path, source)
        values = {k: data.get(k) for k in _REQUIRED + _OPTIONAL if k in data}
        return cls(**values)


# ----------------------------------------------------------------------------------------- library
def _per_file(value: Any, n: int, option: str) -> list[Any]:
    """One value per params file from None, one value, or a sequence of 1 or ``n`` values."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if value is None or isinstance(value, (str, int, float, np.number)):
        return [value] * n
    if isinstance(value, Sequence):
        if len(value) == 1:
            return list(value) * n
        if len(value) == n:
            return list(value)
        raise ConfigError(
            option, f"got {len(value)} values for {n} params files; give one per file or one for all"
        )
    raise ConfigError(option, f"expected a value or a list of values, got {_shown(value)}")


def _read_json(path: Path, what: str) -> Any:
    if not path.exists():
        raise ConfigError("", f"{what} not found: {path}")
    if not path.is_file():
        raise ConfigError("", f"{what} is not a file: {path}")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError("", f"cannot read {what}: {e}", source=str(path)) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise ConfigError(
            "", f"not valid JSON: {e.msg} (line {e.lineno}, column {e.colno})", source=str(path)
        ) from None
    except RecursionError:
        raise ConfigError("", "not valid JSON: nested too deeply", source=str(path)) from None


def _metadata(data: Mapping[str, Any], key: str) -> Any:
    """A fabric metadata value of a params.json: in its ``fabric`` table, else at the top level."""
    fabric = data.get("fabric")
    if isinstance(fabric, Mapping) and fabric.get(key) is not None:
        return fabric[key]
    return data.get(key)


def _default_name(path: Path) -> str:
    if path.name == "params.json" and path.parent.name:
        return path.parent.resolve().name
    stem = path.stem
    return stem[: -len("-params")] if stem.endswith("-params") and len(stem) > 7 else stem


def _loop_length(
    pattern: str, stitch_length: float | None, arc_length: float | None
) -> tuple[float | None, str]:
    """Loop length (mm) for Munden's relations: the arc length, else the pattern's stitch-length table."""
    if arc_length is not None:
        return arc_length, f"loop length {arc_length:g} mm (arc_length)"
    if stitch_length is None:
        return None, ""
    from knitframe.config import instantiate
    from knitframe.geometry import STITCH_LENGTHS

    table = (
        getattr(instantiate(_registry(), "pattern", pattern, "pattern"), "stitch_lengths", None)
        or STITCH_LENGTHS
    )
    for key, mm in table.items():
        if float(key) == float(stitch_length):
            return float(
                mm
            ), f"loop length {float(mm):g} mm (stitch length {stitch_length:g} in the pattern's table)"
    return None, ""


@attrs.frozen
class FabricLibrary:
    """Named candidate fabrics (unique names), with where they came from."""

    name: str
    entries: tuple[FabricEntry, ...] = attrs.field(converter=tuple)
    source: str = ""

    def __attrs_post_init__(self) -> None:
        _string(self.name, "library.name")
        _string(self.source, "library.source", empty=True)
        if not self.entries:
            raise ConfigError("library.entries", "the library has no entries")
        seen: dict[str, int] = {}
        for i, e in enumerate(self.entries):
            if not isinstance(e, FabricEntry):
                raise ConfigError(f"library.entries[{i}]", f"expected a FabricEntry, got {_shown(e)}")
            if e.name in seen:
                raise ConfigError(
                    f"library.entries[{i}].name", f"duplicate name '{e.name}' (also entries[{seen[e.name]}])"
                )
            seen[e.name] = i

    def __len__(self) -> int:
        return len(self.entries)

    def __iter__(self):
        return iter(self.entries)

    def __getitem__(self, key: int | str) -> FabricEntry:
        """An entry by position or by name; an unknown name raises KeyError listing the names."""
        if isinstance(key, str):
            for e in self.entries:
                if e.name == key:
                    return e
            raise KeyError(f"no fabric '{key}' in library '{self.name}'; have {', '.join(self.names)}")
        return self.entries[key]

    @property
    def names(self) -> list[str]:
        """Entry names in library order."""
        return [e.name for e in self.entries]

    def to_json(self) -> dict[str, Any]:
        """Plain data as in library.json."""
        return {
            "knitframe_library": LIBRARY_FORMAT,
            "name": self.name,
            "source": self.source,
            "entries": [e.to_json() for e in self.entries],
        }

    @classmethod
    def from_json(cls, data: Any, path: str = "library", *, source: str | None = None) -> FabricLibrary:
        """Check library.json data (one-line ConfigError naming the JSON path of the first bad field) and build it."""
        if not isinstance(data, Mapping):
            raise ConfigError(path, f"expected a JSON object, got {_shown(data)}", source=source)
        if "knitframe_library" not in data:
            raise ConfigError(
                _at(path, "knitframe_library"),
                "required key is missing (not a knitframe library file)",
                source=source,
            )
        version = data["knitframe_library"]
        if not _is_number(version) or version != LIBRARY_FORMAT:
            raise ConfigError(
                _at(path, "knitframe_library"),
                f"unsupported library format {_shown(version)}; this knitframe reads format {LIBRARY_FORMAT}",
                source=source,
            )
        keys = ("knitframe_library", "name", "source", "entries")
        unknown = sorted(set(data) - set(keys))
        if unknown:
            raise ConfigError(
                _at(path, str(unknown[0])), f"unknown key; a library has {', '.join(keys)}", source=source
            )
        for key in ("name", "entries"):
            if key not in data:
                raise ConfigError(_at(path, key), "required key is missing", source=source)
        name = _string(data["name"], _at(path, "name"), source=source)
        lib_source = _string(data.get("source", ""), _at(path, "source"), empty=True, source=source)
        raw = data["entries"]
        if not isinstance(raw, list):
            raise ConfigError(
                _at(path, "entries"), f"expected a list of entries, got {_shown(raw)}", source=source
            )
        if not raw:
            raise ConfigError(_at(path, "entries"), "the library has no entries", source=source)
        entries, seen = [], {}
        for i, item in enumerate(raw):
            where = f"{_at(path, 'entries')}[{i}]"
            entry = FabricEntry.from_json(item, where, source=source)
            if entry.name in seen:
                raise ConfigError(
                    _at(where, "name"),
                    f"duplicate name '{entry.name}' (also entries[{seen[entry.name]}])",
                    source=source,
                )
            seen[entry.name] = i
            entries.append(entry)
        return cls(name, tuple(entries), lib_source)

    def save(self, path: str | Path) -> None:
        """Write library.json (UTF-8, indented; never NaN or Infinity)."""
        text = json.dumps(self.to_json(), indent=2, ensure_ascii=False, allow_nan=False)
        Path(path).write_text(text + "\n", encoding="utf-8")

    @classmethod
    def load(cls, path: str | Path) -> FabricLibrary:
        """Read and check a library.json; errors name the file and the JSON path."""
        p = Path(path)
        return cls.from_json(_read_json(p, "library file"), "library", source=str(p))

    @classmethod
    def from_fits(
        cls,
        params_files: Sequence[str | Path],
        *,
        names: Any = None,
        course_pitch: Any = None,
        wale_pitch: Any = None,
        max_tension: Any = None,
        max_stretch: Any = None,
        pattern: Any = None,
        yarn: Any = None,
        stitch_length: Any = None,
        arc_length: Any = None,
        source: Any = None,
        pitch_source: Any = None,
        name: str = "library",
        library_source: str = "",
    ) -> FabricLibrary:
        """A library with one entry per fitted model (a ``params.json`` of ``knitframe fit`` or a ``[fit]`` stage).

        Every keyword takes one value for all files or a sequence of one value per file.
        ``pattern``, ``yarn``, ``stitch_length``, ``arc_length`` and ``names`` come from the params
        file's metadata where present (its ``fabric`` table, else its top level: ``pattern``,
        ``yarn``, ``stitch_length``, ``arc_length``, ``name``), else from these keywords; both given
        and different is an error. ``names`` defaults to the params file's folder name (or its
        stem without ``-params``). Pitches not given are estimated by Munden's plain-knit relations
        from the arc length, or from the stitch length through the pattern's stitch-length table.
        ``max_tension`` is required; ``max_stretch`` is optional. ``source`` defaults to the fit's
        model, fitter, data labels and NRMSE. A fit with a parameter at a bound warns.
        """
        from knitframe.fitting import params_to_json
        from knitframe.geometry import MUNDEN_KC, MUNDEN_KW

        files = [Path(p) for p in params_files]
        if not files:
            raise ConfigError("params_files", "no params files given")
        n = len(files)
        opts = {
            k: _per_file(v, n, k)
            for k, v in (
                ("names", names),
                ("course_pitch", course_pitch),
                ("wale_pitch", wale_pitch),
                ("max_tension", max_tension),
                ("max_stretch", max_stretch),
                ("pattern", pattern),
                ("yarn", yarn),
                ("stitch_length", stitch_length),
                ("arc_length", arc_length),
                ("source", source),
                ("pitch_source", pitch_source),
            )
        }
        entries = []
        for i, p in enumerate(files):
            src = str(p)
            data = _read_json(p, "params file")
            if not isinstance(data, Mapping):
                raise ConfigError("", f"expected a params.json object, got {_shown(data)}", source=src)
            if "model" not in data:
                raise ConfigError("model", "required key is missing (not a params.json of a fit)", source=src)
            model = _homogenizer(data["model"], data.get("options") or {}, "", src)
            keys = params_to_json(model.param_names, [0.0] * len(model.param_names))
            values: dict[str, Any] = {
                "model": data["model"],
                "model_options": dict(data.get("options") or {}),
                "params": {k: data[k] for k in keys if k in data},
            }

            def pick(key: str, meta_key: str | None = None) -> Any:
                meta = _metadata(data, meta_key or key)
                given = opts[key][i]
                if meta is not None and given is not None and meta != given:
                    raise ConfigError(
                        key,
                        f"the params file says {_shown(meta)}, the option says {_shown(given)}",
                        source=src,
                    )
                return meta if meta is not None else given

            values["name"] = pick("names", "name")
            if values["name"] is None:
                values["name"] = _default_name(p)
            for key in ("pattern", "yarn"):
                values[key] = pick(key)
                if values[key] is None:
                    raise ConfigError(key, f"not in the params file's metadata; give the {key}", source=src)
            _check_pattern(values["pattern"], "pattern", src)
            for key in ("stitch_length", "arc_length"):
                values[key] = pick(key)
                _number(values[key], key, optional=True, source=src)
            cp, wp = opts["course_pitch"][i], opts["wale_pitch"][i]
            basis = "given"
            if cp is None or wp is None:
                loop, how = _loop_length(values["pattern"], values["stitch_length"], values["arc_length"])
                if loop is None:
                    missing = "course_pitch" if cp is None else "wale_pitch"
                    raise ConfigError(
                        missing,
                        "not given, and no arc length or known stitch length to estimate it "
                        "from by Munden's relations",
                        source=src,
                    )
                which = (
                    "course and wale pitch"
                    if cp is None and wp is None
                    else (
                        "course pitch (wale pitch given)" if cp is None else "wale pitch (course pitch given)"
                    )
                )
                cp = loop / MUNDEN_KW if cp is None else cp
                wp = loop / MUNDEN_KC if wp is None else wp
                basis = (
                    f"{which} from Munden's plain-knit relations (Kc = {MUNDEN_KC:g}, Kw = {MUNDEN_KW:g}; course "
                    f"pitch = l/Kw, wale pitch = l/Kc), {how} (estimate)"
                )
            values["course_pitch"], values["wale_pitch"] = cp, wp
            if opts["max_tension"][i] is None:
                raise ConfigError(
                    "max_tension",
                    "not given: the largest course tension (N/mm) the fabric may carry",
                    source=src,
                )
            values["max_tension"] = opts["max_tension"][i]
            values["max_stretch"] = opts["max_stretch"][i]
            fit = {
                k: data[k]
                for k in (
                    "fitter",
                    "nrmse",
                    "nrmse_transverse",
                    "objective",
                    "n_evals",
                    "converged",
                    "responses",
                    "at_bound",
                    "warnings",
                )
                if k in data
            }
            values["fit"] = fit
            nrmse = fit.get("nrmse", {}).get("overall") if isinstance(fit.get("nrmse"), Mapping) else None
            default_source = (
                f"fit of {', '.join(map(str, fit.get('responses', []))) or 'data'}: {data['model']} by "
                f"{fit.get('fitter', '?')}"
                + (f", NRMSE {100 * nrmse:.2f} %" if _is_number(nrmse) else "")
                + f" ({p.name})"
            )
            values["source"] = opts["source"][i] if opts["source"][i] is not None else default_source
            values["pitch_source"] = opts["pitch_source"][i] if opts["pitch_source"][i] is not None else basis
            _check_entry(values, "", src)
            if fit.get("at_bound"):
                warnings.warn(
                    f"{src}: fitted {', '.join(map(str, fit['at_bound']))} at a bound of the model's box: "
                    "the data do not determine it",
                    KnitframeWarning,
                    stacklevel=2,
                )
            entries.append(FabricEntry(**values))
        seen: dict[str, int] = {}
        for i, e in enumerate(entries):
            if e.name in seen:
                raise ConfigError(
                    "names",
                    f"'{e.name}' is the name of two params files ({files[seen[e.name]]} and "
                    f"{files[i]}); give each an entry name",
                )
            seen[e.name] = i
        return cls(name, tuple(entries), library_source)


@functools.lru_cache(maxsize=1)
def builtin_library() -> FabricLibrary:
    """The shipped library: Singal et al. 2024's pearl cotton and acrylic in 4 patterns (8 entries, see module doc)."""
    return FabricLibrary.load(BUILTIN_FILE)


# ----------------------------------------------------------------------------------------- built-in
def course_limits(x_file: Path) -> tuple[float, float, int]:
    """``(peak tension N/mm, largest stretch, repeats)`` of a course (x) test file over all its repeats."""
    from knitframe.config import instantiate

    reader = instantiate(_registry(), "reader", {"kind": "singal2024", "average": False}, "reader")
    repeats = reader.read(x_file)
    return (
        max(float(r.T1.max()) for r in repeats),
        max(float(r.lambda1.max()) for r in repeats),
        len(repeats),
    )


def build_builtin(
    folder: str | Path, *, data_dir: str | Path = BUILTIN_DATA, plots: bool = True, progress=None
) -> FabricLibrary:
    """Fit the built-in library from the Singal et al. 2024 CSVs; writes ``fits/<name>-params.json`` (and
    ``-fit.png``) into ``folder`` and returns the library (:meth:`FabricLibrary.from_fits` of those files).

    ``progress(name, result)`` is called after each fit.
    """
    from knitframe.config import instantiate
    from knitframe.fitting import write_fit_outputs
    from knitframe.geometry import MUNDEN_KC, MUNDEN_KW

    reg = _registry()
    data_dir = Path(data_dir)
    fits = Path(folder) / "fits"
    fits.mkdir(parents=True, exist_ok=True)
    reader = instantiate(reg, "reader", "singal2024", "reader")
    model = instantiate(reg, "homogenizer", BUILTIN_MODEL, "model")
    fitter = instantiate(reg, "fitter", BUILTIN_FITTER, "fitter")
    fitter_text = f"{BUILTIN_FITTER['kind']} ({BUILTIN_FITTER['starts']} starts from {BUILTIN_FITTER['screen']} screened)"
    kw: dict[str, list[Any]] = {
        k: []
        for k in (
            "names",
            "pattern",
            "yarn",
            "course_pitch",
            "wale_pitch",
            "max_tension",
            "max_stretch",
            "source",
            "pitch_source",
        )
    }
    files = []
    for ykey, (yarn, ydesc, basis) in BUILTIN_YARNS.items():
        for pkey, pattern in BUILTIN_PATTERNS.items():
            name = f"{ykey}-{pattern}"
            x, y = data_dir / f"{ykey}-{pkey}-x.csv", data_dir / f"{ykey}-{pkey}-y.csv"
            responses = [r for f in (x, y) for r in reader.read(f)]
            result = fitter.fit(model, responses)
            params_file = fits / f"{name}-params.json"
            if plots:
                write_fit_outputs(result, responses, params_file, fits / f"{name}-fit.png")
            else:
                params_file.write_text(json.dumps(result.to_json(), indent=2, allow_nan=False) + "\n")
            if progress is not None:
                progress(name, result)
            t_max, lam_max, n_rep = course_limits(x)
            reps = "/".join(str(r.n_samples) for r in responses)
            loop = BUILTIN_LOOP_LENGTH
            files.append(params_file)
            kw["names"].append(name)
            kw["pattern"].append(pattern)
            kw["yarn"].append(yarn)
            kw["course_pitch"].append(loop / MUNDEN_KW)
            kw["wale_pitch"].append(loop / MUNDEN_KC)
            kw["max_tension"].append(t_max)
            kw["max_stretch"].append(lam_max)
            pattern_text = pattern if pkey == pattern else f"{pkey} (= {pattern})"
            kw["source"].append(
                f"fit of Singal et al. 2024 (Nat Commun 15:2622; data sabetta/stitch-by-stitch, MIT) {ydesc} "
                f"{pattern_text}, free-sides uniaxial tests {x.name} (course) and {y.name} (wale), mean of "
                f"{reps} repeats: {BUILTIN_MODEL} by {fitter_text}, tension NRMSE "
                f"{100 * result.nrmse['overall']:.2f} %, transverse strain NRMSE "
                f"{100 * result.nrmse_transverse.get('overall', float('nan')):.2f} %; limits: max_tension = peak course "
                f"tension measured ({x.name}, {n_rep} repeats; the tests end at peak force), max_stretch = 1 + largest "
                "course strain measured there"
            )
            kw["pitch_source"].append(
                f"Munden's plain-knit relations (Kc = {MUNDEN_KC:g}, Kw = {MUNDEN_KW:g}; course pitch = l/Kw, wale pitch "
                f"= l/Kc) with loop length l = {loop:g} mm (estimate: {basis})"
                + (
                    ""
                    if pattern == "jersey"
                    else f"; plain-knit relation applied to {pattern}, whose relaxed pitches "
                    "differ: measure them"
                )
            )
    return FabricLibrary.from_fits(
        files,
        **kw,
        name="singal2024",
        library_source="Singal et al. 2024, Nat Commun 15:2622, doi:10.1038/s41467-024-46498-z: uniaxial tests of pearl "
        "cotton and acrylic in jersey, garter, rib and seed (sabetta/stitch-by-stitch, MIT licence, "
        "Copyright (c) 2023 sabetta), fitted by knitframe (knitframe library build-builtin)",
    )
