"""Several loads in one scene, and the simulated curves drawn over the measured ones with their ratio."""

from __future__ import annotations

import csv

import numpy as np
import pytest

import knitframe
from knitframe.errors import ConfigError
from knitframe.report import compare, curve

DATA = ["cotton-stockinette-x.csv", "cotton-stockinette-y.csv"]


def config(singal_file, loads):
    return {
        "data": {"files": [str(singal_file(f)) for f in DATA]},
        "solver": {"kind": "rod", "segments_per_stitch": 10},
        "fabric": {"pattern": "jersey", "arc_length": 11.28, "yarn": "pearl-cotton"},
        "scene": {"effects": ["large_deformation", "bending", "contact", "prestress"], "load": loads},
    }


def test_two_loads_are_simulated_and_compared_with_the_measured_curves(tmp_path, singal_file):
    """A course and a wale load give two simulated curves, both in simulated.csv, with sim/measured ratios."""
    loads = [{"kind": "uniaxial", "direction": d, "max_strain": 0.3, "steps": 3} for d in ("course", "wale")]
    res = knitframe.run(config(singal_file, loads), tmp_path / "out")
    sims = [r for r in res.responses if r.provenance.kind == "simulation"]
    assert [r.load for r in sims] == ["uniaxial-course", "uniaxial-wale"]
    with open(tmp_path / "out" / "simulated.csv", newline="") as fh:
        assert {row["load"] for row in csv.DictReader(fh)} == {"uniaxial-course", "uniaxial-wale"}
    ratios = res.results["simulate"]["simulated_over_measured"]
    measured = {r.load: r for r in res.responses if r.provenance.kind == "experiment"}
    for sim in sims:
        ((_, e, T, _),) = curve(sim)
        ((_, em, Tm, _),) = curve(measured[sim.load])
        for key, value in ratios[sim.load].items():
            strain = float(key.split()[0]) / 100
            # the simulated path starts from the relaxed cell: zero tension at zero strain
            es, Ts = np.concatenate([[0.0], np.sort(e)]), np.concatenate([[0.0], T[np.argsort(e)]])
            expected = np.interp(strain, es, Ts) / np.interp(strain, np.sort(em), Tm[np.argsort(em)])
            assert value == pytest.approx(expected, rel=1e-12)
    assert set(ratios["uniaxial-course"]) == {
        "10 %",
        "20 %",
        "30 %",
    }  # both curves reach 30 % along the course
    assert "simulated/measured tension" in res.results["simulate"]["headline"]
    assert (tmp_path / "out" / "simulated.png").read_bytes()[:4] == b"\x89PNG"
    # what the solver read from the yarn record, each value with its status
    yarn_csv = (tmp_path / "out" / "yarn.csv").read_text(encoding="utf-8")
    assert yarn_csv.startswith("# yarn: pearl-cotton")
    assert ",EI,0.0708,N·mm²,measured,bending_stiffness," in yarn_csv and ",J_min," in yarn_csv


def test_compare_uses_only_strains_inside_both_curves(singal_file):
    """No ratio is reported at a strain one of the two curves does not reach."""
    reader = knitframe.get_registry()["reader"]["singal2024"]()
    (wale,) = reader.read(singal_file("cotton-stockinette-y.csv"))
    ((_, e, _, _),) = curve(wale)
    ratios = compare([wale], [wale])
    assert ratios["uniaxial-wale"] == {
        f"{100 * s:.0f} %": pytest.approx(1.0) for s in (0.1, 0.2, 0.3) if s <= e.max()
    }


@pytest.mark.parametrize(
    "loads, path",
    [
        ([], "scene.load"),
        (
            [{"kind": "uniaxial", "direction": "course"}, {"kind": "uniaxial", "direction": "course"}],
            "scene.load",
        ),
        (
            [{"kind": "uniaxial", "direction": "course"}, {"kind": "uniaxial", "direction": "sideways"}],
            "scene.load[1].direction",
        ),
    ],
)
def test_bad_load_arrays_name_their_path(singal_file, loads, path):
    """An empty load array, a repeated load, or a bad load names its place in the array."""
    with pytest.raises(ConfigError) as err:
        knitframe.run(config(singal_file, loads))
    assert err.value.path == path
