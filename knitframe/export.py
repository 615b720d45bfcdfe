"""Material cards of fitted reduced models for ABAQUS, CalculiX and FEBio, and the CalculiX check.

``knitframe export PARAMS.json --format F --out FILE``, the ``[fit]`` option ``export = [...]``
and the API all go through :func:`export_card`::

    import json
    from knitframe.export import export_card
    text = export_card(json.load(open("params.json")), "calculix")

Formats (:data:`FORMATS`, with the file suffix the ``[fit]`` stage uses):

* ``abaqus`` — ``*MATERIAL`` with ``*ANISOTROPIC HYPERELASTIC, HOLZAPFEL`` and an ``*ORIENTATION``;
* ``calculix`` — ``*MATERIAL, NAME=ELASTIC_FIBER…`` with ``*USER MATERIAL`` (CalculiX's built-in
  Holzapfel fibre material);
* ``calculix-deck`` — a complete CalculiX input that stretches single-element blocks of that
  material equibiaxially, strip-biaxially (the lateral side held) and in equibiaxial compression,
  with knitframe's expected tensions in its header (:func:`calculix_check` runs it);
* ``febio`` — an FEBio ``<material type="Holzapfel-Gasser-Ogden">`` element.

Which formats a model can be written in is the homogenizer's business: it lists them in
``card_formats`` and writes them with ``card(format, params, **options)``, where ``params`` are
the parameters *as stored in params.json* (angles as ``theta_deg``, in degrees), so no radian
conversion happens between the file and the card. A model that cannot be expressed in a format
says why in ``card_refusal`` (one line). Every card starts with a header line
``** knitframe card 1: <model> -> <format>`` (``<!-- … -->`` for FEBio) that
:func:`is_knitframe_card` recognises, so ``--overwrite`` only ever replaces a card knitframe wrote.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from knitframe.errors import ConfigError, KnitframeError, NumericalError, name_written

__all__ = [
    "FORMATS",
    "CARD_TAG",
    "header_line",
    "is_knitframe_card",
    "load_params",
    "model_of",
    "stored_params",
    "export_card",
    "card_refusal",
    "check_out_file",
    "write_card",
    "read_check_cases",
    "read_dat_totals",
    "read_dat_displacements",
    "run_calculix",
    "calculix_check",
]

#: Every format knitframe knows, with the suffix of the file the ``[fit]`` stage writes
#: (``params.<suffix>``; the two CalculiX files need different names, so the suffix names the format).
FORMATS: dict[str, str] = {
    "abaqus": "abaqus.inp",
    "calculix": "calculix.inp",
    "calculix-deck": "calculix-check.inp",
    "febio": "febio.xml",
}

#: The words after the comment mark on the first line of every card.
CARD_TAG = "knitframe card 1"
_HEADER = re.compile(r"^(\*\*|<!--) knitframe card \d+: [A-Za-z0-9_.-]+ -> [a-z-]+")


def header_line(model: str, fmt: str) -> str:
    """The first line of a card: ``** knitframe card 1: hgo -> abaqus`` (an XML comment for FEBio)."""
    text = f"{CARD_TAG}: {model} -> {fmt}"
    return f"<!-- {text} -->" if fmt == "febio" else f"** {text}"


def is_knitframe_card(path: str | Path) -> bool:
    """Whether ``path`` is a regular file whose first line is a knitframe card header."""
    p = Path(path)
    if p.is_symlink() or not p.is_file():
        return False
    try:
        with open(p, encoding="utf-8") as fh:
            first = fh.readline(400)
    except (OSError, UnicodeDecodeError):
        return False
    return bool(_HEADER.match(first))


# ---------------------------------------------------------------------------------------------
# params.json → model and stored parameters
# ---------------------------------------------------------------------------------------------
def load_params(path: str | Path, option: str = "PARAMS") -> dict[str, Any]:
    """Read a params.json (written by ``knitframe fit`` or a ``[fit]`` stage); one-line errors."""
    p = Path(path)
    where = str(path)
    if not p.exists():
        raise ConfigError(option, f"{where}: file not found")
    if p.is_dir():
        raise ConfigError(option, f"{where}: is a folder; name a params.json file")
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ConfigError(option, f"{where}: is not UTF-8 text; expected a params.json file") from None
    except OSError as e:
        raise ConfigError(option, f"{where}: cannot read it: {e.strerror}") from None
    try:
        data = json.loads(text)
    except ValueError as e:
        raise ConfigError(
            option, f"{where}: is not JSON (line {getattr(e, 'lineno', '?')}): {getattr(e, 'msg', str(e))}"
        ) from None
    if not isinstance(data, dict):
        raise ConfigError(
            option, f"{where}: expected a JSON object (a params.json), got {type(data).__name__}"
        )
    return data


def model_of(data: Mapping[str, Any], path: str = "params", registry=None):
    """The homogenizer a params.json was fitted with (``model`` and ``options``), from the registry."""
    from knitframe.config import instantiate
    from knitframe.plugins import get_registry

    if "model" not in data:
        raise ConfigError(
            f"{path}.model", "required key is missing (the homogenizer the parameters belong to)"
        )
    if not isinstance(data["model"], str):
        raise ConfigError(f"{path}.model", f"expected a homogenizer name, got {data['model']!r}")
    options = data.get("options", {})
    if not isinstance(options, dict):
        raise ConfigError(f"{path}.options", f"expected a table of model options, got {options!r}")
    return instantiate(
        registry or get_registry(), "homogenizer", {"kind": data["model"], **options}, f"{path}.model"
    )


def stored_params(model: Any, data: Mapping[str, Any], path: str = "params") -> dict[str, float]:
    """The model's parameters exactly as stored (``theta_deg`` stays in degrees), each checked finite."""
    from knitframe.fitting import params_from_json, params_to_json

    keys = list(params_to_json(model.param_names, [0.0] * len(model.param_names)))
    params_from_json(
        model.param_names, {k: data[k] for k in keys if k in data}, path
    )  # missing/non-finite: one line
    return {k: float(data[k]) for k in keys}


