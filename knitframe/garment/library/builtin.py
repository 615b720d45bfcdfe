"""The built-in library: Singal et al. 2024's fabrics, the shipped file, and how it is rebuilt."""

from __future__ import annotations

import functools
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe.garment.library.checks import plugin_registry
from knitframe.garment.library.record import FabricLibrary

__all__ = [
    "DATA_DIR",
    "BUILTIN_FILE",
    "BUILTIN_DATA",
    "BUILTIN_MODEL",
    "BUILTIN_FITTER",
    "BUILTIN_LOOP_LENGTH",
    "BUILTIN_YARNS",
    "BUILTIN_PATTERNS",
    "builtin_library",
    "course_limits",
    "SCATTER_POINTS",
    "SCATTER_TOE",
    "tension_scatter",
    "course_scatter",
    "with_builtin_scatter",
    "build_builtin",
]

#: package data of the built-in library
DATA_DIR = Path(__file__).parents[1] / "data"
BUILTIN_FILE = DATA_DIR / "library-singal2024.json"
#: the Singal et al. 2024 CSV files the built-in library is fitted to
BUILTIN_DATA = DATA_DIR / "singal2024"
#: model and fitter of the built-in fits
BUILTIN_MODEL = "hgo2m"
BUILTIN_FITTER = {"kind": "lbfgs", "starts": 16, "screen": 256}
#: estimated loop length (mm of yarn per stitch) of both yarns of the built-in library;
#: see the module docstring
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
        "stitch length of Singal et al.'s own simulation of this acrylic in stockinette "
        "(sabetta/stitch-by-stitch, "
        "stockinetteconfig.dat); not measured",
    ),
}
#: pattern in the file names -> knitframe pattern
BUILTIN_PATTERNS = {"stockinette": "jersey", "garter": "garter", "rib": "rib", "seed": "seed"}


@functools.lru_cache(maxsize=1)
def builtin_library() -> FabricLibrary:
    """The shipped library: Singal et al. 2024's pearl cotton and acrylic in 4 patterns (8 entries, see
    module doc)."""
    return FabricLibrary.load(BUILTIN_FILE)


# ----------------------------------------------------------------------------------------- built-in
def _raw_reader() -> Any:
    """The ``singal2024`` reader giving one Response per repeat."""
    from knitframe.config import instantiate

    return instantiate(plugin_registry(), "reader", {"kind": "singal2024", "average": False}, "reader")


def course_limits(x_file: Path) -> tuple[float, float, int]:
    """``(peak tension N/mm, largest stretch, repeats)`` of a course (x) test file over all its repeats."""
    repeats = _raw_reader().read(x_file)
    return (
        max(float(r.T1.max()) for r in repeats),
        max(float(r.lambda1.max()) for r in repeats),
        len(repeats),
    )


#: grid of common stretches and toe cut-off of :func:`tension_scatter`
SCATTER_POINTS, SCATTER_TOE = 100, 0.1


def tension_scatter(repeats: Sequence[Any]) -> float | None:
    r"""Scatter of the repeats of one course test: the median over stretch of their relative half-spread
    of course tension; None for fewer than 2 repeats, repeats that share no stretch or no tension.

    Each repeat ``k`` (a Response: ``lambda1``, ``T1``), sorted by stretch, is interpolated linearly
    to :data:`SCATTER_POINTS` (100) stretches λ_j evenly spaced over the range every repeat covers,
    [max_k min λ1, min_k max λ1] (as the reader's mean of the repeats). With the mean
    T̄_j = mean_k T_k(λ_j)

    .. math:: s = \operatorname{median}_{j:\ \bar T_j \ge 0.1 \max_i \bar T_i}
              \frac{\max_k T_k(\lambda_j) - \min_k T_k(\lambda_j)}{2 \bar T_j}

    the toe, where the mean tension is below :data:`SCATTER_TOE` (10 %) of its peak, left out. A
    fraction: 0.09 means the repeats lie within about ±9 % of their mean.
    """
    from knitframe.curves import by_strain

    if len(repeats) < 2:
        return None
    curves = [
        by_strain(np.asarray(r.lambda1, dtype=np.float64), np.asarray(r.T1, dtype=np.float64))
        for r in repeats
    ]
    lo, hi = max(lam[0] for lam, _ in curves), min(lam[-1] for lam, _ in curves)
    if not hi > lo:
        return None
    grid = np.linspace(lo, hi, SCATTER_POINTS)
    tension = np.array([np.interp(grid, lam, t) for lam, t in curves])
    mean = tension.mean(axis=0)
    if not mean.max() > 0:
        return None
    kept = mean >= SCATTER_TOE * mean.max()
    spread = (tension.max(axis=0) - tension.min(axis=0))[kept] / (2 * mean[kept])
    return float(np.median(spread))


