"""Contact law ``rod_shell``: a yarn's soft shell on a core (Singal et al. 2024), from the yarn record."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from knitframe_contact.rod_shell import RodShell
from knitframe_linsolvers.direct import direct
from knitframe_solvers.rod_model import RodEnergy, from_cell
from test_rod import assert_matches_finite_differences, assert_parallel_line_load, crossing_rods, wavy_cell

from knitframe import ConfigError, Fabric, Scene, Yarn, get_registry
from knitframe.errors import FieldError
from knitframe.numerics.newton import NewtonOptions, minimise

SHELL = dict(shell_diameter=0.4, core_diameter=0.2, compression_k=50.0, compression_p=2.4)


def shell_yarn(**kw) -> Yarn:
    return Yarn(name="shell", d0=0.4, dk=0.4, E_axial=100.0, E_transverse=0.01, **{**SHELL, **kw})


def test_density_is_singals_law_with_its_derivatives():
    """φ = 2k(D − Dc)²/(p(p − 1))·[z^(1−p) − 1 + (1 − p)(1 − z)]: zero with zero slope where the shells touch,
    infinite at the core, and its derivatives are those of φ."""
    law = RodShell().for_yarn(shell_yarn())
    D, Dc, k, p = 0.4, 0.2, 2 * 50.0, 2.4
    d = np.linspace(0.201, 0.45, 400)
    e, e1, e2 = law.normal(d, D, k)
    z = (d - Dc) / (D - Dc)
    ref = np.where(z < 1, k * (D - Dc) ** 2 / (p * (p - 1)) * (z ** (1 - p) - 1 + (1 - p) * (1 - z)), 0.0)
    assert np.allclose(e, ref, rtol=1e-12, atol=0.0)
    h = 1e-7
    ep, e1p, _ = law.normal(d + h, D, k)
    em, e1m, _ = law.normal(d - h, D, k)
    inner = d < D - 2 * h
    assert np.allclose(e1[inner], ((ep - em) / (2 * h))[inner], rtol=1e-6)
    assert np.allclose(e2[inner], ((e1p - e1m) / (2 * h))[inner], rtol=1e-5)
    at = law.normal(np.array([D, 0.5, Dc, 0.1]), D, k)
    assert at[0][0] == at[1][0] == 0.0 and at[0][1] == at[1][1] == 0.0  # touching, apart
    assert np.isinf(at[0][2]) and np.isinf(at[0][3])  # at and inside the core
    assert np.all(e1[d < D] < 0) and np.all(np.diff(e[d < D]) < 0)  # repulsive, monotone


def test_parallel_yarns_carry_the_line_load_of_the_shell_law():
    """Two straight periodic yarns a distance d apart push each other with −ψ′(d), ψ = ∫ φ(√(d² + τ²)) dτ."""
    law = RodShell().for_yarn(shell_yarn())
    assert_parallel_line_load(
        law, gap=0.3, dk=0.4, k=law.rigidity(shell_yarn()), k_core=None, segments=20, quadrature=6
    )


def test_crossing_rods_pressed_together_follow_the_shell_law():
    """A simply supported rod pressed onto a crossing one: the reaction is 2π d φ(d) (perpendicular lines).

    The rod is stiff enough to stay straight over the contact patch, as the formula assumes."""
    law = RodShell().for_yarn(shell_yarn())
    D, k, EIb, span, z0, drop = 0.4, 100.0, 50.0, 4.0, 0.41, 0.045
    model = crossing_rods(n=60, span=span, z0=z0)
    en = RodEnergy(model, 1e4, EIb, law=law, dk=D, k_contact=k, quadrature=6)
    n = model.n_nodes // 2
    q = np.zeros(model.n_dof)
    ends = [n, 2 * n - 1]
    q[[3 * e + 2 for e in ends]] = -drop
    free = np.ones(model.n_dof, bool)
    free[: 3 * n] = False
    for e in ends:
        free[3 * e : 3 * e + 3] = False
    free[3 * ends[1] + 1] = True
    free[3 * model.n_nodes :] = False
    res = minimise(en, q, free, solve=direct(), options=NewtonOptions(atol=1e-10, rtol=0.0, xtol=1e-13))
    F = -sum(res.gradient[3 * e + 2] for e in ends)
    d = en.pairs(res.x).distance.min()
    assert 0.2 < d < D
    phi = law.normal(np.array([d]), D, k)[0][0]
    assert F > 1e-3 and F == pytest.approx(2 * np.pi * d * phi, rel=5e-3)
    assert (z0 - d) + F * span**3 / (48 * EIb) == pytest.approx(drop, rel=2e-3)


def test_shell_contact_derivatives_match_finite_differences():
    cell = wavy_cell()
    model = from_cell(cell, 8)
    law = RodShell().for_yarn(shell_yarn(shell_diameter=0.62, core_diameter=0.3))
    en = RodEnergy(model, 50.0, 0.05, law=law, dk=0.62, k_contact=40.0)
    rng = np.random.default_rng(3)
    q = np.zeros(model.n_dof)
    q[: 3 * model.n_nodes] = 0.01 * rng.standard_normal(3 * model.n_nodes)
    E, g, H, info = en(q, 2)
    assert info["active_contacts"] > 0 and np.isfinite(E)
    assert_matches_finite_differences(en, q, g, H)


def test_the_compression_law_is_all_four_numbers_or_none():
    with pytest.raises(FieldError) as e:
        shell_yarn(compression_p=None)
    assert e.value.field == "compression_p"
    with pytest.raises(FieldError) as e:
        shell_yarn(core_diameter=0.5)
    assert e.value.field == "core_diameter" and "< shell_diameter" in str(e.value)
    assert get_registry()["yarn"]["acrylic"].has_compression_law
    assert not get_registry()["yarn"]["cotton"].has_compression_law


def test_a_yarn_without_the_law_is_refused_before_any_work(tmp_path):
    reg = get_registry()
    rod = reg["solver"]["rod"](contact_law="rod_shell")
    fabric = Fabric(pattern="jersey", stitch_length=11, yarn=reg["yarn"]["cotton"])
    scene = Scene(effects=frozenset({"contact", "bending", "large_deformation", "prestress"}))
    with pytest.raises(ConfigError) as e:
        rod.validate(fabric, scene, reg)
    assert e.value.path == "solver.contact_law" and "cotton" in str(e.value)
    acrylic = Fabric(pattern="jersey", arc_length=11.28, yarn=reg["yarn"]["acrylic"])
    with pytest.raises(ConfigError) as e:  # the law's stiffness is the record's k: no override
        reg["solver"]["rod"](contact_stiffness=0.01).validate(acrylic, scene, reg)
    assert e.value.path == "solver.contact_stiffness" and "compression_k" in str(e.value)
    reg["solver"]["rod"](contact_law="rod_penalty", contact_stiffness=0.004).validate(acrylic, scene, reg)
    cfg = tmp_path / "cell.toml"
    cfg.write_text(
        '[fabric]\npattern = "jersey"\nstitch_length = 11\nyarn = "cotton"\n'
        '[solver]\nkind = "rod"\ncontact_law = "rod_shell"\n'
        '[scene]\neffects = ["large_deformation", "bending", "contact", "prestress"]\n'
    )
    out = tmp_path / "out"
    r = subprocess.run(
        [sys.executable, "-m", "knitframe", "run", str(cfg), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "solver.contact_law" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not out.exists()


def test_acrylic_with_its_shell_law_stretches_along_the_course():
    """The rod reads the law from the acrylic record: its contact distance is the 1.48 mm shell."""
    reg = get_registry()
    fabric = Fabric(pattern="jersey", arc_length=11.28, yarn=reg["yarn"]["acrylic"])
    scene = Scene.from_dict(
        {
            "effects": ["large_deformation", "bending", "contact", "self_contact", "prestress"],
            "load": {"kind": "uniaxial", "direction": "course", "max_strain": 0.1, "steps": 2},
        },
        "scene",
    )
    r = reg["solver"]["rod"](contact_law="rod_shell", starts=1).simulate(fabric, scene)
    ex = r.provenance.extra
    assert ex["contact_distance_mm"] == pytest.approx(1.48) and ex["dk_mm"] == pytest.approx(0.95)
    assert r.provenance.converged and np.all(np.isfinite(r.T1)) and np.all(np.diff(r.T1) > 0) and r.T1[0] > 0
    assert np.allclose(r.T2, 0.0, atol=1e-9 * r.T1.max())
