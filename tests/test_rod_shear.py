"""The rod's ``shear`` modes on real cells: a shear-deformable (resolved) rod against the effective stiffness.

The element-level references (finite differences, the Timoshenko beam) are in ``test_rod.py``.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from knitframe import get_registry
from knitframe.config import instantiate
from knitframe.errors import ConfigError, KnitframeWarning
from knitframe.records import Fabric, LoadPath, Scene

EFFECTS = ("large_deformation", "bending", "contact", "prestress")
STEP = LoadPath(kind="equibiaxial", max_strain=0.05, steps=1)


#: past the stiff PET cell's multistable range: between 3 and 12 % its tensions depend on which of several
#: near-equal equilibria round-off picks (one ulp on the Hessian moves T1 at 6 % between 0.19 and 0.37 N/mm,
#: docs/notes/2026-11-28-solver-rebuilds.md); at 30 % every branch gives the same tensions to 0.5 %
PAST_BRANCHES = LoadPath(kind="equibiaxial", max_strain=0.3, steps=3)


def run(yarn: str, sl: float, load: LoadPath = STEP, **options):
    reg = get_registry()
    fabric = Fabric(pattern="jersey", yarn=reg["yarn"][yarn], stitch_length=sl)
    return reg["solver"]["rod"](starts=1, **options).simulate(fabric, Scene(load=load, effects=EFFECTS))


def test_a_yarn_stiff_in_shear_bends_alike_resolved_or_effective():
    """PET (shear length √(EI/κGA) = 0.08 mm, far below a stitch): its sections hardly shear, and the
    resolved rod's relaxed lattice and tensions are those of the effective stiffness within 5 %.

    They are not equal: the effective stiffness is taken at one wave number, 2π/(yarn per stitch), the
    resolved rod bends each wave at its own. Compared at 30 %, past the strains where this cell is
    multistable (:data:`PAST_BRANCHES`).
    """
    eff = run("pet", 11, PAST_BRANCHES)
    res = run("pet", 11, PAST_BRANCHES, shear="resolved")
    assert res.provenance.extra["shear_deformable"] and not eff.provenance.extra["shear_deformable"]
    assert res.provenance.extra["max_shear_angle_deg"] < 5.0
    assert "shear length" not in res.provenance.notes  # 0.08 mm: no warning
    # the loop bends at about twice the wavenumber the effective stiffness is taken at
    k_R, k_eff = (
        eff.provenance.extra[k] for k in ("bending_wavenumber_per_mm", "effective_bending_wavenumber_per_mm")
    )
    assert 1.5 < k_R / k_eff < 3.0
    assert np.allclose(
        res.provenance.extra["relaxed_stretch"], eff.provenance.extra["relaxed_stretch"], rtol=0.05
    )
    assert res.T1[-1] == pytest.approx(eff.T1[-1], rel=0.05) and res.T2[-1] == pytest.approx(
        eff.T2[-1], rel=0.05
    )
    assert abs(res.T1[-1] - eff.T1[-1]) > 1e-4 * eff.T1[-1]  # a different model, not the same numbers


def test_sections_sheared_beyond_the_small_angle_law_make_the_curve_suspect():
    """Cotton's record (shear length 19 mm, four stitches): the sections of a resolved rod hardly turn with
    the loop and shear far beyond 30°; the run says so, in a warning and in its notes."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = run("cotton", 12, shear="resolved", prestress_start="straight", prestress_steps=4)
    said = [str(w.message) for w in caught if issubclass(w.category, KnitframeWarning)]
    assert re.search(r"shear length 19(\.\d+)? mm is longer than its stitch \(5\.9 mm\)", said[0])  # first
    assert any(re.search(r"shear by up to \d+° .* the curve is suspect", m) for m in said)
    assert r.provenance.extra["max_shear_angle_deg"] > 30.0
    assert "the curve is suspect" in r.provenance.notes and "shear length" in r.provenance.notes
    assert np.all(np.isfinite(r.T1)) and np.all(np.isfinite(r.T2))


@pytest.mark.parametrize(("value", "mode"), [("resolved", "resolved"), (True, "effective"), (False, "none")])
def test_shear_modes_and_their_older_spelling(value, mode):
    assert instantiate(get_registry(), "solver", {"kind": "rod", "shear": value}, "solver").shear == mode


def test_an_unknown_shear_mode_names_the_key():
    with pytest.raises(ConfigError, match=r"solver\.shear: expected 'resolved' \| 'effective' \| 'none'"):
        instantiate(get_registry(), "solver", {"kind": "rod", "shear": "timoshenko"}, "solver")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # and the default stays the effective stiffness
        assert get_registry()["solver"]["rod"]().shear == "effective"


class Killed(Exception):
    pass


def resolved_pet_killed_in_step_2(checkpoints):
    """Resolved-rod jersey SL11 PET, equibiaxial to 6 % in 3 steps, killed in its second load step with its
    checkpoints in ``checkpoints``; returns the solver, fabric and scene to resume it with."""

    def die(done, total, message):
        if message.startswith("load step 2"):
            raise Killed

    reg = get_registry()
    fabric = Fabric(pattern="jersey", yarn=reg["yarn"]["pet"], stitch_length=11)
    scene = Scene(load=LoadPath(kind="equibiaxial", max_strain=0.06, steps=3), effects=EFFECTS)
    rod = reg["solver"]["rod"](starts=1, shear="resolved")
    with pytest.raises(Killed):
        rod.simulate(fabric, scene, progress=die, checkpoint_dir=checkpoints)
    return rod, fabric, scene


def test_a_resumed_run_judges_the_shear_of_its_whole_path(tmp_path):
    """The largest shear angle of every load step is checkpointed: a run killed in its second load step
    and resumed reports the angles of all three steps, as the run that was not interrupted does."""
    rod, fabric, scene = resolved_pet_killed_in_step_2(tmp_path)
    whole = rod.simulate(fabric, scene).provenance.extra
    resumed = rod.simulate(fabric, scene, checkpoint_dir=tmp_path).provenance.extra
    assert len(whole["max_shear_angle_by_step_deg"]) == 3
    assert resumed["max_shear_angle_by_step_deg"] == pytest.approx(
        whole["max_shear_angle_by_step_deg"], rel=1e-6
    )
    assert resumed["max_shear_angle_deg"] == max(resumed["max_shear_angle_by_step_deg"])


def test_a_checkpoint_written_before_a_state_key_existed_still_resumes(tmp_path):
    """A checkpoint without ``shear_deg`` (written before the key was declared) resumes: the key keeps its
    initial value instead of becoming None, and the resumed steps' shear angles are reported."""
    import json

    rod, fabric, scene = resolved_pet_killed_in_step_2(tmp_path)
    files = sorted(tmp_path.rglob("step-*.npz"))
    assert files
    for path in files:  # as an older version wrote them
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
        meta = json.loads(str(arrays.pop("__meta__")))
        assert meta.pop("shear_deg") is not None
        with open(path, "wb") as fh:
            np.savez(fh, **arrays, __meta__=np.array(json.dumps(meta)))
    resumed = rod.simulate(fabric, scene, checkpoint_dir=tmp_path)
    by_step = resumed.provenance.extra["max_shear_angle_by_step_deg"]
    assert resumed.provenance.converged and len(resumed) == 3
    assert by_step and resumed.provenance.extra["max_shear_angle_deg"] == max(by_step)