def card_refusal(model: Any, fmt: str) -> str | None:
    """Why ``model`` cannot be written as ``fmt`` (one line), or None when it can."""
    if fmt not in FORMATS:
        return f"unknown format {fmt!r}; expected one of {', '.join(FORMATS)}"
    formats = tuple(model.card_formats)
    if fmt in formats:
        return None
    reason = model.card_refusal or "it defines no material cards"
    if formats:
        return (
            f"homogenizer '{model.name}' has no {fmt} card ({reason}); "
            f"it can be written as {', '.join(formats)}"
        )
    return (
        f"homogenizer '{model.name}' has no {fmt} card: none of {', '.join(FORMATS)} can express it: {reason}"
    )


def export_card(
    data: Mapping[str, Any],
    fmt: str,
    *,
    path: str = "params",
    registry=None,
    options: Mapping[str, str] | None = None,
    **card_options: Any,
) -> str:
    """The card text of a params.json's model in format ``fmt``.

    ``card_options`` go to the homogenizer's ``card`` (for ``hgo``: ``thickness`` mm, ``name``,
    ``matrix_fraction``, ``bulk_ratio``, ``max_stretch``). ``path`` names the source in errors
    (a bad parameter is ``<path>.<key>``); ``options`` maps option keywords (and ``format``) to
    the names the caller's user knows them by (``--thickness``, ``fit.export_thickness``).
    A model that cannot be written as ``fmt`` is a one-line :class:`ConfigError`.
    """
    names = dict(options or {})
    model = model_of(data, path, registry)
    why = card_refusal(model, fmt)
    if why:
        raise ConfigError(names.get("format", "format"), why)
    params = stored_params(model, data, path)
    try:
        return model.card(fmt, params, source=_source_note(data), **card_options)
    except ConfigError as e:
        key = f"{path}.{e.path}" if e.path in params else names.get(e.path, e.path)
        raise ConfigError(key, e.problem) from None


