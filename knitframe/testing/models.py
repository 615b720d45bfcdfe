"""Conformance checks for homogenizers, fitters, readers and solvers.

They are merged into :data:`knitframe.testing.CHECKS`.

Each check takes the registered class and raises AssertionError saying what is wrong::

    from knitframe.testing.models import check_homogenizer
    check_homogenizer(MyFabricModel)
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from knitframe import interfaces
from knitframe.errors import DataError
from knitframe.records import EFFECTS, Fabric, LoadPath, Response, Scene, Yarn
from knitframe.testing.members import check_members, protocol_members

__all__ = ["CHECKS", "check_homogenizer", "check_fitter", "check_reader", "check_solver", "LOAD_KINDS"]

#: load-path keys a solver may declare in ``loads``
LOAD_KINDS = frozenset({"equibiaxial", "uniaxial", "uniaxial-course", "uniaxial-wale", "general"})


def _instance(obj: Any) -> Any:
    return obj() if isinstance(obj, type) and attrs.has(obj) else obj


def _stretches(n: int = 40, lo: float = 0.8, hi: float = 1.6):
    rng = np.random.default_rng(12345)
    return rng.uniform(lo, hi, n), rng.uniform(lo, hi, n)


def _close(a, b, rtol: float, what: str, floor: float = 0.0) -> None:
    """max|a − b| <= rtol·max(|a|, |b|) + floor (the floor allows for round-off in a difference quotient)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    scale = max(float(np.abs(b).max()), float(np.abs(a).max()), 1e-12)
    err = float(np.abs(a - b).max())
    assert err <= rtol * scale + floor, (
        f"{what}: max difference {err:.3g} exceeds {rtol:g} x {scale:.3g} + {floor:.3g}"
    )


def _roundoff(values, step: float) -> float:
    """Round-off of a central difference of ``values`` with ``step``: 10 eps max|values| / step."""
    return 10.0 * np.finfo(float).eps * float(np.abs(np.asarray(values)).max()) / step


def _param_sets(model) -> list[np.ndarray]:
    """The default parameters and a second set halfway between them and the upper bounds (log scale
    where the model asks)."""
    from knitframe.fitting import UnitBox

    box = UnitBox(model)
    x0 = np.asarray(model.x0(), dtype=np.float64)
    return [x0, box.to_params(0.5 * (box.to_unit(x0) + 1.0))]


