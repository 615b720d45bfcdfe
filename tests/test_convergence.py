"""Richardson extrapolation and the observed order (knitframe.ladder.convergence)."""

import math

import numpy as np
import pytest

from knitframe.ladder.convergence import convergence_table, mesh_convergence, richardson
from knitframe.records import Response


@pytest.mark.parametrize("p", [0.7, 1.0, 2.0, 3.5])
@pytest.mark.parametrize("h", [(1.0, 0.5, 0.25), (1 / 1.5, 1 / 2.25, 1 / 3.0), (0.9, 0.4, 0.3)])
def test_exact_power_law_recovers_order_and_limit(p, h):
    f0, C = 0.2, 3.0
    f = [f0 + C * x**p for x in h]
    r = richardson(h, f)
    assert r.behaviour == "converging"
    assert r.order == pytest.approx(p, rel=1e-8)
    assert r.extrapolated == pytest.approx(f0, rel=1e-8)
    finest = min(h)
    assert r.error_finest == pytest.approx(C * finest**p / f0, rel=1e-7)


def test_constant_ratio_matches_closed_form():
    # r = 2: p = ln((f3 - f2)/(f2 - f1)) / ln 2, f0 = f1 + (f1 - f2)/(2^p - 1)
    f1, f2, f3 = 1.10, 1.30, 1.90
    r = richardson([0.25, 0.5, 1.0], [f1, f2, f3])
    p = math.log((f3 - f2) / (f2 - f1)) / math.log(2.0)
    assert r.order == pytest.approx(p, rel=1e-10)
    assert r.extrapolated == pytest.approx(f1 + (f1 - f2) / (2**p - 1), rel=1e-10)
    assert r.gci_finest == pytest.approx(1.25 * abs((f2 - f1) / f1) / (2**p - 1), rel=1e-10)


def test_order_does_not_depend_on_argument_order():
    a = richardson([1.0, 0.5, 0.25], [1.9, 1.3, 1.1])
    b = richardson([0.5, 0.25, 1.0], [1.3, 1.1, 1.9])
    assert a == b


def test_oscillating_and_diverging_are_named_not_extrapolated():
    osc = richardson([0.25, 0.5, 1.0], [1.0, 1.2, 1.1])
    assert osc.behaviour == "oscillating" and osc.order is None and osc.extrapolated is None
    div = richardson([0.25, 0.5, 1.0], [1.0, 1.5, 1.6])  # differences grow as the mesh is refined
    assert div.behaviour == "diverging" and div.order is None
    same = richardson([0.25, 0.5, 1.0], [2.0, 2.0, 2.0])
    assert same.behaviour == "converged" and same.extrapolated == 2.0 and same.error_finest == 0.0


@pytest.mark.parametrize(
    "h, f, match",
    [
        ([1.0, 0.5], [1.0, 2.0], "exactly three"),
        ([1.0, 0.5, 0.5], [1.0, 2.0, 3.0], "different"),
        ([1.0, -0.5, 0.2], [1.0, 2.0, 3.0], "positive"),
        ([1.0, 0.5, 0.25], [1.0, float("nan"), 3.0], "finite"),
    ],
)
def test_bad_input_is_refused(h, f, match):
    with pytest.raises(ValueError, match=match):
        richardson(h, f)


def _curve(T_at, h, n=4):
    lam = 1.0 + np.linspace(0.0, 0.3, n)
    T1 = np.array([T_at(x - 1.0, h) for x in lam])
    return Response(lam, lam.copy(), T1, 1.5 * T1, load="equibiaxial", label=f"h={h}")


def test_mesh_convergence_over_a_path_stops_where_the_paths_part():
    def T(e, h):  # converged law e²(1 + e) with an error 0.4·e·h² of order 2
        return e * e * (1 + e) + 0.4 * e * h * h

    sizes = {"volumetric:p2:r/1.5": 1 / 1.5, "volumetric:p2:r/2.25": 1 / 2.25, "volumetric:p2:r/3": 1 / 3}
    curves = {n: _curve(T, h) for n, h in sizes.items()}
    rows = mesh_convergence(sizes, curves, "equibiaxial", "volumetric:p2")
    assert len(rows) == 2 * 3  # two directions, three steps after zero
    assert rows[0]["rungs"].split()[0] == "volumetric:p2:r/3"  # finest first
    for r in rows:
        assert r["order"] == pytest.approx(2.0, rel=1e-6)
        e = r["strain"]
        exact = (e * e * (1 + e)) * (1.0 if r["direction"] == "course" else 1.5)
        assert r["T_extrapolated"] == pytest.approx(exact, rel=1e-6)
    # a truncated coarse run: only the steps all three reached
    short = dict(curves)
    c = curves["volumetric:p2:r/1.5"]
    short["volumetric:p2:r/1.5"] = c.evolve(
        lambda1=c.lambda1[:3], lambda2=c.lambda2[:3], T1=c.T1[:3], T2=c.T2[:3]
    )
    assert len(mesh_convergence(sizes, short, "equibiaxial", "volumetric:p2")) == 2 * 2
    assert mesh_convergence(dict(list(sizes.items())[:2]), curves, "equibiaxial", "volumetric:p2") == []
    text = convergence_table(rows)
    assert "### Mesh convergence of volumetric:p2" in text and "| course | 30 % |" in text
