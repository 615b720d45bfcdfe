"""Conformance checks for patterns, yarns and yarn models, plus the knit/purl topology test.

Each check takes the registered object and raises AssertionError saying what is wrong::

    from knitframe.testing.patterns import check_pattern
    check_pattern(MyTuckPattern)
"""

from __future__ import annotations

from typing import Any

import attrs
import numpy as np

from knitframe.geometry import UnitCell, crossings, frames
from knitframe.records import Fabric, Yarn

__all__ = [
    "CHECKS",
    "check_pattern",
    "check_yarn",
    "check_yarn_model",
    "reference_yarn",
    "knit_topology",
    "derivative_errors",
]


def reference_yarn() -> Yarn:
    """A transversely isotropic test yarn (cotton-sized) that every pattern and yarn model must accept."""
    return Yarn(
        name="check",
        d0=0.445,
        dk=0.444,
        E_axial=100.0,
        E_transverse=5.0,
        G_axial=2.0,
        nu=0.3,
        source="conformance kit",
    )


def _instance(obj: Any) -> Any:
    return obj() if isinstance(obj, type) and attrs.has(obj) else obj


def check_periodicity(cell: UnitCell, tol: float = 1e-9) -> None:
    """End of yarn i at t1 equals the start of its paired yarn + L1, in position and unit tangent."""
    scale = max(1.0, float(np.linalg.norm(cell.L1)))
    for i, j in cell.end_pairs:
        a, b = cell.yarns[i], cell.yarns[j]
        pa, pb = a.position(np.array([a.t1]))[0], b.position(np.array([b.t0]))[0] + cell.L1
        assert np.linalg.norm(pa - pb) <= tol * scale, (
            f"yarn {i} end misses yarn {j} start + L1 by {np.linalg.norm(pa - pb):.3g} mm"
        )
        ta, tb = a.derivative(np.array([a.t1]))[0], b.derivative(np.array([b.t0]))[0]
        ta, tb = ta / np.linalg.norm(ta), tb / np.linalg.norm(tb)
        assert np.linalg.norm(ta - tb) <= tol, (
            f"tangent jumps by {np.linalg.norm(ta - tb):.3g} between yarn {i} and yarn {j}"
        )
        period = a.position(np.array([a.t1]))[0] - a.position(np.array([a.t0]))[0]
        assert np.allclose(period, a.period, atol=tol * scale), (
            f"yarn {i}: period {a.period} != r(t1) - r(t0) = {period}"
        )


def check_tangents(cell: UnitCell, rtol: float = 1e-6) -> None:
    """``derivative`` is the exact derivative of ``position`` (central differences agree)."""
    for c in cell.yarns:
        t = np.linspace(c.t0, c.t1, 97)
        h = 1e-5 * (c.t1 - c.t0)
        fd = (c.position(t + h) - c.position(t - h)) / (2 * h)
        d = c.derivative(t)
        err = np.abs(fd - d).max() / np.abs(d).max()
        assert err < rtol, (
            f"yarn '{c.name}': derivative differs from finite differences of position by {err:.3g}"
        )


def check_pattern(obj: Any) -> None:
    """Builds a valid 2x2 cell: arc length to 1e-6, periodic, exact tangents, NaN-free frames."""
    pattern = _instance(obj)
    target = 4.7
    cell = pattern.cell(Fabric(pattern=pattern.name, yarn=reference_yarn(), arc_length=target))
    assert isinstance(cell, UnitCell), (
        f"cell() must return knitframe.geometry.UnitCell, got {type(cell).__name__}"
    )
    assert cell.pattern == pattern.name, f"cell.pattern is '{cell.pattern}', expected '{pattern.name}'"
    assert np.isclose(cell.radius, 0.222), f"cell.radius must be dk/2 = 0.222, got {cell.radius}"
    assert len(cell.layout) >= 1 and all(s in ("k", "p") for row in cell.layout for s in row), (
        "layout must hold 'k'/'p'"
    )
    got = sum(c.arc_length() for c in cell.yarns) / sum(len(r) for r in cell.layout)
    assert abs(got - target) <= 1e-6 * target, (
        f"arc length per stitch {got} misses the target {target} by more than 1e-6"
    )
    assert abs(cell.arc_length_per_stitch - got) <= 1e-6 * target, (
        "arc_length_per_stitch disagrees with the yarn lengths"
    )
    assert np.allclose(cell.L1, [2 * cell.course_pitch, 0, 0]), (
        f"L1 must be (2 course pitch, 0, 0), got {cell.L1}"
    )
    assert np.allclose(cell.L2, [0, 2 * cell.wale_pitch, 0]), (
        f"L2 must be (0, 2 wale pitch, 0), got {cell.L2}"
    )
    check_periodicity(cell)
    check_tangents(cell)
    for f in frames(cell, 64):
        for arr in (f.tangent, f.normal, f.binormal):
            assert np.all(np.isfinite(arr)), "frames contain NaN or inf"
        assert np.allclose(np.einsum("ij,ij->i", f.tangent, f.normal), 0.0, atol=1e-9), "normal not ⟂ tangent"


def check_yarn(obj: Any) -> None:
    """Is a Yarn with a source, a registered model, and round-trips through a dict."""
    from knitframe.plugins import get_registry

    assert isinstance(obj, Yarn), f"a registered yarn must be a knitframe.Yarn, got {type(obj).__name__}"
    assert Yarn.from_dict(obj.to_dict()) == obj, "yarn must round-trip through to_dict/from_dict"
    assert obj.source.strip(), f"yarn '{obj.name}' must say where its numbers come from (source)"
    assert obj.model in get_registry()["yarn_model"], (
        f"yarn '{obj.name}' names unknown yarn model '{obj.model}'"
    )
    get_registry()["yarn_model"][obj.model].from_yarn(obj)