def _check_parameters(m: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``param_names``, ``bounds()`` and ``x0()`` agree and the per-parameter tuples have their length;
    returns (lo, hi, x0)."""
    names = tuple(m.param_names)
    assert names and all(isinstance(n, str) for n in names), (
        "param_names must be a non-empty tuple of strings"
    )
    for attr in ("units", "log_scale", "symmetric_bounds"):
        assert len(tuple(getattr(m, attr))) == len(names), f"{attr} must have one entry per parameter"
    assert isinstance(m.predicts_lateral, bool), "predicts_lateral must be True or False"
    lo, hi = (np.asarray(b, dtype=np.float64) for b in m.bounds())
    assert lo.shape == hi.shape == (len(names),), f"bounds() must give two arrays of length {len(names)}"
    assert np.all(lo <= hi), "bounds(): lower > upper"
    x0 = np.asarray(m.x0(), dtype=np.float64)
    assert x0.shape == lo.shape and np.all((x0 >= lo) & (x0 <= hi)), (
        f"x0() {x0.tolist()} lies outside bounds()"
    )
    return lo, hi, x0


def _check_stress(m: Any, p: np.ndarray, l1: np.ndarray, l2: np.ndarray, h: float) -> None:
    """Shapes, finite values, P = ∂ψ/∂λ by central differences, and a stress-free, energy-free λ = 1."""
    psi = np.asarray(m.energy(p, l1, l2))
    P1, P2 = (np.asarray(a) for a in m.stress(p, l1, l2))
    assert psi.shape == P1.shape == P2.shape == l1.shape, (
        "energy and stress must keep the shape of the stretches"
    )
    assert np.all(np.isfinite(psi)) and np.all(np.isfinite(P1)) and np.all(np.isfinite(P2)), (
        "non-finite energy or stress"
    )
    fl = _roundoff(psi, h)
    _close(
        P1,
        (m.energy(p, l1 + h, l2) - m.energy(p, l1 - h, l2)) / (2 * h),
        1e-5,
        f"P1 vs dψ/dλ1 at {p.tolist()}",
        fl,
    )
    _close(
        P2,
        (m.energy(p, l1, l2 + h) - m.energy(p, l1, l2 - h)) / (2 * h),
        1e-5,
        f"P2 vs dψ/dλ2 at {p.tolist()}",
        fl,
    )
    one = np.ones(3)
    r1, r2 = m.stress(p, one, one)
    scale = max(float(np.abs(P1).max()), float(np.abs(P2).max()), 1e-12)
    assert np.abs(r1).max() <= 1e-12 * scale and np.abs(r2).max() <= 1e-12 * scale, (
        f"the reference state (λ1 = λ2 = 1) must be stress-free, got P = ({r1[0]:.3g}, {r2[0]:.3g})"
    )
    assert abs(float(np.asarray(m.energy(p, one, one))[0])) <= 1e-12 * scale, "energy must vanish at λ = 1"


def _check_stress_grad(m: Any, p: np.ndarray, l1: np.ndarray, l2: np.ndarray) -> None:
    """``stress_grad``'s parameter derivatives (n, len(param_names)) against central differences."""
    names = tuple(m.param_names)
    P1, P2 = m.stress(p, l1, l2)
    G1, G2 = (np.asarray(a) for a in m.stress_grad(p, l1, l2)[2:])
    assert G1.shape == (len(l1), len(names)), f"stress_grad derivatives must have shape (n, {len(names)})"
    for k, name in enumerate(names):
        e = np.zeros_like(p)
        e[k] = 1e-6 * max(1.0, abs(p[k]))
        a1, a2 = m.stress(p + e, l1, l2)
        b1, b2 = m.stress(p - e, l1, l2)
        fl = _roundoff([P1, P2], e[k])
        _close(G1[:, k], (a1 - b1) / (2 * e[k]), 1e-5, f"dP1/d{name}", fl)
        _close(G2[:, k], (a2 - b2) / (2 * e[k]), 1e-5, f"dP2/d{name}", fl)


def _check_tangent(m: Any, p: np.ndarray, l1: np.ndarray, l2: np.ndarray, h: float) -> None:
    """``tangent`` against central differences of the stress, and ``stress_tangent`` equal to both."""
    P1, P2 = m.stress(p, l1, l2)
    K11, K12, K22 = m.tangent(p, l1, l2)
    a1, a2 = m.stress(p, l1 + h, l2)
    b1, b2 = m.stress(p, l1 - h, l2)
    c1, c2 = m.stress(p, l1, l2 + h)
    d1, d2 = m.stress(p, l1, l2 - h)
    fl = _roundoff([P1, P2], h)
    _close(K11, (a1 - b1) / (2 * h), 1e-5, "dP1/dλ1", fl)
    _close(K12, (c1 - d1) / (2 * h), 1e-5, "dP1/dλ2", fl)
    _close(K12, (a2 - b2) / (2 * h), 1e-5, "dP2/dλ1 (tangent symmetry)", fl)
    _close(K22, (c2 - d2) / (2 * h), 1e-5, "dP2/dλ2", fl)
    both = m.stress_tangent(p, l1, l2)
    for got, want, what in zip(both, (P1, P2, K11, K12, K22), ("P1", "P2", "K11", "K12", "K22"), strict=True):
        _close(got, want, 1e-12, f"stress_tangent {what} vs stress/tangent")


def _check_extremes(m: Any, lo: np.ndarray, hi: np.ndarray) -> None:
    """Finite energy and stress, without a floating-point warning, at λ from 0.05 to 20 with extreme
    parameters."""
    extreme = np.array([0.05, 0.3, 1.0, 3.0, 20.0])
    e1, e2 = (a.ravel() for a in np.meshgrid(extreme, extreme))
    with np.errstate(over="raise", invalid="raise", divide="raise"):
        for p in (hi, np.maximum(lo, 1e-12 * np.ones_like(lo))):
            try:
                vals = [m.energy(p, e1, e2), *m.stress(p, e1, e2)]
            except FloatingPointError as e:
                raise AssertionError(
                    f"floating-point trouble at extreme stretch with parameters {p.tolist()}: {e}"
                ) from None
            assert all(np.all(np.isfinite(v)) for v in vals), (
                f"non-finite energy or stress at extreme stretch, parameters {p.tolist()}"
            )


def _check_uniaxial(m: Any, x0: np.ndarray) -> None:
    """``solve_uniaxial`` returns a state whose free-side tension vanishes, and ``free_side_slack`` a
    stretch >= 1."""
    lam = np.linspace(0.9, 1.5, 7)
    for d in (0, 1):
        direction = ("course", "wale")[d]
        lf, P = m.solve_uniaxial(x0, lam, direction)
        assert np.shape(lf) == np.shape(P) == lam.shape, (
            "solve_uniaxial must return arrays of the input's shape"
        )
        assert np.all(np.isfinite(lf)) and np.all(lf > 0) and np.all(np.isfinite(P)), (
            "solve_uniaxial gave bad values"
        )
        pair = (lam, lf) if d == 0 else (lf, lam)
        Pf = m.stress(x0, *pair)[1 - d]
        interior = lf > 1e-3 * 1.0001
        _close(
            Pf[interior],
            np.zeros(int(interior.sum())),
            0.0,
            "free-side tension after solve_uniaxial",
            1e-8 * float(np.abs(P).max()) + 1e-14,
        )
        slack = float(m.free_side_slack(x0, direction))
        assert slack >= 1.0, f"free_side_slack ({direction}) must be a stretch >= 1, got {slack:.4g}"


def check_homogenizer(obj: Any) -> None:
    """Energy and stresses are consistent, finite and stress-free at λ = 1; derivatives match differences.

    Checks, for the default parameters and a second set: shapes; P = ∂ψ/∂λ by central
    differences; zero energy and stress in the reference state; ``stress_grad``, ``tangent`` and
    ``stress_tangent`` against differences; finite values (no floating-point warning) at λ from
    0.05 to 20 with the upper-bound parameters; ``solve_uniaxial`` returning a state whose
    free-side tension vanishes.
    """
    m = _instance(obj)
    lo, hi, x0 = _check_parameters(m)
    l1, l2 = _stretches()
    h = 1e-6
    for p in _param_sets(m):
        _check_stress(m, p, l1, l2, h)
        _check_stress_grad(m, p, l1, l2)
        _check_tangent(m, p, l1, l2, h)
    _check_extremes(m, lo, hi)
    _check_uniaxial(m, x0)


def check_fitter(obj: Any) -> None:
    """Recovers known ``hgo`` parameters (a = 0.05 N/mm, b = 3, θ = 35°) from noise-free biaxial data.

    The data are two ``general`` Responses (course-dominant and wale-dominant biaxial paths),
    fitted jointly; a, b must come back within 1 %, θ within 0.2°, with NRMSE below 0.1 % and a
    positive evaluation count and wall time.
    """
    from knitframe.plugins import get_registry

    fitter = _instance(obj)
    model = get_registry()["homogenizer"]["hgo"]()
    true = np.array([0.05, 3.0, math.radians(35.0)])
    t = np.linspace(0.0, 1.0, 30)
    curves = []
    for r1, r2 in ((0.4, 0.15), (0.1, 0.35)):
        l1, l2 = 1 + r1 * t, 1 + r2 * t
        P1, P2 = model.stress(true, l1, l2)
        curves.append(Response(l1, l2, P1, P2, load="general", label=f"synthetic {r1}/{r2}"))
    res = fitter.fit(model, curves)
    p = np.asarray(res.params, dtype=np.float64)
    assert p.shape == (3,), f"fit returned {p.shape} parameters for the 3-parameter hgo model"
    assert abs(p[0] / true[0] - 1) < 0.01 and abs(p[1] / true[1] - 1) < 0.01, (
        f"a, b not recovered: got {p[0]:.5g}, {p[1]:.5g}, expected 0.05, 3"
    )
    assert abs(math.degrees(p[2]) - 35.0) < 0.2, (
        f"θ not recovered: got {math.degrees(p[2]):.3f}°, expected 35°"
    )
    assert res.nrmse["overall"] < 1e-3, f"NRMSE {res.nrmse['overall']:.3g} on noise-free data"
    assert res.n_evals > 0 and res.wall_time > 0, "fit must report evaluations and wall time"


def check_reader(obj: Any) -> None:
    """A missing or empty file raises a one-line DataError naming the file; a reader with any member of
    :class:`~knitframe.interfaces.HeaderReader` or :class:`~knitframe.interfaces.DispatchingReader` has
    all of it."""
    for proto in (interfaces.HeaderReader, interfaces.DispatchingReader):
        own = protocol_members(proto) - protocol_members(interfaces.Reader)
        if any(hasattr(obj, m) for m in own):
            check_members(obj, proto, f"reader '{obj.name}'")
    if isinstance(obj, interfaces.HeaderReader):
        assert isinstance(obj.expects, str) and obj.expects, "expects must name the header the reader reads"
        assert obj.accepts([]) is False, "accepts must be False for an empty header"
    reader = _instance(obj)
    with tempfile.TemporaryDirectory() as tmp:
        for name, text in (("missing.csv", None), ("empty.csv", "")):
            path = Path(tmp) / name
            if text is not None:
                path.write_text(text)
            try:
                reader.read(path)
            except DataError as e:
                msg = str(e)
                assert name in msg, f"DataError for {name} must name the file, got {msg!r}"
                assert "\n" not in msg, f"DataError must be one line, got {msg!r}"
            else:
                raise AssertionError(
                    f"reading {'a missing' if text is None else 'an empty'} file must raise DataError"
                )


def check_solver(obj: Any) -> None:
    """Declares effects ⊂ EFFECTS and its loads (its other members are checked by
    :func:`~knitframe.testing.members.check_members`); a solver marked ``conformance_simulate = True``
    also runs a 2-step scene of each load it declares with default options and must return a finite
    Response of the scene's length.

    Unit-cell solvers need minutes and a real fabric, so they are only simulated when they opt in.
    """
    effects, loads = obj.effects, obj.loads
    assert isinstance(effects, frozenset) and effects, "solver.effects must be a non-empty frozenset"
    unknown = sorted(effects - set(EFFECTS))
    assert not unknown, f"solver.effects names unknown effects {unknown}; known: {', '.join(EFFECTS)}"
    assert isinstance(loads, frozenset) and loads, "solver.loads must be a non-empty frozenset"
    assert loads <= LOAD_KINDS, f"solver.loads has unknown load kinds {sorted(loads - LOAD_KINDS)}"
    if not obj.conformance_simulate:
        return
    solver = _instance(obj)
    yarn = Yarn(name="check", d0=0.445, dk=0.444, E_axial=100.0, E_transverse=5.0, source="conformance kit")
    fabric = Fabric(pattern="jersey", yarn=yarn, stitch_length=10.0)
    paths = {
        "equibiaxial": LoadPath("equibiaxial", 0.05, 2),
        "uniaxial-course": LoadPath("uniaxial", 0.05, 2),
        "uniaxial-wale": LoadPath("uniaxial", 0.05, 2, direction="wale"),
        "general": LoadPath("general", lambda1=(1.02, 1.05), lambda2=(1.01, 1.0)),
    }
    for key, load in paths.items():
        if key not in loads and load.kind not in loads:
            continue
        r = solver.simulate(fabric, Scene(load=load, effects=effects))
        assert isinstance(r, Response), f"simulate must return a Response, got {type(r).__name__}"
        assert len(r) == len(load.stretches()[0]), (
            f"{key}: Response has {len(r)} points, the scene has {len(load.stretches()[0])}"
        )
        assert np.all(np.isfinite(r.T1)) and np.all(np.isfinite(r.T2)), f"{key}: non-finite tension"


CHECKS = {
    "homogenizer": check_homogenizer,
    "fitter": check_fitter,
    "reader": check_reader,
    "solver": check_solver,
}
