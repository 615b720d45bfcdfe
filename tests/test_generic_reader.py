"""The generic CSV reader: documented columns, units, repeats and one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from knitframe.errors import DataError
from knitframe.plugins import get_registry


def reader(**kw):
    return get_registry()["reader"]["generic"](**kw)


def write(tmp_path, text, name="test.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_repeats_become_mean_and_sd(tmp_path):
    """Two samples on the same strains give their mean tension and sample sd, with n_samples = 2."""
    p = write(
        tmp_path,
        "# direction = course\nsample,strain,transverse_strain,tension_N_per_mm\n"
        "1,0.0,0.0,0.0\n1,0.1,-0.02,0.10\n1,0.2,-0.05,0.30\n"
        "2,0.0,0.0,0.0\n2,0.1,-0.04,0.14\n2,0.2,-0.07,0.34\n",
    )
    (r,) = reader(points=3).read(p)
    assert r.load == "uniaxial-course" and r.n_samples == 2
    np.testing.assert_allclose(r.lambda1, [1.0, 1.1, 1.2])
    np.testing.assert_allclose(r.T1, [0.0, 0.12, 0.32])
    np.testing.assert_allclose(r.T1_sd, [0.0, np.std([0.10, 0.14], ddof=1), np.std([0.30, 0.34], ddof=1)])
    np.testing.assert_allclose(r.lambda2, [1.0, 0.97, 0.94])
    assert np.all(r.T2 == 0)


def test_stretch_and_stress_with_thickness(tmp_path):
    """Stretch and MPa columns are converted: tension = stress × thickness (from the # line)."""
    p = write(
        tmp_path, "# direction: wale\n# thickness_mm = 0.5\nstretch,stress_MPa\n1.0,0.0\n1.1,0.2\n1.3,0.8\n"
    )
    (r,) = reader().read(p)
    assert r.load == "uniaxial-wale"
    np.testing.assert_allclose(r.lambda2, [1.0, 1.1, 1.3])
    np.testing.assert_allclose(r.T2, [0.0, 0.1, 0.4])
    assert np.all(r.lambda1 == 1.0) and r.provenance.extra["transverse_measured"] is False


def test_direction_column_gives_one_response_per_direction(tmp_path):
    """A direction column splits the file into a course and a wale Response."""
    p = write(
        tmp_path,
        "direction,strain,tension_N_per_mm\ncourse,0.0,0.0\ncourse,0.2,0.1\nwale,0.0,0.0\nwale,0.1,0.2\n",
    )
    rs = reader().read(p)
    assert [r.load for r in rs] == ["uniaxial-course", "uniaxial-wale"]
    assert rs[1].T2[-1] == pytest.approx(0.2)


def test_single_data_point(tmp_path):
    """A file with one measured point gives a one-point Response."""
    (r,) = reader(direction="course").read(write(tmp_path, "strain,tension_N_per_mm\n0.1,0.05\n"))
    assert len(r) == 1 and r.T1[0] == 0.05


@pytest.mark.parametrize(
    "text, match, line, column",
    [
        (
            "# direction = course\nstrain,tension_N_per_mm\n0.0,0.0\n0.1,nan\n",
            "finite number",
            4,
            "tension_n_per_mm",
        ),
        (
            "# direction = course\nstrain,tension_N_per_mm\n0.0,0.0\n-1.5,0.1\n",
            "non-positive stretch",
            4,
            "strain",
        ),
        (
            "# direction = course\nstretch,tension_N_per_mm\n1.0,0.0\n0,0.1\n",
            "non-positive stretch",
            4,
            "stretch",
        ),
        (
            "direction,strain,tension_N_per_mm\ncourse,0.0,0.0\nbias,0.1,0.1\n",
            "course or wale",
            3,
            "direction",
        ),
        (
            "# direction = course\nstrain,tension_N_per_mm\n0.0,0.0\n0.1,abc\n",
            "expected a number",
            4,
            "tension_n_per_mm",
        ),
    ],
)
def test_bad_cells_name_file_line_and_column(tmp_path, text, match, line, column):
    """NaN, non-positive stretch, a bad direction and a non-number are one-line errors at their cell."""
    p = write(tmp_path, text, "bad.csv")
    with pytest.raises(DataError, match=match) as e:
        reader().read(p)
    msg = str(e.value)
    assert "bad.csv" in msg and f"line {line}" in msg and f"column '{column}'" in msg and "\n" not in msg


@pytest.mark.parametrize(
    "text, match",
    [
        ("", "empty file"),
        ("# direction = course\n", "empty file"),
        ("# direction = course\nstrain,tension_N_per_mm\n", "no data rows"),
        ("# direction = course\nstrain,load\n0,0\n", "missing column for the load"),
        ("# direction = course\nstrain,force_N\n0,0\n", "force_N needs the specimen width"),
        ("# direction = course\nstrain,stretch,tension_N_per_mm\n0,1,0\n", "only one of"),
        ("# direction = course\nstrain,stress_MPa\n0,0\n", "needs a thickness"),
        ("strain,tension_N_per_mm\n0,0\n", "cannot tell the direction"),
    ],
)
def test_file_level_errors(tmp_path, text, match):
    """Empty files, missing or doubled columns, a stress without thickness and no direction are one-line
    errors."""
    p = write(tmp_path, text, "f.csv")
    with pytest.raises(DataError, match=match) as e:
        reader().read(p)
    assert "f.csv" in str(e.value) and "\n" not in str(e.value)


def test_missing_file(tmp_path):
    """A missing file is a DataError naming it."""
    with pytest.raises(DataError, match="not found"):
        reader().read(tmp_path / "nope.csv")
