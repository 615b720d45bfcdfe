"""Benchmark of the solid contact laws on the jersey SL11 cotton cell (volumetric solver setup).

Usage::

    python benchmarks/bench_contact.py                          # P1 and P2, both laws, order 0/1/2
    python benchmarks/bench_contact.py --meshes 2 --laws mortar # one mesh order, one law
    python benchmarks/bench_contact.py --material               # time the material assembly too, for scale
    python benchmarks/bench_contact.py --save ref.pkl           # keep the inputs and E, gradient, Hessian
    python benchmarks/bench_contact.py --compare ref.pkl        # same inputs, relative differences to them
    python benchmarks/bench_contact.py --profile mortar-P2-2    # cProfile of one case (top 30 by
                                                                # cumulative time)
    python benchmarks/bench_contact.py --projection 100000      # closest points on random curved
                                                                # facets, and the share of the start
                                                                # search in them

The cell is meshed at seed r/3 as the solver does it, the contact surface is the solver's
two-pass surface with periodic images, and the yarns are shrunk across the fibre about their
centerlines by ``--shrink`` (x = X − (1 − s)·offset), which leaves part of the knitted
interference of the cell in contact. The penalty is the solver's default 10·E_transverse/h and
the reach 0.5·r. Each time is the best of ``--repeat`` evaluations. The mesher is not
bit-reproducible between processes, so ``--save`` stores the surface and the node positions
and ``--compare`` evaluates on those (compare two versions of the laws by saving with one and
comparing with the other).
"""

from __future__ import annotations

import argparse
import cProfile
import pickle
import pstats
import time

import numpy as np


def setup(order: int, seed: float, shrink: float):
    """(fabric, cell mesh, contact surface, x, stiffness, reach) of the jersey cell."""
    from knitframe_solvers.volumetric_model import contact_surface

    from knitframe.geometry import unit_cell
    from knitframe.numerics.mesh import cell_mesh
    from knitframe.numerics.periodic import Lattice
    from knitframe.plugins import get_registry
    from knitframe.records import Fabric

    fabric = Fabric(pattern="jersey", yarn=get_registry()["yarn"]["cotton"], stitch_length=11)
    cell = unit_cell(fabric)
    cm = cell_mesh(cell, seed=seed, order=order)
    surf = contact_surface(cm, Lattice(cell.L1, cell.L2), np.pi * cell.dk)
    x = cm.nodes - (1.0 - shrink) * cm.node_offset
    stiffness = 10.0 * fabric.yarn.E_transverse / (seed * cm.radius)
    return fabric, cm, surf, x, stiffness, 0.5 * cm.radius


def material_time(fabric, cm, u: np.ndarray, repeat: int) -> float:
    """Best time of the yarn solids' energy, residual and tangent (order 2), s."""
    from knitframe_solvers.volumetric_material import SolidForms, YarnLaw

    from knitframe.plugins import get_registry

    forms = SolidForms(
        cm.mesh, YarnLaw.from_yarn(fabric.yarn, get_registry()), cm.node_tangent, node_offset=cm.node_offset
    )
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        forms.evaluate(u, 1.0, 2)
        best = min(best, time.perf_counter() - t0)
    return best


def rel(a, b) -> str:
    """Relative difference |a − b| / |b| (max-norm for sparse matrices), as text."""
    if a is None or b is None:
        return ""
    if hasattr(a, "tocsr"):
        return f"{abs(a - b).max() / max(abs(b).max(), 1e-300):.1e}"
    return f"{np.linalg.norm(np.atleast_1d(a - b)) / max(np.linalg.norm(np.atleast_1d(b)), 1e-300):.1e}"


def projection_time(m: int, repeat: int) -> None:
    """Time ``project_p2`` on m random bowed quadratic facets, and its start search (the 28-point
    lattice) alone."""
    from knitframe.numerics.contact import barycentric, p2

    rng = np.random.default_rng(0)
    c = rng.normal(size=(m, 3, 3)) * 0.1 + np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    mid = 0.5 * (c[:, [0, 1, 2]] + c[:, [1, 2, 0]]) + rng.normal(size=(m, 3, 3)) * 0.05
    X = np.concatenate([c, mid], axis=1)
    p = rng.uniform(-0.2, 0.8, size=(m, 3)) * [1, 1, 0.3]
    a = p2.p2_coefficients(X)
    xi = barycentric(p, X[:, 0], X[:, 1], X[:, 2])[:, 1:].clip(0.0, 1.0)

    def best(f):
        out = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            f()
            out.append(time.perf_counter() - t0)
        return min(out)

    print("| what | s |\n|---|---|")
    print(f"| project_p2, {m} facets | {best(lambda: p2.project_p2(p, X)):.3f} |")
    print(f"| of it the start search (28-point lattice) | {best(lambda: p2._best_start(p, *a, xi)):.3f} |")


