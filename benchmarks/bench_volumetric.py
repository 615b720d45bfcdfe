"""Benchmark of the volumetric solver on jersey SL11 cotton: meshing, Newton-iteration costs, solvers,
full runs.

Usage::

    # mesh sizes and times, P1/P2, several seeds
    python benchmarks/bench_volumetric.py mesh
    # one Newton iteration: assembly, contact, direct vs amg
    python benchmarks/bench_volumetric.py iteration --order 2
    # the same without SuperLU (its fill-in explodes on P2)
    python benchmarks/bench_volumetric.py iteration --order 2 --solvers pardiso,amg
    # pre-stress + equibiaxial 0→30 %
    python benchmarks/bench_volumetric.py run --order 1 --seed 0.6 --steps 6
    # the solid's evaluations per thread count; the pull-back
    python benchmarks/bench_volumetric.py forms --order 2
    # the yarn law alone, per derivative order
    python benchmarks/bench_volumetric.py law
    # summary of a traced run, one row per Newton solve
    python benchmarks/bench_volumetric.py trace --trace run.jsonl

Each command prints a table (and ``--json`` writes the numbers). Peak memory is the process's
maximum resident set size (``resource.getrusage``), so run one command per process.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time

import attrs
import numpy as np
import scipy.sparse as sp


def peak_mb() -> float:
    """Peak resident memory of this process, MB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def fabric():
    from knitframe.plugins import get_registry
    from knitframe.records import Fabric

    return Fabric(pattern="jersey", yarn=get_registry()["yarn"]["cotton"], stitch_length=11)


def scene(steps: int, friction: bool = False):
    from knitframe.records import LoadPath, Scene

    effects = {"large_deformation", "bending", "contact", "self_contact", "prestress", "anisotropy"} | (
        {"friction"} if friction else set()
    )
    return Scene(load=LoadPath(kind="equibiaxial", max_strain=0.3, steps=steps), effects=effects)


def bench_mesh(args) -> list[dict]:
    from knitframe.geometry import unit_cell
    from knitframe.numerics.mesh import cell_mesh, mesh_quality

    cell = unit_cell(fabric())
    rows = []
    for order in (1, 2):
        for seed in (0.6, 1 / 3, 0.25):
            t0 = time.perf_counter()
            cm = cell_mesh(cell, seed=seed, order=order)
            t = time.perf_counter() - t0
            q = mesh_quality(cm)
            rows.append(
                {
                    "order": order,
                    "seed_r": round(1 / seed, 2),
                    "elements": cm.n_elements,
                    "dofs": 3 * cm.n_nodes,
                    "mesh_s": round(t, 2),
                    "min_dihedral": round(q["min_dihedral_deg"], 1),
                    "max_aspect": round(q["max_aspect_ratio"], 2),
                    "min_jac": round(q["min_jacobian_ratio"], 3),
                    "volume_err": f"{q['volume_error']:.2e}",
                }
            )
    return rows