def _source_note(data: Mapping[str, Any]) -> str:
    """One phrase about the fit a params.json came from: fitter and overall NRMSE when present."""
    parts = []
    if isinstance(data.get("fitter"), str) and data["fitter"]:
        parts.append(f"fitted by {data['fitter']}")
    nrmse = data.get("nrmse")
    if (
        isinstance(nrmse, dict)
        and isinstance(nrmse.get("overall"), (int, float))
        and not isinstance(nrmse.get("overall"), bool)
        and math.isfinite(nrmse["overall"])
    ):
        parts.append(f"NRMSE {100 * nrmse['overall']:.2f} %")
    return ", ".join(parts)


# ---------------------------------------------------------------------------------------------
# writing one file safely
# ---------------------------------------------------------------------------------------------
def check_out_file(out: str | Path, *, overwrite: bool = False, option: str = "--out") -> Path:
    """The file a card may be written to, or a one-line ConfigError; nothing is created.

    Refused: an empty name, ``.``/``..`` or a name ending in a separator, a folder, a link, a
    missing parent folder, a parent that cannot be written, and an existing file — unless
    ``overwrite`` and that file is a card knitframe wrote (:func:`is_knitframe_card`).
    """
    text = str(out)
    if not text.strip():
        raise ConfigError(option, "is empty; name the card file to write")
    name = Path(text).name
    if name in ("", ".", "..") or text.endswith(("/", os.sep)):
        raise ConfigError(option, f"{text}: names a folder; give a file name such as knit.inp")
    p = Path(os.path.abspath(Path(text).expanduser()))
    if p.is_symlink():
        raise ConfigError(option, f"{text}: is a link; name the file itself")
    if p.is_dir():
        raise ConfigError(option, f"{text}: is a folder; give a file name inside it")
    parent = p.parent
    if not parent.exists():
        raise ConfigError(option, f"{text}: folder {parent} does not exist")
    if not parent.is_dir():
        raise ConfigError(option, f"{text}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(option, f"{text}: cannot write in {parent}")
    if p.exists() or os.path.lexists(p):
        if not p.is_file():
            raise ConfigError(option, f"{text}: exists and is not a regular file")
        if not overwrite:
            raise ConfigError(
                option,
                f"{text}: exists; name a new file, or give --overwrite to replace a card knitframe wrote",
            )
        if not is_knitframe_card(p):
            raise ConfigError(
                option,
                f"{text}: exists and is not a knitframe card (its first line is not "
                f"'** {CARD_TAG}: ...'); --overwrite only replaces knitframe's own cards",
            )
    return p


def write_card(out: str | Path, text: str, *, overwrite: bool = False, option: str = "--out") -> Path:
    """Write ``text`` to ``out`` atomically (a temporary file in the same folder, then a rename).

    The checks of :func:`check_out_file` run first, and again right before the rename; on any
    failure the temporary file is removed and nothing else is touched.
    """
    p = check_out_file(out, overwrite=overwrite, option=option)
    try:
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".tmp")
    except OSError as e:
        raise ConfigError(option, f"{out}: cannot write in {p.parent}: {e.strerror}") from None
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        check_out_file(out, overwrite=overwrite, option=option)  # nothing appeared meanwhile
        if overwrite:
            os.replace(tmp, p)
        else:  # a hard link never replaces a file that appeared since the check
            try:
                os.link(tmp, p)
            except FileExistsError:
                raise ConfigError(
                    option, f"{out}: appeared while the card was written; not replaced"
                ) from None
            except OSError:  # a file system without hard links
                os.replace(tmp, p)
            Path(tmp).unlink(missing_ok=True)
    except BaseException as e:
        Path(tmp).unlink(missing_ok=True)
        name_written(e, out, tmp)
        raise
    return p


