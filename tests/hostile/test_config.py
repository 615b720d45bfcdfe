"""Hostile configs: every value a config can get wrong is refused before any work.

Each case writes one config into a fresh folder and runs ``knitframe run cfg.toml --out out`` there
(in this process, through :func:`knitframe.cli.main`, so the suite stays fast); a few run as real
subprocesses. :func:`assert_refused` checks exit code 2, one stderr line naming the TOML path, no
traceback, and that the folder holds exactly what it held before: no ``out``, no checkpoints, nothing.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest
import tomli_w

from .conftest import assert_refused, snapshot

DATA = Path(__file__).resolve().parents[1] / "data" / "singal2024"
FABRIC = {"pattern": "jersey", "stitch_length": 11, "yarn": "cotton"}
ROD = {"solver": {"kind": "rod"}, "fabric": FABRIC}
PRESTRESS = ["large_deformation", "bending", "contact", "prestress"]
VOLUMETRIC = {"solver": {"kind": "volumetric"}, "fabric": FABRIC, "scene": {"effects": PRESTRESS}}
REDUCED = {
    "solver": {"kind": "reduced", "model": "hgo", "params": {"a": 0.1, "b": 2.0, "theta_deg": 45.0}},
    "fabric": FABRIC,
    "scene": {"effects": ["large_deformation", "anisotropy"]},
}
MEASURED = {"data": {"files": [str(DATA / "cotton-rib-x.csv")]}}
FIT = {**MEASURED, "fit": {"model": "hgo", "fitter": "lbfgs"}}
DROP = object()  #: a change that removes the key
GENERAL = {"kind": "general", "lambda1": [1.0, 1.1], "lambda2": [1.0, 1.0]}
WOOL = {"like": "cotton"}


def edit(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """A copy of config ``base`` with dotted keys set (or removed with DROP)."""
    out = copy.deepcopy(base)
    for dotted, value in changes.items():
        *parents, last = dotted.split(".")
        table = out
        for key in parents:
            table = table.setdefault(key, {})
        if value is DROP:
            table.pop(last, None)
        else:
            table[last] = value
    return out


def general(**lam) -> dict[str, Any]:
    """A general load path with the given lambda1/lambda2 (the other stays a valid two-point path)."""
    return {"scene": {"load": {**GENERAL, **lam}}}


#: (case, config: a dict or raw TOML text, the field the error line must name, extra files {name: text})
CASES: list[tuple[str, Any, str, dict[str, str]]] = [
    # ---- [fabric]: the stitch-length table and the dimensions a stitch can have
    ("stitch-length-not-in-table-rod", edit(ROD, {"fabric.stitch_length": 1e9}), "fabric.stitch_length", {}),
    (
        "stitch-length-not-in-table-volumetric",
        edit(VOLUMETRIC, {"fabric.stitch_length": 1e9}),
        "fabric.stitch_length",
        {},
    ),
    ("stitch-length-13", edit(ROD, {"fabric.stitch_length": 13}), "fabric.stitch_length", {}),
    ("stitch-length-zero", edit(ROD, {"fabric.stitch_length": 0}), "fabric.stitch_length", {}),
    ("stitch-length-negative", edit(ROD, {"fabric.stitch_length": -11}), "fabric.stitch_length", {}),
    ("stitch-length-nan", edit(ROD, {"fabric.stitch_length": float("nan")}), "fabric.stitch_length", {}),
    ("stitch-length-inf", edit(ROD, {"fabric.stitch_length": float("inf")}), "fabric.stitch_length", {}),
    ("stitch-length-string", edit(ROD, {"fabric.stitch_length": "eleven"}), "fabric.stitch_length", {}),
    ("no-stitch-length-or-arc-length", edit(ROD, {"fabric.stitch_length": DROP}), "fabric.stitch_length", {}),
    ("arc-length-huge", edit(ROD, {"fabric.arc_length": 1e9}), "fabric.arc_length", {}),
    ("arc-length-1e300", edit(ROD, {"fabric.arc_length": 1e300}), "fabric.arc_length", {}),
    ("arc-length-tiny", edit(ROD, {"fabric.arc_length": 0.01}), "fabric.arc_length", {}),
    ("arc-length-too-short-to-interlock", edit(ROD, {"fabric.arc_length": 1.5}), "fabric.arc_length", {}),
    ("course-pitch-tiny", edit(ROD, {"fabric.course_pitch": 1e-9}), "fabric.course_pitch", {}),
    ("course-pitch-longer-than-the-yarn", edit(ROD, {"fabric.course_pitch": 100}), "fabric.course_pitch", {}),
    ("wale-pitch-zero", edit(ROD, {"fabric.wale_pitch": 0}), "fabric.wale_pitch", {}),
    ("wale-pitch-negative", edit(ROD, {"fabric.wale_pitch": -1}), "fabric.wale_pitch", {}),
    ("wale-pitch-huge", edit(ROD, {"fabric.wale_pitch": 50}), "fabric.wale_pitch", {}),
    ("wale-pitch-loops-do-not-reach", edit(ROD, {"fabric.wale_pitch": 2.3}), "fabric.wale_pitch", {}),
    (
        "table-setting-gives-absurd-length",
        edit(ROD, {"fabric.pattern_options": {"stitch_lengths": {"11": 1e9}}}),
        "fabric.stitch_length",
        {},
    ),
    (
        "table-length-negative",
        edit(ROD, {"fabric.pattern_options": {"stitch_lengths": {"11": -1}}}),
        "fabric.pattern_options.stitch_lengths.11",
        {},
    ),
    (
        "pattern-option-unknown",
        edit(ROD, {"fabric.pattern_options": {"loops": 3}}),
        "fabric.pattern_options.loops",
        {},
    ),
    (
        "pattern-option-out-of-range",
        edit(ROD, {"fabric.pattern_options": {"roundness": 100}}),
        "fabric.pattern_options.roundness",
        {},
    ),
    (
        "pattern-option-Kc-1e300",
        edit(ROD, {"fabric.pattern_options": {"Kc": 1e300}}),
        "fabric.pattern_options.Kc",
        {},
    ),
    (
        "pattern-option-Kw-1e-300",
        edit(ROD, {"fabric.pattern_options": {"Kw": 1e-300}}),
        "fabric.pattern_options.Kw",
        {},
    ),
    (
        "pattern-option-depth-1e300",
        edit(ROD, {"fabric.pattern_options": {"depth": 1e300}}),
        "fabric.pattern_options.depth",
        {},
    ),
    ("pattern-unknown", edit(ROD, {"fabric.pattern": "jersy"}), "fabric.pattern", {}),
    ("fabric-key-unknown", edit(ROD, {"fabric.colour": "red"}), "fabric.colour", {}),
    ("fabric-missing", edit(ROD, {"fabric": DROP}), "fabric", {}),
    ("fabric-yarn-missing", edit(ROD, {"fabric.yarn": DROP}), "fabric.yarn", {}),
    ("fabric-yarn-unknown", edit(ROD, {"fabric.yarn": "wool"}), "fabric.yarn", {}),
    ("fabric-yarn-a-number", edit(ROD, {"fabric.yarn": 5}), "fabric.yarn", {}),
    # ---- yarns: names, models and numbers a yarn can have
    (
        "yarn-model-unknown",
        edit(ROD, {"yarns.wool": {**WOOL, "model": "nope"}, "fabric.yarn": "wool"}),
        "yarns.wool.model",
        {},
    ),
    (
        "yarn-model-unknown-inline",
        edit(ROD, {"fabric.yarn": {**WOOL, "model": "nope"}}),
        "fabric.yarn.model",
        {},
    ),
    (
        "yarn-like-unknown",
        edit(ROD, {"yarns.wool": {"like": "mohair"}, "fabric.yarn": "wool"}),
        "yarns.wool.like",
        {},
    ),
    (
        "yarn-transverse-stiffer-than-axial",
        edit(ROD, {"yarns.wool": {**WOOL, "E_transverse": 5000.0}, "fabric.yarn": "wool"}),
        "yarns.wool.E_transverse",
        {},
    ),
    (
        "yarn-dk-above-d0",
        edit(ROD, {"yarns.wool": {**WOOL, "dk": 1.0}, "fabric.yarn": "wool"}),
        "yarns.wool.dk",
        {},
    ),
    (
        "yarn-diameter-subatomic",
        edit(ROD, {"fabric.yarn": {**WOOL, "d0": 1e-300, "dk": 1e-300}}),
        "fabric.yarn.d0",
        {},
    ),
    ("yarn-modulus-negative", edit(ROD, {"fabric.yarn": {**WOOL, "E_axial": -1}}), "fabric.yarn.E_axial", {}),
    ("yarn-modulus-1e300", edit(ROD, {"fabric.yarn": {**WOOL, "E_axial": 1e300}}), "fabric.yarn.E_axial", {}),
    (
        "yarn-transverse-modulus-tiny",
        edit(ROD, {"fabric.yarn": {**WOOL, "E_transverse": 1e-300}}),
        "fabric.yarn.E_transverse",
        {},
    ),
    (
        "yarn-bending-stiffer-than-a-solid-rod",
        edit(ROD, {"fabric.yarn": {**WOOL, "bending_stiffness": 1e300}}),
        "fabric.yarn.bending_stiffness",
        {},
    ),
    ("yarn-poisson-half", edit(ROD, {"fabric.yarn": {**WOOL, "nu": 0.5}}), "fabric.yarn.nu", {}),
    (
        "yarn-modulus-nan",
        edit(ROD, {"fabric.yarn": {**WOOL, "E_axial": float("nan")}}),
        "fabric.yarn.E_axial",
        {},
    ),
    (
        "yarn-key-unknown",
        edit(ROD, {"yarns.wool": {**WOOL, "colour": "grey"}, "fabric.yarn": "wool"}),
        "yarns.wool.colour",
        {},
    ),
    (
        "yarn-table-incomplete",
        edit(ROD, {"yarns.wool": {"dk": 0.4}, "fabric.yarn": "wool"}),
        "yarns.wool.d0",
        {},
    ),
    # ---- [solver] rod: plugins by name and options, stiffness overrides
    ("solver-unknown", edit(ROD, {"solver.kind": "fem"}), "solver.kind", {}),
    ("solver-kind-a-huge-array", "[solver]\nkind = " + "[" * 200 + "]" * 200 + "\n", "solver.kind", {}),
    ("rod-contact-law-unknown", edit(ROD, {"solver.contact_law": "nope"}), "solver.contact_law", {}),
    ("rod-contact-law-for-solids", edit(ROD, {"solver.contact_law": "ipc"}), "solver.contact_law", {}),
    (
        "rod-contact-law-unknown-unused",
        edit(ROD, {"solver.contact_law": "nope", "scene.effects": ["bending"]}),
        "solver.contact_law",
        {},
    ),
    (
        "rod-contact-law-option-range",
        edit(ROD, {"solver.contact_law": {"kind": "rod_penalty", "smoothing": 2}}),
        "solver.contact_law.smoothing",
        {},
    ),
    (
        "rod-contact-law-smoothing-tiny",
        edit(ROD, {"solver.contact_law": {"kind": "rod_penalty", "smoothing": 1e-300}}),
        "solver.contact_law.smoothing",
        {},
    ),
    (
        "rod-contact-law-friction-1e300",
        edit(
            ROD,
            {
                "solver.contact_law": {"kind": "rod_penalty", "friction": 1e300},
                "scene.effects": [*PRESTRESS, "friction"],
            },
        ),
        "solver.contact_law.friction",
        {},
    ),
    (
        "rod-contact-law-stiffness-1e300",
        edit(ROD, {"solver.contact_law": {"kind": "rod_penalty", "stiffness": 1e300}}),
        "solver.contact_law.stiffness",
        {},
    ),
    (
        "rod-contact-law-option-unknown",
        edit(ROD, {"solver.contact_law": {"kind": "rod_penalty", "colour": 1}}),
        "solver.contact_law.colour",
        {},
    ),
    ("rod-linear-solver-unknown", edit(ROD, {"solver.linear_solver": "nope"}), "solver.linear_solver", {}),
    (
        "rod-linear-solver-backend-missing",
        edit(ROD, {"solver.linear_solver": {"kind": "direct", "backend": "cholmod"}}),
        "solver.linear_solver.backend",
        {},
    ),
    (
        "rod-linear-solver-backend-unknown",
        edit(ROD, {"solver.linear_solver": {"kind": "direct", "backend": "mumps"}}),
        "solver.linear_solver.backend",
        {},
    ),
    (
        "rod-amg-theta-out-of-range",
        edit(ROD, {"solver.linear_solver": {"kind": "amg", "theta": 2.0}}),
        "solver.linear_solver.theta",
        {},
    ),
    (
        "rod-linear-solver-option-unknown",
        edit(ROD, {"solver.linear_solver": {"kind": "direct", "colour": 1}}),
        "solver.linear_solver",
        {},
    ),
    ("rod-EA-1e300", edit(ROD, {"solver.EA": 1e300}), "solver.EA", {}),
    ("rod-EI-1e-300", edit(ROD, {"solver.EI": 1e-300}), "solver.EI", {}),
    (
        "rod-contact-stiffness-1e300",
        edit(ROD, {"solver.contact_stiffness": 1e300}),
        "solver.contact_stiffness",
        {},
    ),
    ("rod-EA-inf", edit(ROD, {"solver.EA": float("inf")}), "solver.EA", {}),
    ("rod-segments-huge", edit(ROD, {"solver.segments_per_stitch": 10**9}), "solver.segments_per_stitch", {}),
    (
        "rod-segments-fractional",
        edit(ROD, {"solver.segments_per_stitch": 2.5}),
        "solver.segments_per_stitch",
        {},
    ),
    ("rod-tolerance-negative", edit(ROD, {"solver.tolerance": -1}), "solver.tolerance", {}),
    (
        "rod-prestress-start-unknown",
        edit(ROD, {"solver.prestress_start": "sideways"}),
        "solver.prestress_start",
        {},
    ),
    ("rod-option-unknown", edit(ROD, {"solver.colour": "red"}), "solver.colour", {}),
    ("rod-overlap-without-prestress", edit(ROD, {"fabric.stitch_length": 10}), "scene.effects", {}),
    # ---- [solver] volumetric
    (
        "volumetric-contact-law-for-rods",
        edit(VOLUMETRIC, {"solver.contact_law": "rod_penalty"}),
        "solver.contact_law",
        {},
    ),
    (
        "volumetric-linear-solver-unknown",
        edit(VOLUMETRIC, {"solver.linear_solver": "nope"}),
        "solver.linear_solver",
        {},
    ),
    (
        "volumetric-mortar-past-the-strain-it-finishes",
        edit(VOLUMETRIC, {"solver.contact_law": "mortar"}),
        "solver.contact_law",
        {},
    ),
    ("volumetric-order-3", edit(VOLUMETRIC, {"solver.order": 3}), "solver.order", {}),
    ("volumetric-seed-tiny", edit(VOLUMETRIC, {"solver.seed": 1e-3}), "solver.seed", {}),
    (
        "volumetric-max-step-past-reach",
        edit(VOLUMETRIC, {"solver.newton.max_step": 0.4, "solver.contact_law": "penalty"}),
        "solver.newton.max_step",
        {},
    ),
    (
        "volumetric-overlap-without-prestress",
        edit(VOLUMETRIC, {"scene.effects": ["large_deformation", "contact"]}),
        "scene.effects",
        {},
    ),
    (
        "volumetric-tight-cell-under-min-clearance",
        edit(VOLUMETRIC, {"solver.min_clearance": 2.0}),
        "solver.min_clearance",
        {},
    ),
    (
        "volumetric-tangent-unknown",
        edit(VOLUMETRIC, {"solver.newton.tangent": "magic"}),
        "solver.newton.tangent",
        {},
    ),
    (
        "volumetric-contact-modulus-1e300",
        edit(VOLUMETRIC, {"solver.contact_modulus": 1e300}),
        "solver.contact_modulus",
        {},
    ),
    (
        "volumetric-ipc-dhat-out-of-range",
        edit(VOLUMETRIC, {"solver.contact_law": {"kind": "ipc", "dhat": 5.0}}),
        "solver.contact_law.dhat",
        {},
    ),
    (
        "volumetric-stabilisation-1e300",
        edit(VOLUMETRIC, {"solver.newton.stabilisation": 1e300}),
        "solver.newton.stabilisation",
        {},
    ),
    (
        "volumetric-ipc-stiffness-1e300",
        edit(VOLUMETRIC, {"solver.contact_law": {"kind": "ipc", "stiffness": 1e300}}),
        "solver.contact_law.stiffness",
        {},
    ),
    (
        "volumetric-penalty-factor-1e300",
        edit(VOLUMETRIC, {"solver.contact_law": {"kind": "penalty", "factor": 1e300}}),
        "solver.contact_law.factor",
        {},
    ),
    (
        "volumetric-ipc-friction-1e300",
        edit(VOLUMETRIC, {"solver.contact_law": {"kind": "ipc", "friction": 1e300}}),
        "solver.contact_law.friction",
        {},
    ),
    # ---- [solver] reduced: parameters inside the model's own bounds, params files
    ("reduced-a-negative", edit(REDUCED, {"solver.params.a": -1}), "solver.params.a", {}),
    ("reduced-b-1e300", edit(REDUCED, {"solver.params.b": 1e300}), "solver.params.b", {}),
    ("reduced-theta-past-90", edit(REDUCED, {"solver.params.theta_deg": 120}), "solver.params.theta_deg", {}),
    ("reduced-a-nan", edit(REDUCED, {"solver.params.a": float("nan")}), "solver.params.a", {}),
    (
        "reduced-parameter-missing",
        edit(REDUCED, {"solver.params.theta_deg": DROP}),
        "solver.params.theta_deg",
        {},
    ),
    ("reduced-parameter-unknown", edit(REDUCED, {"solver.params.c": 1.0}), "solver.params.c", {}),
    ("reduced-model-unknown", edit(REDUCED, {"solver.model": "ogden"}), "solver.model", {}),
    (
        "reduced-hgo2m-mu1-too-large",
        edit(
            REDUCED,
            {
                "solver.model": "hgo2m",
                "solver.params": {
                    "mu1": 1e3,
                    "mu2": 0.02,
                    "K": 0.02,
                    "a1": 0.05,
                    "b1": 1.0,
                    "a2": 0.05,
                    "b2": 1.0,
                },
            },
        ),
        "solver.params.mu1",
        {},
    ),
    (
        "reduced-params-file-missing",
        edit(REDUCED, {"solver.params_file": "nope.json"}),
        "solver.params_file",
        {},
    ),
    (
        "reduced-params-file-a-negative",
        edit(REDUCED, {"solver.params_file": "params.json"}),
        "solver.params_file.a",
        {"params.json": json.dumps({"model": "hgo", "a": -1, "b": 1, "theta_deg": 45})},
    ),
    (
        "reduced-params-file-not-json",
        edit(REDUCED, {"solver.params_file": "params.json"}),
        "solver.params_file",
        {"params.json": "a = 1\n"},
    ),
    (
        "reduced-params-file-a-list",
        edit(REDUCED, {"solver.params_file": "params.json"}),
        "solver.params_file",
        {"params.json": "[1, 2, 3]"},
    ),
    (
        "reduced-params-file-nested-deep",
        edit(REDUCED, {"solver.params_file": "params.json"}),
        "solver.params_file",
        {"params.json": "[" * 100000 + "]" * 100000},
    ),
    (
        "reduced-params-file-model-unknown",
        edit(REDUCED, {"solver.params_file": "params.json"}),
        "solver.params_file.model",
        {"params.json": json.dumps({"model": "ogden", "a": 1})},
    ),
    (
        "reduced-with-contact",
        edit(REDUCED, {"scene.effects": ["large_deformation", "contact"]}),
        "scene.effects",
        {},
    ),
    # ---- [scene]: a finite, physical load path and known effects
    ("load-stretch-inf", edit(ROD, general(lambda1=[1.0, float("inf")])), "scene.load.lambda1[1]", {}),
    ("load-stretch-nan", edit(ROD, general(lambda2=[float("nan"), 1.0])), "scene.load.lambda2[0]", {}),
    ("load-stretch-1e300", edit(ROD, general(lambda1=[1.0, 1e300])), "scene.load.lambda1[1]", {}),
    ("load-stretch-zero", edit(ROD, general(lambda1=[1.0, 0.0])), "scene.load.lambda1[1]", {}),
    ("load-stretch-1e-300", edit(REDUCED, general(lambda2=[1.0, 1e-300])), "scene.load.lambda2[1]", {}),
    ("load-stretch-lengths-differ", edit(ROD, general(lambda1=[1.0, 1.1, 1.2])), "scene.load.lambda1", {}),
    ("load-max-strain-1e300", edit(ROD, {"scene.load": {"max_strain": 1e300}}), "scene.load.max_strain", {}),
    (
        "load-max-strain-negative",
        edit(ROD, {"scene.load": {"max_strain": -0.1}}),
        "scene.load.max_strain",
        {},
    ),
    ("load-steps-1e9", edit(ROD, {"scene.load": {"steps": 10**9}}), "scene.load.steps", {}),
    ("load-steps-inf", edit(ROD, {"scene.load": {"steps": float("inf")}}), "scene.load.steps", {}),
    ("load-kind-unknown", edit(ROD, {"scene.load": {"kind": "triaxial"}}), "scene.load.kind", {}),
    (
        "load-direction-unknown",
        edit(ROD, {"scene.load": {"kind": "uniaxial", "direction": "bias"}}),
        "scene.load.direction",
        {},
    ),
    ("effect-unknown", edit(ROD, {"scene.effects": ["magic"]}), "scene.effects", {}),
    ("effect-friction-without-contact", edit(ROD, {"scene.effects": ["friction"]}), "scene.effects", {}),
    ("effect-unsupported-by-rod", edit(ROD, {"scene.effects": ["anisotropy"]}), "scene.effects", {}),
    ("output-unknown", edit(ROD, {"scene.outputs": ["movie"]}), "scene.outputs", {}),
    # ---- [data] and [[fit]]
    ("data-file-missing", {"data": {"files": ["missing.csv"]}}, "data.files[0]", {}),
    ("data-files-empty", {"data": {"files": []}}, "data.files", {}),
    ("data-reader-unknown", edit(MEASURED, {"data.reader": "nope"}), "data.reader", {}),
    (
        "data-reader-points-1",
        edit(MEASURED, {"data.reader": {"kind": "singal2024", "points": 1}}),
        "data.reader.points",
        {},
    ),
    ("fit-model-unknown", edit(FIT, {"fit.model": "ogden"}), "fit.model", {}),
    ("fit-fitter-unknown", edit(FIT, {"fit.fitter": "adam"}), "fit.fitter", {}),
    ("fit-names-repeated", {**MEASURED, "fit": [{"name": "a"}, {"name": "a"}]}, "fit[1].name", {}),
    # ---- the TOML file itself
    ("toml-arrays-1000-deep", "a = " + "[" * 1000 + "]" * 1000 + "\n", "nested too deeply", {}),
    (
        "toml-inline-tables-1000-deep",
        "a = " + "{b = " * 1000 + "1" + "}" * 1000 + "\n",
        "nested too deeply",
        {},
    ),
    ("toml-integer-5000-digits", "[scene]\nload = { steps = " + "9" * 5000 + " }\n", "malformed TOML", {}),
    ("toml-syntax", "[solver\nkind = 1\n", "malformed TOML", {}),
    ("toml-unknown-table", edit(ROD, {"colour": {"x": 1}}), "colour", {}),
    ("toml-pipeline-name-a-number", edit(ROD, {"pipeline.name": 5}), "pipeline.name", {}),
]


def write_case(folder: Path, config: Any, extra: dict[str, str]) -> None:
    """The case's config as ``cfg.toml`` and its extra files, in ``folder``."""
    text = config if isinstance(config, str) else tomli_w.dumps(config)
    (folder / "cfg.toml").write_text(text, encoding="utf-8")
    for name, body in extra.items():
        (folder / name).write_text(body, encoding="utf-8")