def arguments(argv=None) -> argparse.Namespace:
    """The command line of the benchmark (see the module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--meshes", default="1,2", help="mesh orders: 1,2")
    p.add_argument("--orders", default="0,1,2", help="derivative orders: 0,1,2")
    p.add_argument("--laws", default="penalty,mortar")
    p.add_argument("--seed", type=float, default=1 / 3)
    p.add_argument("--shrink", type=float, default=0.9)
    p.add_argument("--repeat", type=int, default=2)
    p.add_argument("--material", action="store_true", help="time the material assembly too")
    p.add_argument(
        "--friction",
        action="store_true",
        help="also time friction_state at x and an order-2 evaluation with friction at x + noise (0.003 mm)",
    )
    p.add_argument("--save")
    p.add_argument("--compare")
    p.add_argument("--profile", help="law-Pk-order, e.g. mortar-P2-2")
    p.add_argument("--projection", type=int, help="only time project_p2 on this many random curved facets")
    return p.parse_args(argv)


def friction_time(
    law, name: str, mo: int, surf, x: np.ndarray, h: np.ndarray, stiffness: float, reach: float
) -> None:
    """Time friction_state at x, and an order-2 evaluation at x + noise (0.003 mm) without and with
    friction."""
    t0 = time.perf_counter()
    state = law.friction_state(surf, x, h, stiffness=stiffness, reach=reach)
    xn = x + 0.003 * np.random.default_rng(0).normal(size=x.shape)
    t1 = time.perf_counter()
    law.evaluate(surf, xn, h, 2, stiffness=stiffness, reach=reach)
    t2 = time.perf_counter()
    E, G, H, info = law.evaluate(surf, xn, h, 2, stiffness=stiffness, reach=reach, friction_state=state)
    t3 = time.perf_counter()
    print(f"| {name}-P{mo} friction_state | {surf.n_nodes} | {len(state)} | {t1 - t0:.2f} | | | |")
    print(
        f"| {name}-P{mo}-2 at x + noise, no friction | {surf.n_nodes} | {info['active']} | "
        f"{t2 - t1:.2f} | | | |"
    )
    print(
        f"| {name}-P{mo}-2 at x + noise, friction ({info['slipping']} of {len(state)} "
        f"slipping) | {surf.n_nodes} | {info['active']} | {t3 - t2:.2f} | | | |",
        flush=True,
    )


def main(argv=None) -> None:
    from knitframe_contact.mortar import SolidMortar
    from knitframe_contact.penalty import SolidPenalty

    args = arguments(argv)
    if args.projection:
        projection_time(args.projection, args.repeat)
        return
    laws = {"penalty": SolidPenalty(), "mortar": SolidMortar()}
    ref = None
    if args.compare:
        with open(args.compare, "rb") as fh:
            ref = pickle.load(fh)
    saved: dict = {"inputs": {}, "results": {}}
    print("| case | nodes | active | s | rel. diff E | rel. diff grad | rel. diff Hess |")
    print("|---|---|---|---|---|---|---|")
    for mo in (int(k) for k in args.meshes.split(",")):
        if ref is not None:
            surf, x, stiffness, reach = ref["inputs"][mo]
            fabric = cm = None
        else:
            fabric, cm, surf, x, stiffness, reach = setup(mo, args.seed, args.shrink)
        saved["inputs"][mo] = (surf, x, stiffness, reach)
        h = np.zeros(6)
        if args.material and cm is not None:
            t = material_time(fabric, cm, (x - cm.nodes).ravel(), args.repeat)
            print(f"| material P{mo} (order 2) | {surf.n_nodes} | | {t:.2f} | | | |", flush=True)
        for name in args.laws.split(","):
            law = laws[name]
            for order in (int(k) for k in args.orders.split(",")):
                key = f"{name}-P{mo}-{order}"
                if args.profile and args.profile != key:
                    continue
                if args.profile:
                    pr = cProfile.Profile()
                    pr.enable()
                    law.evaluate(surf, x, h, order, stiffness=stiffness, reach=reach)
                    pr.disable()
                    pstats.Stats(pr).sort_stats("cumulative").print_stats(30)
                    return
                best = np.inf
                for _ in range(args.repeat):
                    t0 = time.perf_counter()
                    E, G, H, info = law.evaluate(surf, x, h, order, stiffness=stiffness, reach=reach)
                    best = min(best, time.perf_counter() - t0)
                saved["results"][key] = (E, G, H)
                diffs = ["", "", ""]
                if ref is not None and key in ref["results"]:
                    E0, G0, H0 = ref["results"][key]
                    diffs = [rel(E, E0), rel(G, G0), rel(H, H0)]
                print(
                    f"| {key} | {surf.n_nodes} | {info['active']} | {best:.2f} | {' | '.join(diffs)} |",
                    flush=True,
                )
            if args.friction:
                friction_time(law, name, mo, surf, x, h, stiffness, reach)
    if args.save:
        with open(args.save, "wb") as fh:
            pickle.dump(saved, fh)


if __name__ == "__main__":
    main()