# ---------------------------------------------------------------------------------------------
# the CalculiX check
# ---------------------------------------------------------------------------------------------
_CASE = re.compile(
    r"^\*\* check case (?P<set>[A-Z]+): (?P<kind>[a-z-]+), lam1 1 -> (?P<l1>[0-9.eE+-]+), "
    r"lam2 1 -> (?P<l2>[0-9.eE+-]+), (?P<n>\d+) increments"
)
_TOTAL = re.compile(r"total force \(fx,fy,fz\) for set (?P<set>\S+) and time\s+(?P<t>\S+)")
_DISP = re.compile(r"displacements \(vx,vy,vz\) for set (?P<set>\S+) and time\s+(?P<t>\S+)")
_THICK = re.compile(r"^\*\* check block thickness t0 = (?P<t0>[0-9.eE+-]+) mm")
_EXPECTED = re.compile(r"^\*\* (?P<set>[A-Z]+)\s+(?P<v>(?:\s*[-+0-9.eE]+){7})\s*$")


def read_check_cases(deck: str) -> list[dict[str, Any]]:
    """The load cases a ``calculix-deck`` declares in its header.

    Each case: ``set``, ``kind``, end stretches ``lam1``, ``lam2``, ``increments``, the block
    thickness ``t0`` (mm) and ``expected``: the header's rows ``(lam1, lam2, knitframe T1, T2,
    card T1, T2, lam3)``, one per increment.
    """
    cases, t0, expected = [], None, {}
    for line in deck.splitlines():
        line = line.strip()
        m = _CASE.match(line)
        if m:
            cases.append(
                {
                    "set": m["set"],
                    "kind": m["kind"],
                    "lam1": float(m["l1"]),
                    "lam2": float(m["l2"]),
                    "increments": int(m["n"]),
                }
            )
        if m := _THICK.match(line):
            t0 = float(m["t0"])
        if m := _EXPECTED.match(line):
            expected.setdefault(m["set"], []).append(tuple(float(v) for v in m["v"].split()))
    for case in cases:
        case["t0"] = t0
        case["expected"] = expected.get(case["set"], [])
    return cases


def read_dat_totals(text: str) -> dict[str, list[tuple[float, tuple[float, float, float]]]]:
    """``*NODE PRINT, TOTALS=ONLY`` blocks of a CalculiX ``.dat`` file: set → [(time, (fx, fy, fz)), …]."""
    out: dict[str, list] = {}
    lines = text.splitlines()
    for i, line in enumerate(lines):
        m = _TOTAL.search(line)
        if not m:
            continue
        values = next((ln.split() for ln in lines[i + 1 : i + 4] if ln.strip()), None)
        if values is None or len(values) != 3:
            raise NumericalError(f"CalculiX output: no force totals after '{line.strip()}'")
        out.setdefault(m["set"].upper(), []).append((float(m["t"]), tuple(float(v) for v in values)))
    return out


def read_dat_displacements(text: str) -> dict[str, list[tuple[float, dict[int, tuple[float, float, float]]]]]:
    """``*NODE PRINT`` blocks of ``U`` in a CalculiX ``.dat``: set → [(time, {node: (ux, uy, uz)}), …]."""
    out: dict[str, list] = {}
    lines = text.splitlines()
    for i, line in enumerate(lines):
        m = _DISP.search(line)
        if not m:
            continue
        nodes: dict[int, tuple[float, float, float]] = {}
        for ln in lines[i + 1 :]:
            parts = ln.split()
            if not parts:
                if nodes:
                    break
                continue
            if len(parts) != 4:
                break
            nodes[int(parts[0])] = (float(parts[1]), float(parts[2]), float(parts[3]))
        out.setdefault(m["set"].upper(), []).append((float(m["t"]), nodes))
    return out


