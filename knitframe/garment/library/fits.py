"""Building library entries from fits: one :class:`FabricEntry` per ``params.json``, with its metadata,
pitches (given, or estimated by Munden's relations), limits and source."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from knitframe.errors import ConfigError, KnitframeWarning
from knitframe.garment.library.checks import (
    GAUGE_KEYS,
    build_homogenizer,
    check_entry,
    check_number,
    check_pattern,
    gauge_pair,
    gauge_pitches,
    gauge_text,
    is_number,
    plugin_registry,
    short_repr,
)
from knitframe.garment.library.entry import FabricEntry
from knitframe.garment.library.reading import default_name, params_metadata, read_json

__all__ = ["fit_entries"]

#: the keys of a params.json copied into an entry's ``fit``
_FIT_KEYS = (
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
    raise ConfigError(option, f"expected a value or a list of values, got {short_repr(value)}")


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
        getattr(instantiate(plugin_registry(), "pattern", pattern, "pattern"), "stitch_lengths", None)
        or STITCH_LENGTHS
    )
    for key, mm in table.items():
        if float(key) == float(stitch_length):
            return float(
                mm
            ), f"loop length {float(mm):g} mm (stitch length {stitch_length:g} in the pattern's table)"
    return None, ""


def _is_pair(value: Any) -> bool:
    """True for a pair of numbers, as a gauge (stitches, courses) is given."""
    return (
        isinstance(value, Sequence)
        and not isinstance(value, str)
        and len(value) == 2
        and all(is_number(v) for v in value)
    )


def _gauge_pitches(
    values: dict[str, Any], cp: Any, wp: Any, gauge: Any, src: str
) -> tuple[float, float, str]:
    """Course and wale pitch (mm) of a knitter's gauge (stitches, courses) per 10 cm, recorded in
    ``values["gauge"]``; pitches given as well are refused."""
    if cp is not None or wp is not None:
        given = "course_pitch" if cp is not None else "wale_pitch"
        raise ConfigError(
            "gauge", f"give a gauge or the pitches, not both ({given} is given too)", source=src
        )
    gauge = gauge_pair(gauge, "gauge", src)
    cp, wp = gauge_pitches(*gauge, "gauge", src)
    values["gauge"] = dict(zip(GAUGE_KEYS, map(float, gauge)))
    return cp, wp, gauge_text(values["gauge"])


def _pitches(values: Mapping[str, Any], cp: Any, wp: Any, src: str) -> tuple[Any, Any, str]:
    """Course and wale pitch (mm) and how they were found: as given, or by Munden's relations."""
    from knitframe.geometry import MUNDEN_KC, MUNDEN_KW

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
            else ("course pitch (wale pitch given)" if cp is None else "wale pitch (course pitch given)")
        )
        cp = loop / MUNDEN_KW if cp is None else cp
        wp = loop / MUNDEN_KC if wp is None else wp
        basis = (
            f"{which} from Munden's plain-knit relations (Kc = {MUNDEN_KC:g}, Kw = {MUNDEN_KW:g}; "
            f"course pitch = l/Kw, wale pitch = l/Kc), {how} (estimate)"
        )
    return cp, wp, basis


def _fabric_metadata(data: Mapping[str, Any], p: Path, i: int, opts: dict[str, list[Any]]) -> dict[str, Any]:
    """Name, pattern, yarn, stitch and arc length of file ``i``: its metadata, else the options.

    Both given and different is an error; the name defaults to :func:`default_name`.
    """
    src = str(p)
    values: dict[str, Any] = {}

    def pick(key: str, meta_key: str | None = None) -> Any:
        meta = params_metadata(data, meta_key or key)
        given = opts[key][i]
        if meta is not None and given is not None and meta != given:
            raise ConfigError(
                key,
                f"the params file says {short_repr(meta)}, the option says {short_repr(given)}",
                source=src,
            )
        return meta if meta is not None else given

    values["name"] = pick("names", "name")
    if values["name"] is None:
        values["name"] = default_name(p)
    for key in ("pattern", "yarn"):
        values[key] = pick(key)
        if values[key] is None:
            raise ConfigError(key, f"not in the params file's metadata; give the {key}", source=src)
    check_pattern(values["pattern"], "pattern", src)
    for key in ("stitch_length", "arc_length"):
        values[key] = pick(key)
        check_number(values[key], key, optional=True, source=src)
    return values