def derivative_errors(model: Any, F: np.ndarray, a: np.ndarray, h: float = 1e-6) -> tuple[float, float]:
    """Largest relative differences of P from ∂W/∂F and of A from ∂P/∂F (central differences, step h)."""
    W, P, A = model.evaluate(F, a)
    eP = eA = 0.0
    for k in range(3):
        for l in range(3):
            dF = np.zeros((3, 3))
            dF[k, l] = h
            Wp, Pp, _ = model.evaluate(F + dF, a)
            Wm, Pm, _ = model.evaluate(F - dF, a)
            eP = max(eP, float(np.abs((Wp - Wm) / (2 * h) - P[..., k, l]).max() / np.abs(P).max()))
            eA = max(eA, float(np.abs((Pp - Pm) / (2 * h) - A[..., k, l]).max() / np.abs(A).max()))
    return eP, eA


def check_yarn_model(obj: Any) -> None:
    """Stress-free at F = I, P = ∂W/∂F and A = ∂P/∂F by finite differences, frame-indifferent, positive rod
    stiffness."""
    model = obj.from_yarn(reference_yarn())
    rng = np.random.default_rng(7)
    F = np.eye(3) + 0.15 * rng.standard_normal((4, 3, 3))
    a = rng.standard_normal((4, 3))
    a /= np.linalg.norm(a, axis=1)[:, None]
    W, P, A = model.evaluate(F, a)
    assert W.shape == (4,) and P.shape == (4, 3, 3) and A.shape == (4, 3, 3, 3, 3), (
        "evaluate must return W (...), P (...,3,3), A (...,3,3,3,3)"
    )
    W0, P0, _ = model.evaluate(np.eye(3)[None], a[:1])
    assert abs(W0[0]) < 1e-12 and np.abs(P0).max() < 1e-9 * model.E_axial, (
        "the reference state must be stress-free"
    )
    eP, eA = derivative_errors(model, F, a)
    assert eP < 1e-6, f"P differs from dW/dF by {eP:.3g} (relative, central differences)"
    assert eA < 1e-6, f"A differs from dP/dF by {eA:.3g} (relative, central differences)"
    q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    q *= np.sign(np.linalg.det(q))
    Wq = model.evaluate(q[None] @ F, a)[0]
    assert np.allclose(Wq, W, rtol=1e-10, atol=1e-12), "energy must not change under a rigid rotation"
    rod = model.rod()
    assert all(rod[k] > 0 for k in ("EA", "EI", "GJ")), f"rod stiffnesses must be > 0, got {rod}"
    f = np.array([1e-4, 1e-3, 1e-2])
    d = model.contact_approach(f)
    assert np.all(np.diff(d) > 0) and np.all(d > 0), "contact approach must grow with the line load"
    assert np.allclose(model.contact_load(d), f, rtol=1e-8), "contact_load must invert contact_approach"


def knit_topology(cell: UnitCell) -> list[tuple[int, int, str]]:
    """Stitch types read off the geometry: ``(row, column, "k" | "p")`` for every stitch of the cell.

    Row r's yarn interlocks with the loops of the row below (row r-1, or row 1 shifted by -L2
    for row 0). Going from a sinker to the next head, each half of a loop of row r crosses the
    row below twice: first its sinker passes the lower loop's leg, then its leg passes the lower
    loop's head. A knit stitch has its leg in front (+z, the technical face) of the head and its
    sinker behind the leg; a purl stitch the opposite. Raises AssertionError when a half-loop
    does not cross the row below exactly twice or its two crossings disagree.
    """
    rows = len(cell.yarns)
    found: dict[tuple[int, int], set[str]] = {}
    for r in range(rows):
        lower = (r - 1) % rows
        shift = -cell.L2 if r == 0 else np.zeros(3)
        cr = crossings(cell, r, lower, shift)
        c = cell.yarns[r]
        # half-loops: between a sinker (t = (2j - 1)π) and a head (t = 2jπ), and back
        edges = np.arange(c.t0, c.t1 + 1e-9, np.pi)
        for h in range(len(edges) - 1):
            inside = [x for x in cr if edges[h] <= x[0] < edges[h + 1]]
            assert len(inside) == 2, (
                f"row {r}, half-loop {h}: {len(inside)} crossings with the row below, expected 2"
            )
            rising = h % 2 == 0  # from sinker to head
            sinker, leg = (inside[0], inside[1]) if rising else (inside[1], inside[0])
            kind = "k" if leg[2] > 0 else "p"
            assert (sinker[2] < 0) == (leg[2] > 0), (
                f"row {r}, half-loop {h}: leg and sinker crossings disagree"
            )
            col = int(np.rint(leg[1] / cell.course_pitch)) % len(cell.layout[r])
            found.setdefault((r, col), set()).add(kind)
    out = []
    for (r, col), kinds in sorted(found.items()):
        assert len(kinds) == 1, f"stitch (row {r}, column {col}) has knit and purl halves"
        out.append((r, col, kinds.pop()))
    return out


CHECKS = {"pattern": check_pattern, "yarn": check_yarn, "yarn_model": check_yarn_model}
