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
          "tension_scatter": 0.36,             # scatter of the course tests' repeats, or null (optional)
          "source": "...",                     # where the model and the limits came from
          "pitch_source": "...",               # where the pitches came from
          "pitch_measured": false,             # pitches measured (true) or estimated, or null (optional)
          "gauge": null,                       # knitter's gauge of the pitches, or null (optional):
                                               #   {"stitches_per_10cm": 22, "courses_per_10cm": 30}
          "fit": {"nrmse": {...}, ...}         # how the model was fitted (optional; copied from params.json)
        }
      ]
    }

Pitches: a knitter's gauge (stitches and courses per 10 cm of a relaxed swatch) gives course pitch =
100/stitches mm and wale pitch = 100/courses mm (:meth:`FabricEntry.with_gauge`,
:meth:`FabricLibrary.with_gauges`, ``knitframe library build --gauge 22,30``), and an entry with a
gauge has exactly those pitches. :attr:`FabricEntry.pitch_is_estimate` is True unless a gauge or
``pitch_measured: true`` says the pitches were measured; a file without these keys (written before
them) is read by its ``pitch_source``, so Munden estimates are estimates. The three new keys are
optional: files without them still load (format 1).

``tension_scatter``: the median over the tested stretch range of the repeats' relative half-spread
of course tension, (max − min)/(2 mean) among the repeats interpolated to common stretches, the toe
below 10 % of the peak mean tension left out (:func:`tension_scatter`); a fraction (0.09: the repeats
lie within about ±9 % of their mean). None when the entry's tests are unknown.

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
* ``tension_scatter`` from the course test's repeats (:func:`course_scatter`): 0.049–0.098 for
  seven fabrics, 0.36 for cotton rib, whose five repeats differ much more; ``pitch_measured`` false.
* limits: ``max_tension`` = the peak tension measured in the fabric's course (x) tests over all
  repeats (the data's loading branch ends at peak force, so it is the end of the measured range,
  not a proven breaking strength); ``max_stretch`` = 1 + the largest course strain measured there.

Rebuild it (about 40 s on one core) and compare or replace the shipped file::

    knitframe library build-builtin --out builtin-out
    cp builtin-out/library.json knitframe/garment/data/library-singal2024.json

``builtin-out/fits/`` then also holds each fabric's ``params.json`` and ``fit.png``. The
test ``test_builtin_rebuild_reproduces_shipped`` (marked slow) checks that a rebuild reproduces
the shipped parameters. :func:`with_builtin_scatter` recomputes only the scatter (and marks the
pitches estimated) from the shipped data, leaving every fitted number as it is.

Your own library: fit your tests with ``knitframe fit DATA... --model hgo2m --out FIT`` (one fit
per fabric), then ``knitframe library build FIT1/params.json FIT2/params.json --out LIB
--pattern ... --yarn ... --max-tension ...`` (:meth:`FabricLibrary.from_fits`);
``knitframe library show LIB/library.json`` prints it.

Units: mm, N/mm; angles in degrees in files, radians in code.

Modules: :mod:`.checks` (field checks), :mod:`.entry` (:class:`FabricEntry`), :mod:`.record`
(:class:`FabricLibrary`), :mod:`.reading` (JSON files), :mod:`.fits` (entries from fits) and
:mod:`.builtin` (the built-in library).
"""

from knitframe.garment.library.builtin import (
    BUILTIN_DATA,
    BUILTIN_FILE,
    BUILTIN_FITTER,
    BUILTIN_LOOP_LENGTH,
    BUILTIN_MODEL,
    BUILTIN_PATTERNS,
    BUILTIN_YARNS,
    DATA_DIR,
    SCATTER_POINTS,
    SCATTER_TOE,
    build_builtin,
    builtin_library,
    course_limits,
    course_scatter,
    tension_scatter,
    with_builtin_scatter,
)
from knitframe.garment.library.checks import GAUGE_KEYS, gauge_pitches
from knitframe.garment.library.entry import FabricEntry
from knitframe.garment.library.record import LIBRARY_FORMAT, FabricLibrary

__all__ = [
    "FabricEntry",
    "FabricLibrary",
    "builtin_library",
    "build_builtin",
    "course_limits",
    "course_scatter",
    "tension_scatter",
    "with_builtin_scatter",
    "gauge_pitches",
    "GAUGE_KEYS",
    "SCATTER_POINTS",
    "SCATTER_TOE",
    "LIBRARY_FORMAT",
    "BUILTIN_DATA",
    "BUILTIN_FILE",
    "BUILTIN_FITTER",
    "BUILTIN_MODEL",
    "BUILTIN_LOOP_LENGTH",
    "BUILTIN_PATTERNS",
    "BUILTIN_YARNS",
    "DATA_DIR",
]