def _default_source(data: Mapping[str, Any], fit: Mapping[str, Any], p: Path) -> str:
    """The fit's model, fitter, data labels and NRMSE, as an entry's ``source``."""
    nrmse = fit.get("nrmse", {}).get("overall") if isinstance(fit.get("nrmse"), Mapping) else None
    return (
        f"fit of {', '.join(map(str, fit.get('responses', []))) or 'data'}: {data['model']} by "
        f"{fit.get('fitter', '?')}"
        + (f", NRMSE {100 * nrmse:.2f} %" if is_number(nrmse) else "")
        + f" ({p.name})"
    )


def _fit_entry(p: Path, i: int, opts: dict[str, list[Any]]) -> FabricEntry:
    """The entry of params file ``p`` (the ``i``-th), with the options of :meth:`FabricLibrary.from_fits`."""
    from knitframe.fitting import params_to_json

    src = str(p)
    data = read_json(p, "params file")
    if not isinstance(data, Mapping):
        raise ConfigError("", f"expected a params.json object, got {short_repr(data)}", source=src)
    if "model" not in data:
        raise ConfigError("model", "required key is missing (not a params.json of a fit)", source=src)
    model = build_homogenizer(data["model"], data.get("options") or {}, "", src)
    keys = params_to_json(model.param_names, [0.0] * len(model.param_names))
    values: dict[str, Any] = {
        "model": data["model"],
        "model_options": dict(data.get("options") or {}),
        "params": {k: data[k] for k in keys if k in data},
    }
    values.update(_fabric_metadata(data, p, i, opts))
    cp, wp, gauge = opts["course_pitch"][i], opts["wale_pitch"][i], opts["gauge"][i]
    measured = gauge is not None or (cp is not None and wp is not None)
    if gauge is not None:
        cp, wp, basis = _gauge_pitches(values, cp, wp, gauge, src)
    else:
        cp, wp, basis = _pitches(values, cp, wp, src)
    values["course_pitch"], values["wale_pitch"] = cp, wp
    given = opts["pitch_measured"][i]
    values["pitch_measured"] = measured if given is None else given
    values["tension_scatter"] = opts["tension_scatter"][i]
    if opts["max_tension"][i] is None:
        raise ConfigError(
            "max_tension",
            "not given: the largest course tension (N/mm) the fabric may carry",
            source=src,
        )
    values["max_tension"] = opts["max_tension"][i]
    values["max_stretch"] = opts["max_stretch"][i]
    fit = {k: data[k] for k in _FIT_KEYS if k in data}
    values["fit"] = fit
    values["source"] = opts["source"][i] if opts["source"][i] is not None else _default_source(data, fit, p)
    values["pitch_source"] = opts["pitch_source"][i] if opts["pitch_source"][i] is not None else basis
    check_entry(values, "", src)
    if fit.get("at_bound"):
        # attributed to the caller of FabricLibrary.from_fits (this, fit_entries, from_fits, caller)
        warnings.warn(
            f"{src}: fitted {', '.join(map(str, fit['at_bound']))} at a bound of the model's box: "
            "the data do not determine it",
            KnitframeWarning,
            stacklevel=4,
        )
    return FabricEntry(**values)


def fit_entries(params_files: Sequence[str | Path], **options: Any) -> list[FabricEntry]:
    """One entry per params file, the keyword ``options`` of :meth:`FabricLibrary.from_fits` spread
    over the files (:func:`_per_file`); two entries of one name are refused."""
    files = [Path(p) for p in params_files]
    if not files:
        raise ConfigError("params_files", "no params files given")
    n = len(files)
    gauge = options.get("gauge")
    gauge = gauge.tolist() if isinstance(gauge, np.ndarray) else gauge
    options["gauge"] = [gauge] if _is_pair(gauge) else gauge  # one (stitches, courses) for all files
    opts = {k: _per_file(v, n, k) for k, v in options.items()}
    entries = []
    for i, p in enumerate(files):  # a loop, not a comprehension: the warning's stacklevel counts frames
        entries.append(_fit_entry(p, i, opts))
    seen: dict[str, int] = {}
    for i, e in enumerate(entries):
        if e.name in seen:
            raise ConfigError(
                "names",
                f"'{e.name}' is the name of two params files ({files[seen[e.name]]} and "
                f"{files[i]}); give each an entry name",
            )
        seen[e.name] = i
    return entries