def bench_iteration(args) -> list[dict]:
    """One Newton iteration at the first pre-stress increment: assembly, contact, transforms, solves."""
    from knitframe_linsolvers.amg import amg, rigid_body_modes
    from knitframe_linsolvers.direct import UNSYMMETRIC, _pardiso_solver, _refined, direct

    from knitframe.plugins import get_registry

    def pardiso_lu(A, b):  # what a symmetric matrix cost before it got the LDLᵀ
        A = sp.csr_matrix(A)
        return _refined(_pardiso_solver(UNSYMMETRIC), A, A, b, 4, 1e-10)

    from knitframe_solvers.volumetric import VolumetricSolver

    solver = VolumetricSolver(order=args.order, seed=args.seed, contact_law=args.contact)
    t0 = time.perf_counter()
    model = solver.setup(fabric(), scene(6), get_registry())
    t_setup = time.perf_counter() - t0
    r = model.cm.radius
    s0 = min(solver.initial_radius, 0.95 * model.cm.clearance.minimum / (2 * r))
    q = model.shrunk(s0)
    model.s = s0
    # half-way through the pre-stress: the yarns are in contact (the solver's predictor)
    model.anchor(q)
    q = model.grow(q, s0, 0.5 * (s0 + 1.0))
    model.anchor(q)
    model(q, 2)  # warm-up: sparsity pattern, caches
    for k in model.timings:
        model.timings[k] = 0.0 if k != "mesh" else model.timings[k]
    t0 = time.perf_counter()
    E, g, H, info = model(q, 2)
    t_eval = time.perf_counter() - t0
    n_ind = 3 * len(model.independent)
    free = np.ones(H.shape[0], bool)
    free[:3] = False
    free[n_ind:] = False
    A = H[free][:, free].tocsc()
    b = -g[free]
    rows = [
        {"what": "setup (mesh, forms, periodic map)", "s": round(t_setup, 2)},
        {"what": "material energy+residual+tangent", "s": round(model.timings["material"], 2)},
        {
            "what": f"contact ({args.contact}, {info['active']} active)",
            "s": round(model.timings["contact"], 2),
        },
        {"what": "periodic transforms", "s": round(model.timings["transform"], 2)},
        {"what": "whole evaluation (order 2)", "s": round(t_eval, 2)},
    ]
    # a line-search trial (energy only): on the candidates the iterate's search found, and searched afresh
    holds = (
        (("held candidates", True), ("fresh contact search", False))
        if model.hold_candidates
        else (("", False),)
    )
    for label, hold in holds:
        model.hold_candidates = hold
        model(q, 2)
        t0 = time.perf_counter()
        for _ in range(3):
            model(q, 0)
        what = "line-search energy (order 0)" + (f", {label}" if label else "")
        rows.append({"what": what, "s": round((time.perf_counter() - t0) / 3, 2)})
    chosen = {
        "direct": ("direct (SuperLU)", lambda: direct("superlu")),
        "pardiso": ("direct (PARDISO; LDLᵀ for a symmetric matrix)", lambda: direct("pardiso")),
        "pardiso-lu": ("PARDISO LU (the unsymmetric path)", lambda: pardiso_lu),
        "amg": ("amg (SA + rigid modes)", lambda: amg()),
    }
    for name, factory in (chosen[k] for k in args.solvers.split(",")):
        if name.startswith("amg"):
            B = rigid_body_modes(model.X_ind)
            Bq = np.zeros((H.shape[0], 6))
            Bq[:n_ind] = B
            solve_fn = factory()

            def run(A=A, b=b, B=Bq[free], solve_fn=solve_fn):
                return solve_fn(A, b, near_null_space=B)
        else:
            solve_fn = factory()

            def run(A=A, b=b, solve_fn=solve_fn):
                return solve_fn(A, b)

        t0 = time.perf_counter()
        try:
            x = run()
            first = time.perf_counter() - t0
            # a Newton run factorises a new matrix every iteration, after the library's one-off start-up:
            # the second solve (a fresh factorisation of A + a tiny shift) is what an iteration costs
            t0 = time.perf_counter()
            run(A=(A + 1e-12 * sp.identity(A.shape[0], format=A.format)).asformat(A.format))
            again = time.perf_counter() - t0
            res = float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))
            rows.append(
                {
                    "what": f"linear solve {name} (first call / a new matrix)",
                    "s": f"{first:.2f} / {again:.2f}",
                    "residual": f"{res:.1e}",
                }
            )
        except Exception as e:  # report, do not hide, a failing solver
            rows.append(
                {
                    "what": f"linear solve {name}",
                    "s": round(time.perf_counter() - t0, 2),
                    "residual": f"failed: {type(e).__name__}: {str(e)[:80]}",
                }
            )
    rows.append({"what": f"DOFs {A.shape[0]}, nnz {A.nnz}, peak RSS MB", "s": round(peak_mb())})
    return rows


#: 'run' flags forwarded when given (flag → option of the contact law, or of VolumetricSolver); "on"/"off"
#: become booleans
LAW_FLAGS = {"smoothing": "smoothing", "mu": "friction", "dhat": "dhat", "ccd": "ccd", "reuse": "reuse"}
SOLVER_FLAGS = {"step_tol": "step_tolerance"}
#: 'run' flags forwarded to the solver's ``newton`` settings when given
NEWTON_FLAGS = {
    "stabilisation": "stabilisation",
    "max_step": "max_step",
    "cap_shift": "cap_shift",
    "tangent": "tangent",
    "predictor": "predictor",
    "chord": "chord",
    "eigen": "eigenvalue_filter",
    "extrapolate": "extrapolation",
    "halve_reversals": "halve_reversals",
    "chord_full": "chord_after_full_steps",
}


