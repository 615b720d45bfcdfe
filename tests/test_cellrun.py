"""The unit-cell run skeleton (knitframe.numerics.cellrun) through the spring-chain test solver."""

from __future__ import annotations

import re

import numpy as np
import pytest

from knitframe import get_registry
from knitframe.errors import NumericalError
from knitframe.records import Fabric, LoadPath, Scene
from knitframe.testing.springcell import SpringCell

STEPS = 6
UNIAXIAL = LoadPath(kind="uniaxial", direction="course", max_strain=0.3, steps=STEPS)
EQUIBIAXIAL = LoadPath(kind="equibiaxial", max_strain=0.2, steps=STEPS)


class Killed(BaseException):
    """Stands for the process dying."""


def fabric() -> Fabric:
    return Fabric(pattern="jersey", yarn=get_registry()["yarn"]["cotton"], stitch_length=11)


def scene(load: LoadPath = UNIAXIAL, outputs=("vtu",)) -> Scene:
    return Scene(load=load, effects={"prestress"}, outputs=set(outputs))


def closed_form(cell: SpringCell, load: LoadPath) -> np.ndarray:
    """(λ1, λ2, T1, T2) per load step from the closed form; a free wale side has λ2 = ρ and T2 = 0."""
    _, lam1, lam2 = load.stretches()
    out = []
    for k in range(len(lam1)):
        l2 = None if lam2 is None else float(lam2[k])
        T1, T2 = cell.tensions(float(lam1[k]), l2)
        out.append((lam1[k], cell.rest if l2 is None else l2, T1, T2))
    return np.array(out)


def rows(resp) -> np.ndarray:
    return np.column_stack([resp.lambda1, resp.lambda2, resp.T1, resp.T2])


@pytest.mark.parametrize("load", [UNIAXIAL, EQUIBIAXIAL], ids=["uniaxial", "equibiaxial"])
def test_prestress_and_load_reach_the_closed_form(load):
    cell = SpringCell()
    seen = []
    resp = cell.simulate(fabric(), scene(load, outputs=()), progress=lambda *a: seen.append(a))
    assert resp.provenance.converged and resp.provenance.solver == "springcell"
    assert np.allclose(rows(resp), closed_form(cell, load), rtol=1e-9, atol=1e-12)
    total = cell.prestress_steps + STEPS
    assert [s[0] for s in seen] == list(range(1, total + 1)) and {s[1] for s in seen} == {total}
    assert seen[0][2] == f"pre-stress 1/{cell.prestress_steps}"
    assert seen[-1][2] == f"load step {STEPS}/{STEPS}"


@pytest.mark.parametrize("kill_at", [2, 7], ids=["during-prestress", "during-load"])
def test_a_killed_run_resumes_from_its_checkpoint_with_its_files(tmp_path, kill_at):
    cell = SpringCell()
    total = cell.prestress_steps + STEPS
    reference = cell.simulate(fabric(), scene(outputs=()))

    def die(done, _total, _message):
        if done == kill_at:
            raise Killed

    out, ckpt = tmp_path / "vtu", tmp_path / "ckpt"
    with pytest.raises(Killed):
        cell.simulate(fabric(), scene(), progress=die, output_dir=out, checkpoint_dir=ckpt)
    assert len(list(ckpt.glob("step-*.npz"))) == kill_at
    seen = []
    resumed = cell.simulate(
        fabric(), scene(), progress=lambda *a: seen.append(a[0]), output_dir=out, checkpoint_dir=ckpt
    )
    assert seen == list(range(kill_at + 1, total + 1))  # only the steps after the checkpoint are solved
    assert resumed.provenance.converged
    assert np.allclose(rows(resumed), rows(reference), rtol=1e-12, atol=1e-14)
    assert np.allclose(rows(resumed), closed_form(cell, UNIAXIAL), rtol=1e-9, atol=1e-12)
    files = sorted(p.name for p in out.glob("spring-*.vtu"))
    assert files == [f"spring-{k:04d}.vtu" for k in range(total)]
    listed = re.findall(r'file="([^"]+)"', (out / "spring.pvd").read_text())
    assert listed == files


def test_a_failed_load_path_is_truncated_or_raised():
    broken = SpringCell(breaks_at=1.16, on_failure="truncate")
    resp = broken.simulate(fabric(), scene(outputs=()))
    kept = closed_form(broken, UNIAXIAL)
    kept = kept[kept[:, 0] <= 1.16]
    assert not resp.provenance.converged and len(resp.T1) == len(kept) == 3
    assert np.allclose(rows(resp), kept, rtol=1e-9, atol=1e-12)
    assert f"stopped after 3 of {STEPS} load steps" in resp.provenance.notes
    with pytest.raises(NumericalError, match=r"^springcell solver \(jersey, cotton\): .*the chain broke"):
        SpringCell(breaks_at=1.16).simulate(fabric(), scene(outputs=()))
    with pytest.raises(NumericalError, match="springcell solver"):  # nothing converged: nothing to keep
        SpringCell(breaks_at=1.01, on_failure="truncate").simulate(fabric(), scene(outputs=()))