def run_calculix(
    deck: str,
    *,
    ccx: str = "ccx",
    job: str = "check",
    timeout: float = 300.0,
    workdir: str | Path | None = None,
) -> str:
    """Run CalculiX on ``deck`` in a temporary folder (or ``workdir``) and return the ``.dat`` text.

    A missing ``ccx``, a non-zero exit or an ``*ERROR`` in its output is a one-line
    :class:`NumericalError` (exit code 3) that quotes CalculiX's message.
    """
    exe = shutil.which(ccx)
    if exe is None:
        raise KnitframeError(
            f"CalculiX '{ccx}' is not on the PATH (Debian/Ubuntu: apt-get install calculix-ccx)"
        )
    with tempfile.TemporaryDirectory(prefix="knitframe-ccx-") as tmp:
        folder = Path(workdir) if workdir is not None else Path(tmp)
        (folder / f"{job}.inp").write_text(deck, encoding="utf-8")
        env = {**os.environ, "OMP_NUM_THREADS": "1", "CCX_NPROC_STIFFNESS": "1"}
        proc = subprocess.run(
            [exe, "-i", job], cwd=folder, capture_output=True, text=True, timeout=timeout, env=env
        )
        log = proc.stdout + proc.stderr
        dat = folder / f"{job}.dat"
        error = next((ln.strip() for ln in log.splitlines() if "*ERROR" in ln), None)
        if proc.returncode != 0 or error or not dat.is_file():
            raise NumericalError(f"CalculiX failed (exit {proc.returncode}): {error or log.strip()[-300:]}")
        return dat.read_text(encoding="utf-8", errors="replace")


def calculix_check(
    data: Mapping[str, Any], *, ccx: str = "ccx", path: str = "params", **options: Any
) -> list[dict]:
    """Run the ``calculix-deck`` of a params.json and compare CalculiX with knitframe's own model.

    Returns one row per load case and increment: ``case``, ``kind``, ``time``, ``lam1``, ``lam2``,
    ``ccx`` = (T1, T2) tensions per unit width from the reactions (N/mm; the block's faces are
    1 mm wide), ``lam3`` and ``J`` from CalculiX's displacements, ``knitframe`` =
    ``model.stress(params, lam1, lam2)`` of the fitted model, and ``card`` = (T1, T2) of the
    card's own energy as the deck's header states it.
    """
    import numpy as np

    from knitframe.fitting import params_from_json

    model = model_of(data, path)
    deck = export_card(data, "calculix-deck", path=path, **options)
    cases = read_check_cases(deck)
    dat = run_calculix(deck, ccx=ccx)
    totals, disp = read_dat_totals(dat), read_dat_displacements(dat)
    params = params_from_json(model.param_names, stored_params(model, data, path), path)
    rows = []
    for case in cases:
        n = case["increments"]
        fx, fy = totals.get(f"{case['set']}_X1", []), totals.get(f"{case['set']}_Y1", [])
        top = disp.get(f"{case['set']}_TOP", [])
        if not (len(fx) == len(fy) == len(top) == len(case["expected"]) == n):
            raise NumericalError(f"CalculiX output: {len(fx)} increments of case {case['set']}, expected {n}")
        for (t, fxv), (_, fyv), (_, nodes), exp in zip(fx, fy, top, case["expected"]):
            l1, l2 = 1.0 + t * (case["lam1"] - 1.0), 1.0 + t * (case["lam2"] - 1.0)
            P1, P2 = model.stress(params, np.array([l1]), np.array([l2]))
            l3 = 1.0 + float(np.mean([u[2] for u in nodes.values()])) / case["t0"]
            rows.append(
                {
                    "case": case["set"],
                    "kind": case["kind"],
                    "time": t,
                    "lam1": l1,
                    "lam2": l2,
                    "ccx": (fxv[0], fyv[1]),
                    "lam3": l3,
                    "J": l1 * l2 * l3,
                    "knitframe": (float(P1[0]), float(P2[0])),
                    "card": (exp[4], exp[5]),
                }
            )
    return rows