def _given(args, flags: dict[str, str]) -> dict:
    """The options of the flags given on the command line (the others keep their defaults)."""
    out = {opt: getattr(args, flag) for flag, opt in flags.items() if getattr(args, flag) is not None}
    return {k: (v == "on" if v in ("on", "off") else v) for k, v in out.items()}


def bench_run(args) -> list[dict]:
    from knitframe_solvers.volumetric import VolumetricSolver

    law = {"kind": args.contact, **_given(args, LAW_FLAGS)}
    solver = VolumetricSolver(
        order=args.order,
        seed=args.seed,
        contact_law=law,
        prestress_steps=args.prestress,
        linear_solver=args.linear_solver,
        contact_modulus=args.contact_modulus,
        on_failure="truncate" if args.truncate else "raise",
        **_given(args, SOLVER_FLAGS),
        newton={
            "preset": args.newton,
            **({"start_projected": True} if args.start_projected else {}),
            **_given(args, NEWTON_FLAGS),
        },
    )
    fab = attrs.evolve(fabric(), stitch_length=args.stitch_length)
    if args.transverse_ratio is not None:  # a diagnostic: the same yarn with a milder anisotropy
        y = fab.yarn
        fab = attrs.evolve(
            fab,
            yarn=attrs.evolve(
                y,
                name=f"{y.name}-ET{args.transverse_ratio:g}",
                E_transverse=args.transverse_ratio * y.E_axial,
            ),
        )
    t0 = time.perf_counter()

    def progress(done, total, message):
        print(f"  {time.perf_counter() - t0:8.1f} s  {done}/{total}  {message}", file=sys.stderr, flush=True)

    sc = scene(args.steps, args.friction)
    trace_file = open(args.trace, "a") if args.trace else None

    def write_trace(record):
        trace_file.write(json.dumps(record, default=float) + "\n")
        trace_file.flush()

    resp = solver.simulate(
        fab,
        sc,
        progress=progress,
        checkpoint_dir=args.checkpoint,
        trace=write_trace if trace_file is not None else None,
    )
    if trace_file is not None:
        trace_file.close()
    wall = time.perf_counter() - t0
    if args.save:
        with open(args.save, "w") as fh:
            json.dump(
                {"fabric": fab.to_dict(), "scene": sc.to_dict(), "response": resp.to_dict()},
                fh,
                indent=1,
                default=str,
            )
    prov = resp.provenance
    rows = [
        {
            "lambda": round(float(l1), 3),
            "T1_N_per_mm": round(float(t1), 5),
            "T2_N_per_mm": round(float(t2), 5),
        }
        for l1, t1, t2 in zip(resp.lambda1, resp.T1, resp.T2)
    ]
    rows.append({"lambda": "wall s", "T1_N_per_mm": round(wall, 1), "T2_N_per_mm": prov.mesh})
    rows.append(
        {
            "lambda": "split s",
            "T1_N_per_mm": json.dumps(prov.extra["timings_s"]),
            "T2_N_per_mm": json.dumps(prov.extra["newton_evaluations"]),
        }
    )
    tm, ev = prov.extra["timings_s"], prov.extra["newton_evaluations"]
    n_it = max(ev["linear_solves"], 1)
    rows.append(
        {
            "lambda": "per Newton iteration s",
            "T1_N_per_mm": "assembly+contact "
            f"{(tm['material'] + tm['contact'] + tm['transform']) / n_it:.2f}",
            "T2_N_per_mm": f"linear solve {tm['linear_solve'] / n_it:.2f} ({n_it} solves)",
        }
    )
    rows.append({"lambda": "peak RSS MB", "T1_N_per_mm": round(peak_mb()), "T2_N_per_mm": ""})
    return rows


