"""Records: validation, units and the dict/TOML round trip."""

from __future__ import annotations

import numpy as np
import pytest

from knitframe import ConfigError, Fabric, LoadPath, Provenance, Response, Scene, Yarn
from knitframe.errors import FieldError

COTTON = Yarn("cotton", d0=0.445, dk=0.444, E_axial=1200.0, E_transverse=0.12, source="test")


def _response() -> Response:
    lam = np.linspace(1.0, 1.3, 7)
    return Response(
        lam,
        1 - 0.3 * (lam - 1),
        0.1 * (lam - 1),
        np.zeros(7),
        load="uniaxial-course",
        label="r",
        n_samples=3,
        T1_sd=np.full(7, 0.01),
        lambda2_sd=np.full(7, 0.002),
        provenance=Provenance(kind="simulation", solver="rod", wall_time=1.5, extra={"a": 1}),
    )


@pytest.mark.parametrize(
    "record",
    [
        COTTON,
        Fabric("jersey", COTTON, stitch_length=11.0),
        Scene(
            LoadPath("uniaxial", max_strain=0.5, steps=5, direction="wale"), effects={"contact", "friction"}
        ),
        Scene(LoadPath("general", lambda1=(1.0, 1.1), lambda2=(1.0, 0.95))),
        _response(),
    ],
)
def test_round_trip_dict_and_toml(record):
    """Every record comes back equal from to_dict/from_dict and from to_toml/from_toml."""
    cls = type(record)
    assert cls.from_dict(record.to_dict()) == record
    assert cls.from_toml(record.to_toml()) == record


def test_records_are_frozen():
    """Records cannot be mutated after construction."""
    with pytest.raises(AttributeError):
        COTTON.dk = 0.3  # type: ignore[misc]


def test_response_arrays_are_float64_and_read_only():
    """Response arrays are float64 copies that cannot be written."""
    r = _response()
    assert r.T1.dtype == np.float64
    with pytest.raises(ValueError):
        r.T1[0] = 1.0


@pytest.mark.parametrize(
    "bad, field",
    [
        (dict(T1=[0.0, np.nan]), "T1"),
        (dict(lambda1=[1.0, -0.1]), "lambda1"),
        (dict(T2=[0.0]), "T2"),
    ],
)
def test_response_rejects_nan_negative_stretch_and_ragged(bad, field):
    """NaN, non-positive stretch and arrays of unequal length are refused, naming the field."""
    kw = dict(lambda1=[1.0, 1.1], lambda2=[1.0, 1.0], T1=[0.0, 0.1], T2=[0.0, 0.0])
    kw.update(bad)
    with pytest.raises(FieldError) as e:
        Response(**kw)
    assert e.value.field == field


def test_yarn_knitted_diameter_cannot_exceed_free_diameter():
    """dk > d0 is refused with a message naming dk."""
    with pytest.raises(FieldError, match="dk"):
        Yarn("x", d0=0.3, dk=0.4, E_axial=1.0, E_transverse=1.0)


def test_from_dict_names_the_path_of_a_bad_field():
    """Validation errors from nested records carry the dotted path of the field."""
    data = Fabric("jersey", COTTON, stitch_length=11.0).to_dict()
    data["yarn"]["dk"] = -1
    with pytest.raises(ConfigError) as e:
        Fabric.from_dict(data, "fabric")
    assert str(e.value) == "fabric.yarn.dk: must be > 0, got -1"


def test_fabric_needs_a_stitch_length():
    """A fabric without stitch length or arc length is refused."""
    with pytest.raises(FieldError, match="stitch_length"):
        Fabric("jersey", COTTON)


def test_load_path_stretches():
    """Equibiaxial paths stretch both directions; uniaxial leaves the free side as None."""
    t, l1, l2 = LoadPath("equibiaxial", max_strain=0.3, steps=3).stretches()
    assert np.allclose(l1, [1.1, 1.2, 1.3]) and np.allclose(l2, l1)
    _, l1, l2 = LoadPath("uniaxial", max_strain=0.2, steps=2, direction="wale").stretches()
    assert l1 is None and np.allclose(l2, [1.1, 1.2])


def test_scene_effects_are_validated():
    """Unknown effects and friction without contact are refused."""
    with pytest.raises(FieldError, match="warp"):
        Scene(effects={"warp"})
    with pytest.raises(FieldError, match="friction"):
        Scene(effects={"friction"})
