"""Two runs of the same input give the same result, bit for bit, without any setting.

Two things made the volumetric solver's runs differ: ipctk's threads (the broad phase's candidate order
and the sums over pairs follow how the work fell to them), now held to one inside the ``ipc`` law, and
the Newton driver's choice between chord and Newton steps by energy gained per wall second, now per
unit of counted work (:data:`knitframe.numerics.newton_driver.WORK_COST`).
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from knitframe_linsolvers.direct import direct
from test_newton import quartic

from knitframe.numerics.newton import NewtonOptions, minimise
from knitframe.numerics.newton_driver import WORK_COST


class _Solver:
    """The direct solver, counting its factorisations and the solves on kept factors."""

    def __init__(self):
        self.backend = direct()
        self.factorisations = self.solves = 0

    def __call__(self, A, b):
        return self.backend(A, b)

    def factorize(self, A):
        self.factorisations += 1
        kept = self.backend.factorize(A)

        def apply(b):
            self.solves += 1
            return kept(b)

        apply.free = getattr(kept, "free", lambda: None)
        return apply


def _jittery_quartic(calls, rng):
    """``quartic`` that sleeps a random time (0-3 ms) at each evaluation, counting its calls by order."""

    def fun(x, order=2, projected=False):
        calls[order] = calls.get(order, 0) + 1
        time.sleep(rng.uniform(0.0, 0.003))
        return quartic(x, order)

    return fun


def _run(seed):
    calls, solver = {}, _Solver()
    res = minimise(
        _jittery_quartic(calls, np.random.default_rng(seed)),
        np.full(8, 20.0),
        np.ones(8, bool),
        solve=solver,
        options=NewtonOptions(atol=1e-9, rtol=0.0, max_iter=200, chord=True, chord_full=True, max_chord=5),
        step_limit=lambda x, dx: min(1.0, 0.5 / float(np.max(np.abs(dx)))),
    )
    return res, calls, solver


def test_the_chord_rule_counts_work_and_not_seconds():
    """Evaluations that take random times give the same path and minimum, bit for bit; each iteration's
    ``work`` is its evaluations, factorisations and solves weighted by WORK_COST, and they add up to the
    whole run's."""
    (a, calls, solver), (b, _, _) = _run(1), _run(2)
    assert a.converged and b.converged
    assert any(h.get("chord") for h in a.history)
    assert np.array_equal(a.x, b.x) and a.energy == b.energy
    strip = [{k: v for k, v in h.items() if k != "wall_s"} for h in a.history]
    assert strip == [{k: v for k, v in h.items() if k != "wall_s"} for h in b.history]
    assert all(h["work"] > 0 for h in a.history)
    total = (
        sum(WORK_COST[order] * n for order, n in calls.items())
        + WORK_COST["factorisation"] * solver.factorisations
        + WORK_COST["solve"] * solver.solves
    )
    assert sum(h["work"] for h in a.history) == pytest.approx(total, rel=1e-12)


def test_ipctk_runs_on_one_thread_inside_the_law_and_keeps_its_count_outside():
    ipctk = pytest.importorskip("ipctk")
    from knitframe_contact.ipc import SolidIPC
    from knitframe_contact.ipc_mesh import one_thread
    from test_contact_ipc import _block_row

    threads = ipctk.get_num_threads()
    ipctk.set_num_threads(2)
    try:
        with one_thread():
            assert ipctk.get_num_threads() == 1
        assert ipctk.get_num_threads() == 2
        X, _, surf = _block_row(2, 0.04)
        law = SolidIPC(dhat=0.5)
        x = X + 0.01 * np.random.default_rng(3).normal(size=X.shape)
        runs = [law.evaluate(surf, x, np.zeros(6), 2, stiffness=1.0, reach=1.0) for _ in range(2)]
        assert ipctk.get_num_threads() == 2
    finally:
        ipctk.set_num_threads(threads)
    (E0, g0, H0, _), (E1, g1, H1, _) = runs
    assert E0 == E1 and np.array_equal(g0, g1) and (H0 != H1).nnz == 0


#: the small volumetric cell with every effect, run twice in one interpreter: its tensions as hex floats
RUN_TWICE = textwrap.dedent(
    """\
    import json
    from knitframe import get_registry
    from knitframe.records import Fabric, LoadPath, Scene

    reg = get_registry()
    out = []
    for _ in range(2):
        r = reg["solver"]["volumetric"](order=1, seed=1.0).simulate(
            Fabric(pattern="jersey", yarn=reg["yarn"]["cotton"], stitch_length=12),
            Scene(
                load=LoadPath(kind="equibiaxial", max_strain=0.05, steps=1),
                effects=("large_deformation", "bending", "contact", "prestress", "friction", "self_contact"),
            ),
        )
        out.append([float(t).hex() for t in (*r.T1, *r.T2)])
    print(json.dumps(out))
    """
)


@pytest.mark.slow
def test_small_cell_repeats_in_one_process_and_in_two():
    """Jersey cotton SL12, P1, barrier contact, pre-stress, friction, self-contact: two runs in one
    process and two in another, side by side, give the same tensions to the last bit (before, the last
    of two load steps differed by up to 4 %)."""
    pytest.importorskip("gmsh")
    pytest.importorskip("ipctk")
    procs = [
        subprocess.Popen(
            [sys.executable, "-W", "ignore", "-c", RUN_TWICE], stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        for _ in range(2)
    ]
    runs = []
    for p in procs:
        out, err = p.communicate(timeout=900)
        assert p.returncode == 0, err.decode()[-2000:]
        runs += json.loads(out.decode().strip().splitlines()[-1])
    assert len(runs) == 4 and all(r == runs[0] for r in runs)