def bench_trace(args) -> list[dict]:
    """One row per Newton solve of a trace file (``run --trace``): outcome, iterations, wall time, the final
    residual against the force flux, active contacts, and the largest energy jump between an accepted
    line-search step and the next iterate (where the contact pairing changed between them).

    With ``--iterations``: one row per Newton iteration instead, from the records written as each
    iteration completed (a solve that was killed or never converged included): residual, energy,
    the step over the cap, the line search's α, Newton or chord step, projected tangent or not, wall time."""
    rows = []
    with open(args.trace) as fh:
        for line in fh:
            rec = json.loads(line)
            if getattr(args, "iterations", False):
                if rec.get("record") == "iteration":
                    rows.append(
                        {
                            "phase": rec["phase"],
                            "t": round(rec["t"], 5),
                            "it": rec["it"],
                            "residual N": f"{rec['residual']:.3g}",
                            "energy N·mm": f"{rec['energy']:.7g}",
                            "step/cap": f"{rec['step']:.3g}" if "step" in rec else "",
                            "alpha": f"{rec['alpha']:.3g}" if "alpha" in rec else "",
                            "extrapolated": "yes" if "extrapolated" in rec else "",
                            "kind": "chord" if rec.get("chord") else "Newton",
                            "shift": f"{rec.get('shift', 0.0):.2g}",
                            "projected": bool(rec.get("projected")),
                            "active": int(rec.get("active", 0)),
                            "wall s": round(rec.get("wall_s", 0.0), 1),
                            "material+contact s": round(
                                rec.get("material_s", 0.0) + rec.get("contact_s", 0.0), 1
                            ),
                            "linear solves": f"{rec.get('n_linear_solves', '')} "
                            f"({rec.get('linear_solve_s', 0.0):.1f} s)",
                            "evaluations (E, g, H)": f"{rec.get('n_energy', '')}, "
                            f"{rec.get('n_gradient', '')}, "
                            f"{rec.get('n_hessian', '')}",
                        }
                    )
                continue
            if rec.get("record") == "iteration":  # the per-iteration records: the solve record repeats them
                continue
            h = rec.get("history", [])
            last = h[-1] if h else {}
            jumps = [b["energy"] - a["step_energy"] for a, b in zip(h[:-1], h[1:]) if "step_energy" in a]
            jump = max(jumps, key=abs, default=0.0)
            res, flux = last.get("residual", float("nan")), last.get("flux", 0.0)
            rows.append(
                {
                    "phase": rec["phase"],
                    "t": round(rec["t"], 5),
                    "converged": rec["converged"],
                    "iterations": max(len(h) - 1, 0),
                    "chord steps": sum(1 for e in h if e.get("chord")),
                    "extrapolated": sum(1 for e in h if "extrapolated" in e),
                    "wall s": round(rec["wall_s"], 1),
                    "residual N": f"{res:.3g}",
                    "residual/flux": f"{res / flux:.3g}" if flux else "",
                    "active": int(last.get("active", 0)),
                    "largest pairing jump N·mm": f"{jump:.3g}",
                    "relative jump": f"{abs(jump) / abs(last['energy']):.2g}" if last.get("energy") else "",
                }
            )
    return rows


