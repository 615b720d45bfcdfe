"""The solvers' ``[solver.newton]`` tables: presets, overrides and one-line errors at the key's path."""

from __future__ import annotations

import tomllib

import attrs
import pytest
from knitframe_solvers.newton_settings import RodNewton, VolumetricNewton

from knitframe.config import instantiate
from knitframe.errors import ConfigError
from knitframe.numerics.settings import from_config, preset_names
from knitframe.plugins import get_registry


def solver(kind: str, text: str):
    """The solver of ``kind`` built from the TOML ``[solver]`` table ``text``, as a config builds it."""
    table = tomllib.loads(f'[solver]\nkind = "{kind}"\n{text}')["solver"]
    return instantiate(get_registry(), "solver", table, "solver")


@pytest.mark.parametrize("kind, cls", [("rod", RodNewton), ("volumetric", VolumetricNewton)])
def test_default_is_the_class_defaults_and_every_preset_is_documented_and_valid(kind, cls):
    assert solver(kind, "").newton == cls()
    assert solver(kind, 'newton = "default"').newton == cls()
    assert preset_names(cls) == ["default", "robust", "fast"]
    for name, preset in cls.presets.items():
        built = solver(kind, f'newton = "{name}"').newton
        assert built == attrs.evolve(cls(), **preset.values) != cls()
        assert len(preset.reason) > 40  # a reason in words, not a label


def test_the_moved_defaults_are_unchanged():
    """The values the solvers had as top-level options before they moved into the table."""
    rod, vol = RodNewton(), VolumetricNewton()
    assert (rod.max_step, rod.min_step_fraction, rod.stabilisation) == (0.2, 1 / 64, 1e-6)
    assert attrs.asdict(vol) == {
        "max_step": 0.25,
        "reach": 0.5,
        "contact_search": "iteration",
        "tangent": "projected",
        "start_projected": False,
        "eigenvalue_filter": "clamp",
        "flux_tolerance": 5e-3,
        "late_flux_tolerance": 2e-2,
        "correction_tolerance": 1e-2,
        "path_tolerance_factor": 10.0,
        "predictor": "affine",
        "chord": True,
        "chord_after_full_steps": True,
        "halve_reversals": True,
        "extrapolation": 1.0,
        "cap_shift": 0.0,
        "min_step_fraction": 1 / 64,
        "stall_iterations": 10,
        "stabilisation": 1e-4,
        "retain_freed_memory": True,
    }


def test_a_table_overrides_keys_of_a_preset_or_of_the_defaults():
    s = solver("volumetric", 'newton = { preset = "robust", max_step = 0.2 }').newton
    assert s == attrs.evolve(VolumetricNewton(), **VolumetricNewton.presets["robust"].values, max_step=0.2)
    s = solver("volumetric", "[solver.newton]\nmax_step = 0.2\ntangent = 'exact'")
    assert s.newton == VolumetricNewton(max_step=0.2, tangent="exact")
    assert s.order == 2  # the user's options stay in the solver's own table
    r = solver("rod", 'newton = { preset = "fast", min_step_fraction = 0.5 }').newton
    assert r == RodNewton(min_step_fraction=0.5)
    # from Python: a preset name, a table or an instance
    reg = get_registry()["solver"]
    assert reg["rod"](newton="robust").newton == RodNewton(**RodNewton.presets["robust"].values)
    assert reg["rod"](newton={"max_step": 0.1}).newton == RodNewton(max_step=0.1)
    assert reg["rod"](newton=RodNewton(max_step=0.1)).newton == RodNewton(max_step=0.1)


def test_the_newton_options_are_built_from_the_table():
    vol = get_registry()["solver"]["volumetric"](
        newton={"max_step": 0.2, "tangent": "adaptive", "chord": False}
    )
    from knitframe.records import Fabric

    fabric = Fabric(pattern="jersey", yarn=get_registry()["yarn"]["cotton"], stitch_length=11)
    opts, loose = vol.newton_options(fabric, 0.2, True)
    assert (opts.max_step, opts.projection, opts.chord, opts.flux_rtol) == (0.2, "adaptive", False, 5e-3)
    assert loose.flux_rtol == pytest.approx(10 * 5e-3)


@pytest.mark.parametrize(
    "kind, text, message",
    [
        (
            "volumetric",
            "newton = { max_stepp = 0.2 }",
            "solver.newton.max_stepp: unknown key; expected one of",
        ),
        ("volumetric", "newton = { max_step = -1 }", "solver.newton.max_step: must be > 0, got -1"),
        ("volumetric", "newton = { max_step = 'big' }", "solver.newton.max_step: expected a number"),
        ("volumetric", "newton = { tangent = 'magic' }", "solver.newton.tangent: must be one of"),
        ("volumetric", 'newton = "slow"', "solver.newton: unknown preset 'slow'; expected one of default"),
        ("volumetric", 'newton = { preset = "slow" }', "solver.newton.preset: unknown preset 'slow'"),
        ("volumetric", "newton = { preset = 3 }", "solver.newton.preset: unknown preset 3"),
        ("volumetric", "newton = 3", "solver.newton: expected string or table, got 3"),
        ("rod", "[solver.newton]\nmin_step_fraction = 0", "solver.newton.min_step_fraction: must be"),
        ("rod", "[solver.newton]\ntangent = 'exact'", "solver.newton.tangent: unknown key"),
        ("rod", "max_step = 0.2", "solver.max_step: unknown key"),
    ],
)
def test_unknown_keys_and_bad_values_fail_in_one_line_at_their_path(kind, text, message):
    with pytest.raises(ConfigError) as e:
        solver(kind, text)
    assert str(e.value).startswith(message) and "\n" not in str(e.value)


def test_the_held_contact_search_check_names_the_table_key():
    """The check of newton.max_step against the reach refuses in one line at solver.newton.max_step."""
    vol = solver("volumetric", "newton = { max_step = 0.3, reach = 0.5 }")

    class Law:
        holds_candidates = True  # a solid law that takes a search's candidates

        def evaluate(self, candidates=None):
            pass

    with pytest.raises(ConfigError, match=r"^solver\.newton\.max_step: 0\.3 is more than half"):
        vol.holds_candidates(Law())
    assert not solver(
        "volumetric", "newton = { max_step = 0.3, contact_search = 'evaluation' }"
    ).holds_candidates(Law())


def test_from_config_names_its_own_path():
    with pytest.raises(ConfigError, match=r"^newton\.max_step: must be > 0"):
        from_config(RodNewton, {"max_step": 0})