@pytest.mark.parametrize("case, config, field, extra", CASES, ids=[c[0] for c in CASES])
def test_hostile_config_is_refused_before_any_work(tmp_path, knit_here, case, config, field, extra):
    """A bad config value exits 2 with one line naming its TOML path, and creates nothing at all."""
    write_case(tmp_path, config, extra)
    before = snapshot(tmp_path)
    proc = knit_here("run", "cfg.toml", "--out", tmp_path / "out", cwd=tmp_path)
    assert_refused(proc, field, before=before, folder=tmp_path)
    line = proc.stderr.strip()
    assert "solver.solver" not in line and "scene.scene" not in line, line
    assert len(line) < 600, line  # a pasted array or a long value is cut, not echoed whole


def test_the_cases_are_distinct_and_many():
    """The suite holds at least 70 distinct hostile configs, each with its own name."""
    names = [c[0] for c in CASES]
    assert len(set(names)) == len(names) >= 70
    texts = [
        c[1] if isinstance(c[1], str) else json.dumps(c[1], sort_keys=True, default=str) + json.dumps(c[3])
        for c in CASES
    ]
    assert len(set(texts)) == len(texts)


@pytest.mark.parametrize(
    "case",
    [
        "stitch-length-not-in-table-volumetric",
        "toml-arrays-1000-deep",
        "load-stretch-1e300",
        "reduced-params-file-missing",
    ],
)
def test_hostile_config_in_a_real_process(tmp_path, knit, case):
    """In a real process too the refusal is one line and exit 2, with no traceback and no files."""
    _, config, field, extra = next(c for c in CASES if c[0] == case)
    write_case(tmp_path, config, extra)
    before = snapshot(tmp_path)
    proc = knit("run", "cfg.toml", "--out", "out", cwd=tmp_path)
    assert_refused(proc, field, before=before, folder=tmp_path)


def test_valid_configs_of_the_suite_pass_validation(tmp_path):
    """The base configs the cases start from are valid, so each refusal is caused by its one change."""
    from knitframe.pipeline import Pipeline

    for base in (
        ROD,
        VOLUMETRIC,
        REDUCED,
        MEASURED,
        FIT,
        edit(ROD, general()),
        edit(ROD, {"yarns.wool": WOOL, "fabric.yarn": "wool"}),
    ):
        Pipeline(base, base_dir=tmp_path)