def course_scatter(x_file: Path) -> float | None:
    """:func:`tension_scatter` of the repeats of a course (x) test file."""
    return tension_scatter(_raw_reader().read(x_file))


def with_builtin_scatter(library: FabricLibrary, data_dir: str | Path = BUILTIN_DATA) -> FabricLibrary:
    """``library`` (the built-in one) with each entry's ``tension_scatter`` computed from its course test
    in ``data_dir`` (:func:`course_scatter`) and its pitches recorded as estimated; nothing else changes."""
    entries = []
    for e in library:
        x = next(f for f in e.fit["responses"] if f.endswith("-x"))
        entries.append(
            attrs.evolve(e, tension_scatter=course_scatter(Path(data_dir) / f"{x}.csv"), pitch_measured=False)
        )
    return attrs.evolve(library, entries=tuple(entries))


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

    reg = plugin_registry()
    data_dir = Path(data_dir)
    fits = Path(folder) / "fits"
    fits.mkdir(parents=True, exist_ok=True)
    reader = instantiate(reg, "reader", "singal2024", "reader")
    model = instantiate(reg, "homogenizer", BUILTIN_MODEL, "model")
    fitter = instantiate(reg, "fitter", BUILTIN_FITTER, "fitter")
    fitter_text = (
        f"{BUILTIN_FITTER['kind']} ({BUILTIN_FITTER['starts']} starts from "
        f"{BUILTIN_FITTER['screen']} screened)"
    )
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
            "tension_scatter",
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
            source, pitch_source = _builtin_texts(
                (ydesc, basis), (pkey, pattern), (x, y), reps, n_rep, result, fitter_text
            )
            kw["source"].append(source)
            kw["pitch_source"].append(pitch_source)
            kw["tension_scatter"].append(course_scatter(x))
    return FabricLibrary.from_fits(
        files,
        **kw,
        pitch_measured=False,
        name="singal2024",
        library_source="Singal et al. 2024, Nat Commun 15:2622, doi:10.1038/s41467-024-46498-z: uniaxial "
        "tests of pearl cotton and acrylic in jersey, garter, rib and seed (sabetta/stitch-by-stitch, "
        "MIT licence, "
        "Copyright (c) 2023 sabetta), fitted by knitframe (knitframe library build-builtin)",
    )


def _builtin_texts(
    yarn: tuple[str, str],
    patterns: tuple[str, str],
    tests: tuple[Path, Path],
    reps: str,
    n_rep: int,
    result: Any,
    fitter_text: str,
) -> tuple[str, str]:
    """The ``source`` and ``pitch_source`` of a built-in entry: the data, the fit, the limits, the pitches.

    ``yarn`` is (description, how its loop length was estimated), ``patterns`` (file name, knitframe
    pattern), ``tests`` the course (x) and wale (y) files, ``reps`` the repeats per test ("3/3"),
    ``n_rep`` the course test's repeats and ``result`` the fit.
    """
    from knitframe.geometry import MUNDEN_KC, MUNDEN_KW

    ydesc, basis = yarn
    pkey, pattern = patterns
    x, y = tests
    loop = BUILTIN_LOOP_LENGTH
    pattern_text = pattern if pkey == pattern else f"{pkey} (= {pattern})"
    source = (
        f"fit of Singal et al. 2024 (Nat Commun 15:2622; data sabetta/stitch-by-stitch, MIT) {ydesc} "
        f"{pattern_text}, free-sides uniaxial tests {x.name} (course) and {y.name} (wale), mean of "
        f"{reps} repeats: {BUILTIN_MODEL} by {fitter_text}, tension NRMSE "
        f"{100 * result.nrmse['overall']:.2f} %, transverse strain NRMSE "
        f"{100 * result.nrmse_transverse.get('overall', float('nan')):.2f} %; "
        f"limits: max_tension = peak course tension measured ({x.name}, {n_rep} repeats; "
        "the tests end at peak force), max_stretch = 1 + largest course strain measured there"
    )
    pitch_source = (
        f"Munden's plain-knit relations (Kc = {MUNDEN_KC:g}, Kw = {MUNDEN_KW:g}; course pitch = l/Kw, "
        f"wale pitch = l/Kc) with loop length l = {loop:g} mm (estimate: {basis})"
        + (
            ""
            if pattern == "jersey"
            else f"; plain-knit relation applied to {pattern}, whose relaxed pitches differ: measure them"
        )
    )
    return source, pitch_source