def bench_forms(args) -> list[dict]:
    """The solid's evaluations on the cell at the start of the pre-stress, per order and thread count, and the
    pull-back of its tangent to the periodic unknowns (fixed-pattern map against two sparse products)."""
    from knitframe_solvers.volumetric import VolumetricSolver

    from knitframe.plugins import get_registry

    solver = VolumetricSolver(order=args.order, seed=args.seed)
    model = solver.setup(fabric(), scene(6), get_registry())
    r = model.cm.radius
    s0 = min(solver.initial_radius, 0.95 * model.cm.clearance.minimum / (2 * r))
    u = model.T @ model.shrunk(s0)
    rows = []
    for threads in (int(t) for t in args.threads.split(",")):
        forms = model.forms
        forms.threads, forms._pool = threads, None
        forms.evaluate(u, s0, 2, project=True)  # warm-up: pattern and scatter maps
        for order in (0, 1, 2):
            t0 = time.perf_counter()
            for _ in range(3):
                forms.evaluate(u, s0, order, project=True)
            rows.append(
                {
                    "what": f"solid, order {order} ({forms.edofs.shape[1]} elements, "
                    f"{len(forms._chunks())} chunks)",
                    "threads": threads,
                    "s": round((time.perf_counter() - t0) / 3, 4),
                }
            )
    K = model.forms.evaluate(u, s0, 2, project=True)[2]
    t0 = time.perf_counter()
    model.pull_back(K)
    rows.append(
        {
            "what": "pull-back Tᵀ(K + cI)T: building its map (once)",
            "threads": "",
            "s": round(time.perf_counter() - t0, 3),
        }
    )
    for label, fn in (
        ("pull-back Tᵀ(K + cI)T: fixed-pattern map", lambda: model.pull_back(K)),
        (
            "pull-back Tᵀ(K + cI)T: sparse products",
            lambda: (model.TT @ K @ model.T + model.damping * (model.TT @ model.T)).tocsr(),
        ),
    ):
        fn()
        t0 = time.perf_counter()
        for _ in range(3):
            fn()
        rows.append({"what": label, "threads": "", "s": round((time.perf_counter() - t0) / 3, 4)})
    from knitframe_linsolvers.direct import upper

    H = model.pull_back(K)
    for label, fn in (
        ("upper triangle of the Hessian (PARDISO's LDLᵀ input): mask", lambda: upper(H)),
        ("upper triangle of the Hessian: scipy triu", lambda: sp.triu(H, format="csr")),
    ):
        fn()
        t0 = time.perf_counter()
        for _ in range(3):
            fn()
        rows.append({"what": label, "threads": "", "s": round((time.perf_counter() - t0) / 3, 4)})
    rows.append(
        {"what": f"DOFs {K.shape[0]}, tangent nnz {K.nnz}, peak RSS MB", "threads": "", "s": round(peak_mb())}
    )
    return rows


def bench_law(args) -> list[dict]:
    """The cotton yarn law at 20 000 random deformation gradients, a third of them squeezed across
    into the compaction barrier's band: energy only, + stress, + tangent; with the barrier (the
    default) and without it (``compaction = None``)."""
    import attrs

    from knitframe.plugins import get_registry

    model = get_registry()["yarn_model"]["transverse_isotropic"].from_yarn(fabric().yarn)
    rng = np.random.default_rng(1)
    n = 20000
    F = np.eye(3) + 0.05 * rng.normal(size=(n, 3, 3))
    a = rng.normal(size=(n, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    # squeeze a third across their fibre: F (I - a⊗a) scaled by 0.75
    sq = slice(0, n // 3)
    F[sq] = np.einsum("piJ,pJK->piK", F[sq], np.eye(3) - 0.25 * (np.eye(3) - a[sq, :, None] * a[sq, None, :]))
    x = np.linalg.det(F) / np.linalg.norm(np.einsum("piJ,pJ->pi", F, a), axis=1)
    band = float(np.mean(x < 0.5 * (1.0 + model.compaction)))
    rows = []
    for order in (0, 1, 2):
        row = {"order": order, "points in the band": f"{100 * band:.0f} %"}
        for name, m in (("ms with barrier", model), ("ms without", attrs.evolve(model, compaction=None))):
            m.evaluate(F, a, order=order)
            t0 = time.perf_counter()
            for _ in range(5):
                m.evaluate(F, a, order=order)
            row[name] = round(1e3 * (time.perf_counter() - t0) / 5, 1)
        rows.append(row)
    return rows


def table(rows: list[dict]) -> str:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    out = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    out += ["| " + " | ".join(str(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(out)


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("what", choices=["mesh", "iteration", "forms", "run", "law", "trace"])
    p.add_argument("--order", type=int, default=2)
    p.add_argument("--seed", type=float, default=1 / 3)
    p.add_argument("--contact", default="ipc", help="solid contact law: ipc (default), mortar or penalty")
    p.add_argument("--steps", type=int, default=6)
    p.add_argument(
        "--stitch-length", type=float, default=11.0, help="jersey stitch length of 'run' (10, 11, 12)"
    )
    p.add_argument("--prestress", type=int, default=4)
    p.add_argument(
        "--solvers",
        default="direct,amg",
        help="linear solvers to time in 'iteration': direct,pardiso,pardiso-lu,amg",
    )
    p.add_argument(
        "--contact-modulus",
        type=float,
        help="'run': modulus of the contact penalty, MPa (default E_transverse)",
    )
    p.add_argument(
        "--truncate", action="store_true", help="'run': keep the converged steps when a later one fails"
    )
    p.add_argument("--linear-solver", default="direct", help="linear-solver plugin of 'run'")
    p.add_argument("--newton", default="default", help="'run': the solver's [solver.newton] preset")
    p.add_argument("--checkpoint", help="'run': checkpoint directory; a killed run resumes from it")
    p.add_argument("--save", help="'run': write the Response as JSON here (input of benchmarks/agreement.py)")
    p.add_argument(
        "--trace",
        help="'run': append every Newton solve (history, diagnostic) to this JSON-lines file; "
        "'trace': the file to summarise",
    )
    p.add_argument(
        "--friction",
        action="store_true",
        help="'run': the scene asks for yarn-yarn friction (lagged Coulomb)",
    )
    p.add_argument(
        "--dhat",
        type=float,
        help="'run': barrier activation distance of the ipc law / mean surface edge length "
        "(default the law's, 0.1)",
    )
    p.add_argument(
        "--ccd",
        choices=["additive", "tight-inclusion"],
        help="'run': narrow-phase CCD of the ipc law (default the law's, additive)",
    )
    p.add_argument(
        "--reuse",
        type=float,
        help="'run': the ipc law keeps a broad-phase search while no vertex has moved over this × d̂ "
        "(default the law's, 0.5; 0 searches at every evaluation)",
    )
    p.add_argument(
        "--mu",
        type=float,
        help="'run': Coulomb friction coefficient of the contact law (default the law's, 0.3)",
    )
    p.add_argument(
        "--smoothing",
        help="'run': master surface of P1 contact of penalty and mortar, nagata (their default) or none",
    )
    p.add_argument(
        "--transverse-ratio",
        type=float,
        help="'run': set the yarn's E_transverse to this × E_axial (a diagnostic of the anisotropy)",
    )
    p.add_argument(
        "--step-tol",
        type=float,
        help="'run': also converged when the Newton step (exact, or projected) is ≤ this × r",
    )
    p.add_argument(
        "--tangent",
        choices=("adaptive", "exact", "projected"),
        help="'run': Newton's Hessian (default the solver's, projected)",
    )
    p.add_argument(
        "--predictor",
        choices=("affine", "secant"),
        help="'run': the load increments' predictor (default the solver's)",
    )
    p.add_argument(
        "--eigen",
        choices=("clamp", "abs", "element"),
        help="'run': eigenvalue filter of the projected tangent (default the solver's, clamp)",
    )
    p.add_argument(
        "--halve-reversals",
        choices=("on", "off"),
        help="'run': halve full Newton steps that reverse the last move (default the solver's)",
    )
    p.add_argument(
        "--extrapolate",
        type=float,
        help="'run': longest extrapolated step / full step (default the solver's, 1: off; 8 on P1 cells)",
    )
    p.add_argument(
        "--chord",
        choices=("on", "off"),
        help="'run': chord steps on a kept factorisation (default the solver's, on)",
    )
    p.add_argument(
        "--chord-full",
        choices=("on", "off"),
        help="'run': chord steps also after full Newton steps (default the solver's, on)",
    )
    p.add_argument("--iterations", action="store_true", help="'trace': one row per Newton iteration")
    p.add_argument(
        "--start-projected",
        action="store_true",
        help="'run': with the adaptive tangent, start every increment on the projected one",
    )
    p.add_argument(
        "--cap-shift",
        type=float,
        help="'run': raise the Levenberg shift while a Newton step exceeds this × the cap",
    )
    p.add_argument("--max-step", type=float, help="'run': the solver's cap on a Newton step, node move / r")
    p.add_argument(
        "--stabilisation", type=float, help="'run': the solver's stabilisation (weak foundation) factor"
    )
    p.add_argument("--threads", default="1,2", help="'forms': thread counts of the solid's element chunks")
    p.add_argument("--json")
    args = p.parse_args(argv)
    rows = {
        "mesh": bench_mesh,
        "iteration": bench_iteration,
        "forms": bench_forms,
        "run": bench_run,
        "law": bench_law,
        "trace": bench_trace,
    }[args.what](args)
    print(table(rows))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
